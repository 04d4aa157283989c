#pragma once
/// @file cell_mesher.hpp
/// A periodic triangle mesh of a microstructure cell's solid (issue 15; docs/microstructures.md,
/// "Meshing"). The cell's graph coordinates y in [-1, 1]^2 map to the physical box by
///
///     X = (height / 2) (width y_x, y_y),
///
/// so the box is [-width height / 2, width height / 2] x [-height / 2, height / 2]. The solid's
/// boundary inside the box is traced by marching squares on a grid finer than the beams (each
/// crossing found on its grid edge to round-off, the values on the box's right and top rows
/// copied from the left and bottom ones), cut into pieces at the box's sides and corners,
/// resampled at the target size (the contour's samples put back on phi = 0 by Newton steps
/// along grad phi; the sides' samples computed once per pair of opposite sides, so they match
/// exactly), and the inside meshed by gmsh (remesh_domain, shape_opt/remesh.hpp: a boundary
/// edge no longer than the size is kept). The mesh's vertices on opposite sides of the box
/// therefore match, as a periodic scene needs.

#include "forward/mesh/mesh.hpp"
#include "shape_opt/microstructure/cell_family.hpp"

namespace diffipc {

struct CellMeshSettings {
    double height = 1; ///< the box's height (m)
    double size = 0.025; ///< target edge length (m)
    double seconds = 600; ///< gmsh's time limit
};

/// @brief The mesh of the solid phi < 0 of `sdf` in the box of the given width scale.
/// @throws InputError naming "design" if the solid is degenerate: no solid, a piece of it
///         that does not connect to the rest across the box's sides, or a tiling that does not
///         hold together along x or y (no solid on a side of the box); InputError naming the
///         graph's file (sdf.graph().file, else "design") if the cell's 3 x 3 tiling is not one
///         connected solid (its middle copy whole and joined to its neighbours along x and y);
///         RemeshError if gmsh fails
Mesh mesh_cell(const CellSDF& sdf, double width, const CellMeshSettings& settings);

/// @brief mesh_cell's checks that a cell mesh (of the box of the given width scale and height)
/// tiles into one connected solid; `file` names the graph in the error ("" for "design").
/// @throws InputError as mesh_cell
void check_cell_tiling(const Mesh& mesh, double width, double height, const std::string& file);

/// @brief Checks design p against its family's bounds and that no beam is thinner than the mesh
/// size (its thinnest extent, w height / 2 min(width, 1)).
/// @throws InputError naming `field`.<variable> (design.thickness[e], design.width) for either
void check_meshable(
    const CellFamily& family, const VectorXd& p, const CellMeshSettings& settings, const std::string& field = "design");

/// @brief mesh_cell of a family's design p, after check_meshable.
/// @throws InputError as check_meshable
Mesh mesh_design(
    const CellFamily& family, const VectorXd& p, const CellMeshSettings& settings, const std::string& field = "design");

/// The physical box of a cell: its lower and upper corners.
Eigen::Vector2d cell_box_min(double width, double height);
Eigen::Vector2d cell_box_max(double width, double height);

} // namespace diffipc
