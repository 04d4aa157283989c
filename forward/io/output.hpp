#pragma once
/// @file output.hpp
/// The run's summary.json (docs/output_format.md); trajectory.h5 is written by
/// trajectory_writer.hpp, the VTU frames by vtu_frame.hpp.

#include "forward/io/trajectory_writer.hpp"
#include "forward/simulation/simulator.hpp"

#include <nlohmann/json_fwd.hpp>

#include <string>

namespace diffipc {

/// @brief The run's summary: status, counts, per-phase wall times.
nlohmann::json summary_json(const Simulator& simulator);
/// @brief Writes `value` to `path` (replaced whole, forward/io/replace_file.hpp).
/// @throws InputError naming `path` if it cannot be written
void write_json(const std::string& path, const nlohmann::json& value);

} // namespace diffipc
