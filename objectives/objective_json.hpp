#pragma once
/// @file objective_json.hpp
/// Objectives from JSON (the "objective" of a problem file). The key schema
/// is documented in docs/objectives.md.

#include "objectives/objective.hpp"

#include <nlohmann/json_fwd.hpp>

#include <memory>
#include <string>
#include <vector>

namespace diffipc {

/// @brief Builds an objective from its JSON description, validated against the simulator's
/// scene (body names and indices, vertex and element indices, dimension, step count).
/// @param j     the objective object, e.g. {"type": "stress_norm", "p": 8}
/// @param field its JSON path, used in error messages ("objective", "objective.terms[1].objective")
/// @param sim   the simulation the objective will be evaluated on
/// @throws InputError naming the offending field, e.g. "objective.terms[1].objective.p".
std::unique_ptr<Objective> parse_objective(const nlohmann::json& j, const std::string& field, const Simulator& sim);

/// One "type" that parse_objective accepts.
struct ObjectiveType {
    std::string name; ///< the "type" string, e.g. "stress_norm"
    /// The other keys its object may hold, e.g. {"p", "norm", ...}; any other key is an error.
    std::vector<std::string> keys;
};

/// @brief The objective types parse_objective accepts, from the same table it builds them with,
/// as docs/objectives.md's "Objective types" table lists them (a test compares the two).
/// @return one entry per type; the reference stays valid for the program's lifetime
const std::vector<ObjectiveType>& registered_objective_types();

} // namespace diffipc
