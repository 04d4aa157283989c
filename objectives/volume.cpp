#include "objectives/volume.hpp"

#include "objectives/element_kinematics.hpp"
#include "objectives/objective.hpp"

#include <stdexcept>

namespace diffipc {

namespace {
    using namespace detail;

    template <int dim>
    double volume(
        const std::vector<Index>& selected, const Simulator& sim, const VectorXd& x, double scale, VectorXd* dx)
    {
        const Mesh& mesh = sim.mesh();
        const FESpace& space = sim.space();
        const std::vector<Index> elements = selected.empty() ? body_elements(mesh, -1) : selected;
        if (dx)
            gradient_block(*dx, mesh.num_dofs());
        double total = 0;
        for (const Index e : elements) {
            if (e < 0 || e >= mesh.num_elements())
                throw std::invalid_argument("volume: element " + std::to_string(e) + " out of range");
            // det(D_s) / d! directly: no round-off dependence on the rest shape.
            Mat<dim> Ds;
            for (int a = 0; a < dim; ++a)
                Ds.col(a) = x.segment<dim>(mesh.elements(e, a + 1) * dim) - x.segment<dim>(mesh.elements(e, 0) * dim);
            total += Ds.determinant() / (dim == 2 ? 2.0 : 6.0);
            if (dx) {
                const ShapeGradients<dim> G = shape_gradients<dim>(space, e);
                const Mat<dim> F = deformation_gradient<dim>(mesh, G, e, x);
                scatter_positions<dim>(mesh, G, e, cofactor<dim>(F), scale * space.rest_volume(e), *dx);
            }
        }
        return total;
    }
} // namespace

double Volume::value(const Simulator& sim, const StateRef& state) const
{
    if (m_rest) {
        const VectorXd X = flatten(sim.mesh().rest_positions);
        return sim.mesh().dim == 2 ? volume<2>(m_elements, sim, X, 0.0, nullptr)
                                   : volume<3>(m_elements, sim, X, 0.0, nullptr);
    }
    return sim.mesh().dim == 2 ? volume<2>(m_elements, sim, state.positions, 0.0, nullptr)
                               : volume<3>(m_elements, sim, state.positions, 0.0, nullptr);
}

void Volume::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
    VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    if (m_rest) {
        // The same formula at x = X: d(det D_m / d!)/dX_a = |e| G_a, a partial in X.
        if (!request.rest_positions)
            return;
        const VectorXd X = flatten(sim.mesh().rest_positions);
        if (sim.mesh().dim == 2)
            volume<2>(m_elements, sim, X, scale, &partials.rest_positions);
        else
            volume<3>(m_elements, sim, X, scale, &partials.rest_positions);
        return;
    }
    if (sim.mesh().dim == 2)
        volume<2>(m_elements, sim, state.positions, scale, &d_positions);
    else
        volume<3>(m_elements, sim, state.positions, scale, &d_positions);
}

} // namespace diffipc
