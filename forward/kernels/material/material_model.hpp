#pragma once
/// @file material_model.hpp
/// The hyperelastic laws, one enum for the CPU and the GPU paths, and their names in scene files,
/// registered here and nowhere else (parse_material_model and to_string read this table; the GPU
/// checks its codes against MATERIAL_MODEL_COUNT).

#include "forward/kernels/host_device.hpp"

namespace diffipc::kernels {

enum class MaterialModel : int {
    LINEAR = 0, ///< small-strain linear elasticity
    STVK = 1, ///< Saint Venant-Kirchhoff
    NEO_HOOKEAN = 2, ///< neo-Hookean of the IPC family (log J; requires J > 0)
    STABLE_NEO_HOOKEAN = 3, ///< stable neo-Hookean (Smith, de Goes, Kim 2018)
};

/// Number of laws: the codes are 0 .. MATERIAL_MODEL_COUNT - 1.
constexpr int MATERIAL_MODEL_COUNT = 4;

/// The scene file's name of each law, indexed by its code.
constexpr const char* MATERIAL_MODEL_NAMES[MATERIAL_MODEL_COUNT]
    = { "linear", "stvk", "neo_hookean", "stable_neo_hookean" };

} // namespace diffipc::kernels
