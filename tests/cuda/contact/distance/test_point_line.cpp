// cuda/contact/distance/point_line.cuh against forward/contact/distance/point_line.

#include "cuda/contact/distance/point_line.cuh"
#include "forward/contact/distance/point_line.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

using namespace diffipc;

TEST(GpuDistancePointLine, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(13)) {
        if (!((q[2] - q[1]).squaredNorm() > 0))
            continue; // undefined for a degenerate line
        const gpu::vec3 p = test::to_gpu(q[0]), e0 = test::to_gpu(q[1]), e1 = test::to_gpu(q[2]);
        double g[9], H[81];
        t.add(gpu::point_line_distance(p, e0, e1), point_line_distance(q[0], q[1], q[2]));
        gpu::point_line_distance_gradient(p, e0, e1, g);
        t.add(g, point_line_distance_gradient(q[0], q[1], q[2]));
        gpu::point_line_distance_hessian(p, e0, e1, H);
        t.add(H, point_line_distance_hessian(q[0], q[1], q[2]));
    }
    t.expect(1e-12, "point_line");
}
