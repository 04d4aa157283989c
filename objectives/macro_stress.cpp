#include "objectives/macro_stress.hpp"

#include "forward/contact/contact_potential.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "objectives/objective.hpp"

#include <stdexcept>

namespace diffipc {

MacroStress::MacroStress(int i, int j, int dim)
    : m_i(i)
    , m_j(j)
    , m_dim(dim)
{
}

std::string MacroStress::name() const
{
    const char* axes = "xyz";
    return std::string("macro_stress(") + axes[m_i] + axes[m_j] + ")";
}

VectorXd MacroStress::lever(const Simulator& sim) const
{
    const PeriodicCell* cell = sim.periodic();
    if (!cell)
        throw std::logic_error("macro_stress: the scene is not a periodic cell");
    const PeriodicMap& map = cell->map();
    // P's column of L G_ij holds (X_v - X_o)_j / L in the rows (v, i).
    return VectorXd(map.matrix().col(map.macro_dof(m_i, m_j))) * (map.length() / cell->volume());
}

double MacroStress::value(const Simulator& sim, const StateRef& state) const
{
    const VectorXd s = lever(sim);
    VectorXd g = VectorXd::Zero(s.size());
    sim.elastic().add_gradient(state.positions, 1.0, g);
    if (sim.contact())
        sim.contact()->add_gradient(state.positions, 1.0, g);
    return s.dot(g);
}

void MacroStress::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    const Mesh& mesh = sim.mesh();
    const VectorXd s = lever(sim);
    // df/dx = H s with the true Hessian of the elastic energy and the barrier.
    SparseAssembler H;
    H.build(mesh.dim, mesh.num_vertices(), mesh.elements);
    H.set_zero();
    sim.elastic().add_hessian(state.positions, 1.0, false, H);
    if (sim.contact())
        sim.contact()->add_hessian(state.positions, 1.0, false, H);
    H.finalize();
    const VectorXd Hs = H.matrix().selfadjointView<Eigen::Lower>() * s;
    gradient_block(d_positions, mesh.num_dofs()) += scale * Hs;
    if (request.rest_positions) {
        // At fixed x: the lever s_(v,i) = (X_v - X_o)_j / |Y| moves with X, and the potentials'
        // gradients depend on X (their shape derivatives of s^T grad).
        VectorXd& dX = gradient_block(partials.rest_positions, mesh.num_dofs());
        VectorXd g = VectorXd::Zero(s.size());
        sim.elastic().add_gradient(state.positions, 1.0, g);
        if (sim.contact())
            sim.contact()->add_gradient(state.positions, 1.0, g);
        const double volume = sim.periodic()->volume();
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            dX[v * m_dim + m_j] += scale * g[v * m_dim + m_i] / volume;
        sim.elastic().add_shape_derivative(state.positions, s, scale, dX);
        if (sim.contact())
            sim.contact()->add_shape_derivative(state.positions, s, scale, dX);
    }
    if (request.lame)
        sim.elastic().add_lame_derivative(state.positions, s, scale, gradient_block(partials.mu, mesh.num_elements()),
            gradient_block(partials.lambda, mesh.num_elements()));
}

} // namespace diffipc
