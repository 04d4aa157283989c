#pragma once
#include <memory>
#include <string>

namespace diffipc {

class CaseDistribution;

/// What `diffipc optimize` was asked to do.
struct OptimizeOptions {
    std::string problem_path; ///< the problem file; with resume_dir may be empty (the run's initial_problem.json)
    std::string out_dir; ///< "" : the file's output.directory, else output/<stem>
    std::string resume_dir; ///< continue the run in this directory ("": a new run)
    bool quiet = false;
    int max_iterations = -1; ///< >= 0: replaces the file's optimizer.max_iterations
    double max_seconds = -1; ///< >= 0: replaces the file's optimizer.max_seconds
    std::string device; ///< "cpu" or "gpu": replaces the scenes' "device" ("": theirs)
    /// Under mpirun: the load cases over the ranks (rank 0 runs optimize; null: this process alone).
    std::shared_ptr<CaseDistribution> distribution;
};

/// @brief `diffipc optimize PROBLEM.json -o DIR` and `diffipc optimize --resume DIR`: runs the
/// problem's optimizer on its design variables, or continues a run that was stopped
/// (docs/optimization.md). Prints a line per iteration; writes initial_problem.json (the
/// problem as started, with absolute paths), history.h5 and history.csv (a row per iteration,
/// flushed as the run goes), optimizer_state.h5 (what a resume continues from), summary.json
/// (why it stopped), the rest design as VTU at chosen iterations with a .pvd, and
/// optimal_problem.json (the problem starting from the optimum).
/// @return 0 when the optimizer ended (a tolerance, a budget, a stalled line search:
/// summary.json says which), or when a resume finds the run already converged; 1 on bad input
/// (InputError, also a run that cannot be resumed); 2 if the initial design cannot be evaluated
/// or the library failed; 130 / 143 when stopped by SIGINT / SIGTERM (the outputs are written).
int optimize(const OptimizeOptions& options);

} // namespace diffipc
