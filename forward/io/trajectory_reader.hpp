#pragma once
/// @file trajectory_reader.hpp
/// trajectory.h5 read back (for `simulate --restart`), also a file whose writer was killed
/// (it is opened in SWMR mode; docs/output_format.md). The per-step diagnostics are read
/// whole; the states (positions, velocities, accelerations: 3 x N x d values per step) only
/// where asked for, so that continuing a long run does not hold all of it in memory.

#include "forward/simulation/step_record.hpp"

#include <string>

namespace diffipc {

/// What read_trajectory() returns: the initial state and every step in the file, as records
/// (the diagnostics the file keeps; the state only for the steps asked for).
struct StoredTrajectory {
    std::string path;
    Index vertices = 0;
    int dim = 0;
    bool contact = false;
    std::string scene; ///< the root attribute "scene" ("" if absent)
    Trajectory trajectory; ///< initial state and steps 1 .. T, first_index 1
};

/// @brief Reads `path`: the initial state, every step's diagnostics, and the states of the
/// last `last_states` steps (all of them if negative); the other records hold no state.
/// @throws InputError naming the file if it is missing, unreadable, not a diffipc trajectory,
/// or holds a step that is not converged or not finite
StoredTrajectory read_trajectory(const std::string& path, int last_states = -1);

/// @brief Reads the states of steps first .. last (1-based, within stored.trajectory) into
/// their records, from the file `stored` was read from.
/// @throws InputError naming the file if it cannot be read or a state is not finite
void read_states(StoredTrajectory& stored, int first, int last);

} // namespace diffipc
