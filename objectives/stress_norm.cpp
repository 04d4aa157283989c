#include "objectives/stress_norm.hpp"

#include "objectives/element_kinematics.hpp"
#include "objectives/objective.hpp"

#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace diffipc {

namespace {
    using namespace detail;

    struct GradientSink {
        const ParameterRequest& request;
        double scale;
        VectorXd& d_positions;
        ParameterGradient& partials;
    };

    template <int dim> struct MaterialSet {
        std::array<std::unique_ptr<Material<dim>>, 4> laws;
        const Material<dim>& operator()(MaterialModel model)
        {
            auto& law = laws[size_t(model)];
            if (!law)
                law = make_material<dim>(model);
            return *law;
        }
    };

    template <int dim> struct ElementState {
        Mat<dim> F, P, S;
        double s = 0; ///< stress norm
    };

    template <int dim>
    double stress_norm(const StressNormOptions& o, const Simulator& sim, const VectorXd& x, const GradientSink* sink)
    {
        const Mesh& mesh = sim.mesh();
        const FESpace& space = sim.space();
        const ElasticPotential& elastic = sim.elastic();
        const std::vector<Index> all = o.elements.empty() ? body_elements(mesh, -1) : std::vector<Index>();
        const std::vector<Index>& elements = o.elements.empty() ? all : o.elements;
        MaterialSet<dim> materials;

        std::vector<ElementState<dim>> states(elements.size());
        double total_volume = 0, s_max = 0;
        for (size_t i = 0; i < elements.size(); ++i) {
            const Index e = elements[i];
            if (e < 0 || e >= mesh.num_elements())
                throw std::invalid_argument("stress_norm: element " + std::to_string(e) + " out of range");
            ElementState<dim>& st = states[i];
            st.F = deformation_gradient<dim>(mesh, shape_gradients<dim>(space, e), e, x);
            st.P = materials(elastic.models()[size_t(e)]).stress(st.F, elastic.mu()[e], elastic.lambda()[e]);
            st.S = o.stress == StressMeasure::CAUCHY ? Mat<dim>(st.P * st.F.transpose() / st.F.determinant()) : st.P;
            const double trace = st.S.trace();
            const double s2 = o.norm == StressNormType::FROBENIUS ? st.S.squaredNorm()
                                                                  : 1.5 * st.S.squaredNorm() - 0.5 * trace * trace;
            st.s = std::sqrt(std::max(s2, 0.0));
            total_volume += space.rest_volume(e);
            s_max = std::max(s_max, st.s);
        }
        if (!(s_max > 0))
            return s_max; // 0 (or NaN, which must propagate)
        double sum = 0;
        for (size_t i = 0; i < elements.size(); ++i)
            sum += space.rest_volume(elements[i]) * std::pow(states[i].s / s_max, o.p);
        const double volume_scale = o.normalized ? 1.0 / total_volume : 1.0;
        const double J = s_max * std::pow(sum * volume_scale, 1.0 / o.p);
        if (!sink)
            return J;

        const ParameterRequest& request = sink->request;
        const double scale = sink->scale;
        VectorXd* dX
            = request.rest_positions ? &gradient_block(sink->partials.rest_positions, mesh.num_dofs()) : nullptr;
        VectorXd* dmu = request.lame ? &gradient_block(sink->partials.mu, mesh.num_elements()) : nullptr;
        VectorXd* dlambda = request.lame ? &gradient_block(sink->partials.lambda, mesh.num_elements()) : nullptr;
        VectorXd& dx = gradient_block(sink->d_positions, mesh.num_dofs());
        for (size_t i = 0; i < elements.size(); ++i) {
            const Index e = elements[i];
            const ElementState<dim>& st = states[i];
            const double volume = space.rest_volume(e);
            const double ratio = st.s / J;
            // dJ/d(s_e^2) = |e| s_e^{p-2} / (2 J^{p-1}) (times 1/V when normalized).
            double c = st.s > 0 ? volume * std::pow(ratio, o.p - 2) / (2 * J) : (o.p == 2 ? volume / (2 * J) : 0.0);
            c *= volume_scale;
            // Q = dJ/dS.
            Mat<dim> Q = o.norm == StressNormType::FROBENIUS ? Mat<dim>(2 * st.S)
                                                             : Mat<dim>(3 * st.S - st.S.trace() * Mat<dim>::Identity());
            Q *= c;
            Mat<dim> dP = Q, direct = Mat<dim>::Zero();
            if (o.stress == StressMeasure::CAUCHY) {
                // sigma = P F^T / det F: Q : d sigma = (Q F / det F) : dP + (Q^T P / det F - (Q : sigma) F^{-T}) : dF.
                const double det = st.F.determinant();
                dP = Q * st.F / det;
                direct = Q.transpose() * st.P / det - (Q.cwiseProduct(st.S).sum() / det) * cofactor<dim>(st.F);
            }
            const MaterialModel model = elastic.models()[size_t(e)];
            const auto T = materials(model).stress_derivative(st.F, elastic.mu()[e], elastic.lambda()[e]);
            const Mat<dim> B = unflatten_row_major<dim>(T.transpose() * flatten_row_major<dim>(dP)) + direct;
            const ShapeGradients<dim> G = shape_gradients<dim>(space, e);
            scatter_positions<dim>(mesh, G, e, B, scale, dx);
            if (dX) {
                // |e| dJ/d|e|: J^p = \sum |e| s^p (/ V) gives dJ/d|e| = (J / p) ((s/J)^p - [normalized]) (/ V).
                const double dvolume
                    = J / o.p * (std::pow(ratio, o.p) - (o.normalized ? 1.0 : 0.0)) * volume_scale * volume;
                scatter_rest_positions<dim>(mesh, G, e, st.F, B, dvolume, scale, *dX);
            }
            if (dmu) {
                (*dmu)[e] += scale * dP.cwiseProduct(materials(model).stress(st.F, 1.0, 0.0)).sum();
                (*dlambda)[e] += scale * dP.cwiseProduct(materials(model).stress(st.F, 0.0, 1.0)).sum();
            }
        }
        return J;
    }
} // namespace

StressNorm::StressNorm(StressNormOptions options)
    : m_options(std::move(options))
{
    if (!(m_options.p >= 1 && std::isfinite(m_options.p)))
        throw std::invalid_argument("stress_norm: p must be a finite number >= 1");
}

double StressNorm::value(const Simulator& sim, const StateRef& state) const
{
    return sim.mesh().dim == 2 ? stress_norm<2>(m_options, sim, state.positions, nullptr)
                               : stress_norm<3>(m_options, sim, state.positions, nullptr);
}

void StressNorm::add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
    double scale, VectorXd& d_positions, VectorXd&, ParameterGradient& partials) const
{
    const GradientSink sink { request, scale, d_positions, partials };
    if (sim.mesh().dim == 2)
        stress_norm<2>(m_options, sim, state.positions, &sink);
    else
        stress_norm<3>(m_options, sim, state.positions, &sink);
}

} // namespace diffipc
