// What a VTU frame shows (forward/io/vtu_frame.hpp): the bodies' state and stress, checked
// against a homogeneous deformation whose Cauchy stress is known in closed form, and the
// obstacles' geometry (plane patches, obstacle meshes) as they move.

#include "forward/io/vtu_frame.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace diffipc;
namespace fs = std::filesystem;

namespace {

const std::vector<double>& doubles(const VtuArray& a) { return std::get<std::vector<double>>(a.values); }

const VtuArray& array(const std::vector<VtuArray>& arrays, const std::string& name)
{
    for (const VtuArray& a : arrays)
        if (a.name == name)
            return a;
    throw std::runtime_error("no array " + name);
}

bool has_array(const std::vector<VtuArray>& arrays, const std::string& name)
{
    for (const VtuArray& a : arrays)
        if (a.name == name)
            return true;
    return false;
}

/// Neo-Hookean Cauchy stress, written out: sigma = (mu (F F^T - I) + lambda ln J I) / J.
Eigen::MatrixXd neo_hookean_cauchy(const Eigen::MatrixXd& F, double E, double nu)
{
    const double mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), J = F.determinant();
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(F.rows(), F.cols());
    return (mu * (F * F.transpose() - I) + lambda * std::log(J) * I) / J;
}

} // namespace

TEST(VtuFrame, BodyGridOfAHomogeneousDeformation)
{
    for (int dim : { 2, 3 }) {
        const double E = 1e5, nu = 0.3;
        Simulator sim(test::make_scene(test::box_scene(
            dim, std::vector<double>(size_t(dim), 1.0), std::vector<int>(size_t(dim), 2), "neo_hookean", E, nu, 1000)));
        Eigen::MatrixXd F = Eigen::MatrixXd::Identity(dim, dim);
        F(0, 0) = 1.2, F(0, 1) = 0.1, F(1, 1) = 0.9;
        const Index nv = sim.mesh().num_vertices();
        VectorXd x(nv * dim), v = VectorXd::Constant(nv * dim, 0.5);
        for (Index i = 0; i < nv; ++i)
            x.segment(i * dim, dim) = F * sim.mesh().rest_positions.row(i).transpose();
        sim.set_initial_state(x, v);

        const VtuGrid g = body_grid(sim, frame_state(sim));
        ASSERT_EQ(g.num_points(), nv);
        ASSERT_EQ(g.num_cells(), sim.mesh().num_elements());
        for (Index i = 0; i < nv; ++i)
            for (int c = 0; c < 3; ++c) {
                EXPECT_EQ(g.points[size_t(3 * i + c)], c < dim ? x[i * dim + c] : 0.0);
                EXPECT_EQ(doubles(array(g.point_data, "velocity"))[size_t(3 * i + c)], c < dim ? 0.5 : 0.0);
            }
        EXPECT_FALSE(has_array(g.point_data, "contact_force")); // no contact in this scene
        const Eigen::MatrixXd sigma = neo_hookean_cauchy(F, E, nu);
        Eigen::Matrix3d padded = Eigen::Matrix3d::Zero();
        padded.topLeftCorner(dim, dim) = sigma;
        const Eigen::Matrix3d dev = padded - padded.trace() / 3 * Eigen::Matrix3d::Identity();
        const double von_mises = std::sqrt(1.5 * dev.squaredNorm());
        const auto& stress = doubles(array(g.cell_data, "stress"));
        for (Index e = 0; e < g.num_cells(); ++e) {
            for (int k = 0; k < 9; ++k)
                EXPECT_NEAR(stress[size_t(9 * e + k)], padded(k / 3, k % 3), 1e-9 * E) << dim << "D element " << e;
            EXPECT_NEAR(doubles(array(g.cell_data, "von_mises"))[size_t(e)], von_mises, 1e-9 * E);
            EXPECT_NEAR(doubles(array(g.cell_data, "volume_ratio"))[size_t(e)], F.determinant(), 1e-12);
        }
    }
}

TEST(VtuFrame, PlanePatchesMoveWithTheirPlane)
{
    for (int dim : { 2, 3 }) {
        const std::vector<double> hi
            = dim == 2 ? std::vector<double> { 0.4, 0.3 } : std::vector<double> { 0.4, 0.3, 0.2 };
        nlohmann::json s = test::box_scene(dim, hi, std::vector<int>(size_t(dim), 1));
        s["bodies"][0]["translation"] = dim == 2 ? nlohmann::json { 1, 1 } : nlohmann::json { 1, 1, 1 };
        const std::vector<double> n = dim == 2 ? std::vector<double> { 0, 1 } : std::vector<double> { 0, 1, 0 };
        const nlohmann::json motion = dim == 2 ? nlohmann::json { "2*t", 0 } : nlohmann::json { "2*t", 0, 0 };
        s["obstacles"] = { { { "plane",
            { { "point", std::vector<double>(size_t(dim), 0.0) }, { "normal", n }, { "motion", motion } } } } };
        s["time"]["steps"] = 1;
        Simulator sim(test::make_scene(s));
        const double side = plane_patch_size(sim.scene());
        const double diagonal = dim == 2 ? std::hypot(0.4, 0.3) : std::sqrt(0.16 + 0.09 + 0.04);
        EXPECT_NEAR(side, 2 * diagonal, 1e-14);
        ASSERT_EQ(sim.step(), StepStatus::CONVERGED);

        const VtuGrid g = obstacle_grid(sim, frame_state(sim));
        // The patch (2 or 4 corners), then the plane's point as a vertex cell.
        const int corners = dim == 2 ? 2 : 4;
        ASSERT_EQ(g.num_points(), corners + 1);
        ASSERT_EQ(g.num_cells(), 2);
        EXPECT_EQ(g.types[0], dim == 2 ? VtkCell::LINE : VtkCell::QUAD);
        EXPECT_EQ(g.types[1], VtkCell::VERTEX);
        // Centred under the body's bounding-box centre, shifted by the plane's motion 2 t = 0.02 m.
        Eigen::Vector3d center = Eigen::Vector3d::Zero();
        for (int i = 0; i < corners; ++i) {
            const Eigen::Vector3d p(g.points[size_t(3 * i)], g.points[size_t(3 * i + 1)], g.points[size_t(3 * i + 2)]);
            EXPECT_NEAR(p[1], 0.0, 1e-14); // on the plane
            center += p / corners;
        }
        EXPECT_NEAR(center[0], 1.2 + 0.02, 1e-12);
        EXPECT_NEAR(center[2], dim == 2 ? 0.0 : 1.1, 1e-12);
        const Eigen::Vector3d p0(g.points[0], g.points[1], g.points[2]), p1(g.points[3], g.points[4], g.points[5]);
        EXPECT_NEAR((p1 - p0).norm(), side, 1e-12);
        if (dim == 3) {
            const Eigen::Vector3d p3(g.points[9], g.points[10], g.points[11]);
            EXPECT_NEAR((p3 - p0).norm(), side, 1e-12);
            EXPECT_GT((p1 - p0).cross(p3 - p0).dot(Eigen::Vector3d::UnitY()), 0); // faces the bodies' side
        }
        EXPECT_NEAR(g.points[size_t(3 * corners)], 0.02, 1e-12); // the plane's point
        EXPECT_EQ(std::get<std::vector<std::int32_t>>(array(g.cell_data, "obstacle").values),
            (std::vector<std::int32_t> { 0, 0 }));
        EXPECT_EQ(doubles(array(g.point_data, "contact_force")).size(), size_t(3 * (corners + 1)));
    }
}

TEST(VtuFrame, ObstacleMeshesAtTheirCurrentPositions)
{
    const fs::path dir = fs::temp_directory_path() / "diffipc_vtu_frame";
    fs::create_directories(dir);
    std::ofstream((dir / "tri.obj").string()) << "v 0 -1 0\nv 1 -1 0\nv 0 -1 1\nv 1 -1 1\nf 1 3 2\nf 2 3 4\n";
    nlohmann::json s = test::box_scene(3, { 0.5, 0.2, 0.2 }, { 1, 1, 1 });
    s["obstacles"] = { { { "plane", { { "point", { 0, -5, 0 } }, { "normal", { 0, 1, 0 } } } } },
        { { "mesh", { { "file", "tri.obj" }, { "motion", { 0, "-t", 0 } } } } } };
    s["friction"] = { { "coefficient", 0.3 } };
    s["time"]["steps"] = 2;
    Simulator sim(parse_scene(s, dir.string(), "<test>"));
    ASSERT_EQ(sim.step(), StepStatus::CONVERGED);
    ASSERT_EQ(sim.step(), StepStatus::CONVERGED);
    const FrameState state = frame_state(sim);
    const VtuGrid g = obstacle_grid(sim, state);
    // Plane: 4 corners and its point; mesh: 4 vertices, 2 triangles.
    ASSERT_EQ(g.num_points(), 5 + 4);
    ASSERT_EQ(g.num_cells(), 2 + 2);
    const ObstacleSpec& mesh = sim.scene().obstacles[1];
    for (Index i = 0; i < 4; ++i)
        for (int c = 0; c < 3; ++c)
            EXPECT_EQ(g.points[size_t(3 * (5 + i) + c)], state.positions[(mesh.first_vertex + i) * 3 + c]);
    EXPECT_NEAR(g.points[size_t(3 * 5 + 1)], -1.02, 1e-12); // moved by -t at t = 0.02
    EXPECT_EQ(g.types[2], VtkCell::TRIANGLE);
    EXPECT_EQ(std::vector<std::int64_t>(g.connectivity.end() - 6, g.connectivity.end()),
        (std::vector<std::int64_t> { 5, 7, 6, 6, 7, 8 }));
    EXPECT_EQ(std::get<std::vector<std::int32_t>>(array(g.cell_data, "obstacle").values),
        (std::vector<std::int32_t> { 0, 0, 1, 1 }));
    EXPECT_TRUE(has_array(g.point_data, "friction_force"));

    // Both parts written, listed as parts 0 and 1 of the same time.
    const std::vector<PvdEntry> entries = write_vtu_frame(dir.string(), 2, 0.02, sim, VtuEncoding::BINARY);
    ASSERT_EQ(entries.size(), 2u);
    EXPECT_EQ(entries[0].file, "frame_2.vtu");
    EXPECT_EQ(entries[1].file, "obstacles_2.vtu");
    EXPECT_EQ(entries[1].part, 1);
    EXPECT_TRUE(fs::exists(dir / "frame_2.vtu"));
    EXPECT_TRUE(fs::exists(dir / "obstacles_2.vtu"));
    fs::remove_all(dir);
}
