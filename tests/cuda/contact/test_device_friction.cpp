// DeviceFriction (cuda/contact/device_friction.hpp) on the GPU against the CPU's FrictionPotential
// with the same lagged data (lagged by the CPU at 3D and 2D contact scenes, sticking and sliding):
// energy, gradient, Hessian and its product; bitwise repeatability; bad pairs rejected. Skipped
// without a GPU.

#include "cuda/contact/device_friction.hpp"
#include "forward/simulation/device_conversion.hpp"
#include "forward/simulation/device_solver.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

#include <cstring>

using namespace diffipc;

namespace {

/// The device friction of the lagged data (pairs, x0, eps).
gpu::DeviceFriction device_friction(const test::ContactScene& scene, const test::LaggedFriction& lagged)
{
    gpu::DeviceFriction d;
    d.upload(scene.dim(), scene.rest_vector(), int(scene.contact().planes().size()));
    std::vector<gpu::BarrierPair> pairs;
    std::vector<gpu::FrictionPair> data;
    for (const FrictionContact& c : lagged.friction->lagged()) {
        const auto [pair, f] = to_device(c);
        pairs.push_back(pair);
        data.push_back(f);
    }
    d.set_pairs(pairs, data);
    d.set_step_start(
        std::vector<double>(lagged.x0.data(), lagged.x0.data() + lagged.x0.size()), lagged.friction->eps());
    return d;
}

void compare_with_cpu(const test::ContactScene& scene, double motion, const std::string& what)
{
    const test::LaggedFriction lagged = test::lagged_friction(scene, motion);
    const FrictionPotential& cpu = *lagged.friction;
    const gpu::DeviceFriction d = device_friction(scene, lagged);
    ASSERT_GT(d.num_pairs(), 0) << what;
    const std::vector<double> x = scene.x_vector();
    const double weight = 0.7;
    const double e_cpu = cpu.value(scene.x), e = d.energy(x);
    VectorXd g_cpu = VectorXd::Zero(scene.x.size());
    cpu.add_gradient(scene.x, weight, g_cpu);
    const std::vector<double> g = d.gradient(x, weight);
    SparseAssembler A;
    A.build(scene.dim(), scene.sim->mesh().num_vertices(), scene.sim->mesh().elements);
    A.set_zero();
    cpu.add_hessian(scene.x, weight, false, A);
    A.finalize();
    const SparseMatrixd H_cpu = A.matrix().selfadjointView<Eigen::Lower>();
    const SparseMatrixd H = test::to_sparse(d.hessian_bsr(x, false, weight).download());
    // The product with a random vector (H x itself nearly vanishes: the pairs' relative positions are normal).
    const VectorXd v = test::random_vector(scene.x.size(), 11);
    const std::vector<double> y
        = d.hessian_bsr(x, false, weight).multiply(std::vector<double>(v.data(), v.data() + v.size()));
    const VectorXd y_cpu = H_cpu * v;

    const double de = std::abs(e - e_cpu) / std::abs(e_cpu);
    const double dg = (test::as_eigen(g) - g_cpu).lpNorm<Eigen::Infinity>() / g_cpu.lpNorm<Eigen::Infinity>();
    const double dh = test::relative_difference(H, H_cpu);
    const double dy = (test::as_eigen(y) - y_cpu).lpNorm<Eigen::Infinity>() / y_cpu.lpNorm<Eigen::Infinity>();
    EXPECT_GT(e_cpu, 0) << what;
    EXPECT_LE(de, 1e-13) << what;
    EXPECT_LE(dg, 1e-13) << what;
    EXPECT_LE(dh, 1e-13) << what;
    EXPECT_LE(dy, 1e-13) << what;
    std::printf("  %s: %d friction pairs: GPU vs CPU energy %.1e, gradient %.1e, Hessian %.1e, product %.1e "
                "(relative)\n",
        what.c_str(), d.num_pairs(), de, dg, dh, dy);
}

} // namespace

TEST(DeviceFriction, EqualsFrictionPotential3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (double motion : { 2e-6, 1e-3 })
        compare_with_cpu(test::boxes_on_plane(6, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "3D boxes, motion " + std::to_string(motion));
}

TEST(DeviceFriction, EqualsFrictionPotential2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (double motion : { 2e-6, 1e-3 }) {
        compare_with_cpu(test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "2D rings, motion " + std::to_string(motion));
        compare_with_cpu(test::boxes_on_plane_2d(6, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "2D boxes, motion " + std::to_string(motion));
    }
}

TEST(DeviceFriction, RepeatedEvaluationsGiveTheSameBits)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(6, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    const test::LaggedFriction lagged = test::lagged_friction(scene, 1e-5);
    const gpu::DeviceFriction d = device_friction(scene, lagged);
    const std::vector<double> x = scene.x_vector();
    EXPECT_EQ(d.energy(x), d.energy(x));
    const std::vector<double> g0 = d.gradient(x), g1 = d.gradient(x);
    EXPECT_EQ(std::memcmp(g0.data(), g1.data(), g0.size() * sizeof(double)), 0);
    const std::vector<double> h0 = d.hessian_bsr(x, false).download().values;
    const std::vector<double> h1 = d.hessian_bsr(x, false).download().values;
    ASSERT_EQ(h0.size(), h1.size());
    EXPECT_EQ(std::memcmp(h0.data(), h1.data(), h0.size() * sizeof(double)), 0);
}

TEST(DeviceFriction, BadPairsAndStepStartsAreRejected)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    gpu::DeviceFriction d;
    d.upload(2, { 0, 0, 1, 0, 0, 1 }, 0);
    gpu::BarrierPair pair;
    pair.kind = 0; // vertex-edge: 3 vertices
    pair.vertices[0] = 0;
    pair.vertices[1] = 1;
    pair.vertices[2] = 2;
    gpu::FrictionPair f;
    f.num_vertices = 3;
    f.weights[0] = 1;
    f.weights[1] = f.weights[2] = -0.5;
    f.tangent[0] = 1;
    f.scale = 2;
    d.set_pairs({ pair }, { f });
    EXPECT_EQ(d.num_pairs(), 1);
    gpu::FrictionPair wrong_count = f;
    wrong_count.num_vertices = 2;
    EXPECT_THROW(d.set_pairs({ pair }, { wrong_count }), std::invalid_argument);
    gpu::FrictionPair not_finite = f;
    not_finite.scale = std::nan("");
    EXPECT_THROW(d.set_pairs({ pair }, { not_finite }), std::invalid_argument);
    gpu::BarrierPair out_of_range = pair;
    out_of_range.vertices[2] = 7;
    EXPECT_THROW(d.set_pairs({ out_of_range }, { f }), std::invalid_argument);
    EXPECT_THROW(d.set_pairs({ pair, pair }, { f }), std::invalid_argument);
    EXPECT_THROW(d.set_step_start({ 0, 0 }, 1e-5), std::invalid_argument);
    EXPECT_THROW(d.set_step_start({ 0, 0, 1, 0, 0, 1 }, 0.0), std::invalid_argument);
}
