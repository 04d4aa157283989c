#pragma once
/// @file trajectory_writer.hpp
/// trajectory.h5 written as the run goes (docs/output_format.md).
///
/// Every per-step dataset is chunked and extendible along its first axis; a committed
/// step is queued when given and reaches the file in batches (up to 64 steps, about
/// 4 MB) and at every flush() (the CLI flushes at most a second apart, and at the end). The file is in
/// HDF5's single-writer/multiple-reader mode: h5py opens it at any time (also with
/// `swmr=True` to follow a live run) and finds every flushed step; after the writer is
/// killed it holds every step up to the last flush.

#include "forward/mesh/mesh.hpp"
#include "forward/simulation/step_record.hpp"

#include <memory>
#include <string>

namespace diffipc {

class TrajectoryWriter {
public:
    /// @brief Creates `path` (replacing it) with the mesh group and the initial state (row 0).
    /// @param contact also write the contact datasets (min_distance, active_contacts, kappa, ...)
    /// @param attributes text attributes of the root group (name, value), e.g. the program version
    /// @param load_stepping also write the automatic load stepping datasets (substeps, cuts, min_increment)
    /// @throws InputError naming the file if it cannot be created or written
    TrajectoryWriter(const std::string& path, const Mesh& mesh, const Trajectory& initial, bool contact,
        const std::vector<std::pair<std::string, std::string>>& attributes = {}, bool load_stepping = false);
    /// Closes the file; errors are swallowed here (call close() to see them).
    ~TrajectoryWriter();
    TrajectoryWriter(const TrajectoryWriter&) = delete;
    TrajectoryWriter& operator=(const TrajectoryWriter&) = delete;

    /// @brief Appends committed step `record` (the next index).
    /// @throws InputError naming the file (a full disk, for instance)
    void append(const StepRecord& record);
    /// @brief Writes everything appended so far to the file.
    /// @throws InputError naming the file
    void flush();
    /// @brief Flushes and closes; a failure (a full disk) is an InputError naming the file.
    void close();

    int steps() const;
    const std::string& path() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

/// @brief Writes a whole trajectory at once (TrajectoryWriter over every step).
void write_hdf5(const std::string& path, const Mesh& mesh, const Trajectory& trajectory, bool contact = false,
    bool load_stepping = false);

} // namespace diffipc
