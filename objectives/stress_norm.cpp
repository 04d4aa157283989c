#include "objectives/stress_norm.hpp"

#include "forward/common/parallel.hpp"
#include "objectives/element_kinematics.hpp"
#include "objectives/objective.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

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

    /// The material laws of the models in use, made before the parallel loops read them.
    template <int dim> struct MaterialSet {
        std::array<std::unique_ptr<Material<dim>>, 4> laws;
        explicit MaterialSet(const std::vector<MaterialModel>& models)
        {
            for (MaterialModel model : models)
                if (!laws[size_t(model)])
                    laws[size_t(model)] = make_material<dim>(model);
        }
        const Material<dim>& operator()(MaterialModel model) const { return *laws[size_t(model)]; }
    };

    /// Per element; left uninitialized until the parallel loop writes it (see below).
    template <int dim> struct ElementState {
        Mat<dim> F, P, S;
        double s; ///< stress norm
    };

    /// n default-initialized values: no serial first touch of their pages (tens of MB on large meshes),
    /// which the parallel loops that fill them then touch in parallel.
    template <typename T> std::unique_ptr<T[]> uninitialized(size_t n) { return std::unique_ptr<T[]>(new T[n]); }

    template <int dim>
    double stress_norm(const StressNormOptions& o, const Simulator& sim, const VectorXd& x, const GradientSink* sink)
    {
        const Mesh& mesh = sim.mesh();
        const FESpace& space = sim.space();
        const ElasticPotential& elastic = sim.elastic();
        const std::vector<Index> all = o.elements.empty() ? body_elements(mesh, -1) : std::vector<Index>();
        const std::vector<Index>& elements = o.elements.empty() ? all : o.elements;
        for (const Index e : elements)
            if (e < 0 || e >= mesh.num_elements())
                throw std::invalid_argument("stress_norm: element " + std::to_string(e) + " out of range");
        const MaterialSet<dim> materials(elastic.models());

        // Per element, in parallel; the sums over elements are fixed-tree reductions and
        // the position gradients are gathered per vertex in element order
        // (forward/common/parallel.hpp): the same bits for any thread count.
        constexpr size_t GRAIN = 256;
        const std::unique_ptr<ElementState<dim>[]> states = uninitialized<ElementState<dim>>(elements.size());
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, elements.size(), GRAIN), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i < r.end(); ++i) {
                    const Index e = elements[i];
                    ElementState<dim>& st = states[i];
                    st.F = deformation_gradient<dim>(mesh, shape_gradients<dim>(space, e), e, x);
                    st.P = materials(elastic.models()[size_t(e)]).stress(st.F, elastic.mu()[e], elastic.lambda()[e]);
                    st.S = o.stress == StressMeasure::CAUCHY ? cauchy_stress(st.P, st.F) : st.P;
                    st.s = o.norm == StressNormType::FROBENIUS ? std::sqrt(st.S.squaredNorm()) : von_mises_stress(st.S);
                }
            });
        const double total_volume
            = parallel_sum(elements.size(), GRAIN, [&](size_t i) { return space.rest_volume(elements[i]); });
        double s_max = 0;
        for (size_t i = 0; i < elements.size(); ++i)
            s_max = std::max(s_max, states[i].s);
        if (!(s_max > 0))
            return s_max; // 0 (or NaN, which must propagate)
        const double sum = parallel_sum(elements.size(), GRAIN,
            [&](size_t i) { return space.rest_volume(elements[i]) * std::pow(states[i].s / s_max, o.p); });
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
        constexpr int NV = dim + 1;
        // Every entry is written in the loop below.
        const std::unique_ptr<double[]> local_x = uninitialized<double>(elements.size() * NV * dim);
        const std::unique_ptr<double[]> local_X = uninitialized<double>(dX ? elements.size() * NV * dim : 0);
        std::vector<double> local_mu(dmu ? elements.size() : 0), local_lambda(dmu ? elements.size() : 0);
        // The vertex incidence (a serial counting sort) is built beside the parallel element loop.
        VertexScatter scatter;
        tbb::task_group incidence;
        incidence.run([&] {
            scatter.build(mesh.num_vertices(), elements.size(), NV,
                [&](size_t i, int a) { return mesh.elements(elements[i], a); });
        });
        // The task reads only the mesh; wait for it however the loop ends.
        struct Join {
            tbb::task_group& group;
            ~Join()
            {
                try {
                    group.wait(); // the normal path's wait below rethrows the task's failure
                } catch (...) {
                }
            }
        } join { incidence };
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, elements.size(), GRAIN), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i < r.end(); ++i) {
                    const Index e = elements[i];
                    const ElementState<dim>& st = states[i];
                    const double volume = space.rest_volume(e);
                    const double ratio = st.s / J;
                    // dJ/d(s_e^2) = |e| s_e^{p-2} / (2 J^{p-1}) (times 1/V when normalized).
                    double c
                        = st.s > 0 ? volume * std::pow(ratio, o.p - 2) / (2 * J) : (o.p == 2 ? volume / (2 * J) : 0.0);
                    c *= volume_scale;
                    // Q = dJ/dS.
                    Mat<dim> Q = o.norm == StressNormType::FROBENIUS
                        ? Mat<dim>(2 * st.S)
                        : Mat<dim>(3 * st.S - st.S.trace() * Mat<dim>::Identity());
                    Q *= c;
                    Mat<dim> dP = Q, direct = Mat<dim>::Zero();
                    if (o.stress == StressMeasure::CAUCHY) {
                        // sigma = P F^T / det F: Q : d sigma = (Q F / det F) : dP + (Q^T P / det F - (Q : sigma)
                        // F^{-T}) : dF.
                        const double det = st.F.determinant();
                        dP = Q * st.F / det;
                        direct = Q.transpose() * st.P / det - (Q.cwiseProduct(st.S).sum() / det) * cofactor<dim>(st.F);
                    }
                    const MaterialModel model = elastic.models()[size_t(e)];
                    const auto T = materials(model).stress_derivative(st.F, elastic.mu()[e], elastic.lambda()[e]);
                    const Mat<dim> B = unflatten_row_major<dim>(T.transpose() * flatten_row_major<dim>(dP)) + direct;
                    const ShapeGradients<dim> G = shape_gradients<dim>(space, e);
                    // scatter_positions / scatter_rest_positions (element_kinematics.hpp), per local vertex.
                    Mat<dim> C = -st.F.transpose() * B;
                    if (dX) {
                        // |e| dJ/d|e|: J^p = \sum |e| s^p (/ V) gives dJ/d|e| = (J / p) ((s/J)^p - [normalized]) (/ V).
                        C.diagonal().array()
                            += J / o.p * (std::pow(ratio, o.p) - (o.normalized ? 1.0 : 0.0)) * volume_scale * volume;
                    }
                    for (int a = 0; a < NV; ++a) {
                        Eigen::Map<Eigen::Matrix<double, dim, 1>>(local_x.get() + (i * NV + size_t(a)) * dim)
                            = B * G.row(a).transpose();
                        if (dX)
                            Eigen::Map<Eigen::Matrix<double, dim, 1>>(local_X.get() + (i * NV + size_t(a)) * dim)
                                = C * G.row(a).transpose();
                    }
                    if (dmu) {
                        local_mu[i] = scale * dP.cwiseProduct(materials(model).stress(st.F, 1.0, 0.0)).sum();
                        local_lambda[i] = scale * dP.cwiseProduct(materials(model).stress(st.F, 0.0, 1.0)).sum();
                    }
                }
            });
        // In list order (an element may be listed twice).
        for (size_t i = 0; dmu && i < elements.size(); ++i) {
            (*dmu)[elements[i]] += local_mu[i];
            (*dlambda)[elements[i]] += local_lambda[i];
        }
        incidence.wait();
        scatter.add(local_x.get(), dim, scale, dx);
        if (dX)
            scatter.add(local_X.get(), dim, scale, *dX);
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
