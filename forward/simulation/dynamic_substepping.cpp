/// @file dynamic_substepping.cpp
/// Automatic step control in dynamic scenes (docs/scene_format.md, "time.adaptive"): a time step
/// whose solve failed is taken again in sub-steps of its time increment. Each sub-step is a step
/// of the scene's (one-step) integrator with its own increment h_s, started from the state
/// (positions, velocities, accelerations) the last sub-step ended with; prescribed positions,
/// obstacle motions and loads are taken at the sub-step's end time. A failed sub-step is retried
/// with its increment cut, an easy one lets the next grow. Unlike a static step, a dynamic step's
/// state depends on the sub-steps it took: the record keeps their times and intermediate states,
/// and the adjoint sweeps back through them (docs/math.md, "Sub-stepped dynamic steps").

#include "forward/common/error.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/newton.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

namespace diffipc {

void Simulator::set_potential_weights(double w)
{
    m_problem.set_weight(m_elastic.get(), w);
    m_problem.set_weight(m_external.get(), w);
    if (m_contact)
        m_problem.set_weight(m_contact.get(), w);
    if (m_friction)
        m_problem.set_weight(m_friction.get(), w);
}

double Simulator::setup_substep(const TimeIntegrator& sub, double t)
{
    const double w = sub.potential_weight();
    set_potential_weights(w);
    m_inertia->set_target(sub.inertial_target());
    m_external->set_force(external_forces(t));
    return w;
}

NewtonResult Simulator::solve_dynamic_substeps(int k, const NewtonSolver& newton, const std::vector<double>* plan,
    double kappa_before, VectorXd& x, StepRecord& record, std::string& why)
{
    const AdaptiveSpec& a = m_scene.time.adaptive;
    const double dt = m_scene.time.dt, t0 = (k - 1) * dt, t1 = k * dt;
    // A failed full solve leaves no trace: start from the committed state and stiffness.
    restore_kappa(kappa_before);
    VectorXd xj = m_integrator->positions(), vj = m_integrator->velocities(), aj = m_integrator->accelerations();
    double t = t0, h = a.cut * dt;
    NewtonResult total, last;
    double w_last = 0;
    record.cuts = plan ? 0 : 1;
    record.substeps = 0;
    record.min_increment = std::numeric_limits<double>::infinity();
    record.substep_times.clear();
    record.path.clear();
    size_t next = 0;
    while (t < t1) {
        double ts;
        if (plan) // check_substep_plan() made sure the last one is t1 within round-off
            ts = next + 1 == plan->size() ? t1 : (*plan)[next];
        else // land on t1 exactly, without leaving a sliver smaller than a hundredth of the increment
            ts = t1 - (t + h) <= 1e-2 * h ? t1 : t + h;
        const double hs = ts - t;
        const std::unique_ptr<TimeIntegrator> sub = TimeIntegrator::create(m_scene.time.integrator, hs);
        sub->initialize(xj, vj, aj);
        const double ws = setup_substep(*sub, ts);
        VectorXd target = xj;
        prescribed_targets_at(k, ts, target);
        NewtonSettings settings = newton.settings();
        if (m_contact) {
            // As in step(): a Newton step longer than the bodies' size plus the inertial drift is
            // not one a converging solve takes.
            const VectorXd drift = m_inertia->target() - xj;
            double largest = 0;
            for (Index i = 0; i < drift.size(); ++i)
                if (!m_constrained[size_t(i)])
                    largest = std::max(largest, std::abs(drift[i]));
            settings.max_displacement = m_bbox_diagonal + largest;
        }
        const NewtonSolver solver(m_problem, m_assembler, *m_linear, settings);
        const double kappa = solve_kappa();
        VectorXd y = xj;
        restart_friction(xj, hs);
        // In a GPU run on the device, with the sub-step's inertial target and weight.
        NewtonResult r = solve_current(solver, y, target, ws, hs, true);
        total.add_costs(r);
        r = relag_friction(solver, ws, hs, target, y, r, total, true);
        if (r.status == StepStatus::CONVERGED) {
            record.min_increment = std::min(record.min_increment, hs);
            ++record.substeps;
            record.substep_times.push_back(ts);
            VectorXd v, acc;
            sub->update(y, v, acc);
            xj = std::move(y);
            vj = std::move(v);
            aj = std::move(acc);
            t = ts;
            last = r;
            w_last = ws;
            ++next;
            if (t < t1)
                record.path.push_back({ t, xj, vj, aj });
            if (r.iterations <= a.iteration_target)
                h = std::min(dt, h * a.growth);
            continue;
        }
        restore_kappa(kappa); // a failed sub-step leaves no trace either
        if (plan) {
            why = "; its sub-step to t = " + format_number(ts) + " s (given by SimulationParameters::substeps) failed ("
                + to_string(r.status) + ")";
            record.path.clear();
            return r.with_costs_of(total);
        }
        ++record.cuts;
        h *= a.cut;
        if (h < a.min_increment * (1 - 1e-12)) {
            why = substeps_exhausted("automatic step control", record.substeps, t, k, ts, r.status);
            record.path.clear();
            return r.with_costs_of(total);
        }
    }
    if (m_friction) {
        // The data the last solve used, and how far it is from the state it describes.
        std::vector<FrictionContact> used = m_friction->lagged();
        lag_friction_at(xj);
        record.friction_residual = m_device
            ? m_device->residual(xj, current_inertial_target(), w_last, m_external->force()) / (w_last * m_force_scale)
            : force_residual(xj, w_last);
        record.friction_converged = record.friction_residual <= m_scene.solver.residual_tolerance;
        record.friction_iterations = 1;
        m_friction->set_lagged(used);
        if (m_device)
            m_device->set_friction(*m_friction);
        record.friction = std::move(used);
    }
    x = std::move(xj);
    record.velocities = std::move(vj);
    record.accelerations = std::move(aj);
    return last.with_costs_of(total);
}

namespace {
    /// Start and end time of sub-step j (1-based) of a record's sub-steps.
    std::pair<double, double> substep_interval(const StepRecord& r, int j, double dt)
    {
        if (j < 1 || j > int(r.substep_times.size()))
            throw std::out_of_range("sub-step " + std::to_string(j) + " of step " + std::to_string(r.index)
                + ", which took " + std::to_string(r.substep_times.size()) + " dynamic sub-steps");
        const double start = j == 1 ? (r.index - 1) * dt : r.substep_times[size_t(j - 2)];
        return { start, j == int(r.substep_times.size()) ? r.time : r.substep_times[size_t(j - 1)] };
    }
} // namespace

StepScheme Simulator::substep_scheme(int k, int j) const
{
    const StepRecord& r = m_trajectory.step(k);
    const auto [start, end] = substep_interval(r, j, m_scene.time.dt);
    return TimeIntegrator::create(m_scene.time.integrator, end - start)->scheme(1);
}

const Problem& Simulator::substep_problem(int k, int j)
{
    m_friction_at_last_step = false;
    const StepRecord& r = record_of(k, "substep_problem");
    const auto [start, end] = substep_interval(r, j, m_scene.time.dt);
    if (m_friction)
        throw std::logic_error("Simulator::substep_problem: sub-stepped steps with friction are not differentiated");
    const bool first = j == 1;
    const StepRecord* before = first && k > 1 ? &record_of(k - 1, "substep_problem") : nullptr;
    if (!r.holds_state() || (before && !before->holds_state()))
        throw std::logic_error("Simulator::substep_problem: step " + std::to_string(k)
            + " or the one before does not hold its state (it was released)");
    const StepRecord::SubState* s = first ? nullptr : &r.path[size_t(j - 2)];
    const VectorXd& x = s ? s->positions : before ? before->positions : m_trajectory.initial_positions;
    const VectorXd& v = s ? s->velocities : before ? before->velocities : m_trajectory.initial_velocities;
    const VectorXd& a = s ? s->accelerations : before ? before->accelerations : m_trajectory.initial_accelerations;
    const std::unique_ptr<TimeIntegrator> sub = TimeIntegrator::create(m_scene.time.integrator, end - start);
    sub->initialize(x, v, a);
    setup_substep(*sub, end);
    if (m_contact)
        m_contact->set_kappa(r.kappa);
    return m_problem;
}

std::string Simulator::check_substep_plan(const std::vector<std::vector<double>>& plan) const
{
    if (plan.empty())
        return {};
    const int T = m_scene.time.steps;
    const double dt = m_scene.time.dt;
    if (int(plan.size()) != T)
        return "expected " + std::to_string(T) + " entries (one per step, empty for a step taken in one go), got "
            + std::to_string(plan.size());
    for (int k = 1; k <= T; ++k) {
        const std::vector<double>& p = plan[size_t(k - 1)];
        if (p.empty())
            continue;
        const std::string where = "[" + std::to_string(k - 1) + "]: ";
        if (m_scene.time.integrator != IntegratorType::IMPLICIT_EULER
            && m_scene.time.integrator != IntegratorType::NEWMARK)
            return where + "sub-steps need a one-step dynamic integrator (implicit_euler or newmark); this scene is "
                + to_string(m_scene.time.integrator);
        double t = (k - 1) * dt;
        for (double ts : p) {
            if (!(ts > t + 1e-12 * dt))
                return where + "the sub-steps' end times must increase from t_" + std::to_string(k - 1) + " = "
                    + format_number((k - 1) * dt) + " s";
            t = ts;
        }
        if (std::abs(t - k * dt) > 1e-12 * std::max(1.0, k * dt))
            return where + "the last sub-step must end at t_" + std::to_string(k) + " = " + format_number(k * dt)
                + " s, not " + format_number(t) + " s";
    }
    return {};
}

} // namespace diffipc
