#include "shape_opt/parametrization/boundary_extension.hpp"

#include "forward/common/error.hpp"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

namespace diffipc {

struct BoundaryExtension::Solver {
    Eigen::SimplicialLDLT<SparseMatrixd> ldlt;
};

BoundaryExtension::~BoundaryExtension() = default;

namespace {
    /// The P1 Laplacian (stiffness of -div grad) of the rest mesh: K_ab = sum_e |e| grad phi_a . grad phi_b.
    SparseMatrixd p1_laplacian(const Mesh& mesh)
    {
        const int d = mesh.dim;
        std::vector<Eigen::Triplet<double, int>> triplets;
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            MatrixXd D(d, d); // edge vectors x_a - x_0 as columns
            for (int a = 0; a < d; ++a)
                D.col(a)
                    = (mesh.rest_positions.row(mesh.elements(e, a + 1)) - mesh.rest_positions.row(mesh.elements(e, 0)))
                          .transpose();
            const double volume = std::abs(D.determinant()) / (d == 2 ? 2.0 : 6.0);
            const MatrixXd Dinv = D.inverse(); // rows: gradients of phi_1 .. phi_d
            MatrixXd G(d + 1, d);
            G.bottomRows(d) = Dinv;
            G.row(0) = -Dinv.colwise().sum();
            const MatrixXd K = volume * G * G.transpose();
            for (int a = 0; a <= d; ++a)
                for (int b = 0; b <= d; ++b)
                    triplets.emplace_back(mesh.elements(e, a), mesh.elements(e, b), K(a, b));
        }
        SparseMatrixd L(mesh.num_vertices(), mesh.num_vertices());
        L.setFromTriplets(triplets.begin(), triplets.end());
        return L;
    }
} // namespace

BoundaryExtension::BoundaryExtension(
    const Mesh& mesh, const std::vector<Index>& vertices, const std::vector<int>& axes, const std::string& field)
    : m_dim(mesh.dim)
    , m_rest(flatten(mesh.rest_positions))
    , m_vertices(vertices)
    , m_axes(axes)
    , m_solver(std::make_unique<Solver>())
{
    const Index nv = mesh.num_vertices();
    std::vector<char> on_boundary(size_t(nv), 0), chosen(size_t(nv), 0);
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f)
        for (Index a = 0; a < mesh.boundary_facets.cols(); ++a)
            on_boundary[size_t(mesh.boundary_facets(f, a))] = 1;
    for (Index v : m_vertices) {
        if (v < 0 || v >= nv)
            throw InputError(
                field, "vertex " + std::to_string(v) + " is not in the mesh (" + std::to_string(nv) + " vertices)");
        if (!on_boundary[size_t(v)])
            throw InputError(field,
                "vertex " + std::to_string(v)
                    + " is not on the boundary (interior vertices follow the boundary's extension)");
        if (chosen[size_t(v)])
            throw InputError(field, "vertex " + std::to_string(v) + " is listed twice");
        chosen[size_t(v)] = 1;
    }
    std::vector<char> axis_used(size_t(m_dim), 0);
    for (int a : m_axes) {
        if (a < 0 || a >= m_dim || axis_used[size_t(a)])
            throw InputError(field, "axes must be distinct, each in [0, " + std::to_string(m_dim) + ")");
        axis_used[size_t(a)] = 1;
    }
    m_interior_slot.assign(size_t(nv), -1);
    for (Index v = 0; v < nv; ++v)
        if (!on_boundary[size_t(v)]) {
            m_interior_slot[size_t(v)] = Index(m_interior.size());
            m_interior.push_back(v);
        }
    const SparseMatrixd L = p1_laplacian(mesh);
    const Index ni = Index(m_interior.size());
    std::vector<Eigen::Triplet<double, int>> ii, ib;
    for (int k = 0; k < L.outerSize(); ++k)
        for (SparseMatrixd::InnerIterator it(L, k); it; ++it) {
            const Index r = m_interior_slot[size_t(it.row())];
            if (r < 0)
                continue;
            const Index c = m_interior_slot[size_t(it.col())];
            if (c >= 0)
                ii.emplace_back(int(r), int(c), it.value());
            else
                ib.emplace_back(int(r), int(it.col()), it.value());
        }
    SparseMatrixd L_II(ni, ni);
    L_II.setFromTriplets(ii.begin(), ii.end());
    m_L_IB.resize(ni, nv);
    m_L_IB.setFromTriplets(ib.begin(), ib.end());
    if (ni > 0) {
        m_solver->ldlt.compute(L_II);
        if (m_solver->ldlt.info() != Eigen::Success)
            throw InputError(field, "the mesh's Laplacian cannot be factored (a body without boundary?)");
    }
}

VectorXd BoundaryExtension::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", name());
    const Index nv = Index(m_interior_slot.size());
    MatrixXd u = MatrixXd::Zero(nv, m_dim);
    for (size_t i = 0; i < m_vertices.size(); ++i)
        for (size_t a = 0; a < m_axes.size(); ++a)
            u(m_vertices[i], m_axes[a]) = x[Index(i * m_axes.size() + a)];
    if (!m_interior.empty()) {
        const MatrixXd interior = m_solver->ldlt.solve(-(m_L_IB * u));
        for (size_t r = 0; r < m_interior.size(); ++r)
            u.row(m_interior[r]) = interior.row(Index(r));
    }
    VectorXd y = m_rest;
    for (Index v = 0; v < nv; ++v)
        for (int a = 0; a < m_dim; ++a)
            y[v * m_dim + a] += u(v, a);
    return y;
}

VectorXd BoundaryExtension::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", name());
    check_size(y_bar, out_size(), "design", name() + "'s gradient");
    // y = X0 + P u_B + Q (-L_II^-1 L_IB u_B): the adjoint of the interior part is
    // -L_IB^T L_II^-1 y_bar_I (L_II symmetric).
    const Index nv = Index(m_interior_slot.size());
    MatrixXd bar = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        y_bar.data(), nv, m_dim);
    if (!m_interior.empty()) {
        MatrixXd interior_bar(Index(m_interior.size()), m_dim);
        for (size_t r = 0; r < m_interior.size(); ++r)
            interior_bar.row(Index(r)) = bar.row(m_interior[r]);
        bar -= m_L_IB.transpose() * MatrixXd(m_solver->ldlt.solve(interior_bar));
    }
    VectorXd x_bar(in_size());
    for (size_t i = 0; i < m_vertices.size(); ++i)
        for (size_t a = 0; a < m_axes.size(); ++a)
            x_bar[Index(i * m_axes.size() + a)] = bar(m_vertices[i], m_axes[a]);
    return x_bar;
}

VectorXd BoundaryExtension::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, out_size(), field, name());
    VectorXd x(in_size());
    for (size_t i = 0; i < m_vertices.size(); ++i)
        for (size_t a = 0; a < m_axes.size(); ++a) {
            const Index k = m_vertices[i] * m_dim + m_axes[a];
            x[Index(i * m_axes.size() + a)] = y[k] - m_rest[k];
        }
    return x;
}

} // namespace diffipc
