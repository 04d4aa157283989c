#include "objectives/kinetic_energy.hpp"

#include "objectives/objective.hpp"

#include <stdexcept>

namespace diffipc {

double KineticEnergy::evaluate(const Simulator& sim, const VectorXd& v, const ParameterRequest* request, double scale,
    VectorXd* dv, ParameterGradient* partials) const
{
    const Mesh& mesh = sim.mesh();
    const FESpace& space = sim.space();
    const int d = mesh.dim;
    const VectorXd& density = sim.inertia().density();
    const bool consistent = sim.inertia().consistent();
    const std::vector<Index> elements = m_elements.empty() ? body_elements(mesh, -1) : m_elements;
    VectorXd* dX
        = request && request->rest_positions ? &gradient_block(partials->rest_positions, mesh.num_dofs()) : nullptr;
    VectorXd* drho = request && request->density ? &gradient_block(partials->density, mesh.num_elements()) : nullptr;
    if (dv)
        gradient_block(*dv, mesh.num_dofs());

    double total = 0;
    VectorXd sum(d);
    for (const Index e : elements) {
        if (e < 0 || e >= mesh.num_elements())
            throw std::invalid_argument("kinetic_energy: element " + std::to_string(e) + " out of range");
        const double volume = space.rest_volume(e);
        // Per unit density: m_e = |e| / (d+1) (lumped), |e| / ((d+1)(d+2)) (consistent).
        const double base = consistent ? volume / ((d + 1) * (d + 2)) : volume / (d + 1);
        double squares = 0;
        sum.setZero();
        for (int a = 0; a <= d; ++a) {
            const auto va = v.segment(mesh.elements(e, a) * d, d);
            squares += va.squaredNorm();
            sum += va;
        }
        const double per_density = 0.5 * base * (squares + (consistent ? sum.squaredNorm() : 0.0));
        const double K = density[e] * per_density;
        total += K;
        if (!dv)
            continue;
        for (int a = 0; a <= d; ++a) {
            const Index i = mesh.elements(e, a) * d;
            dv->segment(i, d) += scale * density[e] * base * (v.segment(i, d) + (consistent ? sum : VectorXd::Zero(d)));
        }
        if (drho)
            (*drho)[e] += scale * per_density;
        if (dX) {
            const double* G = space.shape_gradients(e);
            for (int a = 0; a <= d; ++a)
                for (int j = 0; j < d; ++j)
                    (*dX)[mesh.elements(e, a) * d + j] += scale * K * G[a * d + j];
        }
    }
    return total;
}

double KineticEnergy::value(const Simulator& sim, const StateRef& state) const
{
    return evaluate(sim, state.velocities, nullptr, 0.0, nullptr, nullptr);
}

void KineticEnergy::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd&, VectorXd& d_velocities, ParameterGradient& partials) const
{
    evaluate(sim, state.velocities, &request, scale, &d_velocities, &partials);
}

} // namespace diffipc
