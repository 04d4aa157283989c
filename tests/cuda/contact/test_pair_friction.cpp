// The GPU path's friction pairs, one pair at a time, on the CPU: the lagged pairs of 3D and 2D contact
// scenes as the GPU path converts them (forward/simulation/device_conversion.hpp, to_device), evaluated
// by the shared kernel (forward/kernels/friction_pair.hpp) and summed, against FrictionPotential's
// assembled value, gradient and Hessian, in the sticking (|u| < eps) and sliding regimes. Runs without
// a GPU. The kernel's derivatives against finite differences are tested in every build
// (tests/forward/kernels/test_friction_pair.cpp).

#include "cuda/common/kernels.cuh"
#include "forward/contact/friction/friction_potential.hpp"
#include "forward/kernels/friction_pair.hpp"
#include "forward/simulation/device_conversion.hpp"
#include "forward/simulation/device_solver.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

using namespace diffipc;

namespace {

/// The pair's displacements x_i - x0_i as the port takes them (z = 0 in 2D).
void displacements(const FrictionContact& c, const VectorXd& x, const VectorXd& x0, int dim, gpu::vec3* dx)
{
    for (int i = 0; i < c.num_vertices; ++i) {
        const Index v = c.vertices[size_t(i)];
        const Eigen::Vector3d d = vertex_point(x, v, dim) - vertex_point(x0, v, dim);
        dx[i] = gpu::vec3(d.x(), d.y(), d.z());
    }
}

/// Compares the port, summed over the lagged pairs, with FrictionPotential at x; returns the pairs.
int compare_with_cpu(const test::ContactScene& scene, double motion, const std::string& what)
{
    const Simulator& sim = *scene.sim;
    const int dim = scene.dim();
    const Index n = scene.x.size();
    const test::LaggedFriction lagged = test::lagged_friction(scene, motion);
    const FrictionPotential& friction = *lagged.friction;
    const VectorXd& x0 = lagged.x0;
    const std::vector<FrictionContact>& pairs = friction.lagged();
    EXPECT_GT(pairs.size(), 0u) << what;

    double energy = 0;
    VectorXd g = VectorXd::Zero(n);
    std::vector<Eigen::Triplet<double>> triplets;
    int sticking = 0;
    for (const FrictionContact& c : pairs) {
        const gpu::FrictionPair f = to_device(c).second;
        gpu::vec3 dx[4];
        displacements(c, scene.x, x0, dim, dx);
        const int m = c.num_vertices * dim;
        double grad[12], hess[144];
        energy += gpu::pair_friction(dim, f, dx, friction.eps(), grad, hess);
        for (int i = 0; i < c.num_vertices; ++i)
            for (int a = 0; a < dim; ++a) {
                g[c.vertices[size_t(i)] * dim + a] += grad[i * dim + a];
                for (int j = 0; j < c.num_vertices; ++j)
                    for (int b = 0; b < dim; ++b)
                        triplets.emplace_back(c.vertices[size_t(i)] * dim + a, c.vertices[size_t(j)] * dim + b,
                            hess[(i * dim + a) * m + j * dim + b]);
            }
        // The sticking regime: the pair's tangential displacement below eps.
        Eigen::Vector3d r = Eigen::Vector3d::Zero();
        for (int i = 0; i < c.num_vertices; ++i)
            r += c.weights[size_t(i)] * Eigen::Vector3d(dx[i].x, dx[i].y, dx[i].z);
        sticking += (c.tangent.transpose() * r).head(dim - 1).norm() < friction.eps();
    }
    SparseMatrixd H(n, n);
    H.setFromTriplets(triplets.begin(), triplets.end());

    const double e_cpu = friction.value(scene.x);
    VectorXd g_cpu = VectorXd::Zero(n);
    friction.add_gradient(scene.x, 1.0, g_cpu);
    SparseAssembler A;
    A.build(dim, sim.mesh().num_vertices(), sim.mesh().elements);
    A.set_zero();
    friction.add_hessian(scene.x, 1.0, false, A);
    A.finalize();
    const SparseMatrixd H_cpu = A.matrix().selfadjointView<Eigen::Lower>();

    const double de = std::abs(energy - e_cpu) / std::abs(e_cpu);
    const double dg = (g - g_cpu).lpNorm<Eigen::Infinity>() / g_cpu.lpNorm<Eigen::Infinity>();
    const double dh = test::relative_difference(H, H_cpu);
    EXPECT_GT(e_cpu, 0) << what;
    EXPECT_LE(de, 1e-13) << what;
    EXPECT_LE(dg, 1e-13) << what;
    EXPECT_LE(dh, 1e-13) << what;
    std::printf("  %s: %zu friction pairs (%d sticking): energy %.1e, gradient %.1e, Hessian %.1e relative\n",
        what.c_str(), pairs.size(), sticking, de, dg, dh);
    return int(pairs.size());
}

} // namespace

TEST(GpuPairFriction, EqualsFrictionPotential3D)
{
    for (double motion : { 2e-6, 1e-3 })
        compare_with_cpu(test::boxes_on_plane(6, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "3D boxes, motion " + std::to_string(motion));
}

TEST(GpuPairFriction, EqualsFrictionPotential2D)
{
    for (double motion : { 2e-6, 1e-3 }) {
        compare_with_cpu(test::rings_on_plane(1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "2D rings, motion " + std::to_string(motion));
        compare_with_cpu(test::boxes_on_plane_2d(6, 3e-4, 1e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } }), motion,
            "2D boxes, motion " + std::to_string(motion));
    }
}
