#pragma once
/// @file pairing.hpp
/// Periodic meshes (issue 14): the pairing of boundary vertices on opposite faces of a periodic
/// box. Vertices that are copies of each other under a translation by a multiple of the box's
/// edge along its periodic axes form one class (a corner of a 2D cell: four vertices, one class);
/// each vertex is its class representative shifted by an integer lattice offset. The faces on
/// periodic axes are not boundaries of the material (it continues into the neighbouring cell):
/// their facets are dropped from the boundary.

#include "forward/common/types.hpp"
#include "forward/mesh/mesh.hpp"

#include <array>
#include <string>

namespace diffipc {

/// An axis-aligned box and which of its axes are periodic.
struct PeriodicBox {
    VectorXd lower, upper; ///< dim-vectors (m)
    std::array<bool, 3> periodic { { true, true, true } };
    /// Edge length along axis a (m).
    double length(int a) const { return upper[a] - lower[a]; }
};

struct PeriodicPairing {
    /// #V: the class of each vertex (0 .. num_classes - 1).
    VectorXi vertex_class;
    /// Per class: its representative, the vertex of the class nearest the box's lower corner
    /// (on the lower face along every periodic axis it touches).
    VectorXi representative;
    /// #V by dim: X_v = X_rep + sum_a offset(v, a) L_a e_a; zero on non-periodic axes.
    MatrixXi offset;
    Index num_classes() const { return representative.size(); }
};

/// @brief Pairs the vertices on opposite faces of `box` along its periodic axes.
/// A vertex within `tolerance` (m) of a face is on it; its partner on the opposite face must lie
/// within `tolerance` of its translate.
/// @param field the input field named in errors (e.g. "bodies[0].mesh" or "periodic.box")
/// @throws InputError(field, ...) naming the first vertex without a partner (its index, position
///         and face), and InputError("periodic.box", ...) if the box does not fit the mesh: along a
///         periodic axis the mesh must span the box exactly (within the tolerance); along the others
///         it must lie inside.
PeriodicPairing pair_periodic_vertices(
    const Mesh& mesh, const PeriodicBox& box, double tolerance, const std::string& field);

/// @brief Drops the boundary facets that lie on a face of the box along a periodic axis
/// (every vertex of the facet on that face): the material continues there.
void remove_periodic_facets(Mesh& mesh, const PeriodicBox& box, double tolerance);

} // namespace diffipc
