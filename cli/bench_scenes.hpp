#pragma once
/// @file bench_scenes.hpp
/// The fixed benchmark scenes shared by `diffipc bench` suites (docs/performance.md).

#include <nlohmann/json.hpp>

#include <vector>

namespace diffipc {

/// @brief A box of `cells` (dim numbers) cubes of P1 elements (6 tets / 2 triangles each) of
/// `extent` (m), clamped at x = 0, under gravity, implicit Euler with `steps` steps of dt.
nlohmann::json beam(int dim, const std::string& model, std::vector<int> cells, std::vector<double> extent, int steps,
    double E = 1e6, double dt = 0.01);

/// @brief The ~20k-tet contact scene (full) or a ~1k-tet one: a soft slab dropped on a clamped one.
/// @param friction coefficient of both slabs (0: frictionless)
nlohmann::json contact_slabs(bool full, int steps, double friction);

} // namespace diffipc
