#include "objectives/body_force.hpp"

#include "forward/potentials/inertia_potential.hpp"

#include <cmath>
#include <stdexcept>

namespace diffipc {

BodyForce::BodyForce(int body, int axis, TimeMode mode, double p)
    : m_body(body)
    , m_axis(axis)
    , m_mode(mode)
    , m_p(p)
{
    if (body < 0 || axis < 0 || axis > 2)
        throw std::invalid_argument("body_force: bad body or axis");
    if (mode == TimeMode::TRAPEZOID)
        throw std::invalid_argument("body_force: the trapezoid rule is not offered (final, sum or max_p)");
    if (mode == TimeMode::MAX_P && !(p >= 1))
        throw std::invalid_argument("body_force: max_p needs p >= 1");
}

std::string BodyForce::name() const
{
    return "body_force(" + std::to_string(m_body) + "." + std::string(1, "xyz"[m_axis]) + ")";
}

VectorXd BodyForce::indicator(const Simulator& sim) const
{
    const Mesh& mesh = sim.mesh();
    if (m_axis >= mesh.dim)
        throw std::invalid_argument("body_force: axis out of range");
    VectorXd s = VectorXd::Zero(mesh.num_dofs());
    bool any = false;
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        if (mesh.vertex_body[v] == m_body) {
            s[v * mesh.dim + m_axis] = 1;
            any = true;
        }
    if (!any)
        throw std::invalid_argument("body_force: the mesh has no vertex of body " + std::to_string(m_body));
    return s;
}

VectorXd BodyForce::delta(const Simulator& sim, const Trajectory& trajectory, int k) const
{
    const double h = state_time(trajectory, k) - state_time(trajectory, k - 1);
    VectorXd d = (state_velocities(trajectory, k) - state_velocities(trajectory, k - 1)) / h;
    const VectorXd& g = sim.scene().gravity;
    const int dim = sim.mesh().dim;
    if (g.size() == dim)
        for (Index v = 0; v < sim.mesh().num_vertices(); ++v)
            d.segment(v * dim, dim) -= g;
    return d;
}

VectorXd BodyForce::forces(const Simulator& sim, const Trajectory& trajectory) const
{
    const int T = num_steps(trajectory);
    const VectorXd Ms = sim.inertia().apply_mass(indicator(sim));
    VectorXd F(T);
    for (int k = 1; k <= T; ++k)
        F[k - 1] = Ms.dot(delta(sim, trajectory, k));
    return F;
}

VectorXd BodyForce::weights(const VectorXd& F) const
{
    const Index T = F.size();
    VectorXd w = VectorXd::Zero(T);
    if (T == 0)
        return w;
    switch (m_mode) {
    case TimeMode::FINAL:
        w[T - 1] = 1;
        break;
    case TimeMode::SUM:
        w.setOnes();
        break;
    case TimeMode::MAX_P: {
        double S = 0;
        for (Index k = 0; k < T; ++k)
            S += std::pow(std::max(F[k], 0.0), m_p);
        if (S > 0)
            for (Index k = 0; k < T; ++k)
                w[k] = std::pow(S, 1 / m_p - 1) * std::pow(std::max(F[k], 0.0), m_p - 1);
        break;
    }
    case TimeMode::TRAPEZOID:
        break;
    }
    return w;
}

double BodyForce::value(const Simulator& sim, const Trajectory& trajectory) const
{
    const VectorXd F = forces(sim, trajectory);
    if (F.size() == 0)
        return 0;
    switch (m_mode) {
    case TimeMode::FINAL:
        return F[F.size() - 1];
    case TimeMode::SUM:
        return F.sum();
    case TimeMode::MAX_P: {
        double S = 0;
        for (Index k = 0; k < F.size(); ++k)
            S += std::pow(std::max(F[k], 0.0), m_p);
        return std::pow(S, 1 / m_p);
    }
    case TimeMode::TRAPEZOID:
        break;
    }
    return 0;
}

void BodyForce::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    const VectorXd s = indicator(sim);
    const VectorXd Ms = sim.inertia().apply_mass(s);
    const VectorXd w = weights(forces(sim, trajectory));
    const Mesh& mesh = sim.mesh();
    for (int k = 1; k <= int(w.size()); ++k) {
        if (w[k - 1] == 0)
            continue;
        const double h = state_time(trajectory, k) - state_time(trajectory, k - 1);
        seed.add_velocity(k, Ms, scale * w[k - 1] / h);
        seed.add_velocity(k - 1, Ms, -scale * w[k - 1] / h);
        if (request.rest_positions || request.density)
            sim.inertia().add_mass_derivatives(s, delta(sim, trajectory, k), scale * w[k - 1],
                request.rest_positions ? &gradient_block(seed.explicit_partials.rest_positions, mesh.num_dofs())
                                       : nullptr,
                request.density ? &gradient_block(seed.explicit_partials.density, mesh.num_elements()) : nullptr);
    }
}

} // namespace diffipc
