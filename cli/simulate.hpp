#pragma once
/// @file simulate.hpp
/// `diffipc simulate`.

#include "forward/simulation/simulator.hpp"

#include <memory>
#include <string>

namespace diffipc {

/// @brief The simulator of a loaded scene; its InputErrors (contact settings against the
/// geometry, for example) name the scene file like the scene's own.
std::unique_ptr<Simulator> open_simulator(Scene scene, const std::string& scene_path);

/// The options of `diffipc simulate`.
struct SimulateOptions {
    std::string scene_path; ///< the scene file (with `restart`, empty: the one the stored run names)
    std::string out_dir; ///< output directory (empty: the scene's output.directory)
    int vtu_every = -1; ///< VTU frame interval (-1: the scene's)
    int steps = -1; ///< time steps, replacing the scene's time.steps (-1: the scene's)
    bool quiet = false;
    std::string device; ///< "cpu" | "gpu": replaces the scene's "device" (empty: the scene's)
    std::string restart; ///< non-empty: continue the run in this directory from its trajectory.h5
};

/// @brief Runs a scene, streaming trajectory.h5, summary.json and VTU frames into the output directory.
/// @return the exit code: 0, 2 (a step failed) or 128 + signal (stopped by SIGINT/SIGTERM)
/// @throws InputError for bad input (exit 1)
int simulate(SimulateOptions options);

} // namespace diffipc
