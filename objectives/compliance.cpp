#include "objectives/compliance.hpp"

#include "objectives/objective.hpp"

namespace diffipc {

double Compliance::value(const Simulator& sim, const StateRef& state) const
{
    return sim.external_forces(state.time).dot(state.positions - flatten(sim.mesh().rest_positions));
}

void Compliance::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    const Index n = sim.mesh().num_dofs();
    const VectorXd f = sim.external_forces(state.time);
    gradient_block(d_positions, n) += scale * f;
    if (!request.rest_positions && !request.density)
        return;
    const VectorXd u = scale * (state.positions - flatten(sim.mesh().rest_positions));
    VectorXd* dX = nullptr;
    if (request.rest_positions) {
        dX = &gradient_block(partials.rest_positions, n);
        *dX -= scale * f;
    }
    VectorXd* drho = request.density ? &gradient_block(partials.density, sim.mesh().num_elements()) : nullptr;
    sim.external_force_derivatives(state.time, u, dX, drho);
}

} // namespace diffipc
