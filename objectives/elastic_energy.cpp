#include "objectives/elastic_energy.hpp"

#include "objectives/element_kinematics.hpp"
#include "objectives/objective.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace diffipc {

namespace {
    using namespace detail;

    template <int dim>
    double elastic_energy(const std::vector<Index>& selected, const Simulator& sim, const VectorXd& x,
        const ParameterRequest* request, double scale, VectorXd* dx, ParameterGradient* partials)
    {
        const Mesh& mesh = sim.mesh();
        const FESpace& space = sim.space();
        const ElasticPotential& elastic = sim.elastic();
        const std::vector<Index> elements = selected.empty() ? body_elements(mesh, -1) : selected;
        std::array<std::unique_ptr<Material<dim>>, 4> laws;
        VectorXd* dX
            = request && request->rest_positions ? &gradient_block(partials->rest_positions, mesh.num_dofs()) : nullptr;
        VectorXd* dmu = request && request->lame ? &gradient_block(partials->mu, mesh.num_elements()) : nullptr;
        VectorXd* dlambda = request && request->lame ? &gradient_block(partials->lambda, mesh.num_elements()) : nullptr;
        if (dx)
            gradient_block(*dx, mesh.num_dofs());

        double energy = 0;
        for (const Index e : elements) {
            if (e < 0 || e >= mesh.num_elements())
                throw std::invalid_argument("elastic_energy: element " + std::to_string(e) + " out of range");
            auto& law = laws[size_t(elastic.models()[size_t(e)])];
            if (!law)
                law = make_material<dim>(elastic.models()[size_t(e)]);
            const ShapeGradients<dim> G = shape_gradients<dim>(space, e);
            const Mat<dim> F = deformation_gradient<dim>(mesh, G, e, x);
            const double volume = space.rest_volume(e), mu = elastic.mu()[e], lambda = elastic.lambda()[e];
            const double psi = law->energy_density(F, mu, lambda);
            energy += volume * psi;
            if (!dx)
                continue;
            const Mat<dim> B = volume * law->stress(F, mu, lambda);
            scatter_positions<dim>(mesh, G, e, B, scale, *dx);
            if (dX)
                scatter_rest_positions<dim>(mesh, G, e, F, B, volume * psi, scale, *dX);
            if (dmu) {
                (*dmu)[e] += scale * volume * law->energy_density(F, 1.0, 0.0);
                (*dlambda)[e] += scale * volume * law->energy_density(F, 0.0, 1.0);
            }
        }
        return energy;
    }
} // namespace

double ElasticEnergy::value(const Simulator& sim, const StateRef& state) const
{
    return sim.mesh().dim == 2 ? elastic_energy<2>(m_elements, sim, state.positions, nullptr, 0.0, nullptr, nullptr)
                               : elastic_energy<3>(m_elements, sim, state.positions, nullptr, 0.0, nullptr, nullptr);
}

namespace {
    template <int dim>
    double elastic_round_off(const std::vector<Index>& selected, const Simulator& sim, const VectorXd& x)
    {
        const Mesh& mesh = sim.mesh();
        const FESpace& space = sim.space();
        const ElasticPotential& elastic = sim.elastic();
        double magnitude = 0;
        const auto add = [&](Index e) {
            const Mat<dim> F = deformation_gradient<dim>(mesh, shape_gradients<dim>(space, e), e, x);
            magnitude
                += space.rest_volume(e) * (elastic.mu()[e] + std::abs(elastic.lambda()[e])) * (1 + F.squaredNorm());
        };
        if (selected.empty())
            for (Index e = 0; e < mesh.num_elements(); ++e)
                add(e);
        else
            for (Index e : selected)
                add(e);
        return 64 * std::numeric_limits<double>::epsilon() * magnitude;
    }
} // namespace

double ElasticEnergy::round_off(const Simulator& sim, const StateRef& state) const
{
    return sim.mesh().dim == 2 ? elastic_round_off<2>(m_elements, sim, state.positions)
                               : elastic_round_off<3>(m_elements, sim, state.positions);
}

void ElasticEnergy::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    if (sim.mesh().dim == 2)
        elastic_energy<2>(m_elements, sim, state.positions, &request, scale, &d_positions, &partials);
    else
        elastic_energy<3>(m_elements, sim, state.positions, &request, scale, &d_positions, &partials);
}

} // namespace diffipc
