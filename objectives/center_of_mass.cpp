#include "objectives/center_of_mass.hpp"

#include <stdexcept>

namespace diffipc {

namespace {
    /// Element masses m_e = rho_e |e| and centroids of the chosen elements.
    struct MassData {
        std::vector<Index> elements;
        VectorXd mass;
        double total = 0;
    };

    MassData masses(const Simulator& sim, const std::vector<Index>& selected)
    {
        MassData m;
        m.elements = selected.empty() ? body_elements(sim.mesh(), -1) : selected;
        m.mass.resize(Index(m.elements.size()));
        for (size_t i = 0; i < m.elements.size(); ++i) {
            const Index e = m.elements[i];
            if (e < 0 || e >= sim.mesh().num_elements())
                throw std::invalid_argument("center_of_mass: element " + std::to_string(e) + " out of range");
            m.mass[Index(i)] = sim.inertia().density()[e] * sim.space().rest_volume(e);
            m.total += m.mass[Index(i)];
        }
        return m;
    }

    VectorXd centroid(const Mesh& mesh, Index e, const VectorXd& x)
    {
        const int d = mesh.dim;
        VectorXd c = VectorXd::Zero(d);
        for (int a = 0; a <= d; ++a)
            c += x.segment(mesh.elements(e, a) * d, d) / (d + 1);
        return c;
    }

    VectorXd center_of(const Mesh& mesh, const MassData& m, const VectorXd& x)
    {
        VectorXd c = VectorXd::Zero(mesh.dim);
        for (size_t i = 0; i < m.elements.size(); ++i)
            c += m.mass[Index(i)] * centroid(mesh, m.elements[i], x);
        return c / m.total;
    }
} // namespace

CenterOfMassTracking::CenterOfMassTracking(
    std::vector<int> steps, Positions targets, double weight, std::vector<Index> elements)
    : m_steps(std::move(steps))
    , m_targets(std::move(targets))
    , m_weight(weight)
    , m_elements(std::move(elements))
{
    if (Index(m_steps.size()) != m_targets.rows())
        throw std::invalid_argument("center_of_mass: expected one target per listed step");
}

VectorXd CenterOfMassTracking::center(const Simulator& sim, const VectorXd& x) const
{
    return center_of(sim.mesh(), masses(sim, m_elements), x);
}

double CenterOfMassTracking::value(const Simulator& sim, const Trajectory& trajectory) const
{
    if (m_targets.size() && m_targets.cols() != sim.mesh().dim)
        throw std::invalid_argument("center_of_mass: targets do not have the scene's dimension");
    const MassData m = masses(sim, m_elements);
    double J = 0;
    for (size_t s = 0; s < m_steps.size(); ++s) {
        const VectorXd r
            = center_of(sim.mesh(), m, state_positions(trajectory, m_steps[s])) - m_targets.row(Index(s)).transpose();
        J += 0.5 * m_weight * r.squaredNorm();
    }
    return J;
}

void CenterOfMassTracking::add_gradient(const Simulator& sim, const Trajectory& trajectory,
    const ParameterRequest& request, double scale, StateSeed& seed) const
{
    if (m_targets.size() && m_targets.cols() != sim.mesh().dim)
        throw std::invalid_argument("center_of_mass: targets do not have the scene's dimension");
    const Mesh& mesh = sim.mesh();
    const int d = mesh.dim;
    const MassData m = masses(sim, m_elements);
    VectorXd* dX
        = request.rest_positions ? &gradient_block(seed.explicit_partials.rest_positions, mesh.num_dofs()) : nullptr;
    VectorXd* drho = request.density ? &gradient_block(seed.explicit_partials.density, mesh.num_elements()) : nullptr;
    for (size_t s = 0; s < m_steps.size(); ++s) {
        const VectorXd& x = state_positions(trajectory, m_steps[s]);
        const VectorXd c = center_of(mesh, m, x);
        const VectorXd g = scale * m_weight * (c - m_targets.row(Index(s)).transpose());
        VectorXd& dx = gradient_block(seed.positions.at(size_t(m_steps[s])), mesh.num_dofs());
        for (size_t i = 0; i < m.elements.size(); ++i) {
            const Index e = m.elements[i];
            for (int a = 0; a <= d; ++a)
                dx.segment(mesh.elements(e, a) * d, d) += m.mass[Index(i)] / ((d + 1) * m.total) * g;
            if (!dX && !drho)
                continue;
            // dJ/dm_e = g . (xbar_e - c) / M.
            const double dm = g.dot(centroid(mesh, e, x) - c) / m.total;
            const double volume = sim.space().rest_volume(e);
            if (drho)
                (*drho)[e] += dm * volume;
            if (dX) {
                const double* G = sim.space().shape_gradients(e);
                const double factor = dm * sim.inertia().density()[e] * volume;
                for (int a = 0; a <= d; ++a)
                    for (int j = 0; j < d; ++j)
                        (*dX)[mesh.elements(e, a) * d + j] += factor * G[a * d + j];
            }
        }
    }
}

} // namespace diffipc
