#pragma once
/// @file mesh.hpp
/// Simplicial volume meshes: P1 triangles (2D) and tetrahedra (3D), possibly
/// made of several bodies, with their boundary facets.

#include "forward/common/types.hpp"

#include <string>
#include <vector>

namespace diffipc {

struct Mesh {
    int dim = 0;
    /// #V by dim list of rest positions (m).
    Positions rest_positions;
    /// #E by (dim+1) list of vertex indices, positively oriented.
    MatrixXi elements;
    /// #V body index of each vertex.
    VectorXi vertex_body;
    /// #E body index of each element.
    VectorXi element_body;
    /// #F by dim boundary facets (edges in 2D, triangles in 3D), oriented so
    /// that the normal points out of the body.
    MatrixXi boundary_facets;
    /// #F body index of each boundary facet.
    VectorXi facet_body;

    Index num_vertices() const { return rest_positions.rows(); }
    Index num_elements() const { return elements.rows(); }
    Index num_dofs() const { return rest_positions.size(); }
};

/// @brief Structured mesh of an axis-aligned box.
/// 2D: each cell is split into two triangles along its (min,min)-(max,max)
/// diagonal. 3D: each cube into six tetrahedra sharing its main diagonal
/// (Kuhn subdivision), which is conforming across cells.
/// @param dim    2 or 3
/// @param lower  dim-vector of the box minimum corner (m)
/// @param upper  dim-vector of the box maximum corner (m)
/// @param cells  dim-vector of cell counts per axis (each >= 1)
Mesh box_mesh(int dim, const VectorXd& lower, const VectorXd& upper, const VectorXi& cells);

/// @brief Signed volume (area in 2D) of element e at positions x.
/// @param x #V by dim positions
double signed_volume(const Positions& x, const MatrixXi& elements, Index e);

/// @brief Fills boundary_facets and facet_body from the elements.
void compute_boundary(Mesh& mesh);

/// @brief Appends `other` to `mesh` (offsetting indices), giving its vertices,
/// elements and facets the body index `body`.
void append_mesh(Mesh& mesh, const Mesh& other, int body);

/// @brief Throws InputError(field, ...) naming the first element whose volume
/// is not positive (inverted) or is tiny relative to the mesh size (degenerate),
/// and for non-finite coordinates or out-of-range indices.
void validate_mesh(const Mesh& mesh, const std::string& field);

} // namespace diffipc

namespace diffipc {

/// @brief Triangle mesh of a 2D annulus (a ring) on a polar grid; each polar
/// cell is split into two positively oriented triangles.
/// @param center   2-vector (m)
/// @param inner_radius, outer_radius  0 < inner < outer (m)
/// @param segments cells around (>= 3), @param layers cells across (>= 1)
Mesh annulus_mesh(const VectorXd& center, double inner_radius, double outer_radius, int segments, int layers);

/// @brief Reads a surface mesh for an obstacle: Wavefront .obj ("v" and "f"
/// lines; faces with more than three vertices are fanned; in 2D "l" polyline
/// records become edges and z is ignored) or a gmsh .msh file (its triangles in
/// 3D, its 2-node lines in 2D). Returns a Mesh with no elements whose
/// boundary_facets hold the surface.
/// @throws InputError naming the file (and line).
Mesh read_surface_mesh(const std::string& path, int dim);

} // namespace diffipc

namespace diffipc {

/// @brief Tetrahedral mesh of a torus with a square cross-section, centred at
/// the origin with its axis along z: the box (rho, z, theta) in
/// [R - a, R + a] x [-a, a] x [0, 2 pi) mapped to (rho cos theta, rho sin theta, z),
/// periodic in theta (Kuhn tets stay conforming across the seam).
/// @param major_radius R (m), @param half_width a, 0 < a < R (m)
/// @param cells_across cells per side of the cross-section (>= 1), @param segments cells around (>= 3)
Mesh torus_mesh(double major_radius, double half_width, int cells_across, int segments);

} // namespace diffipc
