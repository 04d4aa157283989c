/// @file load_stepping.cpp
/// Automatic load stepping (docs/scene_format.md, "time.adaptive"): a static step whose solve
/// failed is solved again in sub-steps of its load increment. Each sub-step is a static solve at
/// an intermediate load time, started from the last converged sub-step; a failed one is retried
/// with the increment cut, an easy one (few Newton iterations) lets the next grow. The step's
/// state is the equilibrium at its own time t_k, which does not depend on the path in a static
/// scene without friction: the adjoint of the step is unchanged.

#include "forward/common/error.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/newton.hpp"

#include <algorithm>
#include <limits>

namespace diffipc {

NewtonResult Simulator::solve_in_substeps(int k, const NewtonSolver& newton, double step_scale, double kappa_before,
    VectorXd& x, StepRecord& record, std::string& why)
{
    const AdaptiveSpec& a = m_scene.time.adaptive;
    const double dt = m_scene.time.dt, t0 = (k - 1) * dt, t1 = k * dt;
    const double w = m_integrator->potential_weight();
    // The full step's failed solve leaves no trace: start from the committed state and stiffness.
    if (m_contact)
        m_contact->set_kappa(kappa_before);
    VectorXd committed = m_integrator->positions();
    double t = t0, h = a.cut * dt;
    NewtonResult total, last;
    record.cuts = 1;
    record.substeps = 0;
    record.min_increment = std::numeric_limits<double>::infinity();
    while (t < t1) {
        // Land on t1 exactly, without leaving a sliver smaller than a hundredth of the increment.
        const double ts = t1 - (t + h) <= 1e-2 * h ? t1 : t + h;
        VectorXd target = committed;
        prescribed_targets_at(k, ts, target);
        m_external->set_force(external_forces(ts));
        const double kappa = m_contact ? m_contact->kappa() : 0.0;
        VectorXd y = committed;
        NewtonResult r = newton.solve(y, target, m_constrained, w * m_force_scale, step_scale);
        total.iterations += r.iterations;
        total.linear_fallbacks += r.linear_fallbacks;
        total.times += r.times;
        if (r.status == StepStatus::CONVERGED) {
            record.min_increment = std::min(record.min_increment, ts - t);
            ++record.substeps;
            committed = std::move(y);
            t = ts;
            last = r;
            if (r.iterations <= a.iteration_target)
                h = std::min(dt, h * a.growth);
            continue;
        }
        if (m_contact)
            m_contact->set_kappa(kappa); // a failed sub-step leaves no trace either
        ++record.cuts;
        h *= a.cut;
        if (h < a.min_increment * (1 - 1e-12)) {
            why = "; automatic load stepping took " + std::to_string(record.substeps) + " sub-steps to t = "
                + format_number(t) + " s of (" + format_number(t0) + ", " + format_number(t1)
                + "] s, then failed to " + format_number(ts) + " s (" + to_string(r.status)
                + ") and would cut the increment below time.adaptive.min_increment = "
                + format_number(a.min_increment) + " s";
            r.iterations = total.iterations;
            r.linear_fallbacks = total.linear_fallbacks;
            r.times = total.times;
            return r;
        }
    }
    x = std::move(committed);
    last.iterations = total.iterations;
    last.linear_fallbacks = total.linear_fallbacks;
    last.times = total.times;
    return last;
}

} // namespace diffipc
