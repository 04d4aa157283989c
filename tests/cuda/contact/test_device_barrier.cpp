// DeviceBarrier (cuda/contact/device_barrier.hpp) on the GPU against the CPU ContactPotential on
// scenes with hundreds of active pairs (the CPU's active set as the pair list): energy, gradient,
// true and projected Hessian; bitwise repeatability; intersecting pairs; the 2D kinds. Skipped
// without a GPU.

#include "cuda/contact/device_barrier.hpp"
#include "cuda/contact/host_barrier.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

#include <chrono>
#include <cstring>

using namespace diffipc;

namespace {

gpu::DeviceBarrier device_barrier(const test::ContactScene& scene)
{
    gpu::DeviceBarrier b;
    b.upload(scene.dim(), scene.rest_vector(), scene.plane_normals());
    const ContactSettings& s = scene.contact().settings();
    b.set_settings({ s.kappa, s.dhat, s.min_distance });
    b.set_pairs(scene.pairs());
    return b;
}

/// Compares the device barrier with the CPU's on the scene; returns the number of pairs.
int compare_with_cpu(const test::ContactScene& scene, const std::string& what)
{
    const gpu::DeviceBarrier b = device_barrier(scene);
    const std::vector<double> x = scene.x_vector();
    const double weight = 0.7;
    const double e_cpu = scene.contact().value(scene.x), e = b.energy(x);
    EXPECT_TRUE(std::isfinite(e_cpu));
    EXPECT_LE(std::abs(e - e_cpu), 1e-12 * std::abs(e_cpu)) << what << ": " << e << " vs " << e_cpu;
    const VectorXd g_cpu = test::cpu_barrier_gradient(scene, scene.x, weight);
    const std::vector<double> g = b.gradient(x, weight);
    const double g_difference = (test::as_eigen(g) - g_cpu).lpNorm<Eigen::Infinity>() / g_cpu.lpNorm<Eigen::Infinity>();
    EXPECT_LE(g_difference, 1e-12) << what;
    double h_difference[2];
    for (bool project : { false, true }) {
        const SparseMatrixd H_cpu = test::cpu_barrier_hessian(scene, scene.x, weight, project);
        const SparseMatrixd H = test::to_sparse(b.hessian_bsr(x, project, weight).download());
        h_difference[project] = test::relative_difference(H, H_cpu);
        EXPECT_LE(h_difference[project], 1e-12) << what << ", project " << project;
        // The BSR product with the contact matrix against the CPU's.
        const std::vector<double> y = b.hessian_bsr(x, project, weight).multiply(x);
        const VectorXd y_cpu = H_cpu * scene.x;
        EXPECT_LE((test::as_eigen(y) - y_cpu).lpNorm<Eigen::Infinity>(), 1e-12 * y_cpu.lpNorm<Eigen::Infinity>());
    }
    std::printf("  %s: %d pairs (%d vertex-edge, %d vertex-face, %d edge-edge, %d vertex-plane): GPU vs CPU "
                "energy %.1e, gradient %.1e, Hessian %.1e, projected Hessian %.1e (relative)\n",
        what.c_str(), b.num_pairs(), scene.kinds()[0], scene.kinds()[1], scene.kinds()[2], scene.kinds()[3],
        std::abs(e - e_cpu) / std::abs(e_cpu), g_difference, h_difference[0], h_difference[1]);
    return b.num_pairs();
}

} // namespace

TEST(DeviceBarrier, EqualsContactPotentialOnHundredsOfPairs3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    std::printf("  %s\n", gpu::cuda_device_description().c_str());
    // Turned by 0.3 rad, and by 0.01 rad (nearly parallel edges: mollified edge-edge pairs).
    for (double angle : { 0.3, 0.01 })
        for (double dmin : { 0.0, 2e-4 }) {
            const test::ContactScene scene = test::boxes_on_plane(
                8, angle, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
            if (angle < 0.1)
                EXPECT_GT(scene.mollified(), 0);
            const int pairs = compare_with_cpu(scene,
                "3D boxes turned " + std::to_string(angle) + ", dmin " + std::to_string(dmin) + ", "
                    + std::to_string(scene.mollified()) + " mollified");
            EXPECT_GE(pairs, 200);
        }
}

TEST(DeviceBarrier, EqualsContactPotential2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (double dmin : { 0.0, 2e-4 }) {
        const test::ContactScene scene
            = test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
        compare_with_cpu(scene, "2D rings, dmin " + std::to_string(dmin));
        const test::ContactScene boxes
            = test::boxes_on_plane_2d(8, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } });
        compare_with_cpu(boxes, "2D boxes, dmin " + std::to_string(dmin));
    }
}

TEST(DeviceBarrier, EvaluationsAreBitwiseRepeatable)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(8, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    const gpu::DeviceBarrier b = device_barrier(scene);
    const std::vector<double> x = scene.x_vector();
    const double e0 = b.energy(x), e1 = b.energy(x);
    EXPECT_EQ(std::memcmp(&e0, &e1, sizeof(double)), 0);
    const std::vector<double> g0 = b.gradient(x, 0.7), g1 = b.gradient(x, 0.7);
    EXPECT_EQ(std::memcmp(g0.data(), g1.data(), g0.size() * sizeof(double)), 0);
    for (bool project : { false, true }) {
        const std::vector<double> h0 = b.hessian_bsr(x, project).download().values;
        const std::vector<double> h1 = b.hessian_bsr(x, project).download().values;
        EXPECT_EQ(std::memcmp(h0.data(), h1.data(), h0.size() * sizeof(double)), 0) << "project " << project;
        // Another object on the same data gives the same bits too.
        const gpu::DeviceBarrier other = device_barrier(scene);
        const std::vector<double> h2 = other.hessian_bsr(x, project).download().values;
        EXPECT_EQ(std::memcmp(h0.data(), h2.data(), h0.size() * sizeof(double)), 0) << "project " << project;
        if (!project) {
            const double e2 = other.energy(x);
            EXPECT_EQ(std::memcmp(&e0, &e2, sizeof(double)), 0);
            const std::vector<double> g2 = other.gradient(x, 0.7);
            EXPECT_EQ(std::memcmp(g0.data(), g2.data(), g0.size() * sizeof(double)), 0);
        }
    }
    // The device results against the host twin (same formulas; the device may contract a*b+c into
    // fused multiply-adds and its log differs by an ulp, so not bitwise).
    gpu::HostBarrier host;
    host.set_mesh(scene.dim(), scene.rest_vector(), scene.plane_normals());
    host.set_settings(b.settings());
    host.set_pairs(scene.pairs());
    const std::vector<double> gh = host.gradient(x, 0.7);
    long equal = 0;
    for (size_t k = 0; k < gh.size(); ++k)
        equal += std::memcmp(&gh[k], &g0[k], sizeof(double)) == 0;
    std::printf("  device vs host twin: energy %.1e relative, %ld of %zu gradient entries bitwise equal\n",
        std::abs(e0 - host.energy(x)) / std::abs(e0), equal, gh.size());
}

TEST(DeviceBarrier, AddsIntoExistingVectorsAndMatrices)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(3, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    const gpu::DeviceBarrier b = device_barrier(scene);
    const std::vector<double> x = scene.x_vector();
    // Twice half the gradient added to the gradient: twice the gradient.
    const std::vector<double> g_once = b.gradient(x, 1.0);
    gpu::DeviceArray<double> d_x(x), d_g(g_once);
    b.add_gradient_device(d_x.data(), 0.5, d_g.data());
    b.add_gradient_device(d_x.data(), 0.5, d_g.data());
    const std::vector<double> g = d_g.download();
    const double scale = test::as_eigen(g_once).lpNorm<Eigen::Infinity>();
    ASSERT_GT(scale, 0);
    for (size_t k = 0; k < g.size(); ++k)
        EXPECT_NEAR(g[k], 2 * g_once[k], 1e-12 * scale);
    gpu::DeviceBsrMatrix H = b.make_hessian_matrix();
    b.add_hessian_device(d_x.data(), 1.0, true, H);
    b.add_hessian_device(d_x.data(), 2.0, true, H);
    const std::vector<double> h = H.download().values, h1 = b.hessian_bsr(x, true, 3.0).download().values;
    double hmax = 0;
    for (double v : h1)
        hmax = std::max(hmax, std::abs(v));
    for (size_t k = 0; k < h.size(); ++k)
        EXPECT_NEAR(h[k], h1[k], 1e-12 * hmax);
    // A matrix of another pattern is refused.
    gpu::DeviceBsrMatrix wrong;
    wrong.set_pattern(3, std::vector<int>(size_t(scene.x.size() / 3) + 1, 0), {});
    EXPECT_THROW(b.add_hessian_device(d_x.data(), 1.0, true, wrong), std::invalid_argument);
}

TEST(DeviceBarrier, IntersectionGivesInfiniteEnergyAndEmptyListGivesZero)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(2, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    gpu::DeviceBarrier b = device_barrier(scene);
    // Push a vertex of a vertex-plane pair through the plane: the pair list stays, the energy is +inf.
    std::vector<double> x = scene.x_vector();
    for (const gpu::BarrierPair& p : scene.pairs())
        if (p.kind == int(ContactKind::VERTEX_PLANE)) {
            x[size_t(p.vertices[0]) * 3 + 1] = -1e-4;
            break;
        }
    EXPECT_TRUE(std::isinf(b.energy(x)));
    EXPECT_TRUE(std::isinf(scene.contact().value(Eigen::Map<const VectorXd>(x.data(), Eigen::Index(x.size())))));
    b.set_pairs({});
    EXPECT_EQ(b.energy(x), 0.0);
    const std::vector<double> g = b.gradient(x);
    EXPECT_EQ(g, std::vector<double>(x.size(), 0.0));
    EXPECT_EQ(b.hessian_bsr(x, true).num_blocks(), 0);
}

TEST(DeviceBarrier, DISABLED_TimingsOfAFewThousandPairs)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(24, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    const gpu::DeviceBarrier b = device_barrier(scene);
    const std::vector<double> x = scene.x_vector();
    gpu::DeviceArray<double> d_x(x), d_g(x.size());
    gpu::DeviceBsrMatrix H = b.make_hessian_matrix();
    auto seconds = [](auto work) {
        work();
        const auto t0 = std::chrono::steady_clock::now();
        for (int k = 0; k < 10; ++k)
            work();
        cudaDeviceSynchronize();
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / 10;
    };
    const double te = seconds([&] { b.energy_device(d_x.data()); });
    const double tg = seconds([&] { b.add_gradient_device(d_x.data(), 1.0, d_g.data()); });
    const double th = seconds([&] { b.add_hessian_device(d_x.data(), 1.0, true, H); });
    std::printf("  %d pairs: energy %.3f ms, gradient %.3f ms, projected Hessian %.3f ms\n", b.num_pairs(), 1e3 * te,
        1e3 * tg, 1e3 * th);
}

TEST(DeviceBarrier, PairsPreparedOnTheDeviceEqualTheHosts)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // set_pairs_device builds the pattern and the incidence lists by radix sorts on the GPU: the same
    // pattern as prepare_barrier_pairs, and so the same energies, gradients and Hessians bit for bit
    // (the gathers then sum in the same order).
    const test::ContactScene scenes[] = {
        test::boxes_on_plane(8, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }),
        test::boxes_on_plane(8, 0.01, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", 2e-4 } }),
        test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }),
        test::boxes_on_plane_2d(8, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }),
    };
    for (const test::ContactScene& scene : scenes) {
        const gpu::DeviceBarrier host = device_barrier(scene);
        gpu::DeviceBarrier device;
        device.upload(scene.dim(), scene.rest_vector(), scene.plane_normals());
        device.set_settings(host.settings());
        std::vector<int> packed;
        for (const gpu::BarrierPair& p : scene.pairs()) {
            packed.push_back(p.kind);
            for (int a = 0; a < 4; ++a)
                packed.push_back(p.vertices[a]);
            packed.push_back(p.plane);
        }
        gpu::DeviceArray<int> d_pairs(packed);
        device.set_pairs_device(d_pairs.data(), int(packed.size() / 6));
        ASSERT_EQ(device.num_pairs(), host.num_pairs());
        ASSERT_GT(device.num_pairs(), 0);
        EXPECT_EQ(device.pairs().row_offsets, host.pairs().row_offsets);
        EXPECT_EQ(device.pairs().col_indices, host.pairs().col_indices);
        const std::vector<double> x = scene.x_vector();
        const double e0 = host.energy(x), e1 = device.energy(x);
        EXPECT_EQ(std::memcmp(&e0, &e1, sizeof(double)), 0);
        const std::vector<double> g0 = host.gradient(x, 0.7), g1 = device.gradient(x, 0.7);
        EXPECT_EQ(std::memcmp(g0.data(), g1.data(), g0.size() * sizeof(double)), 0);
        for (bool project : { false, true }) {
            const std::vector<double> h0 = host.hessian_bsr(x, project).download().values;
            const std::vector<double> h1 = device.hessian_bsr(x, project).download().values;
            ASSERT_EQ(h0.size(), h1.size());
            EXPECT_EQ(std::memcmp(h0.data(), h1.data(), h0.size() * sizeof(double)), 0) << "project " << project;
        }
        std::printf("  %d pairs, %zu blocks: the device's preparation equals the host's\n", device.num_pairs(),
            device.pairs().col_indices.size());
    }
    // No pairs: an empty pattern, zero energy.
    gpu::DeviceBarrier empty;
    empty.upload(scenes[0].dim(), scenes[0].rest_vector(), scenes[0].plane_normals());
    empty.set_pairs_device(nullptr, 0);
    EXPECT_EQ(empty.num_pairs(), 0);
    EXPECT_EQ(empty.energy(scenes[0].x_vector()), 0.0);
    EXPECT_EQ(empty.make_hessian_matrix().num_blocks(), 0);
}
