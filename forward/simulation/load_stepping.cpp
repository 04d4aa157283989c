/// @file load_stepping.cpp
/// Automatic load stepping (docs/scene_format.md, "time.adaptive"): a static step whose solve
/// failed is solved again in sub-steps of its load increment. Each sub-step is a static solve at
/// an intermediate load time, started from the last converged sub-step; a failed one is retried
/// with the increment cut, an easy one (few Newton iterations) lets the next grow. The step's
/// state is the equilibrium at its own time t_k, which does not depend on the path in a static
/// scene without friction: the adjoint of the step is unchanged. Past a limit point of the load,
/// where no sub-step converges however small, pass_limit_point() follows the equilibria by
/// displacement control along the load increment (docs/math.md, "Load stepping past limit points").

#include "forward/common/error.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/newton.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace diffipc {

NewtonResult Simulator::solve_in_substeps(int k, const NewtonSolver& newton, double step_scale, double kappa_before,
    VectorXd& x, StepRecord& record, std::string& why)
{
    const AdaptiveSpec& a = m_scene.time.adaptive;
    const double dt = m_scene.time.dt, t0 = (k - 1) * dt, t1 = k * dt;
    const double w = m_integrator->potential_weight();
    // The full step's failed solve leaves no trace: start from the committed state and stiffness.
    restore_kappa(kappa_before);
    VectorXd committed = m_integrator->positions();
    double t = t0, h = a.cut * dt;
    NewtonResult total, last;
    // A result with the iterations, fallbacks and times of every solve the step took.
    record.cuts = 1;
    record.substeps = 0;
    record.min_increment = std::numeric_limits<double>::infinity();
    while (t < t1) {
        // Land on t1 exactly, without leaving a sliver smaller than a hundredth of the increment.
        const double ts = t1 - (t + h) <= 1e-2 * h ? t1 : t + h;
        VectorXd target = committed;
        prescribed_targets_at(k, ts, target);
        m_external->set_force(external_forces(ts));
        const double kappa = solve_kappa();
        VectorXd y = committed;
        restart_friction(committed, ts - t);
        NewtonResult r = solve_current(newton, y, target, w, step_scale, true);
        total.add_costs(r);
        r = relag_friction(newton, w, step_scale, target, y, r, total, true);
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
        restore_kappa(kappa); // a failed sub-step leaves no trace either
        ++record.cuts;
        h *= a.cut;
        if (h < a.min_increment * (1 - 1e-12)) {
            why = substeps_exhausted("automatic load stepping", record.substeps, t, k, ts, r.status);
            // Past a limit point: displacement control, then relaxation from where it got to (or from
            // the last sub-step), on the device in a GPU run where it can (limit_point_on_device).
            struct OnCpu {
                Simulator& sim;
                explicit OnCpu(Simulator& s)
                    : sim(s)
                {
                    sim.hand_contact_to_cpu();
                }
                ~OnCpu() { sim.hand_contact_to_device(); }
            };
            for (const bool control : { true, false }) {
                if (!(control ? a.displacement_control : a.relaxation))
                    continue;
                std::string note;
                std::optional<OnCpu> on_cpu;
                if (!limit_point_on_device())
                    on_cpu.emplace(*this);
                const NewtonResult c = control
                    ? pass_limit_point(k, newton, step_scale, t, committed, r, record, total, note)
                    : relax_to_equilibrium(k, newton, step_scale, committed, record, total, note);
                if (c.status == StepStatus::CONVERGED) {
                    // Its last solve took the load from t to t_k.
                    record.min_increment = std::min(record.min_increment, t1 - t);
                    x = std::move(committed);
                    return c.with_costs_of(total);
                }
                why += "; " + note;
                r = c;
            }
            return r.with_costs_of(total);
        }
    }
    x = std::move(committed);
    return last.with_costs_of(total);
}

std::string Simulator::substeps_exhausted(
    const char* what, int substeps, double t, int k, double ts, StepStatus status) const
{
    const double dt = m_scene.time.dt;
    return "; " + std::string(what) + " took " + std::to_string(substeps) + " sub-steps to t = " + format_number(t)
        + " s of (" + format_number((k - 1) * dt) + ", " + format_number(k * dt) + "] s, then failed to "
        + format_number(ts) + " s (" + to_string(status) + ") and would cut the increment below "
        + "time.adaptive.min_increment = " + format_number(m_scene.time.adaptive.min_increment) + " s";
}

void Simulator::restart_friction(const VectorXd& from, double h)
{
    if (!m_friction)
        return;
    m_friction->set_step(from, h);
    lag_friction_at(from);
}

const VectorXd& Simulator::current_inertial_target() const
{
    static const VectorXd none;
    return m_integrator->dynamic() ? m_inertia->target() : none;
}

NewtonResult Simulator::solve_current(const NewtonSolver& newton, VectorXd& y, const VectorXd& target, double w,
    double step_scale, bool on_device, LoadControl* control)
{
    if (m_device && on_device)
        return m_device->solve(y, current_inertial_target(), w, m_external->force(), target, w * m_force_scale,
            step_scale, newton.settings(), control);
    return newton.solve(y, target, m_constrained, w * m_force_scale, step_scale, control);
}

bool Simulator::limit_point_on_device() const { return m_device && !m_periodic && !m_inertia->consistent(); }

double Simulator::solve_kappa() const
{
    if (!m_contact)
        return 0.0;
    return m_device && !m_fallback_on_cpu ? m_device->kappa() : m_contact->kappa();
}

void Simulator::hand_contact_to_cpu()
{
    if (!m_device || !m_contact || m_fallback_on_cpu)
        return;
    m_fallback_on_cpu = true;
    m_contact->set_kappa(m_device->kappa());
    if (m_scene.contact.adaptive_kappa)
        m_contact->set_adaptive(
            100 * m_kappa_min, m_bbox_diagonal, [this](const VectorXd& y) { return balancing_kappa(y); },
            m_device->adaptive_rule_applied());
}

void Simulator::hand_contact_to_device()
{
    if (!m_fallback_on_cpu)
        return;
    m_fallback_on_cpu = false;
    m_device->set_kappa(m_contact->kappa());
}

void Simulator::restore_kappa(double kappa)
{
    if (!m_contact)
        return;
    m_contact->set_kappa(kappa);
    if (m_device)
        m_device->set_kappa(kappa);
}

NewtonResult Simulator::relag_friction(const NewtonSolver& newton, double w, double step_scale, const VectorXd& target,
    VectorXd& y, NewtonResult r, NewtonResult& total, bool on_device)
{
    for (int solves = 1; m_friction && r.status == StepStatus::CONVERGED && solves < m_scene.friction.iterations;
         ++solves) {
        const std::vector<FrictionContact> satisfied = m_friction->lagged();
        lag_friction_at(y);
        const double residual = m_device && on_device
            ? m_device->residual(y, current_inertial_target(), w, m_external->force()) / (w * m_force_scale)
            : force_residual(y, w);
        if (residual <= m_scene.solver.residual_tolerance)
            break;
        VectorXd z = y;
        const double kappa = solve_kappa();
        NewtonResult again = solve_current(newton, z, target, w, step_scale, on_device);
        total.add_costs(again);
        if (again.status != StepStatus::CONVERGED) {
            // A failed re-solve fails the solve: its increment is cut.
            m_friction->set_lagged(satisfied);
            if (m_device)
                m_device->set_friction(*m_friction);
            restore_kappa(kappa);
            return again;
        }
        y = std::move(z);
        r = again;
    }
    return r;
}

NewtonResult Simulator::pass_limit_point(int k, const NewtonSolver& newton, double step_scale, double t, VectorXd& x,
    const NewtonResult& failed, StepRecord& record, NewtonResult& total, std::string& why)
{
    const AdaptiveSpec& a = m_scene.time.adaptive;
    const double t1 = k * m_scene.time.dt;
    const double w = m_integrator->potential_weight();
    // The load increment that could not be carried, on the free dofs: its direction is the one the
    // control follows, and the multiplier says which fraction of it the bodies carry.
    const VectorXd f0 = external_forces(t), f1 = external_forces(t1);
    LoadControl control;
    control.direction = f1 - f0;
    for (Index i = 0; i < control.direction.size(); ++i)
        if (m_constrained[size_t(i)])
            control.direction[i] = 0;
    const double increment = control.direction.norm();
    if (!(increment > 0)) {
        why = "displacement control needs a load (traction or gravity) that changes over the step, and this one "
              "changes only prescribed displacements";
        return failed;
    }
    control.direction /= increment;
    control.tolerance = 1e-12 * m_bbox_diagonal;
    // Prescribed displacements stay at t while the load is followed; they move to t_k in the final solve.
    VectorXd target = x;
    prescribed_targets_at(k, t, target);
    const double start = control.direction.dot(x);
    const double min_control = 1e-4 * m_bbox_diagonal;
    double level = start, increment_s = 1e-3 * m_bbox_diagonal, carried = 0, largest = 0;
    // A control solve that needs many times the easy count is cut rather than finished: failing
    // solves then cost little where the path turns.
    const NewtonSolver control_newton = newton.limited(4 * a.iteration_target);
    // In a GPU run the solves run on the device, unless the caller handed the contact to the CPU.
    const bool on_device = limit_point_on_device() && !m_fallback_on_cpu;
    // The last converged state on the path and its level: the secant through it and x predicts the
    // next state (a solve started there takes a few iterations, not the many that a start at x
    // takes where the path turns), shortened to what CCD and the inversion bound allow.
    VectorXd previous;
    double previous_level = start;
    while (record.control_steps < MAX_CONTROL_STEPS && level - start < m_bbox_diagonal) {
        m_external->set_force(f0);
        control.level = level + increment_s;
        VectorXd y = x;
        if (previous.size()) {
            const VectorXd secant = (increment_s / (level - previous_level)) * (x - previous);
            const double reach = m_problem.max_step(x, secant);
            y += std::min(1.0, 0.9 * reach) * secant;
        }
        const double kappa = solve_kappa();
        restart_friction(x, m_scene.time.dt);
        NewtonResult r = solve_current(control_newton, y, target, w, step_scale, on_device, &control);
        total.add_costs(r);
        if (r.status != StepStatus::CONVERGED) {
            restore_kappa(kappa); // a failed solve leaves no trace
            ++record.cuts;
            increment_s *= a.cut;
            // Cut to a hundredth of the longest increment that converged, or to 1e-4 of the
            // bounding-box diagonal: the path has stalled (it turns back in a^T x) and relaxation
            // takes over.
            if (increment_s < std::max(min_control, 1e-2 * largest)) {
                why = "displacement control followed the load to " + format_number(carried)
                    + " of the step's increment over " + format_number(level - start) + " m, then failed ("
                    + to_string(r.status) + ") with the control increment cut to " + format_number(increment_s) + " m";
                return r;
            }
            continue;
        }
        ++record.control_steps;
        largest = std::max(largest, increment_s);
        previous = std::move(x);
        previous_level = level;
        x = std::move(y);
        level = control.level;
        carried = control.multiplier / increment;
        if (r.iterations <= a.iteration_target)
            increment_s = std::min(increment_s * a.growth, 0.1 * m_bbox_diagonal);
        if (carried < 1)
            continue;
        // The path carries the step's load again: solve at t_k itself from here (the same
        // equilibrium branch, just below this state's load).
        VectorXd z = x, final_target = x;
        prescribed_targets_at(k, t1, final_target);
        m_external->set_force(f1);
        const double kappa_final = solve_kappa();
        restart_friction(x, t1 - t);
        NewtonResult last = solve_current(newton, z, final_target, w, step_scale, on_device);
        total.add_costs(last);
        last = relag_friction(newton, w, step_scale, final_target, z, last, total, on_device);
        if (last.status == StepStatus::CONVERGED) {
            x = std::move(z);
            ++record.substeps;
            return last;
        }
        restore_kappa(kappa_final);
    }
    why = "displacement control moved " + format_number(level - start) + " m along the load in "
        + std::to_string(record.control_steps) + " solves, carrying at most " + format_number(carried)
        + " of the step's load increment: the load cannot be carried";
    m_external->set_force(f1);
    NewtonResult result = failed;
    result.status = StepStatus::NEWTON_EXHAUSTED;
    return result;
}

NewtonResult Simulator::relax_to_equilibrium(int k, const NewtonSolver& newton, double step_scale, VectorXd& x,
    StepRecord& record, NewtonResult& total, std::string& why)
{
    const AdaptiveSpec& a = m_scene.time.adaptive;
    const double t1 = k * m_scene.time.dt;
    const double w = m_integrator->potential_weight();
    VectorXd target = x;
    prescribed_targets_at(k, t1, target);
    m_external->set_force(external_forces(t1));
    // The proximal weight c (1/s^2) starts where the mass-weighted term is as stiff as a typical
    // element (force scale / element size over the mean nodal mass).
    double mean_volume = 0;
    for (double v : m_space->rest_volumes())
        mean_volume += v / double(m_space->num_elements());
    const double size = std::pow(mean_volume, 1.0 / m_scene.dim);
    const double c0 = m_force_scale / size / m_inertia->lumped_masses().mean();
    // The inertia potential lends its mass matrix and target to the proximal term while it runs.
    struct Term {
        Problem& problem;
        const Potential* potential;
        ~Term() { problem.remove(potential); }
    } term { m_problem, m_inertia.get() };
    m_problem.add(m_inertia.get(), 0.0);
    double c = c0;
    int plain_tries = 0;
    const VectorXd start = x;
    const VectorXd& mass = m_inertia->lumped_masses();
    const int d = m_scene.dim;
    bool plain = false;
    const NewtonSolver proximal_newton = newton.limited(4 * a.iteration_target);
    // A plain solve is tried once the proximal imbalance is below this; each failed try lowers it.
    double threshold = 1e3 * m_scene.solver.residual_tolerance;
    NewtonResult last;
    last.status = StepStatus::NEWTON_EXHAUSTED;
    // In a GPU run the solves run on the device (its proximal term the CPU's: DeviceSolver::solve_proximal),
    // unless the caller handed the contact to the CPU (limit_point_on_device).
    const bool on_device = limit_point_on_device() && !m_fallback_on_cpu;
    while (record.relaxation_steps < MAX_RELAXATION_STEPS) {
        const double kappa = solve_kappa();
        m_problem.set_weight(m_inertia.get(), plain ? 0.0 : w * c);
        m_inertia->set_target(x);
        restart_friction(x, m_scene.time.dt);
        VectorXd y = x;
        if (on_device && !plain)
            last = m_device->solve_proximal(y, x, w * c, mass, w, m_external->force(), target, w * m_force_scale,
                step_scale, proximal_newton.settings());
        else if (on_device)
            last = solve_current(newton, y, target, w, step_scale, true);
        else
            last = (plain ? newton : proximal_newton).solve(y, target, m_constrained, w * m_force_scale, step_scale);
        total.add_costs(last);
        if (plain)
            last = relag_friction(newton, w, step_scale, target, y, last, total, on_device);
        if (last.status == StepStatus::CONVERGED && plain) {
            x = std::move(y);
            ++record.substeps;
            return last;
        }
        if (last.status != StepStatus::CONVERGED) {
            restore_kappa(kappa);
            ++record.cuts;
            if (plain) {
                ++plain_tries;
                plain = false;
                threshold *= 0.1;
                continue;
            }
            c *= 4;
            if (c > 1e6 * c0)
                break;
            continue;
        }
        // The proximal solution balances the forces up to c M (y - x_j): the plain residual there.
        double imbalance = 0;
        for (Index i = 0; i < y.size(); ++i)
            if (!m_constrained[size_t(i)])
                imbalance = std::max(imbalance, c * mass[i / d] * std::abs(y[i] - x[i]));
        ++record.relaxation_steps;
        x = std::move(y);
        if (last.iterations <= a.iteration_target)
            c = std::max(0.25 * c, 1e-12 * c0);
        // Close to an equilibrium: finish with a plain solve (the proximal term would only slow it).
        plain = imbalance / m_force_scale <= threshold;
        if ((x - start).lpNorm<Eigen::Infinity>() > m_bbox_diagonal) {
            why = "relaxation moved a vertex farther than the bodies' bounding-box diagonal in "
                + std::to_string(record.relaxation_steps)
                + " proximal solves without reaching an equilibrium: the load cannot be carried";
            last.status = StepStatus::NEWTON_EXHAUSTED;
            return last;
        }
    }
    why = "relaxation took " + std::to_string(record.relaxation_steps) + " proximal solves ("
        + std::to_string(plain_tries) + " plain solves failed), then "
        + (record.relaxation_steps >= MAX_RELAXATION_STEPS
                ? std::string("stopped at its limit of ") + std::to_string(MAX_RELAXATION_STEPS)
                : std::string("failed even with a proximal weight 1e6 times its start (") + to_string(last.status)
                    + ")");
    return last;
}

} // namespace diffipc
