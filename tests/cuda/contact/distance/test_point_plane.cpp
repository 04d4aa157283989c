// cuda/contact/distance/point_plane.cuh against forward/contact/distance/point_plane.

#include "cuda/contact/distance/point_plane.cuh"
#include "forward/contact/distance/point_plane.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <Eigen/Geometry>

using namespace diffipc;

TEST(GpuDistancePointPlane, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(14)) {
        if (!((q[2] - q[1]).cross(q[3] - q[1]).squaredNorm() > 0))
            continue; // undefined for collinear points
        const gpu::vec3 p = test::to_gpu(q[0]), t0 = test::to_gpu(q[1]), t1 = test::to_gpu(q[2]),
                        t2 = test::to_gpu(q[3]);
        double g[12], H[144];
        t.add(gpu::point_plane_distance(p, t0, t1, t2), point_plane_distance(q[0], q[1], q[2], q[3]));
        gpu::point_plane_distance_gradient(p, t0, t1, t2, g);
        t.add(g, point_plane_distance_gradient(q[0], q[1], q[2], q[3]));
        gpu::point_plane_distance_hessian(p, t0, t1, t2, H);
        t.add(H, point_plane_distance_hessian(q[0], q[1], q[2], q[3]));
    }
    t.expect(1e-12, "point_plane");
}
