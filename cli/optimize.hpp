#pragma once
#include <string>

namespace diffipc {

/// @brief `diffipc optimize PROBLEM.json -o DIR`: runs the problem's optimizer on its design
/// variables (docs/optimization.md). Prints a line per iteration; writes history.csv,
/// summary.json (why it stopped), the rest design as VTU at chosen iterations with a .pvd,
/// and optimal_problem.json (the problem starting from the optimum).
/// @return 0 when the optimizer ended (a tolerance, a budget, a stalled line search:
/// summary.json says which), 2 if the initial design cannot be evaluated or the library
/// failed, 130 / 143 when stopped by SIGINT / SIGTERM (the outputs are written).
int optimize(const std::string& problem_path, std::string out_dir, bool quiet);

} // namespace diffipc
