#pragma once
/// @file contact_images.hpp
/// Contact across a periodic cell's boundary (issue 14; docs/math.md, "Periodic cells"): the cell's
/// contact surface with its copies shifted by the lattice vectors s in {-1, 0, 1}^(periodic axes),
/// as one collision mesh over the cell's vertices and the copies' image vertices, and the linear
/// map T from the cell's positions to the surface's:
///
///     x_t = x_u + sum_a s_a (x_hi(a) - x_lo(a))
///
/// for an image t of cell vertex u shifted by s, (lo(a), hi(a)) a fixed pair of vertices of one
/// class one lattice step apart along axis a. For the cell's positions x = X + P q
/// (forward/periodic/periodic_map.hpp) x_hi(a) - x_lo(a) = (I + G) L_a e_a, so x_t is u's copy in
/// the deformed tiling, linear in q. Vertices shared by copies are welded (one surface vertex per
/// class and lattice position), and the cell's own vertices keep their indices.
///
/// Each pair of the infinite tiling is counted once per cell (CollisionMesh::point, edge_source):
/// vertex-edge and vertex-face pairs have as their vertex one of the cell per class of translates;
/// edge-edge pairs have one edge of the cell and are kept once of the two translates that have one.

#include "forward/contact/collision_mesh.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/periodic/pairing.hpp"

#include <vector>

namespace diffipc {

struct ContactImages {
    /// Over the #V cell vertices then the image vertices; groups as the cell's (a body's copies
    /// are that body: its self_contact flag decides whether it touches them).
    CollisionMesh mesh;
    /// #S by dim rest positions of the surface's vertices: T X.
    Positions rest;
    /// T (#S dim by #V dim).
    SparseMatrixd map;
    /// Per surface vertex: the cell vertex it is a copy of, and its lattice shift (d values each).
    std::vector<Index> source;
    MatrixXi shift;
};

/// @param mesh the cell (its boundary facets without the periodic faces' facets)
/// @param self_contact, kinematic per group, as for build_collision_mesh
/// @throws std::invalid_argument if a periodic axis has no pair of vertices one lattice step apart
ContactImages build_contact_images(const Mesh& mesh, const PeriodicBox& box, const PeriodicPairing& pairing,
    const std::vector<char>& self_contact, const std::vector<char>& kinematic);

} // namespace diffipc
