#pragma once
/// @file collision_mesh.hpp
/// The surface that takes part in contact: boundary vertices, edges and (3D)
/// faces of the bodies and of obstacle meshes, indexed into the full vertex
/// array of the simulation (so positions are the solver's #V by dim array).

#include "forward/common/types.hpp"

#include <vector>

namespace diffipc {

struct CollisionMesh {
    int dim = 3;
    /// Number of vertices of the full mesh (#V); positions passed to contact code are #V by dim.
    Index num_vertices = 0;
    /// #CV indices (into the full mesh) of the vertices on the contact surface, sorted.
    VectorXi vertices;
    /// #CE by 2 surface edges (full-mesh vertex indices); in 2D these are the boundary facets.
    MatrixXi edges;
    /// #CF by 3 surface triangles (full-mesh vertex indices), outward oriented; empty in 2D.
    MatrixXi faces;
    /// #V contact group of each vertex (a body or an obstacle), -1 for vertices not on the surface.
    std::vector<int> vertex_group;
    /// Per group: may primitives of this group touch each other (self-contact)?
    std::vector<char> group_self_contact;
    /// Per group: is it kinematic (an obstacle)? Two kinematic groups never collide.
    std::vector<char> group_kinematic;

    /// Periodic images (forward/periodic/contact_images.hpp); all empty otherwise. Then the
    /// mesh is a cell's surface with copies of it shifted by lattice vectors, and each pair of the
    /// infinite tiling is counted once: a vertex-edge or vertex-face pair only with a `point`
    /// vertex (one of the cell per class of translates), an edge-edge pair only as accept_edges says.
    std::vector<char> point;
    /// Per edge: the cell's edge it is a translate of (itself for those), and whether the lattice
    /// shift from that edge to this one is lexicographically positive.
    std::vector<Index> edge_source;
    std::vector<char> edge_shift_positive;

    /// May vertex v be the point of a vertex-edge / vertex-face pair?
    bool is_point(Index v) const { return point.empty() || point[size_t(v)] != 0; }
    /// @brief With periodic images: is edge pair (a, b) the one pair of its class of translates that
    /// is counted? One edge must be a cell edge r; the other, a translate by s of the cell edge t,
    /// counts when r < t, or r == t and s is lexicographically positive. Always true otherwise.
    bool accept_edges(Index a, Index b) const
    {
        if (edge_source.empty())
            return true;
        const Index sa = edge_source[size_t(a)], sb = edge_source[size_t(b)];
        if (sa == a && sb == b)
            return true;
        if (sa == a)
            return a < sb || (a == sb && edge_shift_positive[size_t(b)]);
        if (sb == b)
            return b < sa || (b == sa && edge_shift_positive[size_t(a)]);
        return false;
    }

    /// @brief May a primitive with vertex va touch a primitive with vertex vb
    /// (any vertex of each; all vertices of a primitive share one group)?
    /// Sharing a vertex is excluded separately by the callers.
    bool groups_can_collide(Index va, Index vb) const
    {
        const int ga = vertex_group[size_t(va)], gb = vertex_group[size_t(vb)];
        if (ga < 0 || gb < 0)
            return false;
        if (ga == gb)
            return group_self_contact[size_t(ga)] != 0;
        return !(group_kinematic[size_t(ga)] && group_kinematic[size_t(gb)]);
    }
};

} // namespace diffipc

namespace diffipc {

struct Mesh;

/// @brief Collision mesh of all boundary facets of `mesh` (bodies and obstacle
/// surfaces; 3D edges are the unique edges of the faces).
/// @param mesh           the full mesh; facet_body / vertex_body give the contact group
/// @param self_contact   per group (bodies then obstacles): may it touch itself?
/// @param kinematic      per group: is it an obstacle?
CollisionMesh build_collision_mesh(
    const Mesh& mesh, const std::vector<char>& self_contact, const std::vector<char>& kinematic);

} // namespace diffipc
