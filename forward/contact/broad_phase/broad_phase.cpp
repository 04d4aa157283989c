#include "forward/contact/broad_phase/broad_phase.hpp"

#include "forward/common/error.hpp"
#include "forward/contact/broad_phase/aabb.hpp"
#include "forward/contact/broad_phase/bvh.hpp"
#include "forward/contact/broad_phase/hash_grid.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace diffipc {

namespace {

    using Pairs = std::vector<std::array<Index, 2>>;

    void check_inputs(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
    {
        const auto fail = [](const std::string& what) { throw std::invalid_argument("broad phase: " + what); };
        if (mesh.dim != 2 && mesh.dim != 3)
            fail("collision mesh dimension must be 2 or 3, got " + std::to_string(mesh.dim));
        for (const Positions* x : { &x_t0, &x_t1 })
            if (x->rows() != mesh.num_vertices || x->cols() != mesh.dim)
                fail("positions are " + std::to_string(x->rows()) + " by " + std::to_string(x->cols())
                    + ", expected #V = " + std::to_string(mesh.num_vertices) + " by dim = " + std::to_string(mesh.dim));
        if (mesh.edges.rows() > 0 && mesh.edges.cols() != 2)
            fail("collision edges must be #CE by 2");
        if (mesh.dim == 3 && mesh.faces.rows() > 0 && mesh.faces.cols() != 3)
            fail("collision faces must be #CF by 3");
        if (mesh.vertex_group.size() != size_t(mesh.num_vertices))
            fail("vertex_group must have #V entries");
        const size_t num_groups = std::min(mesh.group_self_contact.size(), mesh.group_kinematic.size());
        for (int g : mesh.vertex_group)
            if (g >= 0 && size_t(g) >= num_groups)
                fail("vertex group " + std::to_string(g) + " has no group_self_contact / group_kinematic entry");
        const auto in_range = [&](const auto& indices) {
            return indices.size() == 0 || (indices.minCoeff() >= 0 && indices.maxCoeff() < mesh.num_vertices);
        };
        if (!in_range(mesh.vertices) || !in_range(mesh.edges) || !in_range(mesh.faces))
            fail("collision-mesh vertex index out of range [0, #V)");
        if (!(inflation >= 0) || !std::isfinite(inflation))
            fail("inflation must be finite and >= 0, got " + format_number(inflation));
    }

    void check_finite(const std::vector<AABB>& boxes, const char* what)
    {
        for (const AABB& b : boxes)
            if (!b.is_finite())
                throw std::invalid_argument(
                    std::string("broad phase: non-finite position of a collision-mesh ") + what);
    }

    /// Swept boxes of the primitives the broad phase of this dimension needs.
    struct PrimitiveBoxes {
        std::vector<AABB> vertices, edges, faces;
    };

    PrimitiveBoxes primitive_boxes(
        const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
    {
        check_inputs(mesh, x_t0, x_t1, inflation);
        PrimitiveBoxes boxes;
        boxes.vertices = vertex_boxes(mesh, x_t0, x_t1, inflation);
        boxes.edges = edge_boxes(mesh, x_t0, x_t1, inflation);
        if (mesh.dim == 3)
            boxes.faces = face_boxes(mesh, x_t0, x_t1, inflation);
        check_finite(boxes.vertices, "vertex");
        check_finite(boxes.edges, "edge");
        check_finite(boxes.faces, "face");
        return boxes;
    }

    // Filters, shared by every method so that they agree exactly. `i` indexes mesh.vertices or edge rows.

    bool accept_vertex_edge(const CollisionMesh& mesh, Index i, Index e)
    {
        const Index v = mesh.vertices[i], e0 = mesh.edges(e, 0), e1 = mesh.edges(e, 1);
        return v != e0 && v != e1 && mesh.is_point(v) && mesh.groups_can_collide(v, e0);
    }

    bool accept_vertex_face(const CollisionMesh& mesh, Index i, Index f)
    {
        const Index v = mesh.vertices[i];
        const Index f0 = mesh.faces(f, 0), f1 = mesh.faces(f, 1), f2 = mesh.faces(f, 2);
        return v != f0 && v != f1 && v != f2 && mesh.is_point(v) && mesh.groups_can_collide(v, f0);
    }

    bool accept_edge_edge(const CollisionMesh& mesh, Index a, Index b)
    {
        const Index a0 = mesh.edges(a, 0), a1 = mesh.edges(a, 1), b0 = mesh.edges(b, 0), b1 = mesh.edges(b, 1);
        return a0 != b0 && a0 != b1 && a1 != b0 && a1 != b1 && mesh.groups_can_collide(a0, b0)
            && mesh.accept_edges(a, b);
    }

    /// Replaces the collision-vertex position i of each pair by the full-mesh vertex index.
    void to_full_vertex_index(const CollisionMesh& mesh, Pairs& pairs)
    {
        for (auto& p : pairs)
            p[0] = mesh.vertices[p[0]];
    }

    // ---- brute force ----

    template <typename Accept>
    Pairs brute_force_pairs(const std::vector<AABB>& a, const std::vector<AABB>& b, Accept accept)
    {
        Pairs pairs;
        for (size_t i = 0; i < a.size(); ++i)
            for (size_t j = 0; j < b.size(); ++j)
                if (a[i].intersects(b[j]) && accept(Index(i), Index(j)))
                    pairs.push_back({ Index(i), Index(j) });
        return pairs;
    }

    template <typename Accept> Pairs brute_force_self_pairs(const std::vector<AABB>& a, Accept accept)
    {
        Pairs pairs;
        for (size_t i = 0; i < a.size(); ++i)
            for (size_t j = i + 1; j < a.size(); ++j)
                if (a[i].intersects(a[j]) && accept(Index(i), Index(j)))
                    pairs.push_back({ Index(i), Index(j) });
        return pairs;
    }

    // ---- accelerated ----

    /// Pairs (i, j), i indexing `queries` and j indexing `targets` (j > i when `self`), whose boxes intersect and
    /// that `accept`, sorted by (i, j). Queries run in parallel over fixed blocks whose results are concatenated in
    /// block order, so the output is sorted without a global sort.
    template <typename Structure, typename Accept>
    Pairs query_pairs(const Structure& structure, const std::vector<AABB>& queries, bool self, Accept accept)
    {
        constexpr size_t BLOCK = 128;
        const size_t num_blocks = (queries.size() + BLOCK - 1) / BLOCK;
        std::vector<Pairs> block_pairs(num_blocks);
        tbb::enumerable_thread_specific<std::vector<Index>> scratch;
        tbb::parallel_for(tbb::blocked_range<size_t>(0, num_blocks), [&](const tbb::blocked_range<size_t>& r) {
            std::vector<Index>& hits = scratch.local();
            for (size_t block = r.begin(); block < r.end(); ++block) {
                Pairs& out = block_pairs[block];
                const size_t end = std::min(queries.size(), (block + 1) * BLOCK);
                for (size_t i = block * BLOCK; i < end; ++i) {
                    hits.clear();
                    structure.query(queries[i], [&](Index j) {
                        if ((!self || j > Index(i)) && accept(Index(i), j))
                            hits.push_back(j);
                    });
                    std::sort(hits.begin(), hits.end());
                    for (Index j : hits)
                        out.push_back({ Index(i), j });
                }
            }
        });

        std::vector<size_t> offset(num_blocks + 1, 0);
        for (size_t block = 0; block < num_blocks; ++block)
            offset[block + 1] = offset[block] + block_pairs[block].size();
        Pairs pairs(offset[num_blocks]);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, num_blocks), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t block = r.begin(); block < r.end(); ++block)
                std::copy(block_pairs[block].begin(), block_pairs[block].end(), pairs.begin() + offset[block]);
        });
        return pairs;
    }

    /// Accelerated counterpart of brute_force_pairs / brute_force_self_pairs (targets == nullptr), sorted by (i, j).
    template <typename Accept>
    Pairs accelerated_pairs(BroadPhaseMethod method, int dim, const std::vector<AABB>& queries,
        const std::vector<AABB>* targets, Accept accept)
    {
        const bool self = targets == nullptr;
        const std::vector<AABB>& structure_boxes = self ? queries : *targets;
        if (method == BroadPhaseMethod::HASH) {
            HashGrid grid;
            grid.build(structure_boxes, dim);
            return query_pairs(grid, queries, self, accept);
        }
        BVH bvh;
        bvh.build(structure_boxes);
        return query_pairs(bvh, queries, self, accept);
    }

    /// Sort by full-mesh vertex index after to_full_vertex_index; a no-op when mesh.vertices is increasing (as
    /// documented), since the pairs come sorted by collision-vertex position.
    void sort_by_full_vertex(const CollisionMesh& mesh, Pairs& pairs)
    {
        const bool increasing = std::adjacent_find(mesh.vertices.data(), mesh.vertices.data() + mesh.vertices.size(),
                                    [](int a, int b) { return a >= b; })
            == mesh.vertices.data() + mesh.vertices.size();
        if (!increasing)
            tbb::parallel_sort(pairs.begin(), pairs.end());
    }

} // namespace

Candidates brute_force_candidates(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    const PrimitiveBoxes boxes = primitive_boxes(mesh, x_t0, x_t1, inflation);
    Candidates c;
    if (mesh.dim == 2) {
        c.vertex_edge = brute_force_pairs(
            boxes.vertices, boxes.edges, [&](Index i, Index e) { return accept_vertex_edge(mesh, i, e); });
        to_full_vertex_index(mesh, c.vertex_edge);
        std::sort(c.vertex_edge.begin(), c.vertex_edge.end());
    } else {
        c.vertex_face = brute_force_pairs(
            boxes.vertices, boxes.faces, [&](Index i, Index f) { return accept_vertex_face(mesh, i, f); });
        to_full_vertex_index(mesh, c.vertex_face);
        std::sort(c.vertex_face.begin(), c.vertex_face.end());
        c.edge_edge
            = brute_force_self_pairs(boxes.edges, [&](Index a, Index b) { return accept_edge_edge(mesh, a, b); });
        std::sort(c.edge_edge.begin(), c.edge_edge.end());
    }
    return c;
}

Candidates broad_phase_candidates(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation, BroadPhaseMethod method)
{
    if (method == BroadPhaseMethod::BRUTE_FORCE)
        return brute_force_candidates(mesh, x_t0, x_t1, inflation);
    const PrimitiveBoxes boxes = primitive_boxes(mesh, x_t0, x_t1, inflation);
    Candidates c;
    if (mesh.dim == 2) {
        c.vertex_edge = accelerated_pairs(
            method, 2, boxes.vertices, &boxes.edges, [&](Index i, Index e) { return accept_vertex_edge(mesh, i, e); });
        to_full_vertex_index(mesh, c.vertex_edge);
        sort_by_full_vertex(mesh, c.vertex_edge);
    } else {
        // The two searches are independent; each has serial parts (the grid's sort) that the
        // other's work can overlap.
        tbb::parallel_invoke(
            [&] {
                c.vertex_face = accelerated_pairs(method, 3, boxes.vertices, &boxes.faces,
                    [&](Index i, Index f) { return accept_vertex_face(mesh, i, f); });
                to_full_vertex_index(mesh, c.vertex_face);
                sort_by_full_vertex(mesh, c.vertex_face);
            },
            [&] {
                c.edge_edge = accelerated_pairs(
                    method, 3, boxes.edges, nullptr, [&](Index a, Index b) { return accept_edge_edge(mesh, a, b); });
            });
    }
    return c;
}

Candidates candidates_near(const CollisionMesh& mesh, const Positions& x, double inflation, BroadPhaseMethod method)
{
    return broad_phase_candidates(mesh, x, x, inflation, method);
}

} // namespace diffipc
