#include "forward/mesh/gmsh_writer.hpp"

#include "forward/common/error.hpp"

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace diffipc {

void write_gmsh(const std::string& path, const Mesh& mesh)
{
    FILE* out = std::fopen(path.c_str(), "w");
    if (!out)
        throw InputError(path, "cannot write");
    const int d = mesh.dim;
    std::fprintf(out, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%ld\n", long(mesh.rest_positions.rows()));
    for (Index v = 0; v < mesh.rest_positions.rows(); ++v)
        std::fprintf(out, "%ld %.17g %.17g %.17g\n", long(v + 1), mesh.rest_positions(v, 0), mesh.rest_positions(v, 1),
            d == 3 ? mesh.rest_positions(v, 2) : 0.0);
    std::fprintf(out, "$EndNodes\n$Elements\n%ld\n", long(mesh.elements.rows()));
    for (Index e = 0; e < mesh.elements.rows(); ++e) {
        std::fprintf(out, "%ld %d 2 1 1", long(e + 1), d == 2 ? 2 : 4);
        for (Index a = 0; a < mesh.elements.cols(); ++a)
            std::fprintf(out, " %d", mesh.elements(e, a) + 1);
        std::fprintf(out, "\n");
    }
    std::fprintf(out, "$EndElements\n");
    const bool ok = std::ferror(out) == 0;
    if (std::fclose(out) != 0 || !ok)
        throw InputError(path, "cannot write");
}

TemporaryGmshFile::TemporaryGmshFile(const Mesh& mesh)
{
    static std::atomic<long> count { 0 };
    m_path = (std::filesystem::temp_directory_path()
        / ("diffipc_mesh_" + std::to_string(::getpid()) + "_" + std::to_string(count++) + ".msh"))
                 .string();
    write_gmsh(m_path, mesh);
}

TemporaryGmshFile::~TemporaryGmshFile() { std::remove(m_path.c_str()); }

} // namespace diffipc
