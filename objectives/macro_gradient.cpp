#include "objectives/macro_gradient.hpp"

#include "objectives/objective.hpp"

#include <stdexcept>

namespace diffipc {

MacroGradient::MacroGradient(int i, int j, int dim)
    : m_i(i)
    , m_j(j)
    , m_dim(dim)
{
}

std::string MacroGradient::name() const
{
    const char* axes = "xyz";
    return std::string("macro_gradient(") + axes[m_i] + axes[m_j] + ")";
}

std::pair<Index, Index> MacroGradient::pair(const Simulator& sim) const
{
    if (!sim.periodic())
        throw std::logic_error("macro_gradient: the scene is not a periodic cell");
    const PeriodicPairing& pairing = sim.scene().periodic.pairing;
    for (Index v = 0; v < pairing.offset.rows(); ++v) {
        bool one_step = pairing.offset(v, m_j) == 1;
        for (int a = 0; a < m_dim && one_step; ++a)
            one_step = a == m_j || pairing.offset(v, a) == 0;
        if (one_step)
            return { pairing.representative[pairing.vertex_class[v]], v };
    }
    throw std::logic_error("macro_gradient: no pair of vertices a lattice step apart along the axis");
}

double MacroGradient::value(const Simulator& sim, const StateRef& state) const
{
    const auto [a, b] = pair(sim);
    const Positions& X = sim.mesh().rest_positions;
    const double length = X(b, m_j) - X(a, m_j);
    return (state.positions[b * m_dim + m_i] - state.positions[a * m_dim + m_i]) / length - (m_i == m_j ? 1.0 : 0.0);
}

void MacroGradient::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    const auto [a, b] = pair(sim);
    const Mesh& mesh = sim.mesh();
    const double length = mesh.rest_positions(b, m_j) - mesh.rest_positions(a, m_j);
    VectorXd& dx = gradient_block(d_positions, mesh.num_dofs());
    dx[b * m_dim + m_i] += scale / length;
    dx[a * m_dim + m_i] -= scale / length;
    if (request.rest_positions) {
        const double stretch
            = (state.positions[b * m_dim + m_i] - state.positions[a * m_dim + m_i]) / (length * length);
        VectorXd& dX = gradient_block(partials.rest_positions, mesh.num_dofs());
        dX[b * m_dim + m_j] -= scale * stretch;
        dX[a * m_dim + m_j] += scale * stretch;
    }
}

} // namespace diffipc
