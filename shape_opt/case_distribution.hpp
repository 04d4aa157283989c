#pragma once
/// @file case_distribution.hpp
/// A problem's load cases evaluated over the processes of a Communicator (issue 18).
///
/// Each process runs ReducedFunctional::evaluate_case for the cases assigned to it (assign_cases:
/// round robin at first, then the longest-processing-time rule on each case's last measured
/// seconds); rank 0 gathers the shares and adds them in case order (add_share), then makes
/// evaluate()'s checks on the sum (check_sum). So J, the constraints and the gradients are evaluate()'s
/// bits with any number of processes and any assignment. If cases fail, the lowest failing case's
/// error is thrown, with its type and message, as evaluate() throws the first.
///
/// Two ways to run:
/// - DRIVER (the CLI): rank 0 alone calls evaluate(); it sends the problem (LOAD, its document) and
///   each evaluation's parameters to the other ranks, which serve() until rank 0 calls stop().
/// - COLLECTIVE (Python with mpi4py): every rank calls evaluate() with its own copy of the problem;
///   rank 0's p is used, and every rank gets the result (or the error).

#include "shape_opt/communicator.hpp"
#include "shape_opt/reduced_functional.hpp"

#include <deque>
#include <functional>
#include <map>

namespace diffipc {

class CaseDistribution {
public:
    enum class Mode { DRIVER, COLLECTIVE };
    /// @throws std::invalid_argument without a communicator
    CaseDistribution(std::shared_ptr<Communicator> communicator, Mode mode);
    ~CaseDistribution();

    int rank() const { return m_rank; }
    int size() const { return m_size; }
    Mode mode() const { return m_mode; }

    /// @brief J.evaluate(p, gradient, constraints) over the processes: in DRIVER mode on rank 0
    /// only, in COLLECTIVE mode on every rank.
    /// @throws what evaluate() throws (the lowest failing case's error); std::logic_error when called
    ///         on a serving rank
    Evaluation evaluate(const ReducedFunctional& J, const VectorXd& p, bool gradient, bool constraints);

    /// @brief DRIVER mode, ranks > 0: load problems and evaluate their cases as rank 0 asks, until
    /// it calls stop(). A problem that does not load here is reported with every case of the next
    /// evaluation. Errors outside a case (bytes that do not decode) end the job (Communicator::abort).
    void serve();
    /// @brief DRIVER mode, rank 0: ends the other ranks' serve(). Idempotent; rank 0's destructor
    /// calls it.
    void stop();

    /// Time of the evaluations so far, s: rank 0's wall time in evaluate(), and per rank the time in
    /// its cases (compute) and in loading problems (loading, counted with the evaluation after the
    /// load); the rest of a rank's wall time went to communication and waiting.
    struct Times {
        int evaluations = 0;
        double wall = 0;
        std::vector<double> compute; ///< per rank
        std::vector<double> loading; ///< per rank: loading the problems rank 0 sent (ranks > 0, DRIVER mode)
        std::vector<int> cases; ///< cases evaluated, per rank
    };
    const Times& times() const { return m_times; }
    /// The owner of every case in the last evaluation (assign_cases), and on rank 0 the costs it was
    /// assigned by: each case's seconds in the evaluation before (empty for a problem's first: round robin).
    const std::vector<int>& last_assignment() const { return m_last_owner; }
    const std::vector<double>& last_assignment_costs() const { return m_assignment_costs; }

    /// Rank 0: the cost that the next assignment balances a case by, from the seconds the case took in
    /// this evaluation (unset: those seconds). Measured seconds vary from run to run on a busy machine;
    /// a caller that knows its cases' relative costs (and the tests, which must not depend on timings)
    /// sets this to make the assignment reproducible.
    std::function<double(size_t load_case, double seconds)> case_cost;

    /// Called by rank 0 while it waits for the other ranks' shares: with a line naming each rank and
    /// its cases before, with "" after (the CLI keeps it to print if the job is ended meanwhile).
    std::function<void(const std::string&)> on_wait;

private:
    std::string request(const ReducedFunctional& J, const VectorXd& p, bool gradient, bool constraints);
    std::string evaluate_mine(const ReducedFunctional* J, const std::string& request, const std::string& load_error);
    Evaluation combine(
        const ReducedFunctional& J, const std::vector<std::string>& replies, bool gradient, bool constraints);
    void load_on_servers(const ReducedFunctional& J);

    std::shared_ptr<Communicator> m_comm;
    Mode m_mode;
    int m_rank = 0, m_size = 1;
    bool m_stopped = false;
    Times m_times;
    std::vector<int> m_last_owner;
    // Rank 0: the last measured seconds of each case of the problem with this id (empty: none yet).
    uint64_t m_cost_problem = 0;
    std::vector<double> m_costs, m_assignment_costs;
    double m_unreported_loading = 0; ///< a serving rank's seconds in LOAD since its last reply
    // DRIVER mode: the problems the serving ranks hold, oldest first (rank 0's copy of the list).
    std::deque<uint64_t> m_loaded;
};

} // namespace diffipc
