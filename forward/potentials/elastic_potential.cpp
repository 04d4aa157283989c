#include "forward/potentials/elastic_potential.hpp"

#include "forward/common/error.hpp"
#include "forward/kernels/element.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <array>
#include <cmath>
#include <limits>

namespace diffipc {

namespace {

    template <int dim> struct Kernel {
        static constexpr int L = dim * (dim + 1);
        using Mat = Eigen::Matrix<double, dim, dim>;
        using Tensor = Eigen::Matrix<double, dim * dim, dim * dim>;
        using Grad = Eigen::Matrix<double, dim + 1, dim, Eigen::RowMajor>;

        /// F = sum_a x_a G_a^T with xe (dim+1) x dim rows of vertex positions (the kernel's, as on the GPU).
        static Mat deformation(const Grad& G, const Grad& xe)
        {
            Eigen::Matrix<double, dim, dim, Eigen::RowMajor> F;
            kernels::deformation_gradient<dim>(G.data(), xe.data(), F.data());
            return F;
        }
    };

    template <int dim> struct ElementData {
        typename Kernel<dim>::Grad G;
        double volume;
    };

    template <int dim> ElementData<dim> element_data(const typename Kernel<dim>::Grad& rest)
    {
        ElementData<dim> d;
        const double det = kernels::element_rest_data<dim>(rest.data(), d.G.data(), d.volume);
        if (!(std::abs(det) > 0))
            throw InputError("rest", "degenerate rest element");
        return d;
    }

    template <int dim> typename Kernel<dim>::Grad to_local(const MatrixXd& m)
    {
        if (m.rows() != dim + 1 || m.cols() != dim)
            throw InputError(
                "positions", "expected a " + std::to_string(dim + 1) + " by " + std::to_string(dim) + " matrix");
        return m;
    }

    template <int dim> typename Kernel<dim>::Grad gather(const Mesh& mesh, Index e, const VectorXd& x)
    {
        typename Kernel<dim>::Grad xe;
        for (int a = 0; a <= dim; ++a)
            for (int i = 0; i < dim; ++i)
                xe(a, i) = x[mesh.elements(e, a) * dim + i];
        return xe;
    }

    template <int dim> typename Kernel<dim>::Grad shape(const FESpace& space, Index e)
    {
        return Eigen::Map<const typename Kernel<dim>::Grad>(space.shape_gradients(e));
    }

} // namespace

struct ElasticPotential::Impl {
    std::unique_ptr<Material<2>> materials2[4];
    std::unique_ptr<Material<3>> materials3[4];
    Impl()
    {
        for (int m = 0; m < 4; ++m) {
            materials2[m] = make_material<2>(MaterialModel(m));
            materials3[m] = make_material<3>(MaterialModel(m));
        }
    }
    template <int dim> const Material<dim>& material(MaterialModel m) const
    {
        if constexpr (dim == 2)
            return *materials2[int(m)];
        else
            return *materials3[int(m)];
    }
    /// Calls visit(e, F, P) with the deformation gradient and first Piola-Kirchhoff stress of
    /// every element at x (serially, in element order).
    template <int dim, typename Visit>
    void for_each_stress(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& mu,
        const VectorXd& lambda, const VectorXd& x, Visit visit) const
    {
        for (Index e = 0; e < space.num_elements(); ++e) {
            const Eigen::Matrix<double, dim, dim> F
                = Kernel<dim>::deformation(shape<dim>(space, e), gather<dim>(space.mesh(), e, x));
            const Eigen::Matrix<double, dim, dim> P = material<dim>(models[size_t(e)]).stress(F, mu[e], lambda[e]);
            visit(e, F, P);
        }
    }
};

ElasticPotential::ElasticPotential(
    const FESpace& space, std::vector<MaterialModel> models, VectorXd mu, VectorXd lambda)
    : m_space(space)
    , m_models(std::move(models))
    , m_mu(std::move(mu))
    , m_lambda(std::move(lambda))
    , m_impl(std::make_unique<Impl>())
{
    const Mesh& mesh = m_space.mesh();
    m_scatter.build(mesh.num_vertices(), size_t(mesh.num_elements()), int(mesh.elements.cols()),
        [&](size_t e, int a) { return Index(mesh.elements(Index(e), a)); });
}

ElasticPotential::~ElasticPotential() = default;

void ElasticPotential::set_lame_parameters(const VectorXd& mu, const VectorXd& lambda)
{
    if (mu.size() != m_space.num_elements() || lambda.size() != m_space.num_elements())
        throw InputError("lame_parameters", "expected one value per element");
    m_mu = mu;
    m_lambda = lambda;
}

namespace {

    // Fixed grain and deterministic reduce: the sum order does not depend on scheduling.
    constexpr Index GRAIN = 256;

    template <int dim>
    double value_impl(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& mu,
        const VectorXd& lambda, const VectorXd& x)
    {
        const Mesh& mesh = space.mesh();
        return tbb::parallel_deterministic_reduce(
            tbb::blocked_range<Index>(0, space.num_elements(), GRAIN), 0.0,
            [&](const tbb::blocked_range<Index>& r, double sum) {
                for (Index e = r.begin(); e < r.end(); ++e) {
                    sum += kernels::element_energy<dim>(models[size_t(e)], space.shape_gradients(e),
                        space.rest_volume(e), gather<dim>(mesh, e, x).data(), mu[e], lambda[e]);
                }
                return sum;
            },
            std::plus<double>());
    }

} // namespace

double ElasticPotential::value(const VectorXd& x) const
{
    if (m_space.dim() == 2)
        return value_impl<2>(m_space, m_models, m_mu, m_lambda, x);
    return value_impl<3>(m_space, m_models, m_mu, m_lambda, x);
}

namespace {

    template <int dim>
    void gradient_impl(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& mu,
        const VectorXd& lambda, const VectorXd& x, double weight, VectorXd& g, std::vector<double>& local,
        const VertexScatter& scatter)
    {
        constexpr int L = Kernel<dim>::L;
        const Mesh& mesh = space.mesh();
        const Index ne = space.num_elements();
        local.resize(size_t(ne) * L); // per-element gradients, kept between calls
        tbb::parallel_for(tbb::blocked_range<Index>(0, ne, GRAIN), [&](const tbb::blocked_range<Index>& r) {
            for (Index e = r.begin(); e < r.end(); ++e) {
                kernels::element_gradient<dim>(models[size_t(e)], space.shape_gradients(e),
                    weight * space.rest_volume(e), gather<dim>(mesh, e, x).data(), mu[e], lambda[e],
                    local.data() + size_t(e) * L);
            }
        });
        scatter.add(local.data(), dim, 1.0, g);
    }

    /// The kernel's element Hessian is row-major, add_element reads column-major: it adds the
    /// transpose, the same symmetric matrix.
    template <int dim>
    void hessian_impl(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& mu,
        const VectorXd& lambda, const VectorXd& x, double weight, bool project, SparseAssembler& H)
    {
        const Mesh& mesh = space.mesh();
        for (const auto& color : H.colors())
            tbb::parallel_for(tbb::blocked_range<size_t>(0, color.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t k = r.begin(); k < r.end(); ++k) {
                    const Index e = color[k];
                    std::array<double, Kernel<dim>::L * Kernel<dim>::L> Ke;
                    kernels::element_hessian<dim>(models[size_t(e)], space.shape_gradients(e),
                        weight * space.rest_volume(e), gather<dim>(mesh, e, x).data(), mu[e], lambda[e], project,
                        Ke.data());
                    H.add_element(e, Ke.data());
                }
            });
    }

} // namespace

void ElasticPotential::add_gradient(const VectorXd& x, double weight, VectorXd& g) const
{
    if (m_space.dim() == 2)
        gradient_impl<2>(m_space, m_models, m_mu, m_lambda, x, weight, g, m_gradient_buffer, m_scatter);
    else
        gradient_impl<3>(m_space, m_models, m_mu, m_lambda, x, weight, g, m_gradient_buffer, m_scatter);
}

void ElasticPotential::add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const
{
    if (m_space.dim() == 2)
        hessian_impl<2>(m_space, m_models, m_mu, m_lambda, x, weight, project_to_psd, H);
    else
        hessian_impl<3>(m_space, m_models, m_mu, m_lambda, x, weight, project_to_psd, H);
}

double ElasticPotential::max_step(const VectorXd& x, const VectorXd& p) const
{
    return inversion_free_step(m_space.mesh(), x, p, 0.1);
}

MatrixXd ElasticPotential::element_stresses(const VectorXd& x) const
{
    const int d = m_space.dim();
    MatrixXd S(m_space.num_elements(), d * d);
    auto store = [&](Index e, const auto& F, const auto& P) {
        (void)F;
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                S(e, i * d + j) = P(i, j);
    };
    if (d == 2)
        m_impl->for_each_stress<2>(m_space, m_models, m_mu, m_lambda, x, store);
    else
        m_impl->for_each_stress<3>(m_space, m_models, m_mu, m_lambda, x, store);
    return S;
}

MatrixXd ElasticPotential::element_cauchy_stresses(const VectorXd& x) const
{
    const int d = m_space.dim();
    MatrixXd S = MatrixXd::Zero(m_space.num_elements(), 9);
    auto store = [&](Index e, const auto& F, const auto& P) {
        const auto sigma = cauchy_stress(P, F);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                S(e, i * 3 + j) = sigma(i, j);
    };
    if (d == 2)
        m_impl->for_each_stress<2>(m_space, m_models, m_mu, m_lambda, x, store);
    else
        m_impl->for_each_stress<3>(m_space, m_models, m_mu, m_lambda, x, store);
    return S;
}

namespace {

    template <int dim>
    double element_energy_impl(
        MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda)
    {
        const auto data = element_data<dim>(to_local<dim>(rest));
        return kernels::element_energy<dim>(
            model, data.G.data(), data.volume, to_local<dim>(deformed).data(), mu, lambda);
    }
    template <int dim>
    VectorXd element_gradient_impl(
        MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda)
    {
        const auto data = element_data<dim>(to_local<dim>(rest));
        VectorXd g(Kernel<dim>::L);
        kernels::element_gradient<dim>(
            model, data.G.data(), data.volume, to_local<dim>(deformed).data(), mu, lambda, g.data());
        return g;
    }
    template <int dim>
    MatrixXd element_hessian_impl(
        MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda, bool project)
    {
        const auto data = element_data<dim>(to_local<dim>(rest));
        Eigen::Matrix<double, Kernel<dim>::L, Kernel<dim>::L, Eigen::RowMajor> H;
        kernels::element_hessian<dim>(
            model, data.G.data(), data.volume, to_local<dim>(deformed).data(), mu, lambda, project, H.data());
        return H;
    }

} // namespace

double element_energy(MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda)
{
    return rest.cols() == 2 ? element_energy_impl<2>(model, rest, deformed, mu, lambda)
                            : element_energy_impl<3>(model, rest, deformed, mu, lambda);
}
VectorXd element_gradient(MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda)
{
    return rest.cols() == 2 ? element_gradient_impl<2>(model, rest, deformed, mu, lambda)
                            : element_gradient_impl<3>(model, rest, deformed, mu, lambda);
}
MatrixXd element_hessian(
    MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda, bool project_to_psd)
{
    return rest.cols() == 2 ? element_hessian_impl<2>(model, rest, deformed, mu, lambda, project_to_psd)
                            : element_hessian_impl<3>(model, rest, deformed, mu, lambda, project_to_psd);
}

double ElasticPotential::value_scale(const VectorXd& x) const
{
    double scale = std::abs(value(x));
    for (Index e = 0; e < m_space.num_elements(); ++e)
        if (m_models[size_t(e)] == MaterialModel::NEO_HOOKEAN
            || m_models[size_t(e)] == MaterialModel::STABLE_NEO_HOOKEAN)
            scale += m_space.rest_volume(e) * m_mu[e] * m_space.dim();
    return scale;
}

namespace {

    /// Per element e with L = Lambda_e^T G (the direction's "gradient") and A = dP/dF:
    /// d/dDm [|e| P : L] = |e| [ (P : L) Dm^-T - F^T A[L] Dm^-T - L^T P Dm^-T ],
    /// from dG = -G dDm Dm^-1, dF = -F dDm Dm^-1, d|e| = |e| tr(Dm^-1 dDm).
    /// Dm^-1 is the last dim rows of G; columns of Dm are X_a - X_0 (a = 1..dim).
    template <int dim, typename MaterialOf>
    void shape_impl(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& mu,
        const VectorXd& lambda, const VectorXd& x, const VectorXd& dir, double weight, VectorXd& out,
        std::vector<double>& local, const VertexScatter& scatter, MaterialOf material)
    {
        using Mat = Eigen::Matrix<double, dim, dim>;
        constexpr int LOCAL = Kernel<dim>::L;
        const Mesh& mesh = space.mesh();
        const Index ne = space.num_elements();
        local.resize(size_t(ne) * LOCAL);
        tbb::parallel_for(tbb::blocked_range<Index>(0, ne, GRAIN), [&](const tbb::blocked_range<Index>& r) {
            for (Index e = r.begin(); e < r.end(); ++e) {
                const auto G = shape<dim>(space, e);
                const auto F = Kernel<dim>::deformation(G, gather<dim>(mesh, e, x));
                const Mat L = Kernel<dim>::deformation(G, gather<dim>(mesh, e, dir));
                const Material<dim>& m = material(models[size_t(e)]);
                const Mat P = m.stress(F, mu[e], lambda[e]);
                const typename Kernel<dim>::Tensor A = m.stress_derivative(F, mu[e], lambda[e]);
                Eigen::Matrix<double, dim * dim, 1> l;
                for (int i = 0; i < dim; ++i)
                    for (int j = 0; j < dim; ++j)
                        l[i * dim + j] = L(i, j);
                const Eigen::Matrix<double, dim * dim, 1> al = A * l;
                Mat AL;
                for (int i = 0; i < dim; ++i)
                    for (int j = 0; j < dim; ++j)
                        AL(i, j) = al[i * dim + j];
                const Mat DinvT = G.bottomRows(dim).transpose();
                const double PL = (P.array() * L.array()).sum();
                const Mat Q = weight * space.rest_volume(e)
                    * (PL * DinvT - F.transpose() * AL * DinvT - L.transpose() * P * DinvT);
                // Vertex a >= 1 gets column a - 1 of Q, vertex 0 minus their sum.
                double* le = local.data() + size_t(e) * LOCAL;
                for (int i = 0; i < dim; ++i)
                    le[i] = 0;
                for (int a = 1; a <= dim; ++a)
                    for (int i = 0; i < dim; ++i) {
                        le[a * dim + i] = Q(i, a - 1);
                        le[i] -= Q(i, a - 1);
                    }
            }
        });
        scatter.add(local.data(), dim, 1.0, out);
    }

    template <int dim, typename MaterialOf>
    void lame_impl(const FESpace& space, const std::vector<MaterialModel>& models, const VectorXd& x,
        const VectorXd& dir, double weight, VectorXd& dmu, VectorXd& dlambda, MaterialOf material)
    {
        const Mesh& mesh = space.mesh();
        tbb::parallel_for(
            tbb::blocked_range<Index>(0, space.num_elements(), GRAIN), [&](const tbb::blocked_range<Index>& r) {
                for (Index e = r.begin(); e < r.end(); ++e) {
                    const auto G = shape<dim>(space, e);
                    const auto F = Kernel<dim>::deformation(G, gather<dim>(mesh, e, x));
                    const auto L = Kernel<dim>::deformation(G, gather<dim>(mesh, e, dir));
                    const Material<dim>& m = material(models[size_t(e)]);
                    const double c = weight * space.rest_volume(e);
                    dmu[e] += c * (m.stress(F, 1.0, 0.0).array() * L.array()).sum();
                    dlambda[e] += c * (m.stress(F, 0.0, 1.0).array() * L.array()).sum();
                }
            });
    }

} // namespace

void ElasticPotential::add_shape_derivative(
    const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const
{
    if (m_space.dim() == 2)
        shape_impl<2>(m_space, m_models, m_mu, m_lambda, x, direction, weight, d_rest_positions, m_gradient_buffer,
            m_scatter, [this](MaterialModel m) -> const Material<2>& { return m_impl->material<2>(m); });
    else
        shape_impl<3>(m_space, m_models, m_mu, m_lambda, x, direction, weight, d_rest_positions, m_gradient_buffer,
            m_scatter, [this](MaterialModel m) -> const Material<3>& { return m_impl->material<3>(m); });
}

void ElasticPotential::add_lame_derivative(
    const VectorXd& x, const VectorXd& direction, double weight, VectorXd& dmu, VectorXd& dlambda) const
{
    if (m_space.dim() == 2)
        lame_impl<2>(m_space, m_models, x, direction, weight, dmu, dlambda,
            [this](MaterialModel m) -> const Material<2>& { return m_impl->material<2>(m); });
    else
        lame_impl<3>(m_space, m_models, x, direction, weight, dmu, dlambda,
            [this](MaterialModel m) -> const Material<3>& { return m_impl->material<3>(m); });
}

} // namespace diffipc
