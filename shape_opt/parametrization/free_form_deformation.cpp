#include "shape_opt/parametrization/free_form_deformation.hpp"

#include "forward/common/error.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <stdexcept>

namespace diffipc {

namespace {
    /// B_i^n(s) = C(n, i) s^i (1 - s)^(n - i).
    double bernstein(int n, int i, double s)
    {
        double binomial = 1;
        for (int k = 1; k <= i; ++k)
            binomial = binomial * (n - i + k) / k;
        return binomial * std::pow(s, i) * std::pow(1 - s, n - i);
    }
} // namespace

FreeFormDeformation::FreeFormDeformation(const Positions& rest, const FfdLattice& lattice, const std::string& field)
    : m_lattice(lattice)
    , m_dim(int(rest.cols()))
    , m_rest(flatten(rest))
{
    const int d = m_dim;
    if (lattice.lower.size() != d || lattice.upper.size() != d || lattice.degree.size() != d)
        throw InputError(field, "the box and the degrees need " + std::to_string(d) + " values each");
    for (int a = 0; a < d; ++a) {
        if (!(lattice.upper[a] > lattice.lower[a]) || !std::isfinite(lattice.upper[a] - lattice.lower[a]))
            throw InputError(field, "the box's \"max\" must exceed its \"min\" in every component");
        if (lattice.degree[a] < 1 || lattice.degree[a] > 20)
            throw InputError(field, "degrees must lie in [1, 20], got " + std::to_string(lattice.degree[a]));
    }
    std::vector<char> used(size_t(d), 0);
    if (lattice.axes.empty())
        throw InputError(field, "give at least one active axis");
    for (int a : lattice.axes) {
        if (a < 0 || a >= d || used[size_t(a)])
            throw InputError(field, "axes must be distinct, each in [0, " + std::to_string(d) + ")");
        used[size_t(a)] = 1;
    }
    // Control points in lattice order (axis 0 fastest); without those on fixed faces.
    std::vector<char> fixed(static_cast<size_t>(d), lattice.fixed_border ? 1 : 0);
    for (int a : lattice.fixed_border_axes) {
        if (a < 0 || a >= d)
            throw InputError(field, "fixed_border axes must lie in [0, " + std::to_string(d) + ")");
        fixed[size_t(a)] = 1;
    }
    Index count = 1;
    for (int a = 0; a < d; ++a)
        count *= lattice.degree[a] + 1;
    m_lattice_points = count;
    std::vector<Index> slot(size_t(count), -1);
    for (Index c = 0; c < count; ++c) {
        bool border = false;
        Index rest_index = c;
        for (int a = 0; a < d; ++a) {
            const Index i = rest_index % (lattice.degree[a] + 1);
            rest_index /= lattice.degree[a] + 1;
            border = border || (fixed[size_t(a)] && (i == 0 || i == lattice.degree[a]));
        }
        if (!border) {
            slot[size_t(c)] = Index(m_points.size());
            m_points.push_back(c);
        }
    }
    if (m_points.empty())
        throw InputError(
            field, "a fixed border leaves no control point: raise a degree to 2 or more along the fixed axes");

    const Index axes = Index(lattice.axes.size());
    // With "mesh_at" the given mesh is the shape at those displacements: the basis is
    // evaluated at the positions the lattice moves onto it (remesh.hpp).
    Positions at = rest;
    if (lattice.mesh_at.size() > 0) {
        if (lattice.mesh_at.size() != Index(m_points.size()) * axes)
            throw InputError(field + ".mesh_at",
                "expected " + std::to_string(Index(m_points.size()) * axes) + " values (one per variable), got "
                    + std::to_string(lattice.mesh_at.size()));
        if (!lattice.mesh_at.allFinite())
            throw InputError(field + ".mesh_at", "non-finite value");
        try {
            at = pull_back(rest, lattice.mesh_at);
        } catch (const std::runtime_error& e) {
            throw InputError(field + ".mesh_at", e.what());
        }
        m_rest = flatten(at);
    }
    std::vector<Eigen::Triplet<double, int>> triplets;
    std::vector<std::vector<double>> basis(static_cast<size_t>(d));
    for (Index v = 0; v < at.rows(); ++v) {
        bool inside = true;
        for (int a = 0; a < d; ++a) {
            const double s = (at(v, a) - lattice.lower[a]) / (lattice.upper[a] - lattice.lower[a]);
            inside = inside && s >= 0 && s <= 1;
            basis[size_t(a)].assign(size_t(lattice.degree[a] + 1), 0.0);
            for (int i = 0; i <= lattice.degree[a]; ++i)
                basis[size_t(a)][size_t(i)] = bernstein(lattice.degree[a], i, s);
        }
        if (!inside)
            continue;
        for (Index c = 0; c < count; ++c) {
            if (slot[size_t(c)] < 0)
                continue;
            double weight = 1;
            Index rest_index = c;
            for (int a = 0; a < d; ++a) {
                const Index i = rest_index % (lattice.degree[a] + 1);
                rest_index /= lattice.degree[a] + 1;
                weight *= basis[size_t(a)][size_t(i)];
            }
            if (weight == 0)
                continue;
            for (Index k = 0; k < axes; ++k)
                triplets.emplace_back(int(v * d + lattice.axes[size_t(k)]), int(slot[size_t(c)] * axes + k), weight);
        }
    }
    m_basis.resize(m_rest.size(), Index(m_points.size()) * axes);
    m_basis.setFromTriplets(triplets.begin(), triplets.end());
}

VectorXd FreeFormDeformation::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", name());
    return m_rest + m_basis * x;
}

VectorXd FreeFormDeformation::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", name());
    check_size(y_bar, out_size(), "design", name() + "'s gradient");
    return m_basis.transpose() * y_bar;
}

VectorXd FreeFormDeformation::control_point(Index c) const
{
    VectorXd p(m_dim);
    Index rest_index = m_points.at(size_t(c));
    for (int a = 0; a < m_dim; ++a) {
        const Index i = rest_index % (m_lattice.degree[a] + 1);
        rest_index /= m_lattice.degree[a] + 1;
        p[a] = m_lattice.lower[a] + (m_lattice.upper[a] - m_lattice.lower[a]) * double(i) / m_lattice.degree[a];
    }
    return p;
}

void FreeFormDeformation::displacement(const VectorXd& X, const MatrixXd& control, VectorXd& u, MatrixXd& du) const
{
    const int d = m_dim;
    u.setZero(d);
    du.setZero(d, d);
    VectorXd s(d);
    for (int a = 0; a < d; ++a) {
        s[a] = (X[a] - m_lattice.lower[a]) / (m_lattice.upper[a] - m_lattice.lower[a]);
        if (!(s[a] >= 0 && s[a] <= 1))
            return; // outside the box nothing moves
    }
    // Per axis the Bernstein values and their derivatives in X_a:
    // dB_i^n/ds = n (B_{i-1}^{n-1} - B_i^{n-1}).
    std::vector<std::vector<double>> value(static_cast<size_t>(d)), slope(static_cast<size_t>(d));
    for (int a = 0; a < d; ++a) {
        const int n = m_lattice.degree[a];
        const double to_s = 1.0 / (m_lattice.upper[a] - m_lattice.lower[a]);
        for (int i = 0; i <= n; ++i) {
            value[size_t(a)].push_back(bernstein(n, i, s[a]));
            const double lower = i > 0 ? bernstein(n - 1, i - 1, s[a]) : 0.0;
            const double upper = i < n ? bernstein(n - 1, i, s[a]) : 0.0;
            slope[size_t(a)].push_back(n * (lower - upper) * to_s);
        }
    }
    std::vector<Index> index(static_cast<size_t>(d));
    for (Index c = 0; c < m_lattice_points; ++c) {
        if (control.col(c).isZero(0))
            continue;
        Index rest_index = c;
        for (int a = 0; a < d; ++a) {
            index[size_t(a)] = rest_index % (m_lattice.degree[a] + 1);
            rest_index /= m_lattice.degree[a] + 1;
        }
        double weight = 1;
        for (int a = 0; a < d; ++a)
            weight *= value[size_t(a)][size_t(index[size_t(a)])];
        u += weight * control.col(c);
        for (int b = 0; b < d; ++b) {
            double w = slope[size_t(b)][size_t(index[size_t(b)])];
            for (int a = 0; a < d; ++a)
                if (a != b)
                    w *= value[size_t(a)][size_t(index[size_t(a)])];
            du.col(b) += w * control.col(c);
        }
    }
}

Positions FreeFormDeformation::pull_back(const Positions& current, const VectorXd& x) const
{
    check_size(x, Index(m_points.size()) * Index(m_lattice.axes.size()), "design", name());
    if (current.cols() != m_dim)
        throw std::runtime_error("ffd pull-back: expected " + std::to_string(m_dim) + " coordinates per vertex");
    // Every lattice point's displacement (the fixed ones zero).
    const Index axes = Index(m_lattice.axes.size());
    MatrixXd control = MatrixXd::Zero(m_dim, m_lattice_points);
    for (size_t k = 0; k < m_points.size(); ++k)
        for (Index j = 0; j < axes; ++j)
            control(m_lattice.axes[size_t(j)], m_points[k]) = x[Index(k) * axes + j];
    // Relative to the lattice's size, and above the rounding of coordinates far from the origin.
    const double reach = std::max({ m_lattice.lower.lpNorm<Eigen::Infinity>(),
        m_lattice.upper.lpNorm<Eigen::Infinity>(), current.lpNorm<Eigen::Infinity>() });
    const double tolerance = 1e-13 * (m_lattice.upper - m_lattice.lower).norm() + 16 * DBL_EPSILON * reach;
    const auto clamp
        = [&](const VectorXd& X) { return VectorXd(X.cwiseMax(m_lattice.lower).cwiseMin(m_lattice.upper)); };
    // Newton's method from X, kept inside the box when `inside` (damped where a step does not
    // reduce the residual); returns whether it converged.
    const auto solve = [&](const VectorXd& y, VectorXd& X, bool inside) {
        VectorXd u, ut;
        MatrixXd du, dut;
        for (int it = 0; it < 100; ++it) {
            displacement(X, control, u, du);
            const VectorXd r = X + u - y;
            if (r.norm() <= tolerance)
                return true;
            const VectorXd step = (MatrixXd::Identity(m_dim, m_dim) + du).fullPivLu().solve(r);
            if (!step.allFinite())
                return false;
            bool moved = false;
            double t = 1;
            for (int h = 0; h < 30 && !moved; ++h, t *= 0.5) {
                VectorXd trial = X - t * step;
                if (inside)
                    trial = clamp(trial);
                displacement(trial, control, ut, dut);
                if ((trial + ut - y).norm() < r.norm()) {
                    X = trial;
                    moved = true;
                }
            }
            if (!moved)
                return false;
        }
        return false;
    };
    Positions rest(current.rows(), m_dim);
    VectorXd X, u;
    MatrixXd du;
    for (Index v = 0; v < current.rows(); ++v) {
        const VectorXd y = current.row(v).transpose();
        // Outside the box nothing moves, so y itself solves X + u(X) = y there; but the box's
        // moving faces can carry a point of the box out to y too. The body lies in the box:
        // look for the preimage inside the box first (from y clamped into it, then from one
        // fixed-point step), and take y itself only if there is none.
        X = clamp(y);
        bool converged = solve(y, X, true);
        if (!converged) {
            displacement(clamp(y), control, u, du);
            X = clamp(y - u);
            converged = solve(y, X, true);
        }
        if (!converged) {
            displacement(y, control, u, du);
            X = y;
            converged = u.isZero(0);
        }
        if (!converged)
            throw std::runtime_error("the free-form deformation cannot be inverted at vertex " + std::to_string(v)
                + ": no point of the lattice's box moves onto it (the design folds the lattice there, or the body "
                  "crosses a face of the box that moves: fix that face with fixed_border)");
        rest.row(v) = X.transpose();
    }
    return rest;
}

} // namespace diffipc
