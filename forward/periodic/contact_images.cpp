#include "forward/periodic/contact_images.hpp"

#include "forward/periodic/tiling.hpp"

#include <array>
#include <map>
#include <stdexcept>
#include <string>

namespace diffipc {

namespace {

    /// A class and a lattice position: one vertex of the infinite tiling.
    using TilingVertex = std::array<int, 4>;

    /// A cell vertex's pair (lo, hi) one lattice step apart along axis a.
    std::array<Index, 2> reference_pair(const PeriodicPairing& pairing, int dim, int axis)
    {
        std::map<TilingVertex, Index> cell;
        for (Index v = 0; v < pairing.vertex_class.size(); ++v) {
            TilingVertex key { pairing.vertex_class[v], 0, 0, 0 };
            for (int a = 0; a < dim; ++a)
                key[size_t(a + 1)] = pairing.offset(v, a);
            cell.emplace(key, v);
        }
        for (const auto& [key, v] : cell) {
            TilingVertex lower = key;
            --lower[size_t(axis + 1)];
            const auto it = cell.find(lower);
            if (it != cell.end())
                return { it->second, v };
        }
        throw std::invalid_argument("build_contact_images: no two vertices of a class lie one box length apart "
                                    "along the periodic axis "
            + std::to_string(axis));
    }

    bool lexicographically_positive(const std::array<int, 3>& s)
    {
        for (int k : s)
            if (k != 0)
                return k > 0;
        return false;
    }

} // namespace

ContactImages build_contact_images(const Mesh& mesh, const PeriodicBox& box, const PeriodicPairing& pairing,
    const std::vector<char>& self_contact, const std::vector<char>& kinematic)
{
    const int d = mesh.dim;
    const Index nv = mesh.num_vertices();
    const MatrixXi& facets = mesh.boundary_facets;
    ContactImages out;
    std::vector<std::array<int, 3>> shift_of;
    auto lattice_position = [&](Index u, const std::array<int, 3>& s) {
        TilingVertex key { pairing.vertex_class[u], 0, 0, 0 };
        for (int a = 0; a < d; ++a)
            key[size_t(a + 1)] = pairing.offset(u, a) + s[size_t(a)];
        return key;
    };

    // The cell's vertices keep their indices; images are added per copy, welded by tiling vertex.
    std::map<TilingVertex, Index> index;
    for (Index v = 0; v < nv; ++v) {
        index.emplace(lattice_position(v, { 0, 0, 0 }), v);
        out.source.push_back(v);
        shift_of.push_back({ 0, 0, 0 });
    }
    std::vector<int> surface_facets(facets.data(), facets.data() + facets.size());
    std::vector<int> facet_body(mesh.facet_body.data(), mesh.facet_body.data() + mesh.facet_body.size());
    for (const auto& s : lattice_shifts(box, d, 1)) {
        if (s == std::array<int, 3> { 0, 0, 0 })
            continue;
        for (Index f = 0; f < facets.rows(); ++f) {
            for (int k = 0; k < d; ++k) {
                const Index u = facets(f, k);
                const auto [it, fresh] = index.emplace(lattice_position(u, s), Index(out.source.size()));
                if (fresh) {
                    out.source.push_back(u);
                    shift_of.push_back(s);
                }
                surface_facets.push_back(int(it->second));
            }
            facet_body.push_back(mesh.facet_body[f]);
        }
    }
    const Index ns = Index(out.source.size());
    out.shift.resize(ns, d);
    for (Index t = 0; t < ns; ++t)
        for (int a = 0; a < d; ++a)
            out.shift(t, a) = shift_of[size_t(t)][size_t(a)];

    // T: identity on the cell's vertices, x_u + sum_a s_a (x_hi - x_lo) on the images.
    std::vector<std::array<Index, 2>> reference(size_t(d), { -1, -1 });
    for (int a = 0; a < d; ++a)
        if (box.periodic[size_t(a)])
            reference[size_t(a)] = reference_pair(pairing, d, a);
    std::vector<Eigen::Triplet<double>> entries;
    for (Index t = 0; t < ns; ++t)
        for (int i = 0; i < d; ++i) {
            entries.emplace_back(int(t * d + i), int(out.source[size_t(t)] * d + i), 1.0);
            for (int a = 0; a < d; ++a) {
                const int s = shift_of[size_t(t)][size_t(a)];
                if (s == 0)
                    continue;
                entries.emplace_back(int(t * d + i), int(reference[size_t(a)][1] * d + i), double(s));
                entries.emplace_back(int(t * d + i), int(reference[size_t(a)][0] * d + i), -double(s));
            }
        }
    out.map.resize(ns * d, nv * d);
    out.map.setFromTriplets(entries.begin(), entries.end());
    const Eigen::Map<const VectorXd> X(mesh.rest_positions.data(), nv * d);
    const VectorXd rest = out.map * X;
    out.rest = Eigen::Map<const Positions>(rest.data(), ns, d);

    Mesh surface;
    surface.dim = d;
    surface.rest_positions = out.rest;
    surface.elements.resize(0, d + 1);
    surface.vertex_body.resize(ns);
    for (Index t = 0; t < ns; ++t)
        surface.vertex_body[t] = mesh.vertex_body[out.source[size_t(t)]];
    surface.boundary_facets = Eigen::Map<const MatrixXi>(surface_facets.data(), Index(facet_body.size()), d);
    surface.facet_body = Eigen::Map<const VectorXi>(facet_body.data(), Index(facet_body.size()));
    out.mesh = build_collision_mesh(surface, self_contact, kinematic);
    CollisionMesh& c = out.mesh;

    // Points: per class, its first cell vertex on the surface.
    c.point.assign(size_t(ns), 0);
    std::vector<char> class_done(size_t(pairing.num_classes()), 0);
    for (Index v = 0; v < nv; ++v) {
        const int k = pairing.vertex_class[v];
        if (c.vertex_group[size_t(v)] >= 0 && !class_done[size_t(k)]) {
            class_done[size_t(k)] = 1;
            c.point[size_t(v)] = 1;
        }
    }
    // Edges: a class of translates is (both endpoints' classes, their lattice difference); its
    // source is its first edge of the cell, and each edge's shift its anchor's lattice offset from it.
    using EdgeKey = std::array<int, 5>;
    auto describe = [&](Index e, EdgeKey& key, std::array<int, 3>& anchor) {
        TilingVertex p = lattice_position(out.source[size_t(c.edges(e, 0))], shift_of[size_t(c.edges(e, 0))]);
        TilingVertex q = lattice_position(out.source[size_t(c.edges(e, 1))], shift_of[size_t(c.edges(e, 1))]);
        if (q < p)
            std::swap(p, q);
        key = { p[0], q[0], q[1] - p[1], q[2] - p[2], q[3] - p[3] };
        anchor = { p[1], p[2], p[3] };
    };
    std::map<EdgeKey, Index> cell_edge;
    const Index ne = c.edges.rows();
    std::vector<EdgeKey> keys(static_cast<size_t>(ne));
    std::vector<std::array<int, 3>> anchors(static_cast<size_t>(ne));
    for (Index e = 0; e < ne; ++e) {
        describe(e, keys[size_t(e)], anchors[size_t(e)]);
        if (c.edges(e, 0) < nv && c.edges(e, 1) < nv)
            cell_edge.emplace(keys[size_t(e)], e);
    }
    c.edge_source.resize(size_t(ne));
    c.edge_shift_positive.resize(size_t(ne));
    for (Index e = 0; e < ne; ++e) {
        const auto it = cell_edge.find(keys[size_t(e)]);
        if (it == cell_edge.end())
            throw std::logic_error("build_contact_images: an image edge is no translate of an edge of the cell");
        const Index r = it->second;
        std::array<int, 3> s {};
        for (int a = 0; a < 3; ++a)
            s[size_t(a)] = anchors[size_t(e)][size_t(a)] - anchors[size_t(r)][size_t(a)];
        c.edge_source[size_t(e)] = r;
        c.edge_shift_positive[size_t(e)] = lexicographically_positive(s);
    }
    return out;
}

} // namespace diffipc
