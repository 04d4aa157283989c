#pragma once
/// @file study.hpp
/// `diffipc study NAME [--full] [--threads N]`: runs a study of the source tree this CLI was built
/// from (studies/NAME*/run.py) with this CLI and its Python module.

#include <string>
#include <vector>

namespace diffipc {

struct StudyOptions {
    std::string name; ///< a study folder's name or its number ("502" or "502_error_vs_time")
    bool full = false; ///< the study's --full sweep
    bool list = false; ///< print the studies that have a run.py and return
};

/// @brief The folders under `studies` with a run.py, sorted.
std::vector<std::string> runnable_studies(const std::string& studies);

/// @brief Runs the study's run.py with /usr/bin/python3 (or $DIFFIPC_PYTHON), PYTHONPATH set to this
/// build's Python module and DIFFIPC_CLI to this executable. Of `--results studies/NAME` (its
/// figures, tables and CSV into its own folder), `-o output/NAME` (its runs) and `--cli` (this
/// executable), those the script declares are passed, and `--full` when asked. Studies are found
/// in $DIFFIPC_STUDIES, else in the source tree's studies/.
/// @return the study's exit code
/// @throws InputError("study", ...) for an unknown or ambiguous name, naming the studies there are
int run_study(const StudyOptions& options);

} // namespace diffipc
