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

/// @brief contact_slabs' scene with other resolutions: a slab of 1 x 0.2 x 1 m (`slab_cells` cubes, 6 tets
/// each) dropped at 1 m/s from 2 mm onto a clamped base of 1.2 x 0.15 x 1.2 m (`base_cells`).
nlohmann::json contact_slabs(std::vector<int> base_cells, std::vector<int> slab_cells, int steps, double friction);

} // namespace diffipc
