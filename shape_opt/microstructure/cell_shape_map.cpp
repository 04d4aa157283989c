#include "shape_opt/microstructure/cell_shape_map.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/microstructure/cell_mesher.hpp"
#include "shape_opt/parametrization/boundary_extension.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace diffipc {

CellShapeMap::CellShapeMap(const CellFamily& family, const VectorXd& p, const Mesh& mesh, double height)
    : m_family(family)
    , m_p(p)
    , m_mesh(mesh)
    , m_height(height)
{
    family.check(p, "design");
    const double width = p[family.width_index()];
    m_scale = Eigen::Vector2d(0.5 * width * height, 0.5 * height);
    const Eigen::Vector2d lo = cell_box_min(width, height), hi = cell_box_max(width, height);
    const double tol = 1e-9 * height;
    const Index nv = mesh.rest_positions.rows();
    m_kind.assign(size_t(nv), 0);
    auto on_side = [&](Index v, int axis) {
        const double x = mesh.rest_positions(v, axis);
        return std::abs(x - lo[axis]) < tol || std::abs(x - hi[axis]) < tol;
    };
    std::set<std::pair<Index, Index>> boundary_edges;
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        const Index a = mesh.boundary_facets(f, 0), b = mesh.boundary_facets(f, 1);
        boundary_edges.emplace(std::min(a, b), std::max(a, b));
        for (Index v : { a, b })
            if (m_kind[size_t(v)] == 0)
                m_kind[size_t(v)] = on_side(v, 0) && on_side(v, 1) ? 3 : on_side(v, 0) || on_side(v, 1) ? 4 : 1;
    }
    std::vector<Index> slot(size_t(nv), -1);
    for (Index v = 0; v < nv; ++v)
        if (m_kind[size_t(v)] != 0) {
            slot[size_t(v)] = Index(m_boundary.size());
            m_boundary.push_back(v);
        }
    // Each side's runs of boundary edges: their ends are crossings (or corners), the vertices
    // between follow them.
    for (int axis = 0; axis < 2; ++axis)
        for (double at : { lo[axis], hi[axis] }) {
            const int along = 1 - axis;
            std::vector<Index> side;
            for (Index v : m_boundary)
                if (std::abs(mesh.rest_positions(v, axis) - at) < tol)
                    side.push_back(v);
            std::sort(side.begin(), side.end(),
                [&](Index a, Index b) { return mesh.rest_positions(a, along) < mesh.rest_positions(b, along); });
            size_t first = 0;
            while (first < side.size()) {
                size_t last = first;
                while (last + 1 < side.size()
                    && boundary_edges.count(
                        { std::min(side[last], side[last + 1]), std::max(side[last], side[last + 1]) }))
                    ++last;
                for (size_t end : { first, last })
                    if (m_kind[size_t(side[end])] == 4)
                        m_kind[size_t(side[end])] = 2;
                const double s0 = mesh.rest_positions(side[first], along), s1 = mesh.rest_positions(side[last], along);
                for (size_t k = first + 1; k < last; ++k)
                    if (m_kind[size_t(side[k])] == 4)
                        m_between.push_back({ slot[size_t(side[k])], slot[size_t(side[first])],
                            slot[size_t(side[last])], (mesh.rest_positions(side[k], along) - s0) / (s1 - s0) });
                first = last + 1;
            }
        }
    // Directions: the normal inside the box, the side's tangent at a crossing.
    const CellSDF sdf(family.graph(), family.cell_parameters(p));
    m_direction.assign(m_boundary.size(), Eigen::Vector2d::Zero());
    for (size_t s = 0; s < m_boundary.size(); ++s) {
        const Index v = m_boundary[s];
        const Eigen::Vector2d X = mesh.rest_positions.row(v).transpose();
        if (m_kind[size_t(v)] == 1) {
            Eigen::Vector2d g;
            psi(sdf, X, &g);
            m_direction[s] = g.normalized();
        } else if (m_kind[size_t(v)] == 2)
            m_direction[s] = on_side(v, 0) ? Eigen::Vector2d(0, 1) : Eigen::Vector2d(1, 0);
    }
    m_extension = std::make_unique<BoundaryExtension>(mesh, m_boundary, std::vector<int> { 0, 1 }, "cell mesh");

    // The velocity, per variable.
    const Index n = family.size(), nb = Index(m_boundary.size());
    m_velocity = MatrixXd::Zero(2 * nv, n);
    MatrixXd dpsi(nb, n); // d psi / d p at the boundary vertices (fixed X)
    std::vector<double> normal_slope(size_t(nb), 0.0); // grad psi . direction
    for (Index s = 0; s < nb; ++s) {
        if (m_direction[size_t(s)].isZero())
            continue;
        const Eigen::Vector2d X = mesh.rest_positions.row(m_boundary[size_t(s)]).transpose();
        Eigen::Vector2d g;
        psi(sdf, X, &g);
        normal_slope[size_t(s)] = g.dot(m_direction[size_t(s)]);
        dpsi.row(s) = (sdf.parameter_gradient(X.cwiseQuotient(m_scale)).transpose() * family.jacobian());
    }
    const VectorXd rest = flatten(mesh.rest_positions);
    for (Index j = 0; j < n; ++j) {
        if (j == family.width_index()) {
            for (Index v = 0; v < nv; ++v)
                m_velocity(2 * v, j) = mesh.rest_positions(v, 0) / width;
            continue;
        }
        VectorXd vb = VectorXd::Zero(2 * nb);
        for (Index s = 0; s < nb; ++s)
            if (normal_slope[size_t(s)] != 0)
                vb.segment<2>(2 * s) = -dpsi(s, j) / normal_slope[size_t(s)] * m_direction[size_t(s)];
        for (const Between& b : m_between)
            vb.segment<2>(2 * b.slot) = (1 - b.weight) * vb.segment<2>(2 * b.a) + b.weight * vb.segment<2>(2 * b.b);
        m_velocity.col(j) = m_extension->apply(vb) - rest;
    }
}

CellShapeMap::~CellShapeMap() = default;

double CellShapeMap::psi(const CellSDF& sdf, const Eigen::Vector2d& X, Eigen::Vector2d* grad) const
{
    const Eigen::Vector2d y = X.cwiseQuotient(m_scale);
    if (grad)
        *grad = sdf.gradient(y).cwiseQuotient(m_scale);
    return sdf.value(y);
}

MatrixXd CellShapeMap::boundary_displacement(const VectorXd& q, MatrixXd* jacobian) const
{
    const CellSDF sdf(m_family.graph(), m_family.cell_parameters(q));
    const Index nb = Index(m_boundary.size());
    MatrixXd d = MatrixXd::Zero(nb, 2);
    if (jacobian)
        jacobian->setZero(2 * nb, m_family.size());
    for (Index s = 0; s < nb; ++s) {
        const Eigen::Vector2d n = m_direction[size_t(s)];
        if (n.isZero())
            continue;
        const Eigen::Vector2d X = m_mesh.rest_positions.row(m_boundary[size_t(s)]).transpose();
        double t = 0;
        bool converged = false;
        for (int it = 0; it < 30 && !converged; ++it) {
            Eigen::Vector2d g;
            const double f = psi(sdf, X + t * n, &g);
            const double slope = g.dot(n);
            if (!(std::abs(slope) > 1e-12) || !std::isfinite(f))
                break;
            const double dt = f / slope;
            t -= dt;
            converged = std::abs(dt) < 1e-14 * m_height;
        }
        if (!converged || std::abs(t) > 0.5 * m_height)
            throw InputError("design",
                "the cell's boundary cannot follow the design from its mesh (vertex "
                    + std::to_string(m_boundary[size_t(s)]) + " finds no level set along its normal): remesh");
        d.row(s) = t * n.transpose();
        if (jacobian) {
            Eigen::Vector2d g;
            const Eigen::Vector2d at = X + t * n;
            psi(sdf, at, &g);
            const VectorXd dpsi = m_family.jacobian().transpose() * sdf.parameter_gradient(at.cwiseQuotient(m_scale));
            for (int a = 0; a < 2; ++a)
                jacobian->row(2 * s + a) = -n[a] / g.dot(n) * dpsi.transpose();
        }
    }
    for (const Between& b : m_between) {
        d.row(b.slot) = (1 - b.weight) * d.row(b.a) + b.weight * d.row(b.b);
        if (jacobian)
            for (int a = 0; a < 2; ++a)
                jacobian->row(2 * b.slot + a)
                    = (1 - b.weight) * jacobian->row(2 * b.a + a) + b.weight * jacobian->row(2 * b.b + a);
    }
    return d;
}

Positions CellShapeMap::moved(const VectorXd& q) const
{
    m_family.check(q, "design");
    const MatrixXd d = boundary_displacement(q);
    VectorXd flat(d.size());
    for (Index s = 0; s < d.rows(); ++s)
        flat.segment<2>(2 * s) = d.row(s).transpose();
    const VectorXd x = m_extension->apply(flat);
    const Index nv = m_mesh.rest_positions.rows();
    Positions X(nv, 2);
    const double stretch = q[m_family.width_index()] / m_p[m_family.width_index()];
    for (Index v = 0; v < nv; ++v)
        X.row(v) << stretch * x[2 * v], x[2 * v + 1];
    return X;
}

MatrixXd CellShapeMap::moved_jacobian(const VectorXd& q) const
{
    m_family.check(q, "design");
    MatrixXd db;
    const MatrixXd d = boundary_displacement(q, &db);
    const Index nb = d.rows(), nv = m_mesh.rest_positions.rows(), w = m_family.width_index();
    const double stretch = q[w] / m_p[w];
    const VectorXd rest = flatten(m_mesh.rest_positions);
    MatrixXd J(2 * nv, m_family.size());
    for (Index j = 0; j < m_family.size(); ++j) {
        if (j == w) { // moved = (stretch x, y) of the extension: d/dq_w = (x / p_w, 0)
            VectorXd flat(2 * nb);
            for (Index s = 0; s < nb; ++s)
                flat.segment<2>(2 * s) = d.row(s).transpose();
            const VectorXd x = m_extension->apply(flat);
            J.col(j).setZero();
            for (Index v = 0; v < nv; ++v)
                J(2 * v, j) = x[2 * v] / m_p[w];
            continue;
        }
        J.col(j) = m_extension->apply(db.col(j)) - rest;
        for (Index v = 0; v < nv; ++v)
            J(2 * v, j) *= stretch;
    }
    return J;
}

} // namespace diffipc
