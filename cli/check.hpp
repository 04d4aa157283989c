#pragma once
/// @file check.hpp
/// `diffipc check`: the committed states of a run checked by the exact tests of
/// forward/contact/intersection.hpp (GMP rationals, independent of the distance, broad-phase and
/// CCD code the solver steps with).

#include <string>

namespace diffipc {

/// @brief Checks every state in run_dir/trajectory.h5 (the initial one and each committed step):
/// no element inverted, no pair of surface primitives intersecting (every body also against
/// itself, whatever its self_contact flag) and no body inside another's closed surface.
/// @param scene_path the scene the run was made from (empty: the one the trajectory names)
/// @return 0 if every state is valid, 2 if one is not (each invalid state is printed)
/// @throws InputError for a missing or unreadable run or scene (exit 1)
int check_run(const std::string& run_dir, std::string scene_path, bool quiet);

} // namespace diffipc
