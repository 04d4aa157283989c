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

    /// Box of the vertices `ids` (n of them) at both ends of the step, grown by `radius` per side
    /// and rounded outward by at least one ulp.
    template <int N>
    AABB primitive_box(const Positions& x_t0, const Positions& x_t1, const int* ids, int dim, double radius)
    {
        AABB box = AABB::empty();
        bool finite = true;
        for (int a = 0; a < N; ++a) {
            for (int k = 0; k < dim; ++k) {
                const double p0 = x_t0(ids[a], k), p1 = x_t1(ids[a], k);
                finite = finite && std::isfinite(p0) && std::isfinite(p1);
                box.min[k] = std::min(box.min[k], std::min(p0, p1));
                box.max[k] = std::max(box.max[k], std::max(p0, p1));
            }
        }
        for (int k = 0; k < dim; ++k) {
            box.min[k] = round_down(box.min[k] - radius);
            box.max[k] = round_up(box.max[k] + radius);
        }
        for (int k = dim; k < 3; ++k)
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
        tbb::parallel_for(tbb::blocked_range<Index>(0, count, 1024), [&](const tbb::blocked_range<Index>& r) {
            for (Index i = r.begin(); i < r.end(); ++i)
                boxes[size_t(i)] = primitive_box<N>(x_t0, x_t1, rows + N * i, mesh.dim, radius);
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
