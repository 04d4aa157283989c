#pragma once
#include <string>

namespace diffipc {

struct BenchOptions {
    std::string size = "full"; ///< small: seconds, for a smoke run; full: the documented figures
    int steps = 4;
    /// forward: elasticity without contact; contact: the ~20k-tet contact scene;
    /// scenes: the full contact studies (studies/2xx) run to the end with exact checks;
    /// adjoint: the contact scene with a fixed kappa, then shape and material gradients
    std::string suite = "forward";
    std::string source_dir = "."; ///< repository root (for the studies)
    double friction = 0; ///< contact suite: friction coefficient of the slabs (0: frictionless)
};

/// Runs the fixed benchmark scenes and prints per-phase timings; returns an exit code.
int run_bench(const BenchOptions& options);

} // namespace diffipc
