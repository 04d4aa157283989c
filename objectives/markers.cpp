#include "objectives/markers.hpp"

#include <cmath>
#include <stdexcept>

namespace diffipc {

MarkerPoint MarkerPoint::barycentric(const Mesh& mesh, Index e, const std::vector<double>& weights)
{
    if (e < 0 || e >= mesh.num_elements())
        throw std::invalid_argument("marker: element " + std::to_string(e) + " out of range");
    if (int(weights.size()) != mesh.dim + 1)
        throw std::invalid_argument("marker: expected " + std::to_string(mesh.dim + 1) + " barycentric weights");
    double sum = 0;
    for (double w : weights)
        sum += w;
    if (!(std::abs(sum - 1) <= 1e-12))
        throw std::invalid_argument("marker: barycentric weights must sum to 1");
    MarkerPoint p;
    for (int a = 0; a <= mesh.dim; ++a)
        p.vertices.push_back(mesh.elements(e, a));
    p.weights = weights;
    return p;
}

MarkerTracking::MarkerTracking(
    std::vector<MarkerPoint> markers, std::vector<int> steps, std::vector<Positions> targets, VectorXd weights)
    : m_markers(std::move(markers))
    , m_steps(std::move(steps))
    , m_targets(std::move(targets))
    , m_weights(weights.size() ? std::move(weights) : VectorXd::Ones(Index(m_markers.size())))
{
    const Index M = Index(m_markers.size());
    if (M == 0)
        throw std::invalid_argument("markers: no marker points");
    if (m_weights.size() != M)
        throw std::invalid_argument("markers: expected one weight per marker");
    if (m_steps.size() != m_targets.size())
        throw std::invalid_argument("markers: expected one target set per listed step");
    for (const MarkerPoint& p : m_markers)
        if (p.vertices.empty() || p.vertices.size() != p.weights.size())
            throw std::invalid_argument("markers: a marker needs vertices and one weight per vertex");
    for (const Positions& y : m_targets)
        if (y.rows() != M)
            throw std::invalid_argument("markers: expected one target position per marker");
}

Positions MarkerTracking::positions(const VectorXd& x, int dim) const
{
    Positions p = Positions::Zero(Index(m_markers.size()), dim);
    for (size_t m = 0; m < m_markers.size(); ++m)
        for (size_t i = 0; i < m_markers[m].vertices.size(); ++i) {
            const Index v = m_markers[m].vertices[i];
            if (v < 0 || (v + 1) * dim > x.size())
                throw std::out_of_range("markers: vertex " + std::to_string(v) + " out of range");
            p.row(Index(m)) += m_markers[m].weights[i] * x.segment(v * dim, dim).transpose();
        }
    return p;
}

Positions MarkerTracking::residual(const Trajectory& trajectory, size_t s, int dim) const
{
    if (m_targets[s].cols() != dim)
        throw std::invalid_argument("markers: targets have " + std::to_string(m_targets[s].cols())
            + " components, the scene " + std::to_string(dim));
    return positions(state_positions(trajectory, m_steps[s]), dim) - m_targets[s];
}

double MarkerTracking::value(const Simulator& sim, const Trajectory& trajectory) const
{
    const int d = sim.mesh().dim;
    double J = 0;
    for (size_t s = 0; s < m_steps.size(); ++s) {
        const Positions r = residual(trajectory, s, d);
        J += 0.5 * (m_weights.array() * r.rowwise().squaredNorm().array()).sum();
    }
    return J;
}

void MarkerTracking::add_gradient(
    const Simulator& sim, const Trajectory& trajectory, const ParameterRequest&, double scale, StateSeed& seed) const
{
    const int d = sim.mesh().dim;
    for (size_t s = 0; s < m_steps.size(); ++s) {
        const Positions r = residual(trajectory, s, d);
        VectorXd& g = gradient_block(seed.positions.at(size_t(m_steps[s])), sim.mesh().num_dofs());
        for (size_t m = 0; m < m_markers.size(); ++m)
            for (size_t i = 0; i < m_markers[m].vertices.size(); ++i)
                g.segment(m_markers[m].vertices[i] * d, d)
                    += scale * m_weights[Index(m)] * m_markers[m].weights[i] * r.row(Index(m)).transpose();
    }
}

} // namespace diffipc
