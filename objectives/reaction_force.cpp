#include "objectives/reaction_force.hpp"

#include "forward/contact/contact_potential.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <stdexcept>

namespace diffipc {

namespace {
    /// The indicator vector s of the dofs (#V*dim).
    VectorXd indicator(const Simulator& sim, const std::vector<Index>& dofs)
    {
        VectorXd s = VectorXd::Zero(sim.mesh().num_dofs());
        for (const Index i : dofs)
            s[i] = 1.0;
        return s;
    }

    /// Calls f(e, rest, deformed, local s) for every element with a vertex among the dofs'.
    template <typename F>
    void for_each_touching_element(const Simulator& sim, const VectorXd& s, const VectorXd& x, F&& f)
    {
        const Mesh& mesh = sim.mesh();
        const int d = mesh.dim;
        const int nv = d + 1;
        MatrixXd rest(nv, d), deformed(nv, d);
        VectorXd local(nv * d);
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            for (int a = 0; a < nv; ++a) {
                const Index v = mesh.elements(e, a);
                local.segment(a * d, d) = s.segment(v * d, d);
                rest.row(a) = mesh.rest_positions.row(v);
                deformed.row(a) = x.segment(v * d, d).transpose();
            }
            if (!local.isZero(0.0))
                f(e, rest, deformed, local);
        }
    }

    void check_no_friction(const Simulator& sim)
    {
        if (sim.friction())
            throw std::logic_error("reaction_force: scenes with friction are not supported");
    }
} // namespace

ReactionForce::ReactionForce(std::vector<Index> dofs, std::string label)
    : m_dofs(std::move(dofs))
    , m_label(std::move(label))
{
}

std::vector<Index> prescribed_dofs_of(const Simulator& sim, int condition, int axis)
{
    const std::vector<int>& owner = sim.prescribing_condition();
    const int d = sim.mesh().dim;
    std::vector<Index> dofs;
    for (size_t i = 0; i < owner.size(); ++i)
        if (owner[i] == condition && int(i) % d == axis)
            dofs.push_back(Index(i));
    return dofs;
}

double ReactionForce::value(const Simulator& sim, const StateRef& state) const
{
    check_no_friction(sim);
    const VectorXd s = indicator(sim, m_dofs);
    const ElasticPotential& elastic = sim.elastic();
    const std::vector<MaterialModel>& models = elastic.models();
    double R = 0;
    for_each_touching_element(
        sim, s, state.positions, [&](Index e, const MatrixXd& rest, const MatrixXd& deformed, const VectorXd& local) {
            R += local.dot(element_gradient(models[size_t(e)], rest, deformed, elastic.mu()[e], elastic.lambda()[e]));
        });
    if (sim.contact()) {
        VectorXd g = VectorXd::Zero(s.size());
        sim.contact()->add_gradient(state.positions, 1.0, g);
        R += s.dot(g);
    }
    return R - s.dot(sim.external_forces(state.time));
}

void ReactionForce::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    check_no_friction(sim);
    const Mesh& mesh = sim.mesh();
    const Index n = mesh.num_dofs();
    const int d = mesh.dim;
    const VectorXd s = indicator(sim, m_dofs);
    const VectorXd& x = state.positions;
    const ElasticPotential& elastic = sim.elastic();
    const std::vector<MaterialModel>& models = elastic.models();
    // dR/dx = H s: the element Hessians of the elements that touch S, then the barrier's.
    VectorXd& dx = gradient_block(d_positions, n);
    for_each_touching_element(
        sim, s, x, [&](Index e, const MatrixXd& rest, const MatrixXd& deformed, const VectorXd& local) {
            const VectorXd Hs
                = element_hessian(models[size_t(e)], rest, deformed, elastic.mu()[e], elastic.lambda()[e], false)
                * local;
            for (int a = 0; a <= d; ++a)
                dx.segment(mesh.elements(e, a) * d, d) += scale * Hs.segment(a * d, d);
        });
    const ContactPotential* contact = sim.contact();
    if (contact) {
        // Contacts couple vertices outside the element pattern: a pattern of the diagonal
        // blocks only, with the contacts' local matrices merged by finalize().
        SparseAssembler H;
        H.build(d, mesh.num_vertices(), MatrixXi(0, d + 1));
        H.set_zero();
        contact->add_hessian(x, 1.0, false, H);
        H.finalize();
        const VectorXd Hs = H.matrix().selfadjointView<Eigen::Lower>() * s;
        dx += scale * Hs;
    }
    if (request.lame)
        elastic.add_lame_derivative(x, s, scale, gradient_block(partials.mu, mesh.num_elements()),
            gradient_block(partials.lambda, mesh.num_elements()));
    VectorXd* dX = request.rest_positions ? &gradient_block(partials.rest_positions, n) : nullptr;
    VectorXd* drho = request.density ? &gradient_block(partials.density, mesh.num_elements()) : nullptr;
    if (dX) {
        elastic.add_shape_derivative(x, s, scale, *dX);
        if (contact)
            contact->add_shape_derivative(x, s, scale, *dX);
    }
    if (dX || drho)
        sim.external_force_derivatives(state.time, -scale * s, dX, drho);
}

} // namespace diffipc
