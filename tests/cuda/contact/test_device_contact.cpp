// DeviceContact (cuda/contact/device_contact.hpp) on the GPU against the CPU ContactPotential at the
// same states: the active set (the same pairs in the same order), the energy at a state and on a
// line-search segment, the gradient, the minimum distance and the smallest active gap. Skipped
// without a GPU.

#include "cuda/contact/device_contact.hpp"
#include "forward/simulation/device_conversion.hpp"
#include "forward/simulation/device_solver.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

#include <cmath>
#include <limits>

using namespace diffipc;

namespace {

gpu::DeviceContact device_contact(const test::ContactScene& scene)
{
    return gpu::DeviceContact(to_device(scene.contact().collision_mesh()), scene.rest_vector(),
        to_device(scene.contact().planes()), to_device(scene.contact().settings()));
}

void compare_with_cpu(const test::ContactScene& scene, const std::string& what)
{
    gpu::DeviceContact contact = device_contact(scene);
    const ContactPotential& cpu = scene.contact();
    const std::vector<double> x = scene.x_vector();
    gpu::DeviceArray<double> d_x(x);

    // The active set: the CPU's pairs in the CPU's order.
    const int n = contact.update_active(d_x.data());
    const std::vector<gpu::BarrierPair> expected = scene.pairs();
    ASSERT_EQ(size_t(n), expected.size()) << what;
    ASSERT_GT(n, 0) << what;
    const std::vector<gpu::BarrierPair>& got = contact.active_pairs();
    int mismatches = 0;
    for (size_t p = 0; p < expected.size(); ++p) {
        bool same = got[p].kind == expected[p].kind && got[p].plane == expected[p].plane;
        for (int a = 0; a < 4; ++a)
            same = same && got[p].vertices[a] == expected[p].vertices[a];
        mismatches += !same;
    }
    EXPECT_EQ(mismatches, 0) << what;

    // The smallest active gap (ContactPotential::end_iteration's).
    double gap2 = std::numeric_limits<double>::infinity();
    for (const Contact& c : cpu.contacts(scene.x)) {
        const double gap = std::sqrt(std::max(c.distance_squared, 0.0)) - cpu.settings().min_distance;
        gap2 = std::min(gap2, gap * gap);
    }
    EXPECT_LE(std::abs(contact.min_active_gap_squared() - gap2), 1e-14 * gap2) << what;

    // Energy: the candidates' sum against the CPU's sum over its active set.
    const double e_cpu = cpu.value(scene.x), e = contact.energy(d_x.data(), false);
    EXPECT_LE(std::abs(e - e_cpu), 1e-12 * std::abs(e_cpu)) << what;

    // Gradient of the active set.
    const VectorXd g_cpu = test::cpu_barrier_gradient(scene, scene.x, 0.7);
    gpu::DeviceArray<double> d_g(x.size());
    d_g.set_zero();
    contact.add_gradient(d_x.data(), 0.7, d_g.data());
    const double g_difference
        = (test::as_eigen(d_g.download()) - g_cpu).lpNorm<Eigen::Infinity>() / g_cpu.lpNorm<Eigen::Infinity>();
    EXPECT_LE(g_difference, 1e-12) << what;

    // Minimum distance within radii below, at and above dmin + dhat.
    for (double radius : { 1e-4, 1e-3, 2e-2 }) {
        const double d_cpu = cpu.min_distance(scene.x, radius), d = contact.min_distance(d_x.data(), radius);
        EXPECT_LE(std::abs(d - d_cpu), 1e-14 * d_cpu) << what << ", radius " << radius;
    }

    // A line-search segment x -> x + p: the energy of its points from the swept candidates equals
    // the energy from a fresh broad phase and the CPU's.
    const VectorXd p = 2e-4 * test::random_vector(scene.x.size(), 5);
    const std::vector<double> pv(p.data(), p.data() + p.size());
    gpu::DeviceArray<double> d_p(pv);
    const gpu::StepBoundResult bound = contact.max_step(d_x.data(), d_p.data());
    EXPECT_EQ(bound.alpha, cpu.max_step(scene.x, p)) << what;
    double worst = 0;
    for (double t : { 0.25, 0.5 * bound.alpha, bound.alpha }) {
        const VectorXd y = scene.x + t * p;
        const std::vector<double> yv(y.data(), y.data() + y.size());
        gpu::DeviceArray<double> d_y(yv);
        const double on_segment = contact.energy(d_y.data(), true);
        const double fresh = contact.energy(d_y.data(), false);
        const double reference = cpu.value(y);
        EXPECT_EQ(on_segment, fresh) << what << ", t = " << t;
        if (std::isfinite(reference))
            worst = std::max(worst, std::abs(on_segment - reference) / std::abs(reference));
        else
            EXPECT_FALSE(std::isfinite(on_segment)) << what << ", t = " << t;
    }
    EXPECT_LE(worst, 1e-12) << what;
    std::printf("  %s: %d active pairs; energy %.1e, gradient %.1e relative; step bound %.4f; segment energies "
                "%.1e\n",
        what.c_str(), n, std::abs(e - e_cpu) / std::abs(e_cpu), g_difference, bound.alpha, worst);
}

} // namespace

TEST(DeviceContact, EqualsContactPotential3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (double angle : { 0.3, 0.01 })
        for (double dmin : { 0.0, 2e-4 })
            compare_with_cpu(
                test::boxes_on_plane(8, angle, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } }),
                "3D boxes turned " + std::to_string(angle) + ", dmin " + std::to_string(dmin));
}

TEST(DeviceContact, EqualsContactPotential2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (double dmin : { 0.0, 2e-4 }) {
        compare_with_cpu(test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } }),
            "2D rings, dmin " + std::to_string(dmin));
        compare_with_cpu(
            test::boxes_on_plane_2d(8, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 }, { "min_distance", dmin } }),
            "2D boxes, dmin " + std::to_string(dmin));
    }
}

TEST(DeviceContact, KappaScalesTheEnergyAndNoPairsGiveZero)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(3, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    gpu::DeviceContact contact = device_contact(scene);
    gpu::DeviceArray<double> d_x(scene.x_vector());
    const double e3 = contact.energy(d_x.data(), false);
    contact.set_kappa(6.0);
    EXPECT_EQ(contact.energy(d_x.data(), false), 2 * e3);
    // Lifted 1 m: nothing within dhat of anything.
    VectorXd far = scene.x;
    for (Index v = 0; v < far.size() / 3; ++v)
        if (scene.sim->mesh().vertex_body[v] == 1)
            far[v * 3 + 1] += 1.0;
    for (Index v = 0; v < far.size() / 3; ++v)
        if (scene.sim->mesh().vertex_body[v] == 0)
            far[v * 3 + 1] += 0.5;
    gpu::DeviceArray<double> d_far(std::vector<double>(far.data(), far.data() + far.size()));
    EXPECT_EQ(contact.update_active(d_far.data()), 0);
    EXPECT_EQ(contact.energy(d_far.data(), false), 0.0);
    EXPECT_EQ(contact.min_active_gap_squared(), std::numeric_limits<double>::infinity());
    EXPECT_EQ(contact.hessian().num_blocks(), 0);
}
