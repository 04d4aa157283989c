#include "forward/time/integrator.hpp"

namespace diffipc {

void TimeIntegrator::initialize(const VectorXd& x0, const VectorXd& v0, const VectorXd& a0)
{
    m_x = x0;
    m_v = v0;
    m_a = a0;
    m_x_prev = x0;
    m_v_prev = v0;
    m_steps = 0;
}

void TimeIntegrator::commit(const VectorXd& x_next, const VectorXd& v_next, const VectorXd& a_next)
{
    m_x_prev = m_x;
    m_v_prev = m_v;
    m_x = x_next;
    m_v = v_next;
    m_a = a_next;
    ++m_steps;
}

void TimeIntegrator::restore(
    int steps, const VectorXd& x, const VectorXd& v, const VectorXd& a, const VectorXd& x_prev, const VectorXd& v_prev)
{
    m_x = x;
    m_v = v;
    m_a = a;
    // Only a two-step scheme reads the previous state; a one-step one is given none.
    m_x_prev = history() == 2 ? x_prev : x;
    m_v_prev = history() == 2 ? v_prev : v;
    m_steps = steps;
}

namespace {

    /// Quasi-static load stepping: no inertia; velocities are reported as (x_{n+1} - x_n) / h.
    class Static final : public TimeIntegrator {
    public:
        explicit Static(double dt)
            : TimeIntegrator(dt)
        {
        }
        IntegratorType type() const override { return IntegratorType::STATIC; }
        VectorXd inertial_target() const override { return m_x; }
        double potential_weight() const override { return 1.0; }
        void update(const VectorXd& x_next, VectorXd& v_next, VectorXd& a_next) const override
        {
            v_next = (x_next - m_x) / m_dt;
            a_next = VectorXd::Zero(x_next.size());
        }
        StepScheme scheme(int) const override
        {
            StepScheme s;
            s.inertia = false;
            s.weight = 1;
            s.vx[0] = 1 / m_dt;
            s.vx[1] = -1 / m_dt;
            return s;
        }
    };

    /// Implicit Euler's maps (also BDF2's first step).
    StepScheme implicit_euler_scheme(double h)
    {
        StepScheme s;
        s.weight = h * h;
        s.tx[1] = 1;
        s.tv[1] = h;
        s.vx[0] = 1 / h;
        s.vx[1] = -1 / h;
        s.ax[0] = 1 / (h * h);
        s.ax[1] = -1 / (h * h);
        s.av[1] = -1 / h;
        return s;
    }

    /// Implicit Euler: x~ = x_n + h v_n, c = 1, v_{n+1} = (x_{n+1} - x_n) / h.
    class ImplicitEuler final : public TimeIntegrator {
    public:
        explicit ImplicitEuler(double dt)
            : TimeIntegrator(dt)
        {
        }
        IntegratorType type() const override { return IntegratorType::IMPLICIT_EULER; }
        VectorXd inertial_target() const override { return m_x + m_dt * m_v; }
        double potential_weight() const override { return m_dt * m_dt; }
        void update(const VectorXd& x_next, VectorXd& v_next, VectorXd& a_next) const override
        {
            v_next = (x_next - m_x) / m_dt;
            a_next = (v_next - m_v) / m_dt;
        }
        StepScheme scheme(int) const override { return implicit_euler_scheme(m_dt); }
    };

    /// BDF2 (first step by implicit Euler):
    /// x~ = 4/3 x_n - 1/3 x_{n-1} + 2h/3 (4/3 v_n - 1/3 v_{n-1}), c = 4/9,
    /// v_{n+1} = (3 x_{n+1} - 4 x_n + x_{n-1}) / (2h).
    class BDF2 final : public TimeIntegrator {
    public:
        explicit BDF2(double dt)
            : TimeIntegrator(dt)
        {
        }
        IntegratorType type() const override { return IntegratorType::BDF2; }
        int history() const override { return 2; }
        VectorXd inertial_target() const override
        {
            if (m_steps == 0)
                return m_x + m_dt * m_v;
            return (4.0 / 3.0) * m_x - (1.0 / 3.0) * m_x_prev
                + (2.0 * m_dt / 3.0) * ((4.0 / 3.0) * m_v - (1.0 / 3.0) * m_v_prev);
        }
        double potential_weight() const override { return m_steps == 0 ? m_dt * m_dt : 4.0 / 9.0 * m_dt * m_dt; }
        void update(const VectorXd& x_next, VectorXd& v_next, VectorXd& a_next) const override
        {
            if (m_steps == 0) {
                v_next = (x_next - m_x) / m_dt;
                a_next = (v_next - m_v) / m_dt;
                return;
            }
            v_next = (3.0 * x_next - 4.0 * m_x + m_x_prev) / (2.0 * m_dt);
            a_next = (3.0 * v_next - 4.0 * m_v + m_v_prev) / (2.0 * m_dt);
        }
        StepScheme scheme(int k) const override
        {
            const double h = m_dt;
            if (k <= 1)
                return implicit_euler_scheme(h);
            StepScheme s;
            s.weight = 4.0 / 9.0 * h * h;
            s.tx[1] = 4.0 / 3.0;
            s.tx[2] = -1.0 / 3.0;
            s.tv[1] = 8.0 * h / 9.0;
            s.tv[2] = -2.0 * h / 9.0;
            s.vx[0] = 3.0 / (2.0 * h);
            s.vx[1] = -2.0 / h;
            s.vx[2] = 1.0 / (2.0 * h);
            for (int j = 0; j < 3; ++j)
                s.ax[j] = 3.0 / (2.0 * h) * s.vx[j];
            s.av[1] = -2.0 / h;
            s.av[2] = 1.0 / (2.0 * h);
            return s;
        }
    };

    /// Newmark, average acceleration (beta = 1/4, gamma = 1/2):
    /// x~ = x_n + h v_n + (1/2 - beta) h^2 a_n, c = beta,
    /// a_{n+1} = (x_{n+1} - x~) / (beta h^2), v_{n+1} = v_n + h ((1 - gamma) a_n + gamma a_{n+1}).
    class Newmark final : public TimeIntegrator {
    public:
        static constexpr double BETA = 0.25, GAMMA = 0.5;
        explicit Newmark(double dt)
            : TimeIntegrator(dt)
        {
        }
        IntegratorType type() const override { return IntegratorType::NEWMARK; }
        VectorXd inertial_target() const override { return m_x + m_dt * m_v + (0.5 - BETA) * m_dt * m_dt * m_a; }
        double potential_weight() const override { return BETA * m_dt * m_dt; }
        void update(const VectorXd& x_next, VectorXd& v_next, VectorXd& a_next) const override
        {
            a_next = (x_next - inertial_target()) / (BETA * m_dt * m_dt);
            v_next = m_v + m_dt * ((1.0 - GAMMA) * m_a + GAMMA * a_next);
        }
        StepScheme scheme(int) const override
        {
            const double h = m_dt, c = 1.0 / (BETA * h * h);
            StepScheme s;
            s.weight = BETA * h * h;
            s.tx[1] = 1;
            s.tv[1] = h;
            s.ta[1] = (0.5 - BETA) * h * h;
            s.ax[0] = c;
            s.ax[1] = -c * s.tx[1];
            s.av[1] = -c * s.tv[1];
            s.aa[1] = -c * s.ta[1];
            s.vx[0] = h * GAMMA * s.ax[0];
            s.vx[1] = h * GAMMA * s.ax[1];
            s.vv[1] = 1 + h * GAMMA * s.av[1];
            s.va[1] = h * (1 - GAMMA) + h * GAMMA * s.aa[1];
            return s;
        }
    };

} // namespace

std::unique_ptr<TimeIntegrator> TimeIntegrator::create(IntegratorType type, double dt)
{
    switch (type) {
    case IntegratorType::STATIC:
        return std::make_unique<Static>(dt);
    case IntegratorType::IMPLICIT_EULER:
        return std::make_unique<ImplicitEuler>(dt);
    case IntegratorType::BDF2:
        return std::make_unique<BDF2>(dt);
    case IntegratorType::NEWMARK:
        return std::make_unique<Newmark>(dt);
    }
    return nullptr;
}

} // namespace diffipc
