#pragma once
/// @file optimization_history.hpp
/// What an optimization run keeps in its output directory to be read and continued
/// (docs/output_format.md, docs/optimization.md):
///
/// - history.h5 and history.csv: a row per iteration (x, J, the constraints' values by name,
///   norms, counts, times), appended and flushed as the run goes, so that a run that is
///   killed keeps every iteration it completed. history.h5 is an HDF5 single-writer /
///   multiple-reader file with extendible chunked datasets (as trajectory.h5).
/// - optimizer_state.h5: the state after the last completed iteration (the optimizer's
///   checkpoint, shape_opt/optimizer/optimizer.hpp, and the objective's scale), replaced whole
///   after every iteration (written next to it and renamed), so that it is never half written.
///
/// A row reaches the history before the state is replaced: after a kill the state's iteration
/// is the last row's or the one before, and `diffipc optimize --resume` drops the rows after
/// the state's iteration.

#include "shape_opt/optimizer/optimizer.hpp"

#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace diffipc {

/// What history.h5 says about the run as a whole (its root attributes).
struct HistoryHeader {
    std::string problem; ///< the problem file the run was started with
    std::string algorithm; ///< to_string(OptimizerAlgorithm)
    Index design_size = 0; ///< n
    std::vector<std::string> constraint_names; ///< m, the problem's order
};

/// One iteration's row.
struct HistoryRow {
    int iteration = 0; ///< 0: the start
    VectorXd x; ///< n design variables
    double J = 0; ///< the objective, unscaled
    VectorXd constraints; ///< m values g_i (unscaled, not compared with their bounds)
    double gradient_norm = 0; ///< as the optimizer reports it (IterationInfo::gradient_norm)
    double step_norm = 0; ///< inf-norm of the iteration's change of x
    int evaluations = 0, rejected = 0; ///< so far
    double evaluation_seconds = 0, optimizer_seconds = 0, wall_seconds = 0; ///< so far
};

/// Writes history.h5 and history.csv into a directory, a row at a time.
class HistoryWriter {
public:
    /// @brief Creates `directory`/history.h5 and history.csv, replacing them, holding `rows`
    /// (a resumed run's earlier rows; empty for a new run). Both are first written under a
    /// temporary name and renamed once complete.
    /// @throws InputError naming the file if it cannot be written
    HistoryWriter(const std::string& directory, const HistoryHeader& header, const std::vector<HistoryRow>& rows = {});
    /// Closes the files; errors are swallowed here (call close() to see them).
    ~HistoryWriter();
    HistoryWriter(const HistoryWriter&) = delete;
    HistoryWriter& operator=(const HistoryWriter&) = delete;

    /// @brief Appends a row to both files and flushes them.
    /// @throws InputError naming the file (a full disk, or a row that does not fit the header)
    void append(const HistoryRow& row);
    /// @brief Closes both files; a failure is an InputError naming the file.
    void close();
    /// Rows in the files.
    int rows() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// history.h5 read back.
struct StoredHistory {
    std::string path;
    HistoryHeader header;
    std::vector<HistoryRow> rows; ///< every complete row (the shortest dataset's length)
};

/// @brief Reads a history.h5, also one whose writer was killed (opened in SWMR mode).
/// @throws InputError naming the file if it is missing, unreadable or not a diffipc history
StoredHistory read_history(const std::string& path);

/// What optimizer_state.h5 holds.
struct RunState {
    OptimizerCheckpoint checkpoint;
    double objective_scale = 1; ///< J = objective_scale * f (DesignProblem::objective_scale())
    std::string last_rejection; ///< why the last rejected point was rejected ("" if none was)
};

/// @brief Writes `path` through `path + ".tmp"`, renamed over it once complete.
/// @throws InputError naming `path` if it cannot be written
void write_run_state(const std::string& path, const RunState& state);

/// @brief Reads a file written by write_run_state().
/// @throws InputError naming `path` if it is missing, unreadable or incomplete
RunState read_run_state(const std::string& path);

} // namespace diffipc
