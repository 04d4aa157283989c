// cuda/contact/distance/edge_edge.cuh against forward/contact/distance/edge_edge, for the
// classified type and for every type whose formula is defined.

#include "cuda/contact/distance/edge_edge.cuh"
#include "forward/contact/distance/edge_edge.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <Eigen/Geometry>

using namespace diffipc;

TEST(GpuDistanceEdgeEdge, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(18)) {
        const gpu::vec3 a0 = test::to_gpu(q[0]), a1 = test::to_gpu(q[1]), b0 = test::to_gpu(q[2]),
                        b1 = test::to_gpu(q[3]);
        EXPECT_EQ(
            int(gpu::edge_edge_distance_type(a0, a1, b0, b1)), int(edge_edge_distance_type(q[0], q[1], q[2], q[3])));
        t.add(gpu::edge_edge_distance(a0, a1, b0, b1), edge_edge_distance(q[0], q[1], q[2], q[3]));
        const bool a = (q[1] - q[0]).squaredNorm() > 0, b = (q[3] - q[2]).squaredNorm() > 0;
        const bool lines = (q[1] - q[0]).cross(q[3] - q[2]).squaredNorm() > 0;
        for (int type = 0; type < 9; ++type) {
            if ((type == 8 && !lines) || ((type == 4 || type == 5) && !a) || ((type == 6 || type == 7) && !b))
                continue;
            const auto cpu_type = EdgeEdgeDistanceType(type);
            const auto gpu_type = gpu::EdgeEdgeDistanceType(type);
            double g[12], H[144];
            t.add(gpu::edge_edge_distance(a0, a1, b0, b1, gpu_type),
                edge_edge_distance(q[0], q[1], q[2], q[3], cpu_type));
            gpu::edge_edge_distance_gradient(a0, a1, b0, b1, gpu_type, g);
            t.add(g, edge_edge_distance_gradient(q[0], q[1], q[2], q[3], cpu_type));
            gpu::edge_edge_distance_hessian(a0, a1, b0, b1, gpu_type, H);
            t.add(H, edge_edge_distance_hessian(q[0], q[1], q[2], q[3], cpu_type));
        }
    }
    t.expect(1e-12, "edge_edge");
}
