#include "forward/contact/broad_phase/aabb.hpp"

#include <tbb/parallel_for.h>

#include <cmath>

namespace diffipc {

namespace {

    // At least one ulp outward (cheaper than std::nextafter): |v| * 2^-52 >= ulp(v) for normal v, and the smallest
    // subnormal covers v = 0.
    inline double round_down(double v)
    {
        return v - (std::abs(v) * std::numeric_limits<double>::epsilon() + std::numeric_limits<double>::denorm_min());
    }
    inline double round_up(double v)
    {
        return v + (std::abs(v) * std::numeric_limits<double>::epsilon() + std::numeric_limits<double>::denorm_min());
    }

    /// Box of the N vertices `ids` at both ends of the step, grown by `radius` per side and rounded outward by at
    /// least one ulp.
    template <int N, int DIM> AABB primitive_box(const double* x_t0, const double* x_t1, const int* ids, double radius)
    {
        double lo[3] = { 0, 0, 0 }, hi[3] = { 0, 0, 0 };
        bool finite = true;
        for (int k = 0; k < DIM; ++k) {
            lo[k] = std::numeric_limits<double>::infinity();
            hi[k] = -lo[k];
        }
        for (int a = 0; a < N; ++a) {
            const double* p0 = x_t0 + size_t(ids[a]) * DIM;
            const double* p1 = x_t1 + size_t(ids[a]) * DIM;
            for (int k = 0; k < DIM; ++k) {
                finite = finite && std::isfinite(p0[k]) && std::isfinite(p1[k]);
                lo[k] = std::min(lo[k], std::min(p0[k], p1[k]));
                hi[k] = std::max(hi[k], std::max(p0[k], p1[k]));
            }
        }
        AABB box;
        for (int k = 0; k < DIM; ++k) {
            box.min[k] = round_down(lo[k] - radius);
            box.max[k] = round_up(hi[k] + radius);
        }
        for (int k = DIM; k < 3; ++k)
            box.min[k] = box.max[k] = 0;
        if (!finite) // std::min/max skip NaN: mark the box so that callers can reject it
            box.min[0] = std::numeric_limits<double>::quiet_NaN();
        return box;
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
