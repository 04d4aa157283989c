#include "cli/distributed_run.hpp"

#include "cli/stop_signal.hpp"
#include "forward/common/threads.hpp"

#ifdef DIFFIPC_HAVE_MPI
#include "shape_opt/mpi_communicator.hpp"
#endif

#include <algorithm>

namespace diffipc {

#ifdef DIFFIPC_HAVE_MPI
struct DistributedRun::Session {
    MpiSession mpi;
    Session(int* argc, char*** argv)
        : mpi(argc, argv)
    {
    }
};
#else
struct DistributedRun::Session { };
#endif

std::unique_ptr<DistributedRun> DistributedRun::start(int* argc, char*** argv)
{
#ifdef DIFFIPC_HAVE_MPI
    if (!launched_by_mpi())
        return nullptr;
    std::unique_ptr<DistributedRun> run(new DistributedRun());
    run->m_session = std::make_unique<Session>(argc, argv);
    run->m_world = run->m_session->mpi.world();
    return run;
#else
    (void)argc;
    (void)argv;
    return nullptr;
#endif
}

DistributedRun::~DistributedRun()
{
    if (m_world && m_world->rank() == 0 && !m_every_rank) {
        // The serving ranks wait for rank 0's next message however it ended (a usage error, --help, a command
        // other than optimize or gradcheck): tell them to stop.
        set_waiting_message("");
        try {
            distribution()->stop();
        } catch (...) {
            // The other ranks are gone already.
        }
    }
    m_distribution.reset();
}

int DistributedRun::rank() const { return m_world->rank(); }
int DistributedRun::size() const { return m_world->size(); }

const std::shared_ptr<CaseDistribution>& DistributedRun::distribution()
{
    if (m_distribution)
        return m_distribution;
    m_distribution = std::make_shared<CaseDistribution>(m_world, CaseDistribution::Mode::DRIVER);
    if (m_world->rank() == 0) {
        // If the job is ended while rank 0 waits (a rank died; mpirun signals the rest), say for whom.
        end_on_signals_while_waiting();
        m_distribution->on_wait = [](const std::string& ranks) {
            set_waiting_message(ranks.empty() ? ""
                                              : "diffipc: rank 0 was stopped while it waited for the load cases of "
                        + ranks + " (if a rank ended, mpirun names it); the iterations written so far are kept\n");
        };
    }
    return m_distribution;
}

void DistributedRun::divide_cores()
{
#ifdef DIFFIPC_HAVE_MPI
    const ThreadConfig config = thread_config();
    if (config.source != ThreadSource::DEFAULT)
        return;
    const CoreBudget cores = core_budget();
    const int here = m_session->mpi.ranks_on_this_node();
    // A launcher that bound each rank to its own cores left the affinity mask smaller than the node.
    if (here <= 1 || cores.affinity < cores.hardware)
        return;
    const int threads = std::max(1, cores.usable / here);
    set_threads(threads, ThreadSource::DEFAULT, "the usable cores / " + std::to_string(here) + " ranks on this node");
#endif
}

int DistributedRun::serve()
{
    distribution()->serve();
    return 0;
}

nlohmann::json distribution_summary(const CaseDistribution& distribution)
{
    const CaseDistribution::Times& t = distribution.times();
    nlohmann::json ranks = nlohmann::json::array();
    for (int r = 0; r < distribution.size(); ++r)
        ranks.push_back({ { "rank", r }, { "load_cases_evaluated", t.cases[size_t(r)] },
            { "seconds_in_load_cases", t.compute[size_t(r)] }, { "seconds_loading_problems", t.loading[size_t(r)] } });
    return { { "ranks", distribution.size() }, { "evaluations", t.evaluations }, { "evaluation_wall_seconds", t.wall },
        { "per_rank", ranks } };
}

} // namespace diffipc
