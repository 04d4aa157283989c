// cuda/contact/distance/point_triangle.cuh against forward/contact/distance/point_triangle, for
// the classified type and for every type whose formula is defined.

#include "cuda/contact/distance/point_triangle.cuh"
#include "forward/contact/distance/point_triangle.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <Eigen/Geometry>

using namespace diffipc;

TEST(GpuDistancePointTriangle, ValueGradientHessianEqualCpu)
{
    test::Tally t;
    for (const test::Quad& q : test::test_quads(17)) {
        const gpu::vec3 p = test::to_gpu(q[0]), t0 = test::to_gpu(q[1]), t1 = test::to_gpu(q[2]),
                        t2 = test::to_gpu(q[3]);
        EXPECT_EQ(int(gpu::point_triangle_distance_type(p, t0, t1, t2)),
            int(point_triangle_distance_type(q[0], q[1], q[2], q[3])));
        t.add(gpu::point_triangle_distance(p, t0, t1, t2), point_triangle_distance(q[0], q[1], q[2], q[3]));
        const bool plane = (q[2] - q[1]).cross(q[3] - q[1]).squaredNorm() > 0;
        const bool edges[3]
            = { (q[2] - q[1]).squaredNorm() > 0, (q[3] - q[2]).squaredNorm() > 0, (q[1] - q[3]).squaredNorm() > 0 };
        for (int type = 0; type < 7; ++type) {
            if ((type == 6 && !plane) || (type >= 3 && type < 6 && !edges[type - 3]))
                continue;
            const auto cpu_type = PointTriangleDistanceType(type);
            const auto gpu_type = gpu::PointTriangleDistanceType(type);
            double g[12], H[144];
            t.add(gpu::point_triangle_distance(p, t0, t1, t2, gpu_type),
                point_triangle_distance(q[0], q[1], q[2], q[3], cpu_type));
            gpu::point_triangle_distance_gradient(p, t0, t1, t2, gpu_type, g);
            t.add(g, point_triangle_distance_gradient(q[0], q[1], q[2], q[3], cpu_type));
            gpu::point_triangle_distance_hessian(p, t0, t1, t2, gpu_type, H);
            t.add(H, point_triangle_distance_hessian(q[0], q[1], q[2], q[3], cpu_type));
        }
    }
    t.expect(1e-12, "point_triangle");
}
