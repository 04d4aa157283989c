// cuda/contact/distance/distance_type.cuh against forward/contact/distance/distance_type: the same
// closest-feature type for every configuration, with every ordering of the points, including the
// degenerate ones (parallel and collinear edges, points on an edge's line, coincident points,
// degenerate edges and triangles).

#include "cuda/contact/distance/distance_type.cuh"
#include "forward/contact/distance/distance_type.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <algorithm>

using namespace diffipc;

TEST(GpuDistanceType, ClassificationEqualsCpuForEveryOrdering)
{
    int count = 0, plane_types = 0, line_line_types = 0;
    for (const test::Quad& q0 : test::test_quads(19)) {
        std::array<int, 4> order = { 0, 1, 2, 3 };
        do {
            const Eigen::Vector3d &a = q0[size_t(order[0])], &b = q0[size_t(order[1])], &c = q0[size_t(order[2])],
                                  &d = q0[size_t(order[3])];
            const gpu::vec3 ga = test::to_gpu(a), gb = test::to_gpu(b), gc = test::to_gpu(c), gd = test::to_gpu(d);
            const int pe = int(point_edge_distance_type(a, b, c));
            const int pt = int(point_triangle_distance_type(a, b, c, d));
            const int ee = int(edge_edge_distance_type(a, b, c, d));
            ASSERT_EQ(int(gpu::point_edge_distance_type(ga, gb, gc)), pe);
            ASSERT_EQ(int(gpu::point_triangle_distance_type(ga, gb, gc, gd)), pt);
            ASSERT_EQ(int(gpu::edge_edge_distance_type(ga, gb, gc, gd)), ee);
            plane_types += pt == int(PointTriangleDistanceType::P_T);
            line_line_types += ee == int(EdgeEdgeDistanceType::EA_EB);
            ++count;
        } while (std::next_permutation(order.begin(), order.end()));
    }
    std::printf("  %d configurations: %d point-plane, %d line-line types\n", count, plane_types, line_line_types);
    EXPECT_GT(plane_types, 0);
    EXPECT_GT(line_line_types, 0);
}
