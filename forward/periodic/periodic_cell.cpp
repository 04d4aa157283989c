#include "forward/periodic/periodic_cell.hpp"

#include "forward/common/error.hpp"

#include <cmath>
#include <limits>

namespace diffipc {

PeriodicCell::PeriodicCell(const Scene& scene, const Problem& full, SparseAssembler& full_assembler)
    : m_scene(scene)
    , m_map(scene.mesh, scene.periodic.pairing, scene.periodic.box.lower,
          (scene.periodic.box.upper - scene.periodic.box.lower).maxCoeff())
    , m_potential(full, full_assembler, m_map)
    , m_linear(scene.solver.linear_solver)
{
    const int d = scene.dim;
    const PeriodicSpec& p = scene.periodic;
    m_reduced.add(&m_potential, 1.0);
    m_assembler.build(d, m_map.num_classes() + d, periodic_elements(scene.mesh, p.pairing), false);
    // The class of the vertex nearest the lower corner carries no fluctuation.
    double nearest = std::numeric_limits<double>::infinity();
    for (Index v = 0; v < scene.mesh.num_vertices(); ++v) {
        const double distance = (scene.mesh.rest_positions.row(v).transpose() - p.box.lower).squaredNorm();
        if (distance < nearest) {
            nearest = distance;
            m_pinned = p.pairing.vertex_class[v];
        }
    }
    m_constrained.assign(size_t(m_map.num_reduced()), 0);
    for (int i = 0; i < d; ++i) {
        m_constrained[size_t(m_map.fluctuation_dof(m_pinned, i))] = 1;
        for (int j = 0; j < d; ++j)
            m_constrained[size_t(m_map.macro_dof(i, j))] = prescribed(i, j);
    }
    m_volume = 1;
    for (int a = 0; a < d; ++a)
        m_volume *= p.box.length(a);
}

VectorXd PeriodicCell::prescribed_values(double t, const MatrixXd* given, int k) const
{
    const int d = m_scene.dim;
    VectorXd values = VectorXd::Zero(d * d);
    for (int c = 0; c < d * d; ++c)
        if (m_scene.periodic.gradient[size_t(c)])
            values[c] = given ? (*given)(k - 1, c) : (*m_scene.periodic.gradient[size_t(c)])(t, 0, 0, 0);
    return values;
}

void PeriodicCell::step_unknowns(
    const VectorXd& x, const VectorXd& G, double t, const VectorXd* given, VectorXd& q, VectorXd& target) const
{
    const int d = m_scene.dim;
    q = m_map.reduced(x, G);
    target = q;
    const VectorXd values = given ? *given : prescribed_values(t);
    for (int i = 0; i < d; ++i) {
        target[m_map.fluctuation_dof(m_pinned, i)] = 0;
        for (int j = 0; j < d; ++j)
            if (prescribed(i, j))
                target[m_map.macro_dof(i, j)] = m_map.length() * values[i * d + j];
    }
    if (!target.allFinite())
        throw InputError("periodic.gradient", "not finite at t = " + format_number(t) + " s");
}

NewtonResult PeriodicCell::solve(VectorXd& x, VectorXd& G, double t, const NewtonSettings& settings, double force_scale,
    double step_scale, const VectorXd* given)
{
    VectorXd q, target;
    step_unknowns(x, G, t, given, q, target);
    const NewtonSolver newton(m_reduced, m_assembler, m_linear, settings);
    NewtonResult r = newton.solve(q, target, m_constrained, force_scale, step_scale);
    if (r.status == StepStatus::CONVERGED) {
        x = m_map.positions(q);
        G = m_map.macro_gradient(q);
    }
    return r;
}

VectorXd PeriodicCell::average_stress(const Potential& potential, const VectorXd& x) const
{
    VectorXd g = VectorXd::Zero(x.size());
    potential.add_gradient(x, 1.0, g);
    return m_map.macro_derivative(g) / m_volume;
}

} // namespace diffipc
