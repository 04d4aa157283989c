#include "shape_opt/design_problem.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "shape_opt/parametrization/map_json.hpp"

#include <cmath>
#include <filesystem>

#include <unistd.h>

namespace diffipc {

DesignProblem::DesignProblem(const ReducedFunctional& functional)
    : m_functional(&functional)
{
    build_validity();
    const RemeshSettings& remesh = functional.remesh_settings();
    if (remesh.enabled()) {
        const Mesh mesh = bodies_mesh(functional.scene());
        m_remesh_size = remesh.size > 0 ? remesh.size : mean_edge_length(mesh.rest_positions, mesh.elements);
        m_remesh_trigger = remesh.quality;
    }
    const auto& constraints = functional.constraints();
    m_scale.resize(Index(constraints.size()));
    for (size_t i = 0; i < constraints.size(); ++i) {
        (constraints[i].kind == ConstraintSpec::Kind::EQUALS ? m_equality : m_inequality).push_back(i);
        m_scale[Index(i)] = constraints[i].bound != 0 ? std::abs(constraints[i].bound) : 1.0;
    }
}

DesignProblem::~DesignProblem() = default;

VectorXd DesignProblem::parameters(const VectorXd& x)
{
    // The maps of the last design again (an evaluation, then the step bound from it): p once.
    if (m_parameters_x.size() == x.size() && m_parameters_x == x)
        return m_parameters_p;
    VectorXd p = m_functional->parameters_of(x);
    m_parameters_x = x;
    m_parameters_p = p;
    return p;
}

void DesignProblem::build_validity()
{
    m_validity.reset();
    if (m_functional->has_shape())
        m_validity = std::make_unique<RestValidity>(bodies_mesh(m_functional->scene()));
}

bool DesignProblem::constraints_hold(const OptimizationValues& v) const
{
    // The constraints reach the optimizer scaled by their bounds (header).
    for (Index i = 0; i < v.inequality.size(); ++i)
        if (!(v.inequality[i] <= m_constraint_tolerance))
            return false;
    for (Index i = 0; i < v.equality.size(); ++i)
        if (!(std::abs(v.equality[i]) <= m_constraint_tolerance))
            return false;
    return true;
}

bool DesignProblem::reject(const std::string& why)
{
    m_last_rejection = why;
    ++m_rejections;
    return false;
}

bool DesignProblem::evaluate(const VectorXd& x, OptimizationValues& out)
{
    Evaluation e;
    VectorXd p;
    try {
        {
            const Timer maps;
            p = parameters(x);
            maps.add_to(m_times.parametrization);
        }
        if (m_validity) {
            const Timer validity;
            const std::string problem = m_validity->problem(m_functional->rest_positions_of(p));
            validity.add_to(m_times.validity);
            if (!problem.empty())
                return reject("invalid rest mesh: " + problem);
        }
        e = m_functional->evaluate(p, true, !m_functional->constraints().empty());
    } catch (const AdjointError& error) {
        return reject(error.what());
    } catch (const InputError& error) {
        // A value outside a map's or the simulation's domain (nu >= 0.5, a negative modulus),
        // an objective undefined there: this design, not the problem, is at fault.
        return reject(error.what());
    }
    if (!(m_objective_scale > 0))
        m_objective_scale = std::abs(e.value) > 1e-300 ? std::abs(e.value) : 1.0;
    const Timer maps;
    out.f = e.value / m_objective_scale;
    out.gradient = m_functional->design_gradient(x, e.gradient) / m_objective_scale;
    const auto& constraints = m_functional->constraints();
    const Index n = x.size();
    out.inequality.resize(Index(m_inequality.size()));
    out.inequality_jacobian.resize(Index(m_inequality.size()), n);
    out.equality.resize(Index(m_equality.size()));
    out.equality_jacobian.resize(Index(m_equality.size()), n);
    const auto row = [&](size_t i) {
        return VectorXd(
            m_functional->design_gradient(x, e.constraint_gradients.row(Index(i)).transpose()) / m_scale[Index(i)]);
    };
    for (size_t k = 0; k < m_inequality.size(); ++k) {
        const size_t i = m_inequality[k];
        const double g = e.constraint_values[Index(i)], b = constraints[i].bound, s = m_scale[Index(i)];
        const double sign = constraints[i].kind == ConstraintSpec::Kind::UPPER ? 1.0 : -1.0;
        out.inequality[Index(k)] = sign * (g - b) / s;
        out.inequality_jacobian.row(Index(k)) = sign * row(i).transpose();
    }
    for (size_t k = 0; k < m_equality.size(); ++k) {
        const size_t i = m_equality[k];
        out.equality[Index(k)] = (e.constraint_values[Index(i)] - constraints[i].bound) / m_scale[Index(i)];
        out.equality_jacobian.row(Index(k)) = row(i).transpose();
    }
    maps.add_to(m_times.parametrization);
    m_last_constraints = e.constraint_values;
    m_last = std::move(e);
    return true;
}

double DesignProblem::max_valid_step(const VectorXd& x, const VectorXd& dx)
{
    if (!m_validity)
        return 1.0;
    const Timer validity;
    struct Add {
        const Timer& timer;
        double& to;
        ~Add() { timer.add_to(to); }
    } add { validity, m_times.validity };
    try {
        // The rest positions move along X(x + t dx); for the linear shape maps (boundary
        // extension, free-form deformation, none) that is the line X0 + t dX.
        const VectorXd X0 = m_functional->rest_positions_of(parameters(x));
        const VectorXd X1 = m_functional->rest_positions_of(parameters(x + dx));
        return m_validity->max_step(X0, X1 - X0);
    } catch (const InputError&) {
        return 0.0;
    }
}

bool DesignProblem::iteration(const IterationInfo& info)
{
    m_restart_clock = Timer();
    bool go_on = on_iteration ? on_iteration(info) : true;
    if (go_on && info.values && info.values->f * objective_scale() <= m_objective_target
        && constraints_hold(*info.values)) {
        m_target_reached = true;
        return false;
    }
    // gmsh gets at most what is left of the run's time budget.
    double seconds = 600;
    if (m_time_budget > 0 && info.checkpoint)
        seconds = std::min(seconds, m_time_budget - info.checkpoint->elapsed_seconds);
    if (go_on && info.x && info.checkpoint && remesh_if_needed(*info.x, info.iteration, false, seconds)) {
        m_restart = std::make_unique<OptimizerCheckpoint>(*info.checkpoint);
        return false; // minimize_design() goes on with the values on the new mesh
    }
    return go_on;
}

bool DesignProblem::remesh_if_needed(const VectorXd& x, int iteration, bool force, double seconds)
{
    const RemeshSettings& settings = m_functional->remesh_settings();
    if (!settings.enabled() || m_remesh_attempts >= settings.max_remeshes || !(seconds > 0))
        return false;
    const double quality = design_quality(*m_functional, x);
    if (!force && quality >= m_remesh_trigger)
        return false;
    std::string directory = m_remesh_directory;
    if (directory.empty())
        directory
            = (std::filesystem::temp_directory_path() / ("diffipc_remesh_" + std::to_string(::getpid()))).string();
    const Timer timer;
    ++m_remesh_attempts;
    RemeshRecord record;
    record.iteration = iteration;
    std::unique_ptr<ReducedFunctional> fresh;
    const auto failed = [&](const std::string& why) {
        // The next attempt waits for the quality to fall further; the files of this one go.
        m_remesh_trigger = std::min(settings.quality, 0.9 * quality);
        m_remesh_failure = why;
        m_failed_remesh_seconds += timer.seconds();
        for (const std::string& file : record.files)
            std::remove(file.c_str());
        if (on_remesh_attempt)
            on_remesh_attempt();
        return false;
    };
    try {
        std::filesystem::create_directories(directory);
        const nlohmann::json doc = remeshed_document(*m_functional, x, m_remesh_size, directory,
            "remesh_" + std::to_string(next_remesh_number(directory)), seconds, record);
        if (!force && !(record.quality_after > record.quality_before))
            return failed("the new mesh's worst quality " + std::to_string(record.quality_after)
                + " is not above the old one's " + std::to_string(record.quality_before) + "; kept the old mesh");
        fresh = std::make_unique<ReducedFunctional>(
            doc, m_functional->base_directory(), "remeshed problem", m_functional->device_override());
        fresh->set_distribution(m_functional->distribution()); // over the same processes
        if (fresh->design_layout() != m_functional->design_layout())
            return failed("the design variables change with the mesh");
        // J and the constraints at x on both meshes: the remesh's discretization change.
        const bool constraints = !m_functional->constraints().empty();
        const Evaluation before = m_functional->evaluate(m_functional->parameters_of(x), false, constraints);
        const Evaluation after = fresh->evaluate(fresh->parameters_of(x), false, constraints);
        record.J_before = before.value;
        record.J_after = after.value;
        record.constraints_before = before.constraint_values;
        record.constraints_after = after.constraint_values;
    } catch (const AdjointError& e) {
        return failed(std::string("the forward run on the new mesh failed: ") + e.what());
    } catch (const std::exception& e) { // RemeshError, InputError, filesystem errors, ...
        return failed(e.what());
    }
    record.seconds = timer.seconds();
    m_remesh_trigger = std::min(settings.quality, 0.9 * record.quality_after);
    m_remeshed = std::move(fresh);
    m_functional = m_remeshed.get();
    m_parameters_x.resize(0); // the new mesh's p
    build_validity();
    m_remeshes.push_back(record);
    m_remesh_failure.clear();
    if (on_remesh)
        on_remesh(m_remeshes.back());
    if (on_remesh_attempt)
        on_remesh_attempt();
    return true;
}

void DesignProblem::restore_remeshes(
    const std::vector<RemeshRecord>& records, int attempts, double trigger, double failed_seconds)
{
    m_remeshes = records;
    m_remesh_attempts = attempts;
    if (trigger > 0)
        m_remesh_trigger = trigger;
    m_failed_remesh_seconds = failed_seconds;
}

double DesignProblem::remesh_seconds() const
{
    double total = m_failed_remesh_seconds;
    for (const RemeshRecord& r : m_remeshes)
        total += r.seconds;
    return total;
}

} // namespace diffipc

namespace diffipc {

OptimizerResult minimize_design(
    DesignProblem& problem, const VectorXd& x0, const OptimizerSettings& settings, const OptimizerCheckpoint* resume)
{
    problem.set_objective_target(settings.objective_target);
    problem.set_time_budget(settings.max_seconds);
    problem.set_constraint_tolerance(settings.constraint_tolerance);
    OptimizerResult result = resume ? resume_minimize(problem, *resume, settings) : minimize(problem, x0, settings);
    while (problem.restart_pending()) {
        std::unique_ptr<OptimizerCheckpoint> c = problem.take_restart();
        const Timer timer;
        OptimizationValues values;
        const bool ok = problem.evaluate(c->x, values);
        c->evaluations += 1;
        c->evaluation_seconds += timer.seconds();
        // The run's wall time goes on through the callback, the remesh and this evaluation.
        c->elapsed_seconds += problem.seconds_since_iteration();
        if (!ok) {
            // The new mesh cannot be evaluated where the old one could: end the run with the
            // old mesh's result (the remesh is in remeshes(), the reason in last_rejection()).
            result.reason = StopReason::FAILED;
            result.message
                = "the problem on the new mesh cannot be evaluated at the remesh's design: " + problem.last_rejection();
            break;
        }
        c->values = values;
        c->previous_f = std::nan(""); // f on the old mesh does not compare with the new
        // Values on the old mesh do not compare with the new: the remesh's iterate is the best
        // point so far if it is feasible on the new mesh, else there is none yet.
        bool feasible = true;
        for (Index i = 0; i < values.inequality.size(); ++i)
            feasible = feasible && values.inequality[i] <= settings.constraint_tolerance;
        for (Index i = 0; i < values.equality.size(); ++i)
            feasible = feasible && std::abs(values.equality[i]) <= settings.constraint_tolerance;
        c->has_best = feasible;
        c->best_x = feasible ? c->x : VectorXd();
        c->best_values = feasible ? values : OptimizationValues();
        c->best_evaluation = feasible ? c->evaluations : 0;
        c->best_iteration = feasible ? c->iteration : -1;
        if (problem.on_restart)
            problem.on_restart(*c);
        result = resume_minimize(problem, *c, settings);
    }
    if (problem.target_reached()) {
        result.reason = StopReason::OBJECTIVE_TARGET;
        result.message = "J reached the objective target";
    }
    return result;
}

} // namespace diffipc
