#pragma once
#include <string>
#include <vector>

namespace diffipc {

struct BenchOptions {
    std::string size = "full"; ///< small: seconds, for a smoke run; full: the documented figures
    int steps = 4;
    /// forward: elasticity without contact; contact: the ~20k-tet contact scene;
    /// scenes: the full contact studies (studies/2xx) run to the end with exact checks;
    /// adjoint: the contact scene with a fixed kappa, then shape and material gradients;
    /// scaling: the 50k and 200k-tet boxes, the contact scene and the adjoint per thread count;
    /// gpu: the elastic boxes on the CPU and the GPU path
    std::string suite = "forward";
    std::string source_dir = "."; ///< repository root (for the studies)
    double friction = 0; ///< contact suite: friction coefficient of the slabs (0: frictionless)
    /// scaling suite: thread counts (default 1, 2, 4, ... up to the usable cores)
    std::vector<int> thread_counts;
    /// scaling suite: which of "50k,200k,contact,adjoint,factor" to run (empty: all)
    std::string scenes;
};

/// Runs the fixed benchmark scenes and prints per-phase timings; returns an exit code.
int run_bench(const BenchOptions& options);

/// The scaling suite (cli/bench_scaling.cpp): every scene per thread count, efficiency per phase.
int run_scaling_bench(const BenchOptions& options);

/// The gpu suite (cli/bench_gpu.cpp): 50k, 200k and 1M-tet boxes on the CPU path (all usable cores)
/// and on the GPU path, side by side; `scenes` picks any of 50k,200k,1m.
int run_gpu_bench(const BenchOptions& options);

/// @brief CHOLMOD's and diffipc's numeric factorization of the same Newton matrices (the two
/// boxes, the contact scene) per thread count (cli/bench_factorization.cpp).
/// @param repeats factorizations per count; the fastest is printed
void factorization_comparison(bool full, const std::vector<int>& counts, int repeats);

} // namespace diffipc
