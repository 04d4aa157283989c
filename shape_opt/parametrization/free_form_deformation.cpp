#include "shape_opt/parametrization/free_form_deformation.hpp"

#include "forward/common/error.hpp"

#include <cmath>

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
    // Control points in lattice order (axis 0 fastest); with a fixed border only the interior.
    Index count = 1;
    for (int a = 0; a < d; ++a)
        count *= lattice.degree[a] + 1;
    std::vector<Index> slot(size_t(count), -1);
    for (Index c = 0; c < count; ++c) {
        bool border = false;
        Index rest_index = c;
        for (int a = 0; a < d; ++a) {
            const Index i = rest_index % (lattice.degree[a] + 1);
            rest_index /= lattice.degree[a] + 1;
            border = border || i == 0 || i == lattice.degree[a];
        }
        if (!lattice.fixed_border || !border) {
            slot[size_t(c)] = Index(m_points.size());
            m_points.push_back(c);
        }
    }
    if (m_points.empty())
        throw InputError(field, "a fixed border leaves no control point: raise a degree to 2 or more");

    const Index axes = Index(lattice.axes.size());
    std::vector<Eigen::Triplet<double, int>> triplets;
    std::vector<std::vector<double>> basis(static_cast<size_t>(d));
    for (Index v = 0; v < rest.rows(); ++v) {
        bool inside = true;
        for (int a = 0; a < d; ++a) {
            const double s = (rest(v, a) - lattice.lower[a]) / (lattice.upper[a] - lattice.lower[a]);
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

} // namespace diffipc
