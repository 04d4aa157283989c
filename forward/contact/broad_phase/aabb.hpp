#pragma once
/// @file aabb.hpp
/// Axis-aligned bounding boxes of contact primitives over a linear trajectory
/// (t0 -> t1), inflated so that box overlap is a conservative proximity test.
///
/// Inflation convention: every primitive box is grown by inflation / 2 on each
/// side. If two primitives come within Euclidean distance d <= inflation at
/// some time t of the linear motion, then along every axis their (uninflated)
/// swept boxes are at most d apart, so the inflated boxes overlap. The bounds
/// are additionally rounded outward by at least one ulp, so the test stays conservative
/// under floating-point rounding. The box of a primitive with a non-finite
/// coordinate has min[0] = NaN (is_finite() is false), so callers can reject it.

#include "forward/common/types.hpp"
#include "forward/contact/collision_mesh.hpp"

#include <Eigen/Core>

#include <limits>
#include <vector>

namespace diffipc {

/// Closed axis-aligned box in 3D; 2D boxes have min.z = max.z = 0.
struct AABB {
    Eigen::Array3d min;
    Eigen::Array3d max;

    /// @brief The empty box (min = +inf, max = -inf): it intersects nothing and is the identity of `extend`.
    static AABB empty()
    {
        constexpr double inf = std::numeric_limits<double>::infinity();
        return { Eigen::Array3d::Constant(inf), Eigen::Array3d::Constant(-inf) };
    }

    /// @brief Do the closed boxes share a point? (False if either is empty or NaN.)
    bool intersects(const AABB& other) const
    {
        return min[0] <= other.max[0] && other.min[0] <= max[0] //
            && min[1] <= other.max[1] && other.min[1] <= max[1] //
            && min[2] <= other.max[2] && other.min[2] <= max[2];
    }

    /// @brief Grow this box to contain `other`.
    void extend(const AABB& other)
    {
        min = min.min(other.min);
        max = max.max(other.max);
    }

    bool is_finite() const { return min.allFinite() && max.allFinite(); }
};

/// @brief Swept, inflated boxes of the collision-mesh vertices.
/// @param mesh       collision mesh (dim 2 or 3)
/// @param x_t0       #V by dim positions at the start of the step (m)
/// @param x_t1       #V by dim positions at the end of the step (m); pass x_t0 for a static box
/// @param inflation  total inflation (m); each box grows by inflation / 2 per side
/// @return #CV boxes, entry i for vertex mesh.vertices[i]
std::vector<AABB> vertex_boxes(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation);

/// @brief Swept, inflated boxes of the collision-mesh edges (same arguments as vertex_boxes).
/// @return #CE boxes, entry e for mesh.edges.row(e)
std::vector<AABB> edge_boxes(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation);

/// @brief Swept, inflated boxes of the collision-mesh faces (3D; same arguments as vertex_boxes).
/// @return #CF boxes, entry f for mesh.faces.row(f)
std::vector<AABB> face_boxes(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation);

} // namespace diffipc
