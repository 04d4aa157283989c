#include "forward/fem/fe_space.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace diffipc {

FESpace::FESpace(const Mesh& mesh)
    : m_mesh(mesh)
    , m_dim(mesh.dim)
{
    const Index ne = mesh.num_elements();
    const int d = m_dim;
    m_volumes.resize(size_t(ne));
    m_gradients.resize(size_t(ne) * size_t((d + 1) * d));
    for (Index e = 0; e < ne; ++e) {
        Eigen::MatrixXd Dm(d, d);
        for (int a = 0; a < d; ++a)
            Dm.col(a)
                = (mesh.rest_positions.row(mesh.elements(e, a + 1)) - mesh.rest_positions.row(mesh.elements(e, 0)))
                      .transpose();
        const double det = Dm.determinant();
        m_volumes[size_t(e)] = std::abs(det) / (d == 2 ? 2.0 : 6.0);
        const Eigen::MatrixXd Dinv = Dm.inverse();
        double* G = m_gradients.data() + size_t(e) * size_t((d + 1) * d);
        for (int j = 0; j < d; ++j) {
            double sum = 0;
            for (int a = 1; a <= d; ++a) {
                G[a * d + j] = Dinv(a - 1, j);
                sum += Dinv(a - 1, j);
            }
            G[j] = -sum;
        }
    }
}

void FESpace::deformation_gradient(Index e, const VectorXd& x, double* F) const
{
    const int d = m_dim;
    const double* G = shape_gradients(e);
    std::fill_n(F, d * d, 0.0);
    for (int a = 0; a <= d; ++a) {
        const Index v = m_mesh.elements(e, a);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                F[i * d + j] += x[v * d + i] * G[a * d + j];
    }
}

VectorXd FESpace::lumped_masses(const VectorXd& density) const
{
    VectorXd m = VectorXd::Zero(m_mesh.num_vertices());
    for (Index e = 0; e < num_elements(); ++e)
        for (int a = 0; a <= m_dim; ++a)
            m[m_mesh.elements(e, a)] += density[e] * m_volumes[size_t(e)] / (m_dim + 1);
    return m;
}

SparseMatrixd FESpace::consistent_mass(const VectorXd& density) const
{
    std::vector<Eigen::Triplet<double>> triplets;
    const int d = m_dim;
    for (Index e = 0; e < num_elements(); ++e) {
        const double base = density[e] * m_volumes[size_t(e)] / ((d + 1) * (d + 2));
        for (int a = 0; a <= d; ++a)
            for (int b = 0; b <= d; ++b)
                for (int c = 0; c < d; ++c)
                    triplets.emplace_back(
                        m_mesh.elements(e, a) * d + c, m_mesh.elements(e, b) * d + c, base * (a == b ? 2.0 : 1.0));
    }
    SparseMatrixd M(m_mesh.num_dofs(), m_mesh.num_dofs());
    M.setFromTriplets(triplets.begin(), triplets.end());
    return M;
}

double FESpace::min_volume_ratio(const VectorXd& x) const
{
    // In parallel: the minimum does not depend on the order, so the result is the serial loop's for
    // any thread count (a GPU step records it after every solve: at 200k tetrahedra the serial loop
    // was a visible share of the step).
    const Positions P = unflatten(x, m_dim);
    return tbb::parallel_reduce(
        tbb::blocked_range<Index>(0, num_elements(), 4096), std::numeric_limits<double>::infinity(),
        [&](const tbb::blocked_range<Index>& range, double r) {
            for (Index e = range.begin(); e < range.end(); ++e)
                r = std::min(r, signed_volume(P, m_mesh.elements, e) / m_volumes[size_t(e)]);
            return r;
        },
        [](double a, double b) { return std::min(a, b); });
}

Eigen::Vector4d volume_polynomial(const Mesh& mesh, Index e, const VectorXd& x, const VectorXd& p)
{
    const int d = mesh.dim;
    const Index v0 = mesh.elements(e, 0);
    if (d == 2) {
        Eigen::Vector2d u, v, du, dv;
        for (int i = 0; i < 2; ++i) {
            u[i] = x[mesh.elements(e, 1) * 2 + i] - x[v0 * 2 + i];
            v[i] = x[mesh.elements(e, 2) * 2 + i] - x[v0 * 2 + i];
            du[i] = p[mesh.elements(e, 1) * 2 + i] - p[v0 * 2 + i];
            dv[i] = p[mesh.elements(e, 2) * 2 + i] - p[v0 * 2 + i];
        }
        return Eigen::Vector4d(u[0] * v[1] - u[1] * v[0], u[0] * dv[1] + du[0] * v[1] - u[1] * dv[0] - du[1] * v[0],
            du[0] * dv[1] - du[1] * dv[0], 0.0);
    }
    Eigen::Matrix3d A, B;
    for (int a = 0; a < 3; ++a)
        for (int i = 0; i < 3; ++i) {
            A(i, a) = x[mesh.elements(e, a + 1) * 3 + i] - x[v0 * 3 + i];
            B(i, a) = p[mesh.elements(e, a + 1) * 3 + i] - p[v0 * 3 + i];
        }
    auto mixed = [](const Eigen::Matrix3d& P, const Eigen::Matrix3d& Q) {
        // t-coefficient of det(P + t Q): sum over columns of Q_k . (P_{k+1} x P_{k+2})
        return Q.col(0).dot(P.col(1).cross(P.col(2))) + Q.col(1).dot(P.col(2).cross(P.col(0)))
            + Q.col(2).dot(P.col(0).cross(P.col(1)));
    };
    return Eigen::Vector4d(A.determinant(), mixed(A, B), mixed(B, A), B.determinant());
}

namespace {

    double eval_cubic(const Eigen::Vector4d& c, double t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }

    /// First t in (0, 1] where q(t) = c(t) - target <= 0, or 1 if none; returns a t with q(t) > 0.
    double first_crossing(const Eigen::Vector4d& c, double target)
    {
        Eigen::Vector4d q = c;
        q[0] -= target;
        // Critical points of q: roots of q'(t) = q1 + 2 q2 t + 3 q3 t^2 in (0, 1).
        double breaks[4] = { 0, 1, 1, 1 };
        int nb = 1;
        const double a = 3 * q[3], b = 2 * q[2], cc = q[1];
        const double scale = std::abs(a) + std::abs(b) + std::abs(cc);
        if (std::abs(a) > 1e-14 * scale) {
            const double disc = b * b - 4 * a * cc;
            if (disc >= 0) {
                const double s = std::sqrt(disc);
                const double qq = -0.5 * (b + (b >= 0 ? s : -s));
                const double r1 = qq / a, r2 = qq != 0 ? cc / qq : r1;
                for (double r : { std::min(r1, r2), std::max(r1, r2) })
                    if (r > 0 && r < 1)
                        breaks[nb++] = r;
            }
        } else if (std::abs(b) > 1e-14 * scale) {
            const double r = -cc / b;
            if (r > 0 && r < 1)
                breaks[nb++] = r;
        }
        std::sort(breaks + 1, breaks + nb);
        breaks[nb++] = 1.0;
        for (int k = 1; k < nb; ++k) {
            double lo = breaks[k - 1], hi = breaks[k];
            if (eval_cubic(q, hi) > 0)
                continue;
            for (int it = 0; it < 80 && hi - lo > 1e-15; ++it) {
                const double mid = 0.5 * (lo + hi);
                (eval_cubic(q, mid) > 0 ? lo : hi) = mid;
            }
            return lo;
        }
        return 1.0;
    }

} // namespace

double inversion_free_step(const Mesh& mesh, const VectorXd& x, const VectorXd& p, double keep)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<Index>(0, mesh.num_elements(), 1024), 1.0,
        [&](const tbb::blocked_range<Index>& r, double t) {
            for (Index e = r.begin(); e < r.end(); ++e) {
                const Eigen::Vector4d c = volume_polynomial(mesh, e, x, p);
                if (c[0] <= 0)
                    return 0.0; // already not positive: no step is admissible
                if (c[1] >= 0 && c[2] >= 0 && c[3] >= 0)
                    continue; // volume never decreases along the step
                t = std::min(t, first_crossing(c, keep * c[0]));
            }
            return t;
        },
        [](double a, double b) { return std::min(a, b); });
}

} // namespace diffipc
