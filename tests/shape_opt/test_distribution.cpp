// shape_opt/distribution.hpp: the assignment of load cases to processes (round robin, and the
// longest-processing-time rule checked against Graham's bound on the optimum found by search), and an evaluation's
// bytes (bit for bit back, shapes kept, malformed bytes refused).

#include "shape_opt/distribution.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>

using namespace diffipc;

namespace {

/// Each process's summed cost under `owner`.
std::vector<double> loads(const std::vector<int>& owner, const std::vector<double>& costs, int processes)
{
    std::vector<double> l(size_t(processes), 0.0);
    for (size_t c = 0; c < owner.size(); ++c) {
        EXPECT_GE(owner[c], 0);
        EXPECT_LT(owner[c], processes);
        l[size_t(owner[c])] += costs[c];
    }
    return l;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

} // namespace

TEST(AssignCases, RoundRobinWithoutCosts)
{
    EXPECT_EQ(assign_cases(5, {}, 3), (std::vector<int> { 0, 1, 2, 0, 1 }));
    EXPECT_EQ(assign_cases(2, {}, 4), (std::vector<int> { 0, 1 }));
    EXPECT_EQ(assign_cases(3, {}, 1), (std::vector<int> { 0, 0, 0 }));
    EXPECT_TRUE(assign_cases(0, {}, 2).empty());
}

TEST(AssignCases, LongestFirstToTheLeastLoadedProcess)
{
    // By hand: 1 (5) -> 0; 4 (4) -> 1; 2 (2) -> 1; 3 (2) -> 0; 0 (1) -> 1: loads 7 and 7, the optimum.
    const std::vector<double> costs { 1, 5, 2, 2, 4 };
    EXPECT_EQ(assign_cases(5, costs, 2), (std::vector<int> { 1, 0, 1, 0, 1 }));
    // More processes than cases: every case alone.
    std::vector<int> alone = assign_cases(5, costs, 8);
    std::sort(alone.begin(), alone.end());
    EXPECT_EQ(std::adjacent_find(alone.begin(), alone.end()), alone.end());
    // Eight equal cases on four processes: two each.
    const std::vector<double> l
        = loads(assign_cases(8, std::vector<double>(8, 1.5), 4), std::vector<double>(8, 1.5), 4);
    EXPECT_EQ(l, std::vector<double>(4, 3.0));
    // Random costs: the longest process within Graham's bound (4/3 - 1/(3P)) of the optimum, found here by
    // trying every assignment of small instances; and the same assignment when computed again.
    std::mt19937 random(18);
    std::uniform_real_distribution<double> cost(0.1, 10.0);
    for (int trial = 0; trial < 300; ++trial) {
        const size_t cases = 1 + random() % 8;
        const int processes = 1 + int(random() % 3);
        std::vector<double> costs_t(cases);
        for (double& c : costs_t)
            c = trial % 3 == 0 ? double(1 + random() % 3) : cost(random); // ties too
        const std::vector<int> owner = assign_cases(cases, costs_t, processes);
        ASSERT_EQ(owner.size(), cases);
        const std::vector<double> l = loads(owner, costs_t, processes);
        double best = std::numeric_limits<double>::infinity();
        std::vector<int> a(cases, 0);
        for (;;) {
            std::vector<double> la(size_t(processes), 0.0);
            for (size_t c = 0; c < cases; ++c)
                la[size_t(a[c])] += costs_t[c];
            best = std::min(best, *std::max_element(la.begin(), la.end()));
            size_t k = 0;
            while (k < cases && ++a[k] == processes)
                a[k++] = 0;
            if (k == cases)
                break;
        }
        EXPECT_LE(*std::max_element(l.begin(), l.end()), (4.0 / 3.0 - 1.0 / (3.0 * processes)) * best * (1 + 1e-12))
            << "trial " << trial;
        EXPECT_EQ(assign_cases(cases, costs_t, processes), owner);
    }
}

TEST(AssignCases, RefusesBadInput)
{
    EXPECT_THROW(assign_cases(3, {}, 0), std::invalid_argument);
    EXPECT_THROW(assign_cases(3, { 1, 2 }, 2), std::invalid_argument);
    EXPECT_THROW(assign_cases(2, { 1, -1 }, 2), std::invalid_argument);
    EXPECT_THROW(assign_cases(2, { 1, std::numeric_limits<double>::quiet_NaN() }, 2), std::invalid_argument);
    EXPECT_THROW(assign_cases(2, { 1, std::numeric_limits<double>::infinity() }, 2), std::invalid_argument);
}

TEST(PackEvaluation, BitForBitBackWithShapesAndRecords)
{
    Evaluation e;
    e.value = 0.1 + 0.2; // not a short decimal
    e.forward_time = 1.25;
    e.adjoint_time = -0.0;
    e.gradient.resize(4);
    e.gradient << std::nextafter(1.0, 2.0), -3e-310 /* subnormal */, std::numeric_limits<double>::quiet_NaN(), 7;
    e.constraint_values.resize(2);
    e.constraint_values << 1.0 / 3.0, -2;
    e.constraint_gradients.resize(2, 4);
    for (Index i = 0; i < e.constraint_gradients.size(); ++i)
        e.constraint_gradients.data()[i] = std::sqrt(double(i + 2));
    e.adjoint_blocks = { "density", "", "rest_positions" };
    LoadCaseCheckpoint c;
    c.records.steps = 16;
    c.records.stride = 4;
    c.records.peak_stored_bytes = size_t(1) << 40;
    c.records.cost_ratio = 2.125;
    c.records.adjoint.device_pcg_iterations = 123456789012L;
    c.records.adjoint.solve_time = 0.75;
    c.objective_stored_states = 17;
    c.objective_stored_bytes = 4096;
    e.checkpoints = { c, c };
    e.checkpoints[1].records.recomputed_steps = 9;

    const Evaluation back = unpack_evaluation(pack_evaluation(e));
    EXPECT_TRUE(same_bits(back.value, e.value));
    EXPECT_TRUE(same_bits(back.forward_time, e.forward_time));
    EXPECT_TRUE(same_bits(back.adjoint_time, e.adjoint_time));
    ASSERT_EQ(back.gradient.size(), e.gradient.size());
    for (Index i = 0; i < e.gradient.size(); ++i)
        EXPECT_TRUE(same_bits(back.gradient[i], e.gradient[i])) << i;
    ASSERT_EQ(back.constraint_values.size(), 2);
    EXPECT_TRUE(same_bits(back.constraint_values[0], e.constraint_values[0]));
    ASSERT_EQ(back.constraint_gradients.rows(), 2);
    ASSERT_EQ(back.constraint_gradients.cols(), 4);
    EXPECT_EQ(back.constraint_gradients, e.constraint_gradients);
    EXPECT_EQ(back.adjoint_blocks, e.adjoint_blocks);
    ASSERT_EQ(back.checkpoints.size(), 2u);
    EXPECT_EQ(back.checkpoints[0].records.steps, 16);
    EXPECT_EQ(back.checkpoints[0].records.peak_stored_bytes, size_t(1) << 40);
    EXPECT_EQ(back.checkpoints[0].records.adjoint.device_pcg_iterations, 123456789012L);
    EXPECT_EQ(back.checkpoints[0].records.adjoint.solve_time, 0.75);
    EXPECT_EQ(back.checkpoints[0].records.cost_ratio, 2.125);
    EXPECT_EQ(back.checkpoints[1].records.recomputed_steps, 9);
    EXPECT_EQ(back.checkpoints[1].objective_stored_states, 17);
    EXPECT_EQ(back.checkpoints[1].objective_stored_bytes, 4096u);

    // Empty parts keep their shapes: no gradient, no constraints, a 0 x n constraint Jacobian.
    Evaluation bare;
    bare.value = 2;
    bare.constraint_gradients.resize(0, 4);
    const Evaluation bare_back = unpack_evaluation(pack_evaluation(bare));
    EXPECT_EQ(bare_back.value, 2);
    EXPECT_EQ(bare_back.gradient.size(), 0);
    EXPECT_EQ(bare_back.constraint_gradients.rows(), 0);
    EXPECT_EQ(bare_back.constraint_gradients.cols(), 4);
    EXPECT_TRUE(bare_back.checkpoints.empty() && bare_back.adjoint_blocks.empty());
}

TEST(PackEvaluation, RefusesMalformedBytes)
{
    Evaluation e;
    e.value = 1;
    e.gradient = VectorXd::Ones(3);
    e.adjoint_blocks = { "lame" };
    const std::string bytes = pack_evaluation(e);
    // Every truncation, and trailing bytes.
    for (size_t n = 0; n < bytes.size(); ++n)
        EXPECT_THROW(unpack_evaluation(bytes.substr(0, n)), std::invalid_argument) << n << " bytes";
    EXPECT_THROW(unpack_evaluation(bytes + "x"), std::invalid_argument);
    // A gradient that claims more entries than there are bytes.
    std::string huge = bytes;
    const uint64_t claim = uint64_t(1) << 60;
    std::memcpy(&huge[3 * sizeof(double)], &claim, sizeof(claim));
    EXPECT_THROW(unpack_evaluation(huge), std::invalid_argument);
}
