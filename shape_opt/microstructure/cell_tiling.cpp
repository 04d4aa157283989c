#include "shape_opt/microstructure/cell_tiling.hpp"

#include "forward/common/error.hpp"
#include "forward/common/union_find.hpp"

#include <algorithm>
#include <cmath>

namespace diffipc {

namespace {

    /// Pairs the vertices on the side where coordinate `axis` is `low` with those where it is
    /// `high`, by their other coordinate: partner[v] for v on the high side (else -1).
    std::vector<Index> side_partners(const Positions& X, int axis, double low, double high, double tolerance)
    {
        std::vector<Index> lo, hi;
        for (Index v = 0; v < X.rows(); ++v) {
            if (std::abs(X(v, axis) - low) <= tolerance)
                lo.push_back(v);
            if (std::abs(X(v, axis) - high) <= tolerance)
                hi.push_back(v);
        }
        const int other = 1 - axis;
        auto along = [&](Index a, Index b) { return X(a, other) < X(b, other); };
        std::sort(lo.begin(), lo.end(), along);
        std::sort(hi.begin(), hi.end(), along);
        const std::string side = axis == 0 ? "left and right" : "bottom and top";
        if (lo.size() != hi.size() || lo.empty())
            throw InputError("cell mesh",
                "not periodic: " + std::to_string(lo.size()) + " and " + std::to_string(hi.size()) + " vertices on its "
                    + side + " sides");
        std::vector<Index> partner(size_t(X.rows()), -1);
        for (size_t k = 0; k < lo.size(); ++k) {
            if (std::abs(X(lo[k], other) - X(hi[k], other)) > tolerance)
                throw InputError("cell mesh",
                    "not periodic: vertex " + std::to_string(hi[k]) + " on the " + side
                        + " sides has no partner on the opposite side");
            partner[size_t(hi[k])] = lo[k];
        }
        return partner;
    }

} // namespace

CellTiling::CellTiling(const Mesh& cell, double width, double height, int nx, int ny)
    : m_nx(nx)
    , m_ny(ny)
    , m_height(height)
    , m_cell_vertices(cell.num_vertices())
{
    if (nx < 1 || ny < 1)
        throw InputError("cells", "expected at least one cell along each axis");
    const Index n = m_cell_vertices;
    const double tolerance = 1e-9 * height;
    const std::vector<Index> right
        = side_partners(cell.rest_positions, 0, -width * height / 2, width * height / 2, tolerance);
    const std::vector<Index> top = side_partners(cell.rest_positions, 1, -height / 2, height / 2, tolerance);
    auto id = [&](Index v, int i, int j) { return (Index(i) * ny + j) * n + v; };
    UnionFind weld(n * nx * ny);
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (Index v = 0; v < n; ++v) {
                if (right[size_t(v)] >= 0 && i + 1 < nx)
                    weld.join(id(v, i, j), id(right[size_t(v)], i + 1, j));
                if (top[size_t(v)] >= 0 && j + 1 < ny)
                    weld.join(id(v, i, j), id(top[size_t(v)], i, j + 1));
            }
    // A class's root is its smallest member: the first copy's vertex, numbered in that order.
    std::vector<Index> number(size_t(n * nx * ny), -1);
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (Index v = 0; v < n; ++v) {
                const Index g = id(v, i, j), root = weld.find(g);
                if (root == g) {
                    number[size_t(g)] = Index(m_source.size());
                    m_source.push_back(v);
                    m_copy.emplace_back(i, j);
                }
            }
    m_mesh.dim = 2;
    m_mesh.elements.resize(cell.num_elements() * nx * ny, 3);
    Index e = 0;
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (Index c = 0; c < cell.num_elements(); ++c, ++e)
                for (int a = 0; a < 3; ++a)
                    m_mesh.elements(e, a) = int(number[size_t(weld.find(id(cell.elements(c, a), i, j)))]);
    m_mesh.rest_positions = positions(cell.rest_positions, width);
    m_mesh.vertex_body = VectorXi::Zero(Index(m_source.size()));
    m_mesh.element_body = VectorXi::Zero(m_mesh.elements.rows());
    compute_boundary(m_mesh);
}

Positions CellTiling::positions(const Positions& cell, double width) const
{
    Positions X(Index(m_source.size()), 2);
    for (size_t v = 0; v < m_source.size(); ++v) {
        X(Index(v), 0) = cell(m_source[v], 0) + (m_copy[v].x() + 0.5) * width * m_height;
        X(Index(v), 1) = cell(m_source[v], 1) + (m_copy[v].y() + 0.5) * m_height;
    }
    return X;
}

VectorXd CellTiling::pullback(const VectorXd& dJ_dpad) const
{
    VectorXd g = VectorXd::Zero(2 * m_cell_vertices);
    for (size_t v = 0; v < m_source.size(); ++v)
        g.segment<2>(2 * m_source[v]) += dJ_dpad.segment<2>(2 * Index(v));
    return g;
}

} // namespace diffipc
