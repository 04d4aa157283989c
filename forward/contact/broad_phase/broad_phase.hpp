#pragma once
/// @file broad_phase.hpp
/// Contact broad phase: the primitive pairs of a collision mesh that may come
/// within the inflation distance of each other during a linear trajectory
/// x(t) = (1 - t) x_t0 + t x_t1, t in [0, 1] (pass x_t1 = x_t0 for a static
/// configuration). A pair is a candidate when the swept, inflated boxes of its
/// two primitives overlap (see aabb.hpp: each box grows by inflation / 2 per
/// side, so every pair whose distance is <= inflation at some t is included),
/// the primitives share no vertex, and their contact groups may collide
/// (CollisionMesh::groups_can_collide).
///
/// Primitive pairs: 2D vertex-edge; 3D vertex-face and edge-edge, which cover
/// every closest-feature case between two triangle meshes (IPC, Li et al.
/// 2020).

#include "forward/common/types.hpp"
#include "forward/contact/collision_mesh.hpp"

#include <array>
#include <cstddef>
#include <vector>

namespace diffipc {

/// Candidate primitive pairs. Each list is sorted lexicographically and has no duplicates,
/// so the result of every method is deterministic and directly comparable.
struct Candidates {
    /// 2D: (vertex index into the full mesh, row of CollisionMesh::edges).
    std::vector<std::array<Index, 2>> vertex_edge;
    /// 3D: (vertex index into the full mesh, row of CollisionMesh::faces).
    std::vector<std::array<Index, 2>> vertex_face;
    /// 3D: (row a, row b) of CollisionMesh::edges, a < b.
    std::vector<std::array<Index, 2>> edge_edge;

    /// Total number of pairs.
    size_t size() const { return vertex_edge.size() + vertex_face.size() + edge_edge.size(); }
    bool empty() const { return size() == 0; }
    void clear()
    {
        vertex_edge.clear();
        vertex_face.clear();
        edge_edge.clear();
    }
    bool operator==(const Candidates& other) const
    {
        return vertex_edge == other.vertex_edge && vertex_face == other.vertex_face && edge_edge == other.edge_edge;
    }
    bool operator!=(const Candidates& other) const { return !(*this == other); }
};

/// How broad_phase_candidates finds overlapping boxes. All methods return the same candidates; they differ in
/// speed (bench/broad_phase.cpp): HASH is fastest when most boxes have similar sizes, as with the usual small
/// per-step motion (1.2 to 2 times faster than BVH; a few huge boxes such as a two-triangle floor are handled too),
/// BVH when sweeps are large and uneven, e.g. a fast rotation (up to 1.5 times faster than HASH).
enum class BroadPhaseMethod {
    BRUTE_FORCE, ///< all pairs, O(n^2); the reference the others are tested against
    HASH, ///< uniform grid, cell size from the median box extent (hash_grid.hpp)
    BVH, ///< median-split bounding volume hierarchy (bvh.hpp)
};

/// @brief Reference broad phase: tests every pair of primitives (serial, O(#CV #CF + #CE^2)).
/// @param mesh       collision mesh (dim 2 or 3)
/// @param x_t0       #V by dim full-mesh positions at the start of the step (m)
/// @param x_t1       #V by dim full-mesh positions at the end of the step (m); x_t0 for a static query
/// @param inflation  distance (m) below which a pair must be reported, e.g. dhat or dhat + min_distance; >= 0
/// @return the candidates (sorted, without duplicates)
/// @throws std::invalid_argument for mismatched shapes, a negative or non-finite inflation, or non-finite
///         positions of collision-mesh vertices
Candidates brute_force_candidates(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation);

/// @brief Broad phase with an acceleration structure, parallel with TBB. Returns exactly the pairs of
/// brute_force_candidates (the same boxes and the same overlap test), in O(n log n + k) for n primitives
/// and k box overlaps on well-distributed meshes.
/// @param mesh       collision mesh (dim 2 or 3)
/// @param x_t0       #V by dim full-mesh positions at the start of the step (m)
/// @param x_t1       #V by dim full-mesh positions at the end of the step (m); x_t0 for a static query
/// @param inflation  distance (m) below which a pair must be reported, e.g. dhat or dhat + min_distance; >= 0
/// @param method     acceleration structure; BRUTE_FORCE forwards to brute_force_candidates
/// @return the candidates (sorted, without duplicates)
/// @throws std::invalid_argument as brute_force_candidates
Candidates broad_phase_candidates(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1,
    double inflation, BroadPhaseMethod method = BroadPhaseMethod::HASH);

/// @brief Static broad phase: the pairs that may be within `inflation` of each other at positions x
/// (broad_phase_candidates with x_t1 = x_t0).
/// @param mesh       collision mesh (dim 2 or 3)
/// @param x          #V by dim full-mesh positions (m)
/// @param inflation  distance (m) below which a pair must be reported; >= 0
/// @param method     acceleration structure
Candidates candidates_near(
    const CollisionMesh& mesh, const Positions& x, double inflation, BroadPhaseMethod method = BroadPhaseMethod::HASH);

} // namespace diffipc
