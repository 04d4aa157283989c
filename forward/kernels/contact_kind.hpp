#pragma once
/// @file contact_kind.hpp
/// The kinds of contact pairs, one enum for the CPU (forward/contact/contact_set.hpp) and the GPU
/// (cuda/contact/), and the number of vertices of each.

#include "forward/kernels/host_device.hpp"

namespace diffipc::kernels {

enum class ContactKind : unsigned char {
    VERTEX_EDGE = 0, ///< 2D (or 3D): vertices (v, e0, e1)
    VERTEX_FACE = 1, ///< 3D: vertices (v, t0, t1, t2)
    EDGE_EDGE = 2, ///< 3D: vertices (ea0, ea1, eb0, eb1), mollified
    VERTEX_PLANE = 3, ///< vertices (v, plane point); one-sided, signed distance
};

/// Vertices of a pair of this kind.
DIFFIPC_HD inline int contact_num_vertices(ContactKind kind)
{
    return kind == ContactKind::VERTEX_EDGE ? 3 : kind == ContactKind::VERTEX_PLANE ? 2 : 4;
}

/// The most local dofs of a pair (4 vertices in 3D).
constexpr int CONTACT_MAX_DOFS = 12;

} // namespace diffipc::kernels
