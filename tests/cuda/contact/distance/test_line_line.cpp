// cuda/contact/distance/line_line.cuh against forward/contact/distance/line_line.

#include "cuda/contact/distance/line_line.cuh"
#include "forward/contact/distance/line_line.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <Eigen/Geometry>

using namespace diffipc;

TEST(GpuDistanceLineLine, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(15)) {
        if (!((q[1] - q[0]).cross(q[3] - q[2]).squaredNorm() > 0))
            continue; // undefined for parallel lines
        const gpu::vec3 a0 = test::to_gpu(q[0]), a1 = test::to_gpu(q[1]), b0 = test::to_gpu(q[2]),
                        b1 = test::to_gpu(q[3]);
        double g[12], H[144];
        t.add(gpu::line_line_distance(a0, a1, b0, b1), line_line_distance(q[0], q[1], q[2], q[3]));
        gpu::line_line_distance_gradient(a0, a1, b0, b1, g);
        t.add(g, line_line_distance_gradient(q[0], q[1], q[2], q[3]));
        gpu::line_line_distance_hessian(a0, a1, b0, b1, H);
        t.add(H, line_line_distance_hessian(q[0], q[1], q[2], q[3]));
    }
    t.expect(1e-12, "line_line");
}
