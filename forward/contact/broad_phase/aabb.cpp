#include "forward/contact/broad_phase/aabb.hpp"

#include "forward/kernels/primitive_box.hpp"

#include <tbb/parallel_for.h>

#include <cmath>

namespace diffipc {

namespace {

    /// The kernel's swept, inflated box of N vertices (forward/kernels/primitive_box.hpp), which the GPU's broad
    /// phase builds too.
    template <int N, int DIM> AABB primitive_box(const double* x_t0, const double* x_t1, const int* ids, double radius)
    {
        const kernels::Box b = kernels::primitive_box<N, DIM>(x_t0, x_t1, ids, radius);
        return { Eigen::Array3d(b.min[0], b.min[1], b.min[2]), Eigen::Array3d(b.max[0], b.max[1], b.max[2]) };
    }

    template <int N>
    std::vector<AABB> boxes_of_rows(const CollisionMesh& mesh, const int* rows, Index count, const Positions& x_t0,
        const Positions& x_t1, double inflation)
    {
        std::vector<AABB> boxes(static_cast<size_t>(count));
        const double radius = 0.5 * inflation;
        // Positions is row-major: vertex v's coordinates are data()[v * dim .. v * dim + dim).
        const double *p0 = x_t0.data(), *p1 = x_t1.data();
        tbb::parallel_for(tbb::blocked_range<Index>(0, count, 1024), [&](const tbb::blocked_range<Index>& r) {
            for (Index i = r.begin(); i < r.end(); ++i)
                boxes[size_t(i)] = mesh.dim == 3 ? primitive_box<N, 3>(p0, p1, rows + N * i, radius)
                                                 : primitive_box<N, 2>(p0, p1, rows + N * i, radius);
        });
        return boxes;
    }

} // namespace

std::vector<AABB> vertex_boxes(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    return boxes_of_rows<1>(mesh, mesh.vertices.data(), mesh.vertices.size(), x_t0, x_t1, inflation);
}

std::vector<AABB> edge_boxes(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    return boxes_of_rows<2>(mesh, mesh.edges.data(), mesh.edges.rows(), x_t0, x_t1, inflation);
}

std::vector<AABB> face_boxes(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    return boxes_of_rows<3>(mesh, mesh.faces.data(), mesh.faces.rows(), x_t0, x_t1, inflation);
}

} // namespace diffipc
