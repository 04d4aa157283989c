// The GPU port of the distance kernels (cuda/contact/distance/distance_kernels.cuh) against the
// CPU's (forward/contact/distance/distance_kernels.hpp) on random and degenerate vectors.

#include "cuda/contact/distance/distance_kernels.cuh"
#include "forward/contact/distance/distance_kernels.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

#include <Eigen/Geometry>

using namespace diffipc;
namespace dk = diffipc::distance_kernels;
namespace gk = diffipc::gpu::distance_kernels;

TEST(GpuDistanceKernels, CrossSquaredNormPointLineAndPointPlaneEqualCpu)
{
    test::Tally cross, line, plane;
    for (const test::Quad& q : test::test_quads(11)) {
        const Eigen::Vector3d r = q[0] - q[1], a = q[2] - q[1], b = q[3] - q[1];
        {
            dk::Vector<2> g;
            dk::Matrix<2> H;
            const double v = dk::cross_squarednorm(a, b, &g, &H);
            double gg[6], gH[36];
            cross.add(gk::cross_squarednorm(test::to_gpu(a), test::to_gpu(b), gg, gH), v);
            cross.add(gg, g);
            cross.add(gH, H);
        }
        if (a.squaredNorm() > 0) {
            dk::Vector<2> g;
            dk::Matrix<2> H;
            const double v = dk::point_line(r, a, &g, &H);
            double gg[6], gH[36];
            line.add(gk::point_line(test::to_gpu(r), test::to_gpu(a), gg, gH), v);
            line.add(gg, g);
            line.add(gH, H);
            line.add(gk::point_line(test::to_gpu(r), test::to_gpu(a), nullptr, nullptr), v);
        }
        if (a.cross(b).squaredNorm() > 0) {
            dk::Vector<3> g;
            dk::Matrix<3> H;
            const double v = dk::point_plane(r, a, b, &g, &H);
            double gg[9], gH[81];
            plane.add(gk::point_plane(test::to_gpu(r), test::to_gpu(a), test::to_gpu(b), gg, gH), v);
            plane.add(gg, g);
            plane.add(gH, H);
        }
    }
    cross.expect(1e-12, "cross_squarednorm");
    line.expect(1e-12, "point_line kernel");
    plane.expect(1e-12, "point_plane kernel");
}
