#include "shape_opt/design_problem.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "shape_opt/parametrization/map_json.hpp"

#include <cmath>

namespace diffipc {

DesignProblem::DesignProblem(const ReducedFunctional& functional)
    : m_functional(functional)
{
    if (functional.has_shape())
        m_validity = std::make_unique<RestValidity>(bodies_mesh(functional.scene()));
    const auto& constraints = functional.constraints();
    m_scale.resize(Index(constraints.size()));
    for (size_t i = 0; i < constraints.size(); ++i) {
        (constraints[i].kind == ConstraintSpec::Kind::EQUALS ? m_equality : m_inequality).push_back(i);
        m_scale[Index(i)] = constraints[i].bound != 0 ? std::abs(constraints[i].bound) : 1.0;
    }
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
        p = m_functional.parameters_of(x);
        if (m_validity) {
            const std::string problem = m_validity->problem(m_functional.rest_positions_of(p));
            if (!problem.empty())
                return reject("invalid rest mesh: " + problem);
        }
        e = m_functional.evaluate(p, true, !m_functional.constraints().empty());
    } catch (const AdjointError& error) {
        return reject(error.what());
    } catch (const InputError& error) {
        // A value outside a map's or the simulation's domain (nu >= 0.5, a negative modulus),
        // an objective undefined there: this design, not the problem, is at fault.
        return reject(error.what());
    }
    if (!(m_objective_scale > 0))
        m_objective_scale = std::abs(e.value) > 1e-300 ? std::abs(e.value) : 1.0;
    out.f = e.value / m_objective_scale;
    out.gradient = m_functional.design_gradient(x, e.gradient) / m_objective_scale;
    const auto& constraints = m_functional.constraints();
    const Index n = x.size();
    out.inequality.resize(Index(m_inequality.size()));
    out.inequality_jacobian.resize(Index(m_inequality.size()), n);
    out.equality.resize(Index(m_equality.size()));
    out.equality_jacobian.resize(Index(m_equality.size()), n);
    const auto row = [&](size_t i) {
        return VectorXd(
            m_functional.design_gradient(x, e.constraint_gradients.row(Index(i)).transpose()) / m_scale[Index(i)]);
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
    m_last_constraints = e.constraint_values;
    m_last = std::move(e);
    return true;
}

double DesignProblem::max_valid_step(const VectorXd& x, const VectorXd& dx)
{
    if (!m_validity)
        return 1.0;
    try {
        // The rest positions move along X(x + t dx); for the linear shape maps (boundary
        // extension, free-form deformation, none) that is the line X0 + t dX.
        const VectorXd X0 = m_functional.rest_positions_of(m_functional.parameters_of(x));
        const VectorXd X1 = m_functional.rest_positions_of(m_functional.parameters_of(x + dx));
        return m_validity->max_step(X0, X1 - X0);
    } catch (const InputError&) {
        return 0.0;
    }
}

bool DesignProblem::iteration(const IterationInfo& info) { return on_iteration ? on_iteration(info) : true; }

} // namespace diffipc
