#pragma once
#include <string>

namespace diffipc {

struct BenchOptions {
    std::string size = "full"; ///< small: seconds, for a smoke run; full: the documented figures
    int steps = 4;
};

/// Runs the fixed benchmark scenes and prints per-phase timings; returns an exit code.
int run_bench(const BenchOptions& options);

} // namespace diffipc
