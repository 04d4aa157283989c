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
