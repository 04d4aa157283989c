#pragma once
/// @file candidate_filter.cuh
/// Which primitive pairs of a collision mesh may be contact candidates, on host and device: the CPU broad phase's
/// exclusion rules (forward/contact/broad_phase/broad_phase.cpp: accept_vertex_edge, accept_vertex_face,
/// accept_edge_edge, with CollisionMesh::is_point, groups_can_collide and accept_edges), rule for rule:
///  - the two primitives share no vertex (incident primitives are never candidates);
///  - both contact groups exist (vertex_group >= 0), and they are one group with self contact, or two groups that
///    are not both kinematic (obstacle-obstacle pairs never collide);
///  - periodic images: a vertex-edge / vertex-face pair only with a `point` vertex, an edge-edge pair only as
///    accept_edges says (one pair per class of translates).
///
/// Layouts (all int indices, row-major): vertices #CV full-mesh vertex ids; edges #CE by 2; faces #CF by 3;
/// vertex_group #V; group_self_contact, group_kinematic one char per group; point #V chars or null (no periodic
/// images); edge_source #CE ints and edge_shift_positive #CE chars, or null. The pointers are device pointers in
/// kernels and host pointers in host code.

#include "cuda/common/kernels.cuh"

namespace diffipc {
namespace gpu {

    /// Non-owning view of a collision mesh's index data (the CPU CollisionMesh, flattened).
    struct CollisionMeshView {
        int dim = 3;
        int num_vertices = 0; ///< #V of the full mesh
        int num_collision_vertices = 0; ///< #CV
        int num_edges = 0; ///< #CE
        int num_faces = 0; ///< #CF (0 in 2D)
        const int* vertices = nullptr;
        const int* edges = nullptr;
        const int* faces = nullptr;
        const int* vertex_group = nullptr;
        const char* group_self_contact = nullptr;
        const char* group_kinematic = nullptr;
        const char* point = nullptr; ///< null: every vertex may be a pair's point
        const int* edge_source = nullptr; ///< null: every edge pair counts
        const char* edge_shift_positive = nullptr;

        /// CollisionMesh::is_point.
        DIFFIPC_HD bool is_point(int v) const { return point == nullptr || point[v] != 0; }

        /// CollisionMesh::groups_can_collide.
        DIFFIPC_HD bool groups_can_collide(int va, int vb) const
        {
            const int ga = vertex_group[va], gb = vertex_group[vb];
            if (ga < 0 || gb < 0)
                return false;
            if (ga == gb)
                return group_self_contact[ga] != 0;
            return !(group_kinematic[ga] && group_kinematic[gb]);
        }

        /// CollisionMesh::accept_edges.
        DIFFIPC_HD bool accept_edges(int a, int b) const
        {
            if (edge_source == nullptr)
                return true;
            const int sa = edge_source[a], sb = edge_source[b];
            if (sa == a && sb == b)
                return true;
            if (sa == a)
                return a < sb || (a == sb && edge_shift_positive[b]);
            if (sb == b)
                return b < sa || (b == sa && edge_shift_positive[a]);
            return false;
        }

        /// May full-mesh vertex v be the point of any pair? (The vertex-side part of the rules, to skip a query.)
        DIFFIPC_HD bool may_be_point(int v) const { return is_point(v) && vertex_group[v] >= 0; }

        /// accept_vertex_edge: v a full-mesh vertex, e an edge row.
        DIFFIPC_HD bool accept_vertex_edge(int v, int e) const
        {
            const int e0 = edges[2 * e], e1 = edges[2 * e + 1];
            return v != e0 && v != e1 && is_point(v) && groups_can_collide(v, e0);
        }

        /// accept_vertex_face: v a full-mesh vertex, f a face row.
        DIFFIPC_HD bool accept_vertex_face(int v, int f) const
        {
            const int f0 = faces[3 * f], f1 = faces[3 * f + 1], f2 = faces[3 * f + 2];
            return v != f0 && v != f1 && v != f2 && is_point(v) && groups_can_collide(v, f0);
        }

        /// accept_edge_edge: a, b edge rows.
        DIFFIPC_HD bool accept_edge_edge(int a, int b) const
        {
            const int a0 = edges[2 * a], a1 = edges[2 * a + 1], b0 = edges[2 * b], b1 = edges[2 * b + 1];
            return a0 != b0 && a0 != b1 && a1 != b0 && a1 != b1 && groups_can_collide(a0, b0) && accept_edges(a, b);
        }
    };

} // namespace gpu
} // namespace diffipc
