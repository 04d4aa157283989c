#include "shape_opt/microstructure/cell_objective.hpp"

#include "forward/common/error.hpp"
#include "forward/io/output.hpp"
#include "forward/mesh/gmsh_writer.hpp"
#include "shape_opt/microstructure/cell_shape_map.hpp"

#include <filesystem>

namespace diffipc {

DesignMesh mesh_with_velocity(const CellObjective& objective, const VectorXd& p, bool velocity)
{
    DesignMesh out;
    out.mesh = mesh_design(objective.family(), p, objective.mesh_settings());
    if (velocity)
        out.velocity = CellShapeMap(objective.family(), p, out.mesh, objective.mesh_settings().height).velocity();
    return out;
}

DesignValue evaluate_new_mesh(const CellObjective& objective, const VectorXd& p)
{
    const DesignMesh m = mesh_with_velocity(objective, p, true);
    return objective.value(m.mesh, p, &m.velocity);
}

std::string write_mesh_and_scene(
    const std::string& directory, const std::string& mesh_name, const Mesh& mesh, const nlohmann::json& scene)
{
    std::filesystem::create_directories(directory);
    const std::filesystem::path folder(directory);
    write_gmsh((folder / mesh_name).string(), mesh);
    const std::string path = (folder / "scene.json").string();
    write_json(path, scene); // checked to the last byte: an unflushed ofstream hid a full disk
    return path;
}

} // namespace diffipc
