#include "forward/periodic/pairing.hpp"

#include "forward/common/error.hpp"
#include "forward/common/union_find.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <unordered_map>
#include <vector>

namespace diffipc {

namespace {

    std::string position_of(const Mesh& mesh, Index v)
    {
        std::string s = "(";
        for (int a = 0; a < mesh.dim; ++a)
            s += (a ? ", " : "") + format_number(mesh.rest_positions(v, a));
        return s + ")";
    }

    const char* axis_name(int a) { return a == 0 ? "x" : a == 1 ? "y" : "z"; }

    /// The vertices on the lower face of axis a, hashed by their other coordinates on a grid of
    /// cells of twice the tolerance: a partner within the tolerance lies in a neighbouring cell.
    class FaceIndex {
    public:
        FaceIndex(const Mesh& mesh, int axis, double cell)
            : m_mesh(mesh)
            , m_axis(axis)
            , m_cell(cell)
        {
        }
        void add(Index v) { m_cells[key(cell_of(v))].push_back(v); }
        /// The nearest vertex of the index within `tolerance` of v in the other coordinates, or -1.
        Index partner(Index v, double tolerance) const
        {
            const std::array<long long, 2> c = cell_of(v);
            const long long span = m_mesh.dim == 3 ? 1 : 0; // a 2D face is a line
            Index best = -1;
            double best_distance = tolerance;
            for (long long i = -1; i <= 1; ++i)
                for (long long j = -span; j <= span; ++j) {
                    const auto it = m_cells.find(key({ c[0] + i, c[1] + j }));
                    if (it == m_cells.end())
                        continue;
                    for (Index u : it->second) {
                        double distance = 0;
                        for (int b = 0; b < m_mesh.dim; ++b)
                            if (b != m_axis)
                                distance = std::max(
                                    distance, std::abs(m_mesh.rest_positions(u, b) - m_mesh.rest_positions(v, b)));
                        if (distance <= best_distance) {
                            best_distance = distance;
                            best = u;
                        }
                    }
                }
            return best;
        }

    private:
        std::array<long long, 2> cell_of(Index v) const
        {
            std::array<long long, 2> c { 0, 0 };
            int n = 0;
            for (int b = 0; b < m_mesh.dim; ++b)
                if (b != m_axis)
                    c[size_t(n++)] = (long long)std::floor(m_mesh.rest_positions(v, b) / m_cell);
            return c;
        }
        static long long key(const std::array<long long, 2>& c) { return c[0] * 73856093LL ^ c[1] * 19349663LL; }
        const Mesh& m_mesh;
        int m_axis;
        double m_cell;
        std::unordered_map<long long, std::vector<Index>> m_cells;
    };

} // namespace

PeriodicPairing pair_periodic_vertices(
    const Mesh& mesh, const PeriodicBox& box, double tolerance, const std::string& field)
{
    const int d = mesh.dim;
    const Index n = mesh.num_vertices();
    if (box.lower.size() != d || box.upper.size() != d)
        throw InputError("periodic.box", "expected " + std::to_string(d) + " coordinates for each corner");
    if (!(tolerance > 0))
        throw std::invalid_argument("pair_periodic_vertices: the tolerance must be positive");
    bool any = false;
    for (int a = 0; a < d; ++a) {
        if (!(box.length(a) > 0) || !std::isfinite(box.length(a)))
            throw InputError(
                "periodic.box", std::string("its ") + axis_name(a) + " extent must be positive and finite");
        any = any || box.periodic[size_t(a)];
    }
    if (!any)
        throw InputError("periodic.axes", "no axis is periodic");
    if (n == 0)
        throw InputError(field, "the mesh has no vertices");
    // The box must fit the mesh: spanned exactly along periodic axes, contained along the others.
    for (int a = 0; a < d; ++a) {
        const double lo = mesh.rest_positions.col(a).minCoeff(), hi = mesh.rest_positions.col(a).maxCoeff();
        if (box.periodic[size_t(a)]) {
            if (std::abs(lo - box.lower[a]) > tolerance || std::abs(hi - box.upper[a]) > tolerance)
                throw InputError("periodic.box",
                    std::string("along the periodic axis ") + axis_name(a) + " the box spans ["
                        + format_number(box.lower[a]) + ", " + format_number(box.upper[a]) + "] m but the mesh spans ["
                        + format_number(lo) + ", " + format_number(hi) + "] m (tolerance " + format_number(tolerance)
                        + " m)");
        } else if (lo < box.lower[a] - tolerance || hi > box.upper[a] + tolerance) {
            throw InputError("periodic.box",
                std::string("the mesh spans [") + format_number(lo) + ", " + format_number(hi) + "] m along "
                    + axis_name(a) + ", outside the box's [" + format_number(box.lower[a]) + ", "
                    + format_number(box.upper[a]) + "] m");
        }
    }
    UnionFind classes(n);
    for (int a = 0; a < d; ++a) {
        if (!box.periodic[size_t(a)])
            continue;
        FaceIndex lower(mesh, a, 2 * tolerance), upper(mesh, a, 2 * tolerance);
        std::vector<Index> on_lower, on_upper;
        for (Index v = 0; v < n; ++v) {
            if (std::abs(mesh.rest_positions(v, a) - box.lower[a]) <= tolerance) {
                lower.add(v);
                on_lower.push_back(v);
            } else if (std::abs(mesh.rest_positions(v, a) - box.upper[a]) <= tolerance) {
                upper.add(v);
                on_upper.push_back(v);
            }
        }
        const auto unmatched = [&](Index v, bool at_upper) {
            return InputError(field,
                "the mesh is not periodic along " + std::string(axis_name(a)) + ": vertex " + std::to_string(v) + " at "
                    + position_of(mesh, v) + " on the face " + axis_name(a) + " = "
                    + format_number(at_upper ? box.upper[a] : box.lower[a]) + " has no partner on the face "
                    + axis_name(a) + " = " + format_number(at_upper ? box.lower[a] : box.upper[a]) + " (tolerance "
                    + format_number(tolerance) + " m)");
        };
        for (Index v : on_upper) {
            const Index u = lower.partner(v, tolerance);
            if (u < 0)
                throw unmatched(v, true);
            classes.join(v, u);
        }
        for (Index u : on_lower)
            if (upper.partner(u, tolerance) < 0)
                throw unmatched(u, false);
    }
    // Classes, their representatives (the vertex nearest the lower corner) and the offsets.
    PeriodicPairing p;
    p.vertex_class = VectorXi::Constant(n, -1);
    std::vector<Index> root_class(size_t(n), -1), reps;
    for (Index v = 0; v < n; ++v) {
        const Index r = classes.find(v);
        if (root_class[size_t(r)] < 0) {
            root_class[size_t(r)] = Index(reps.size());
            reps.push_back(v);
        }
        const Index c = root_class[size_t(r)];
        p.vertex_class[v] = int(c);
        double here = 0, there = 0;
        for (int a = 0; a < d; ++a)
            if (box.periodic[size_t(a)]) {
                here += (mesh.rest_positions(v, a) - box.lower[a]) / box.length(a);
                there += (mesh.rest_positions(reps[size_t(c)], a) - box.lower[a]) / box.length(a);
            }
        if (here < there)
            reps[size_t(c)] = v;
    }
    p.representative.resize(Index(reps.size()));
    for (size_t c = 0; c < reps.size(); ++c)
        p.representative[Index(c)] = int(reps[c]);
    p.offset = MatrixXi::Zero(n, d);
    std::vector<std::vector<Index>> members(reps.size());
    for (Index v = 0; v < n; ++v) {
        const Index r = p.representative[p.vertex_class[v]];
        for (int a = 0; a < d; ++a) {
            if (!box.periodic[size_t(a)])
                continue;
            const double shift = (mesh.rest_positions(v, a) - mesh.rest_positions(r, a)) / box.length(a);
            p.offset(v, a) = int(std::lround(shift));
            if (std::abs(shift - p.offset(v, a)) * box.length(a) > d * tolerance)
                throw InputError(field,
                    "vertex " + std::to_string(v) + " at " + position_of(mesh, v) + " is paired with vertex "
                        + std::to_string(r) + " at " + position_of(mesh, r) + ", which is not a translate by the box");
        }
        members[size_t(p.vertex_class[v])].push_back(v);
    }
    // Two vertices of a class at the same offset are duplicates: the pairing would be ambiguous.
    for (const std::vector<Index>& m : members)
        for (size_t i = 0; i < m.size(); ++i)
            for (size_t j = i + 1; j < m.size(); ++j)
                if (p.offset.row(m[i]) == p.offset.row(m[j]))
                    throw InputError(field,
                        "vertices " + std::to_string(m[i]) + " and " + std::to_string(m[j]) + " at "
                            + position_of(mesh, m[i]) + " coincide (duplicate vertices on a periodic face)");
    return p;
}

void remove_periodic_facets(Mesh& mesh, const PeriodicBox& box, double tolerance)
{
    const int d = mesh.dim;
    std::vector<Index> keep;
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        bool on_face = false;
        for (int a = 0; a < d && !on_face; ++a) {
            if (!box.periodic[size_t(a)])
                continue;
            for (const double face : { box.lower[a], box.upper[a] }) {
                bool all = true;
                for (int i = 0; i < d; ++i)
                    all = all && std::abs(mesh.rest_positions(mesh.boundary_facets(f, i), a) - face) <= tolerance;
                on_face = on_face || all;
            }
        }
        if (!on_face)
            keep.push_back(f);
    }
    MatrixXi facets(Index(keep.size()), d);
    VectorXi body(Index(keep.size()));
    for (size_t i = 0; i < keep.size(); ++i) {
        facets.row(Index(i)) = mesh.boundary_facets.row(keep[i]);
        body[Index(i)] = mesh.facet_body[keep[i]];
    }
    mesh.boundary_facets = std::move(facets);
    mesh.facet_body = std::move(body);
}

} // namespace diffipc
