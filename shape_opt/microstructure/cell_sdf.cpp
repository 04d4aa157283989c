#include "shape_opt/microstructure/cell_sdf.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace diffipc {

VectorXd CellParameters::flatten() const
{
    const Index n = offsets.rows(), m = thickness.size();
    VectorXd p(2 * n + m + 1);
    for (Index i = 0; i < n; ++i)
        p.segment<2>(2 * i) = offsets.row(i).transpose();
    p.segment(2 * n, m) = thickness;
    p[2 * n + m] = blend;
    return p;
}

CellParameters CellParameters::unflatten(const VectorXd& p, Index n, Index m)
{
    if (p.size() != 2 * n + m + 1)
        throw std::invalid_argument("CellParameters::unflatten: expected 2 #N + #M + 1 values");
    CellParameters c;
    c.offsets.resize(n, 2);
    for (Index i = 0; i < n; ++i)
        c.offsets.row(i) = p.segment<2>(2 * i).transpose();
    c.thickness = p.segment(2 * n, m);
    c.blend = p[2 * n + m];
    return c;
}

CellSDF::CellSDF(WireGraph graph, CellParameters parameters)
    : m_graph(std::move(graph))
    , m_p(std::move(parameters))
{
    if (m_p.offsets.rows() != m_graph.nodes.rows() || m_p.offsets.cols() != 2
        || m_p.thickness.size() != m_graph.edges.rows())
        throw std::invalid_argument("CellSDF: parameters do not fit the graph (#N by 2 offsets, #M thicknesses)");
    if (!(m_p.blend > 0))
        throw std::invalid_argument("CellSDF: the blending radius must be positive");
}

double CellSDF::value(const Eigen::Vector2d& x) const { return evaluate(x, nullptr, nullptr); }

Eigen::Vector2d CellSDF::gradient(const Eigen::Vector2d& x) const
{
    Eigen::Vector2d g;
    evaluate(x, &g, nullptr);
    return g;
}

VectorXd CellSDF::parameter_gradient(const Eigen::Vector2d& x) const
{
    VectorXd g;
    evaluate(x, nullptr, &g);
    return g;
}

double CellSDF::evaluate(const Eigen::Vector2d& x_any, Eigen::Vector2d* dx, VectorXd* dp) const
{
    // Into the cell first (a translation by whole periods): the 3 x 3 window is then the same for
    // every copy of a point, and phi exactly periodic.
    const Eigen::Vector2d x = x_any - 2.0 * (x_any / 2.0).array().round().matrix();
    const Index n = m_graph.nodes.rows(), m = m_graph.edges.rows();
    const double k = m_p.blend;
    // One term per edge and shift: its distance d, the nearest point's parameter t and the unit
    // direction from the nearest point to y (zero on the axis, where d is not differentiable).
    struct Term {
        Index edge;
        double d, t;
        Eigen::Vector2d normal;
    };
    std::vector<Term> terms;
    terms.reserve(size_t(9 * m));
    double d_min = std::numeric_limits<double>::infinity();
    for (Index e = 0; e < m; ++e) {
        const int ia = m_graph.edges(e, 0), ib = m_graph.edges(e, 1);
        const Eigen::Vector2d a = m_graph.nodes.row(ia).transpose() + m_p.offsets.row(ia).transpose();
        const Eigen::Vector2d b = m_graph.nodes.row(ib).transpose() + m_p.offsets.row(ib).transpose();
        const Eigen::Vector2d ab = b - a;
        for (int sx = -1; sx <= 1; ++sx)
            for (int sy = -1; sy <= 1; ++sy) {
                const Eigen::Vector2d y = x - 2.0 * Eigen::Vector2d(sx, sy);
                const double t = std::clamp((y - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
                const Eigen::Vector2d r = y - (a + t * ab);
                const double length = r.norm();
                Term term { e, length - 0.5 * m_p.thickness[e], t, Eigen::Vector2d::Zero() };
                if (length > 0)
                    term.normal = r / length;
                d_min = std::min(d_min, term.d);
                terms.push_back(term);
            }
    }
    // phi = d_min - k log sum exp(-(d - d_min) / k): no overflow, the weights are the softmax.
    double sum = 0;
    for (const Term& term : terms)
        sum += std::exp(-(term.d - d_min) / k);
    const double phi = d_min - k * std::log(sum);
    if (!dx && !dp)
        return phi;
    if (dx)
        dx->setZero();
    if (dp)
        dp->setZero(2 * n + m + 1);
    double weighted_d = 0;
    for (const Term& term : terms) {
        const double w = std::exp(-(term.d - d_min) / k) / sum; // d phi / d d_e
        weighted_d += w * term.d;
        if (dx)
            *dx += w * term.normal;
        if (dp) {
            const int ia = m_graph.edges(term.edge, 0), ib = m_graph.edges(term.edge, 1);
            // d |y - c| / d(a, b) = -normal (1 - t), -normal t (the nearest point's own motion
            // along the segment does not change the distance to first order).
            dp->segment<2>(2 * ia) -= w * (1 - term.t) * term.normal;
            dp->segment<2>(2 * ib) -= w * term.t * term.normal;
            (*dp)[2 * n + term.edge] -= 0.5 * w;
        }
    }
    if (dp) // d phi / d k = -log sum exp(-d/k) - sum_i w_i d_i / k = (phi - sum_i w_i d_i) / k
        (*dp)[2 * n + m] = (phi - weighted_d) / k;
    return phi;
}

} // namespace diffipc
