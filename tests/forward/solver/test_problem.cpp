// Problem (forward/solver/problem.hpp): the sum of weighted terms, and its account of the work
// done per potential. A term with weight 0 or one that vanishes() is skipped: it adds nothing and
// counts nothing; every evaluation of a live term is counted once per call.

#include "forward/potentials/inertia_potential.hpp"
#include "forward/solver/problem.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

/// E(x) = c/2 |x|^2 with its calls counted by the test itself.
class Quadratic : public Potential {
public:
    explicit Quadratic(double c)
        : m_c(c)
    {
    }
    std::string name() const override { return "quadratic"; }
    double value(const VectorXd& x) const override
    {
        ++calls;
        return 0.5 * m_c * x.squaredNorm();
    }
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override
    {
        ++calls;
        g += weight * m_c * x;
    }
    void add_hessian(const VectorXd&, double, bool, SparseAssembler&) const override { ++calls; }
    double max_step(const VectorXd&, const VectorXd&) const override
    {
        ++calls;
        return 0.5;
    }
    mutable int calls = 0;

private:
    double m_c;
};

const Problem::TermWork& work_of(const Problem& p, const std::string& name)
{
    for (const auto& w : p.work())
        if (w.name == name)
            return w;
    throw std::logic_error("no work entry " + name);
}

} // namespace

TEST(Problem, CountsTheWorkOfLiveTermsOnly)
{
    const VectorXd x = VectorXd::LinSpaced(6, 1, 2);
    Quadratic q(3.0);
    ExternalForcePotential f(VectorXd::Zero(6)); // all forces zero: vanishes
    Problem p;
    p.add(&q, 2.0);
    p.add(&f, 2.0);
    ASSERT_EQ(p.work().size(), 2u);

    EXPECT_DOUBLE_EQ(p.energy(x), 2.0 * 1.5 * x.squaredNorm());
    VectorXd g;
    p.gradient(x, g);
    EXPECT_TRUE(g.isApprox(6.0 * x));
    EXPECT_EQ(p.max_step(x, x), 0.5);
    EXPECT_EQ(q.calls, 3);
    EXPECT_EQ(work_of(p, "quadratic").values, 1);
    EXPECT_EQ(work_of(p, "quadratic").gradients, 1);
    EXPECT_EQ(work_of(p, "quadratic").step_bounds, 1);
    EXPECT_GE(work_of(p, "quadratic").time, 0.0);
    const auto& ext = work_of(p, "external_force");
    EXPECT_EQ(ext.values + ext.gradients + ext.hessians + ext.step_bounds, 0);

    // Forces switched on: the term is live and its energy counts.
    VectorXd force = VectorXd::Zero(6);
    force(1) = 4.0;
    f.set_force(force);
    EXPECT_DOUBLE_EQ(p.energy(x), 2.0 * 1.5 * x.squaredNorm() - 2.0 * 4.0 * x(1));
    EXPECT_EQ(work_of(p, "external_force").values, 1);
    EXPECT_EQ(q.calls, 4);
    EXPECT_EQ(work_of(p, "quadratic").values, 2);

    // Weight 0: skipped and not counted; removing and re-adding keeps one entry and its counts.
    p.set_weight(&q, 0.0);
    EXPECT_DOUBLE_EQ(p.energy(x), -2.0 * 4.0 * x(1));
    EXPECT_EQ(q.calls, 4);
    EXPECT_EQ(work_of(p, "quadratic").values, 2);
    p.remove(&q);
    p.add(&q, 1.0);
    EXPECT_EQ(p.work().size(), 2u);
    p.energy_magnitude(x);
    EXPECT_EQ(work_of(p, "quadratic").values, 3);
    EXPECT_EQ(q.calls, 5);
}
