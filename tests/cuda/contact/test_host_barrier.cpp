// cuda/contact/host_barrier (the CPU twin of DeviceBarrier: the same per-pair functions and the
// same gathers) against the CPU ContactPotential on scenes with active pairs of every kind: energy,
// gradient, true and projected Hessian, with and without a minimum separation; and its gradient
// and Hessian against finite differences. No GPU needed.

#include "cuda/contact/host_barrier.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

using namespace diffipc;

namespace {

gpu::HostBarrier host_barrier(const test::ContactScene& scene)
{
    gpu::HostBarrier b;
    b.set_mesh(scene.dim(), scene.rest_vector(), scene.plane_normals());
    const ContactSettings& s = scene.contact().settings();
    b.set_settings({ s.kappa, s.dhat, s.min_distance, s.penalty });
    b.set_pairs(scene.pairs());
    return b;
}

void compare_with_cpu(const test::ContactScene& scene, const std::string& what)
{
    const gpu::HostBarrier b = host_barrier(scene);
    const std::vector<double> x = scene.x_vector();
    const double weight = 0.7;
    const double e_cpu = scene.contact().value(scene.x), e = b.energy(x);
    ASSERT_TRUE(std::isfinite(e_cpu));
    EXPECT_LE(std::abs(e - e_cpu), 1e-12 * std::abs(e_cpu)) << what;
    const VectorXd g_cpu = test::cpu_barrier_gradient(scene, scene.x, weight);
    const std::vector<double> g = b.gradient(x, weight);
    const double g_difference = (test::as_eigen(g) - g_cpu).lpNorm<Eigen::Infinity>() / g_cpu.lpNorm<Eigen::Infinity>();
    EXPECT_LE(g_difference, 1e-12) << what;
    double h_difference[2];
    for (bool project : { false, true }) {
        const SparseMatrixd H_cpu = test::cpu_barrier_hessian(scene, scene.x, weight, project);
        const SparseMatrixd H = test::to_sparse(b.hessian(x, project, weight));
        h_difference[project] = test::relative_difference(H, H_cpu);
        EXPECT_LE(h_difference[project], 1e-12) << what << ", project " << project;
    }
    std::printf("  %s: %d pairs, energy %.6e (relative difference %.1e), gradient %.1e, Hessian %.1e, "
                "projected Hessian %.1e\n",
        what.c_str(), b.pairs().num_pairs, e, std::abs(e - e_cpu) / e_cpu, g_difference, h_difference[0],
        h_difference[1]);
}

/// The scene's bodies moved down by `sink` (body 0) and 2 sink (body 1): with sink > 0.5 mm, body 0
/// passes the plane and body 1 enters body 0 (states the penalty baseline allows).
void sink_bodies(test::ContactScene& scene, double sink)
{
    const int dim = scene.dim();
    for (Index v = 0; v < scene.sim->scene().body_vertices; ++v)
        scene.x[v * dim + 1] -= sink * (1 + scene.sim->mesh().vertex_body[v]);
}

/// The penalty baseline ("model": "penalty", stiffness 3 N/m) as the scenes' contact.
const nlohmann::json PENALTY = { { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 3.0 } };

} // namespace

TEST(HostBarrier, PenaltyEqualsContactPotential)
{
    // HostBarrier with BarrierSettings::penalty (pair_energy's penalty model) against ContactPotential's
    // penalty, at the scenes' states and with the bodies pushed 0.2 mm into the plane and into each other.
    for (const double sink : { 0.0, 7e-4 }) {
        const std::string where = sink > 0 ? ", penetrating" : "";
        test::ContactScene boxes = test::boxes_on_plane(8, 0.3, 5e-5, PENALTY);
        sink_bodies(boxes, sink);
        const std::array<int, 4> k = boxes.kinds();
        EXPECT_GT(k[1], 0);
        EXPECT_GT(k[2], 0);
        EXPECT_GT(k[3], 0);
        compare_with_cpu(boxes, "3D boxes, penalty" + where);
        test::ContactScene rings = test::rings_on_plane(1e-5, PENALTY);
        sink_bodies(rings, sink);
        compare_with_cpu(rings, "2D rings, penalty" + where);
        test::ContactScene boxes_2d = test::boxes_on_plane_2d(8, 3e-4, 1e-5, PENALTY);
        sink_bodies(boxes_2d, sink);
        compare_with_cpu(boxes_2d, "2D boxes, penalty" + where);
        if (sink > 0) {
            // Some vertex is behind the plane: its pair pushes it back (a negative height, a finite energy).
            bool behind = false;
            for (Index v = 0; v < boxes.sim->scene().body_vertices; ++v)
                behind = behind || boxes.x[v * 3 + 1] < 0;
            EXPECT_TRUE(behind);
        }
    }
}

TEST(HostBarrier, EqualsContactPotential3D)
{
    // Turned by 0.3 rad, and by 0.01 rad (nearly parallel edges: mollified edge-edge pairs).
    for (double angle : { 0.3, 0.01 })
        for (double dmin : { 0.0, 2e-4 }) {
            const test::ContactScene scene = test::boxes_on_plane(
                8, angle, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
            if (angle < 0.1)
                EXPECT_GT(scene.mollified(), 0);
            const std::array<int, 4> k = scene.kinds();
            EXPECT_GT(k[1], 0);
            EXPECT_GT(k[2], 0);
            EXPECT_GT(k[3], 0);
            compare_with_cpu(scene,
                "3D boxes turned " + std::to_string(angle) + ", dmin " + std::to_string(dmin) + ", "
                    + std::to_string(scene.mollified()) + " mollified");
        }
}

TEST(HostBarrier, EqualsContactPotential2D)
{
    for (double dmin : { 0.0, 2e-4 }) {
        const test::ContactScene scene
            = test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
        const std::array<int, 4> k = scene.kinds();
        EXPECT_GT(k[0], 0);
        EXPECT_GT(k[3], 0);
        compare_with_cpu(scene, "2D rings, dmin " + std::to_string(dmin));
        const test::ContactScene boxes
            = test::boxes_on_plane_2d(8, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
        compare_with_cpu(boxes, "2D boxes, dmin " + std::to_string(dmin));
    }
}

TEST(HostBarrier, GradientAndHessianMatchFiniteDifferences)
{
    // 3D turned by 0.3 rad, 3D turned by 0.01 rad (mollified edge-edge pairs), 2D; the barrier, then the
    // penalty baseline with the bodies pushed into the plane and into each other.
    for (int which = 0; which < 6; ++which) {
        const bool penalty = which >= 3;
        const nlohmann::json settings
            = penalty ? PENALTY : nlohmann::json { { "dhat", 1e-3 }, { "kappa", 1.0 }, { "min_distance", 1e-4 } };
        test::ContactScene scene = which % 3 == 0 ? test::boxes_on_plane(2, 0.3, 5e-5, settings)
            : which % 3 == 1                      ? test::boxes_on_plane(4, 0.01, 5e-5, settings)
                                                  : test::boxes_on_plane_2d(8, 3e-4, 1e-5, settings);
        if (penalty)
            sink_bodies(scene, 7e-4);
        const int dim = scene.dim();
        if (which % 3 == 1)
            EXPECT_GT(scene.mollified(), 0);
        const gpu::HostBarrier b = host_barrier(scene); // the pair list at x, kept fixed
        const std::vector<double> x = scene.x_vector();
        const std::vector<double> g = b.gradient(x);
        const SparseMatrixd H = test::to_sparse(b.hessian(x, false));
        const double h = 1e-7 * 1e-3;
        double worst_gradient = 0, worst_hessian = 0;
        for (unsigned seed = 1; seed <= 4; ++seed) {
            const VectorXd dir = test::random_vector(Eigen::Index(x.size()), seed);
            std::vector<double> xp = x, xm = x;
            for (size_t k = 0; k < x.size(); ++k) {
                xp[k] += h * dir[Eigen::Index(k)];
                xm[k] -= h * dir[Eigen::Index(k)];
            }
            const double fd = (b.energy(xp) - b.energy(xm)) / (2 * h);
            worst_gradient = std::max(
                worst_gradient, std::abs(fd - test::as_eigen(g).dot(dir)) / (test::as_eigen(g).norm() * dir.norm()));
            const VectorXd Hd = H * dir;
            const VectorXd fd_g = (test::as_eigen(b.gradient(xp)) - test::as_eigen(b.gradient(xm))) / (2 * h);
            worst_hessian = std::max(worst_hessian, (fd_g - Hd).norm() / Hd.norm());
        }
        std::printf("  %s, dim %d, %d pairs (%d mollified): finite-difference errors, gradient %.2e, Hessian %.2e\n",
            penalty ? "penalty, penetrating" : "barrier", dim, b.pairs().num_pairs, scene.mollified(), worst_gradient,
            worst_hessian);
        EXPECT_LT(worst_gradient, 1e-5);
        EXPECT_LT(worst_hessian, 1e-5);
    }
}
