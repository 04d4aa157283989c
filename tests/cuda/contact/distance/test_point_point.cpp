// cuda/contact/distance/point_point.cuh against forward/contact/distance/point_point.

#include "cuda/contact/distance/point_point.cuh"
#include "forward/contact/distance/point_point.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

using namespace diffipc;

TEST(GpuDistancePointPoint, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(12)) {
        const gpu::vec3 p0 = test::to_gpu(q[0]), p1 = test::to_gpu(q[1]);
        double g[6], H[36];
        t.add(gpu::point_point_distance(p0, p1), point_point_distance(q[0], q[1]));
        gpu::point_point_distance_gradient(p0, p1, g);
        t.add(g, point_point_distance_gradient(q[0], q[1]));
        gpu::point_point_distance_hessian(p0, p1, H);
        t.add(H, point_point_distance_hessian(q[0], q[1]));
    }
    t.expect(1e-12, "point_point");
}
