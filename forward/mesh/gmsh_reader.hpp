#pragma once
/// @file gmsh_reader.hpp
/// Reader for gmsh ASCII meshes, format versions 2.x and 4.1.

#include "forward/mesh/mesh.hpp"

#include <string>

namespace diffipc {

/// @brief Reads the simplices of dimension `dim` (3-node triangles for 2D,
/// 4-node tetrahedra for 3D) of a gmsh .msh file; lower-dimensional elements
/// (points, lines, surface triangles of a 3D mesh) are skipped. Vertices not
/// used by any kept element are dropped. In 2D the z coordinate is ignored.
/// Elements with negative orientation are kept as they are: validate_mesh
/// rejects them.
/// @param path  file to read
/// @param dim   2 or 3
/// @throws InputError naming the file (and line) on any format error.
Mesh read_gmsh(const std::string& path, int dim);

/// @brief Reads the facets of a surface mesh (3-node triangles for dim 3,
/// 2-node lines for dim 2) into boundary_facets, with no elements.
Mesh read_gmsh_facets(const std::string& path, int dim);

} // namespace diffipc
