// shape_opt/case_distribution.hpp in one process: rank 0 (this thread) drives a serving rank 1 (another thread)
// through an in-memory communicator that lets one of them run at a time. The distributed evaluation gives
// ReducedFunctional::evaluate's bits, problems travel by LOAD (two held, the older dropped), a failing case on
// rank 1 is the serial error with its type and message, and misuse is refused. The MPI runs themselves are
// tests/python/test_mpi_runs.py and test_mpi_python.py.

#include "shape_opt/case_distribution.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "objectives/objective.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>

using namespace diffipc;
using nlohmann::json;

namespace {

/// Rank 0 and rank 1 in one process. Rank 0's broadcast returns only once rank 1 has taken the message and is
/// blocked in the communicator again, so the two never compute at the same time.
struct Channel {
    std::mutex mutex;
    std::condition_variable changed;
    std::deque<std::string> to_server, to_driver;
    bool server_waiting = false;
    bool server_gone = false; ///< rank 1's serve() ended (then rank 0 waits for nothing)
    int broadcasts = 0; ///< messages rank 0 sent
};

class ThreadCommunicator : public Communicator {
public:
    ThreadCommunicator(std::shared_ptr<Channel> channel, int rank)
        : m_channel(std::move(channel))
        , m_rank(rank)
    {
    }
    int rank() const override { return m_rank; }
    int size() const override { return 2; }
    void broadcast(std::string& bytes) override
    {
        std::unique_lock<std::mutex> lock(m_channel->mutex);
        if (m_rank == 0) {
            ++m_channel->broadcasts;
            m_channel->to_server.push_back(bytes);
            m_channel->changed.notify_all();
            m_channel->changed.wait(lock,
                [&] { return (m_channel->to_server.empty() && m_channel->server_waiting) || m_channel->server_gone; });
            return;
        }
        m_channel->server_waiting = true;
        m_channel->changed.notify_all();
        m_channel->changed.wait(lock, [&] { return !m_channel->to_server.empty(); });
        bytes = m_channel->to_server.front();
        m_channel->to_server.pop_front();
        m_channel->server_waiting = false;
    }
    std::vector<std::string> gather(const std::string& mine) override
    {
        std::unique_lock<std::mutex> lock(m_channel->mutex);
        if (m_rank == 1) {
            m_channel->to_driver.push_back(mine);
            m_channel->server_waiting = true; // until its next broadcast: nothing runs in between
            m_channel->changed.notify_all();
            return {};
        }
        m_channel->changed.wait(lock, [&] { return !m_channel->to_driver.empty() || m_channel->server_gone; });
        if (m_channel->to_driver.empty())
            throw std::runtime_error("rank 1 ended");
        std::vector<std::string> all { mine, m_channel->to_driver.front() };
        m_channel->to_driver.pop_front();
        return all;
    }
    [[noreturn]] void abort(const std::string& message, int) override { throw std::runtime_error(message); }

private:
    std::shared_ptr<Channel> m_channel;
    int m_rank;
};

/// A clamped 2D strip under gravity (E per body): three load cases with their own gravity, weight and steps (3,
/// 4 and 12), and a constraint on case 2. With `undefined_case` >= 0, that case's objective is sqrt(-energy): not
/// defined; with `failing_case` >= 0, that case's Newton solver stops after one iteration: its first step fails.
json strips(int undefined_case = -1, double gravity_scale = 1, int failing_case = -1)
{
    json scenes = json::array();
    for (int c = 0; c < 3; ++c) {
        json scene = { { "dimension", 2 },
            { "bodies",
                { { { "name", "b" },
                    { "mesh", { { "box", { { "min", { 0, 0 } }, { "max", { 0.5, 0.1 } }, { "cells", { 6, 2 } } } } } },
                    { "material",
                        { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 1000 } } } } } },
            { "dirichlet",
                { { { "body", "b" }, { "region", { { "min", { -1, -1 } }, { "max", { 1e-6, 1 } } } },
                    { "displacement", { 0, 0 } } } } },
            { "gravity", { 0, -9.81 * gravity_scale * (1 + c) } },
            { "time", { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", c == 2 ? 12 : 3 + c } } },
            { "solver", { { "residual_tolerance", 1e-10 } } } };
        if (c == failing_case)
            scene["solver"]["max_iterations"] = 1;
        json objective = { { "type", "elastic_energy" }, { "time", "final" } };
        if (c == undefined_case)
            objective = { { "type", "power" }, { "q", 0.5 },
                { "objective",
                    { { "type", "sum" }, { "terms", { { { "weight", -1 }, { "objective", objective } } } } } } };
        scenes.push_back({ { "scene", scene }, { "objective", objective }, { "weight", 1.0 / (1 + c) } });
    }
    return { { "scenes", scenes }, { "parameters", { { { "type", "E" }, { "per", "body" }, { "body", "b" } } } },
        { "constraints",
            { { { "name", "energy" }, { "objective", { { "type", "elastic_energy" }, { "time", "final" } } },
                { "upper", 1.0 }, { "case", 2 } } } } };
}

/// The longest-processing-time rule written out here (not shape_opt/distribution.cpp's): cases by decreasing
/// cost (ties: lower case), each to the least loaded process (ties: lower process).
std::vector<int> longest_first(const std::vector<double>& costs, int processes)
{
    std::vector<size_t> order;
    for (size_t c = 0; c < costs.size(); ++c)
        order.push_back(c);
    std::sort(order.begin(), order.end(),
        [&](size_t a, size_t b) { return costs[a] > costs[b] || (costs[a] == costs[b] && a < b); });
    std::vector<double> load(size_t(processes), 0.0);
    std::vector<int> owner(costs.size());
    for (const size_t c : order) {
        int least = 0;
        for (int p = 1; p < processes; ++p)
            if (load[size_t(p)] < load[size_t(least)])
                least = p;
        owner[c] = least;
        load[size_t(least)] += costs[c];
    }
    return owner;
}

bool same_bits(const VectorXd& a, const VectorXd& b)
{
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * size_t(a.size())) == 0;
}

void expect_same_bits(const Evaluation& a, const Evaluation& b)
{
    EXPECT_EQ(std::memcmp(&a.value, &b.value, sizeof(double)), 0) << a.value << " " << b.value;
    EXPECT_TRUE(same_bits(a.gradient, b.gradient));
    EXPECT_TRUE(same_bits(a.constraint_values, b.constraint_values));
    EXPECT_TRUE(same_bits(a.constraint_gradients.reshaped(), b.constraint_gradients.reshaped()));
    EXPECT_EQ(a.adjoint_blocks, b.adjoint_blocks);
}

/// Rank 1 serving in a thread for the life of the object; rank 0's distribution to drive it.
struct TwoRanks {
    std::shared_ptr<Channel> channel = std::make_shared<Channel>();
    std::shared_ptr<CaseDistribution> driver = std::make_shared<CaseDistribution>(
        std::make_shared<ThreadCommunicator>(channel, 0), CaseDistribution::Mode::DRIVER);
    CaseDistribution server { std::make_shared<ThreadCommunicator>(channel, 1), CaseDistribution::Mode::DRIVER };
    std::string server_error;
    std::thread thread { [this] {
        try {
            server.serve();
        } catch (const std::exception& e) {
            server_error = e.what();
        }
        const std::lock_guard<std::mutex> lock(channel->mutex);
        channel->server_gone = true;
        channel->changed.notify_all();
    } };
    ~TwoRanks()
    {
        driver->stop();
        thread.join();
    }
};

} // namespace

TEST(CaseDistribution, TwoRanksGiveTheSerialBitsAndBalanceByCost)
{
    const ReducedFunctional serial(strips(), ".", "strips");
    ReducedFunctional J(strips(), ".", "strips");
    TwoRanks ranks;
    // The cases' costs are their step counts (3, 4 and 12), not their measured seconds: on a busy machine the
    // seconds need not follow the steps, and the assignment must not depend on them here.
    const std::vector<double> steps { 3, 4, 12 };
    std::vector<double> measured(3, -1.0);
    ranks.driver->case_cost = [&](size_t c, double seconds) {
        measured.at(c) = seconds;
        return steps.at(c);
    };
    J.set_distribution(ranks.driver);
    for (const double E : { 1e5, 1.3e5, 0.8e5 }) {
        const VectorXd p = VectorXd::Constant(1, E);
        expect_same_bits(J.evaluate(p, true, true), serial.evaluate(p, true, true));
        expect_same_bits(J.evaluate(p, false, false), serial.evaluate(p, false, false));
    }
    const CaseDistribution::Times& t = ranks.driver->times();
    EXPECT_EQ(t.evaluations, 6);
    EXPECT_EQ(t.cases[0] + t.cases[1], 18);
    EXPECT_GT(t.cases[1], 0);
    EXPECT_GT(t.compute[1], 0);
    // After the first evaluation the cases go by their costs: case 2 (12 steps) has rank 0 to itself.
    EXPECT_EQ(ranks.driver->last_assignment_costs(), steps);
    EXPECT_EQ(ranks.driver->last_assignment(), longest_first(steps, 2));
    EXPECT_EQ(ranks.driver->last_assignment(), (std::vector<int> { 1, 1, 0 }));
    for (const double s : measured) // every case's seconds were measured and handed to the cost
        EXPECT_GE(s, 0.0);
    EXPECT_TRUE(ranks.server_error.empty()) << ranks.server_error;
}

TEST(CaseDistribution, ProblemsTravelAndTheLowestFailingCaseIsTheSerialError)
{
    TwoRanks ranks;
    // Three problems through one distribution (as a remesh does): each loaded once while held.
    ReducedFunctional a(strips(), ".", "a"), b(strips(-1, 2), ".", "b"), c(strips(-1, 3), ".", "c");
    for (ReducedFunctional* J : { &a, &b, &c })
        J->set_distribution(ranks.driver);
    const VectorXd p = VectorXd::Constant(1, 1e5);
    const auto check = [&](const ReducedFunctional& J, const json& document) {
        expect_same_bits(J.evaluate(p, true, true), ReducedFunctional(document, ".", "serial").evaluate(p, true, true));
    };
    check(a, strips());
    const int after_a = ranks.channel->broadcasts; // LOAD + EVALUATE
    check(b, strips(-1, 2));
    check(a, strips());
    EXPECT_EQ(ranks.channel->broadcasts, after_a + 3); // b loaded, a still held: no LOAD for it
    check(c, strips(-1, 3)); // drops b, the least recently evaluated
    check(a, strips()); // still held
    EXPECT_EQ(ranks.channel->broadcasts, after_a + 6);
    check(b, strips(-1, 2)); // loaded again
    EXPECT_EQ(ranks.channel->broadcasts, after_a + 8);

    // Case 1 is not defined (sqrt of a negative energy) and case 2's first step fails: rank 1 evaluates case 1 and
    // rank 0 case 2 (round robin). The serial evaluation throws case 1's ObjectiveDomainError, the first; so must
    // the distributed one, though rank 0's own case failed with an AdjointError.
    const ReducedFunctional serial(strips(1, 1, 2), ".", "undefined");
    std::string expected;
    try {
        serial.evaluate(p, true);
    } catch (const ObjectiveDomainError& e) {
        expected = e.what();
    }
    ASSERT_FALSE(expected.empty());
    EXPECT_THROW(serial.evaluate_case(2, p, true), AdjointError);
    ReducedFunctional undefined(strips(1, 1, 2), ".", "undefined");
    undefined.set_distribution(ranks.driver);
    try {
        undefined.evaluate(p, true);
        ADD_FAILURE() << "no error";
    } catch (const ObjectiveDomainError& e) {
        EXPECT_EQ(e.what(), expected);
    }
    EXPECT_EQ(ranks.driver->last_assignment(), (std::vector<int> { 0, 1, 0 }));
    // A non-finite p: evaluate()'s InputError, before anything is sent.
    const int before = ranks.channel->broadcasts;
    EXPECT_THROW(undefined.evaluate(VectorXd::Constant(1, std::nan("")), true), InputError);
    EXPECT_EQ(ranks.channel->broadcasts, before);
    // The serving rank is still in step.
    check(a, strips());
    EXPECT_TRUE(ranks.server_error.empty()) << ranks.server_error;
}

TEST(CaseDistribution, RefusesMisuse)
{
    EXPECT_THROW(CaseDistribution(nullptr, CaseDistribution::Mode::DRIVER), std::invalid_argument);
    CaseDistribution alone(std::make_shared<SerialCommunicator>(), CaseDistribution::Mode::DRIVER);
    EXPECT_THROW(alone.serve(), std::logic_error); // rank 0 drives
    ReducedFunctional J(strips(), ".", "strips");
    const VectorXd p = VectorXd::Constant(1, 1e5);
    // One process: the serial bits through the same path.
    expect_same_bits(alone.evaluate(J, p, true, true), J.evaluate(p, true, true));
    alone.stop();
    EXPECT_THROW(alone.evaluate(J, p, true, true), std::logic_error);
    auto channel = std::make_shared<Channel>();
    CaseDistribution server(std::make_shared<ThreadCommunicator>(channel, 1), CaseDistribution::Mode::DRIVER);
    EXPECT_THROW(server.evaluate(J, p, true, true), std::logic_error); // rank 1 serves
    CaseDistribution collective(std::make_shared<SerialCommunicator>(), CaseDistribution::Mode::COLLECTIVE);
    EXPECT_THROW(collective.serve(), std::logic_error);
    expect_same_bits(collective.evaluate(J, p, true, true), J.evaluate(p, true, true));
}
