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

/// A mesh written to a new file in the system's temporary folder (for a scene that reads its
/// mesh from a file), removed when this goes out of scope.
class TemporaryGmshFile {
public:
    /// @throws InputError naming the file if it cannot be written
    explicit TemporaryGmshFile(const Mesh& mesh);
    ~TemporaryGmshFile();
    TemporaryGmshFile(const TemporaryGmshFile&) = delete;
    TemporaryGmshFile& operator=(const TemporaryGmshFile&) = delete;
    const std::string& path() const { return m_path; }

private:
    std::string m_path;
};

} // namespace diffipc
