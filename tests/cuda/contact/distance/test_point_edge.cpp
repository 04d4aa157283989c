// cuda/contact/distance/point_edge.cuh against forward/contact/distance/point_edge, for the
// classified type and for every type whose formula is defined.

#include "cuda/contact/distance/point_edge.cuh"
#include "forward/contact/distance/point_edge.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

using namespace diffipc;

TEST(GpuDistancePointEdge, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(16)) {
        const gpu::vec3 p = test::to_gpu(q[0]), e0 = test::to_gpu(q[1]), e1 = test::to_gpu(q[2]);
        EXPECT_EQ(int(gpu::point_edge_distance_type(p, e0, e1)), int(point_edge_distance_type(q[0], q[1], q[2])));
        t.add(gpu::point_edge_distance(p, e0, e1), point_edge_distance(q[0], q[1], q[2]));
        for (int type = 0; type < 3; ++type) {
            if (type == 2 && !((q[2] - q[1]).squaredNorm() > 0))
                continue;
            const auto cpu_type = PointEdgeDistanceType(type);
            const auto gpu_type = gpu::PointEdgeDistanceType(type);
            double g[9], H[81];
            t.add(gpu::point_edge_distance(p, e0, e1, gpu_type), point_edge_distance(q[0], q[1], q[2], cpu_type));
            gpu::point_edge_distance_gradient(p, e0, e1, gpu_type, g);
            t.add(g, point_edge_distance_gradient(q[0], q[1], q[2], cpu_type));
            gpu::point_edge_distance_hessian(p, e0, e1, gpu_type, H);
            t.add(H, point_edge_distance_hessian(q[0], q[1], q[2], cpu_type));
        }
    }
    t.expect(1e-12, "point_edge");
}
