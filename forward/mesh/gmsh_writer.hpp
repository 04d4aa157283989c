#pragma once
/// @file gmsh_writer.hpp
/// Writer for gmsh ASCII meshes (format 2.2), the counterpart of gmsh_reader.hpp.

#include "forward/mesh/mesh.hpp"

#include <string>

namespace diffipc {

/// @brief Writes the elements of `mesh` (triangles or tetrahedra) as a gmsh 2.2 ASCII file,
/// every coordinate exact (%.17g).
/// @throws InputError naming the file if it cannot be written.
void write_gmsh(const std::string& path, const Mesh& mesh);

} // namespace diffipc
