#pragma once
/// @file distributed_run.hpp
/// The CLI under mpirun (issue 18): `mpirun -n N diffipc optimize|gradcheck PROBLEM.json` runs the
/// command on rank 0, which drives, prints and writes; ranks 1..N-1 evaluate the load cases rank 0
/// gives them (CaseDistribution::serve) until it is done. `sweep` runs on every rank (each its share of
/// the runs); other commands run on rank 0 alone.
/// Without DIFFIPC_MPI, or when no MPI launcher started the process, there is no DistributedRun.

#include "shape_opt/case_distribution.hpp"

#include <nlohmann/json.hpp>

#include <memory>

namespace diffipc {

class DistributedRun {
public:
    /// @brief MPI initialised, if this build has MPI and a launcher started the process (one rank
    /// too: the same path as N); else null.
    /// @throws std::runtime_error if MPI cannot be initialised
    static std::unique_ptr<DistributedRun> start(int* argc, char*** argv);
    ~DistributedRun();

    int rank() const;
    int size() const;
    /// Every rank of the job (MPI_COMM_WORLD), for a command all ranks run (sweep).
    const std::shared_ptr<Communicator>& world() const { return m_world; }
    /// Rank 0 driving the others (made at the first call; then rank 0's end stops the serving ranks).
    const std::shared_ptr<CaseDistribution>& distribution();

    /// @brief Threads per rank when nothing chose them (no --threads, DIFFIPC_THREADS or file
    /// setting): the cores this process may use, divided by the ranks on this node when the launcher
    /// did not bind the ranks to parts of the node already.
    void divide_cores();
    /// @brief Ranks > 0: serve rank 0 until it stops the run; returns the exit code (0).
    int serve();
    /// @brief A command every rank runs (sweep): then no rank serves, and rank 0's end stops none. Otherwise
    /// rank 0's end (whatever ended it: a command, an error, --help) stops the serving ranks.
    void run_on_every_rank() { m_every_rank = true; }

private:
    DistributedRun() = default;
    struct Session;
    std::unique_ptr<Session> m_session;
    std::shared_ptr<Communicator> m_world;
    std::shared_ptr<CaseDistribution> m_distribution;
    bool m_every_rank = false;
};

/// The processes of a run for summary.json: ranks, evaluations, and per rank its cases and seconds
/// in them.
nlohmann::json distribution_summary(const CaseDistribution& distribution);

} // namespace diffipc
