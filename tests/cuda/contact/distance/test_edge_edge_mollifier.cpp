// cuda/contact/distance/edge_edge_mollifier.cuh against forward/contact/distance/edge_edge_mollifier:
// thresholds, scalar mollifier and its derivatives, and the position derivatives, mollified and
// not.

#include "cuda/contact/distance/edge_edge_mollifier.cuh"
#include "forward/contact/distance/edge_edge_mollifier.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

using namespace diffipc;

TEST(GpuDistanceEdgeEdgeMollifier, EqualsCpu)
{
    test::Tally t;
    int mollified = 0;
    const std::vector<test::Quad> rest = test::test_quads(20);
    const std::vector<test::Quad> current = test::test_quads(21);
    for (size_t k = 0; k < rest.size(); ++k) {
        const test::Quad& r = rest[k];
        // Current edges: the rest ones, nearly parallel ones, or unrelated ones.
        test::Quad q = current[k];
        if (k % 3 == 1)
            q = { r[0], r[1], r[2], r[2] + (r[1] - r[0]) + 1e-3 * (r[3] - r[2]) };
        else if (k % 3 == 2)
            q = r;
        const double eps_cpu = edge_edge_mollifier_threshold(r[0], r[1], r[2], r[3]);
        const double eps = gpu::edge_edge_mollifier_threshold(
            test::to_gpu(r[0]), test::to_gpu(r[1]), test::to_gpu(r[2]), test::to_gpu(r[3]));
        t.add(eps, eps_cpu);
        const gpu::vec3 a0 = test::to_gpu(q[0]), a1 = test::to_gpu(q[1]), b0 = test::to_gpu(q[2]),
                        b1 = test::to_gpu(q[3]);
        const double x = edge_edge_cross_squarednorm(q[0], q[1], q[2], q[3]);
        t.add(gpu::edge_edge_cross_squarednorm(a0, a1, b0, b1), x);
        mollified += x < eps_cpu;
        for (double s : { 0.0, 0.3, 0.999, 1.0, 2.0 }) {
            t.add(gpu::edge_edge_mollifier(s * eps_cpu, eps_cpu), edge_edge_mollifier(s * eps_cpu, eps_cpu));
            t.add(gpu::edge_edge_mollifier_gradient(s * eps_cpu, eps_cpu),
                edge_edge_mollifier_gradient(s * eps_cpu, eps_cpu));
            t.add(gpu::edge_edge_mollifier_hessian(s * eps_cpu, eps_cpu),
                edge_edge_mollifier_hessian(s * eps_cpu, eps_cpu));
        }
        double g[12], H[144];
        gpu::edge_edge_cross_squarednorm_gradient(a0, a1, b0, b1, g);
        t.add(g, edge_edge_cross_squarednorm_gradient(q[0], q[1], q[2], q[3]));
        gpu::edge_edge_cross_squarednorm_hessian(a0, a1, b0, b1, H);
        t.add(H, edge_edge_cross_squarednorm_hessian(q[0], q[1], q[2], q[3]));
        t.add(gpu::edge_edge_mollifier(a0, a1, b0, b1, eps), edge_edge_mollifier(q[0], q[1], q[2], q[3], eps_cpu));
        gpu::edge_edge_mollifier_gradient(a0, a1, b0, b1, eps, g);
        t.add(g, edge_edge_mollifier_gradient(q[0], q[1], q[2], q[3], eps_cpu));
        gpu::edge_edge_mollifier_hessian(a0, a1, b0, b1, eps, H);
        t.add(H, edge_edge_mollifier_hessian(q[0], q[1], q[2], q[3], eps_cpu));
    }
    std::printf("  %d of %zu pairs mollified\n", mollified, rest.size());
    EXPECT_GT(mollified, 10);
    t.expect(1e-12, "edge_edge_mollifier");
}
