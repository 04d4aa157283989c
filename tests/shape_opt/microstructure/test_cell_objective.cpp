// shape_opt/microstructure/cell_objective.hpp: the files a design is written as.

#include "shape_opt/microstructure/cell_objective.hpp"

#include "forward/common/error.hpp"
#include "forward/mesh/mesh.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>

#include <unistd.h>

using namespace diffipc;
namespace fs = std::filesystem;

TEST(CellObjective, ASceneFileThatCannotBeWrittenIsAnErrorNamingIt)
{
    // Before: the scene went through an ofstream checked before its buffer was flushed, so a
    // full disk (here scene.json linked to /dev/full) was not reported.
    if (!fs::exists("/dev/full"))
        GTEST_SKIP() << "no /dev/full";
    const fs::path dir = fs::temp_directory_path() / ("diffipc_cell_objective_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    fs::create_symlink("/dev/full", dir / "scene.json");
    const Mesh mesh = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(1, 1));
    const nlohmann::json scene = { { "dimension", 2 } };
    try {
        write_mesh_and_scene(dir.string(), "cell.msh", mesh, scene);
        FAIL() << "a write to /dev/full was not reported";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), (dir / "scene.json").string());
    }
    fs::remove_all(dir);
}
