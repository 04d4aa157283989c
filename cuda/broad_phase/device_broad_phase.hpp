#pragma once
/// @file device_broad_phase.hpp
/// Contact broad phase on the GPU: the primitive pairs of a collision mesh whose swept, inflated boxes overlap
/// during x(t) = (1 - t) x_t0 + t x_t1 (x_t1 = x_t0 for a static query), exactly the pairs of the CPU's
/// broad_phase_candidates (forward/contact/broad_phase/broad_phase.hpp): the same boxes bit for bit
/// (forward/kernels/primitive_box.hpp), the same closed-box overlap test and the same exclusion rules
/// (candidate_filter.cuh). 2D: vertex-edge pairs; 3D: vertex-face and edge-edge pairs.
///
/// Method: a linear BVH (Karras 2012, "Maximizing parallelism in the construction of BVHs, octrees, and k-d
/// trees") rebuilt per call over the target primitives (edges, faces): 63-bit Morton codes of the box centres,
/// CUB radix sort of (code, index), one thread per internal node for the topology, a bottom-up refit of the node
/// boxes (exact unions), then one thread per query primitive traversing the tree and emitting every accepted pair
/// whose boxes overlap. Why a BVH rather than a spatial hash or sweep-and-prune: it needs no cell size, so it
/// stays output-sensitive when box sizes vary a lot (long sweeps next to static primitives, a large obstacle
/// triangle next to fine body facets), where a grid needs the CPU's special list of large boxes and a single-axis
/// sweep degenerates on flat contact surfaces that extend along the sweep axis; and building it costs one radix
/// sort plus two linear passes, cheap enough to rebuild at every query (no refit heuristics to tune).
///
/// Determinism: pairs are emitted in scheduling-dependent order, then radix-sorted on the 64-bit key
/// (first << 32 | second); every pair is emitted once (a query meets each leaf once), so the sorted list is the
/// unique, lexicographically ordered list of the CPU, whatever the scheduling.
///
/// Layouts (the CPU's Candidates, with int indices): vertex-edge (full-mesh vertex, edge row) in 2D;
/// vertex-face (full-mesh vertex, face row) and edge-edge (edge row a, edge row b), a < b, in 3D. Device lists
/// hold 2 ints per pair, pair k at [2k, 2k + 1]. Positions are #V by dim doubles, row-major (xyxy / xyzxyz),
/// metres, for every full-mesh vertex.
///
/// Host code; this header compiles with a plain C++ compiler (no CUDA headers).

#include "cuda/linalg/device_array.hpp"

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace diffipc::gpu {

/// A collision mesh in plain arrays: forward/contact/collision_mesh.hpp's CollisionMesh, field for field.
struct CollisionMeshData {
    int dim = 3; ///< 2 or 3
    int num_vertices = 0; ///< #V of the full mesh
    std::vector<int> vertices; ///< #CV full-mesh indices of the surface vertices
    std::vector<int> edges; ///< #CE by 2, row-major
    std::vector<int> faces; ///< #CF by 3, row-major (empty in 2D)
    std::vector<int> vertex_group; ///< #V contact group per vertex, -1 off the surface
    std::vector<char> group_self_contact; ///< per group
    std::vector<char> group_kinematic; ///< per group
    std::vector<char> point; ///< #V or empty (periodic images only)
    std::vector<int> edge_source; ///< #CE or empty (periodic images only)
    std::vector<char> edge_shift_positive; ///< #CE or empty
};

/// Candidate pairs on the host, each list sorted and without duplicates (the CPU's Candidates with int indices).
struct CandidatePairs {
    std::vector<std::array<int, 2>> vertex_edge; ///< 2D: (full-mesh vertex, edge row)
    std::vector<std::array<int, 2>> vertex_face; ///< 3D: (full-mesh vertex, face row)
    std::vector<std::array<int, 2>> edge_edge; ///< 3D: (edge row a, edge row b), a < b

    std::size_t size() const { return vertex_edge.size() + vertex_face.size() + edge_edge.size(); }
};

/// Candidate pairs on the device: views into the broad phase's buffers, valid until its next call.
struct DeviceCandidates {
    const int* vertex_edge = nullptr; ///< 2 ints per pair; null when empty
    std::size_t num_vertex_edge = 0;
    const int* vertex_face = nullptr;
    std::size_t num_vertex_face = 0;
    const int* edge_edge = nullptr;
    std::size_t num_edge_edge = 0;

    std::size_t size() const { return num_vertex_edge + num_vertex_face + num_edge_edge; }
};

/// Device times of the last call (CUDA events, milliseconds).
struct BroadPhaseTiming {
    float boxes_ms = 0; ///< primitive boxes
    float build_ms = 0; ///< Morton codes, sort, tree, refit
    float query_ms = 0; ///< traversal (both passes when the pair buffer had to grow)
    float sort_ms = 0; ///< sorting and unpacking the pairs
    float total_ms = 0; ///< all of the above, from the first kernel to the pairs' count on the host
};

class DeviceBroadPhase {
public:
    /// @brief Checks the mesh (the CPU broad phase's check_inputs: dimension, shapes, index ranges, group flags)
    /// and uploads it.
    /// @throws std::invalid_argument with a "broad phase: " message on an inconsistent mesh
    explicit DeviceBroadPhase(const CollisionMeshData& mesh);
    ~DeviceBroadPhase();
    DeviceBroadPhase(const DeviceBroadPhase&) = delete;
    DeviceBroadPhase& operator=(const DeviceBroadPhase&) = delete;

    /// @brief The candidates on the device (pairs sorted, unique).
    /// @param d_x_t0     device pointer, #V by dim positions at the start of the step (m)
    /// @param d_x_t1     device pointer, #V by dim positions at the end (m); d_x_t0 for a static query
    /// @param inflation  distance (m) below which a pair must be reported (e.g. dhat + dmin); finite, >= 0
    /// @return views valid until the next call on this object
    /// @throws std::invalid_argument as the CPU: a negative or non-finite inflation, a non-finite position of a
    ///         collision-mesh vertex, edge or face ("broad phase: non-finite position of a collision-mesh ...");
    ///         std::runtime_error on a CUDA error or without a GPU ("no CUDA device: ...")
    DeviceCandidates find(const double* d_x_t0, const double* d_x_t1, double inflation);

    /// @brief find() from host positions, with the pairs copied back.
    /// @param x_t0, x_t1  #V * dim doubles each (m)
    /// @throws std::invalid_argument also on positions of the wrong size
    CandidatePairs candidates(const std::vector<double>& x_t0, const std::vector<double>& x_t1, double inflation);

    /// @brief The static query: candidates(x, x, inflation).
    CandidatePairs candidates_near(const std::vector<double>& x, double inflation);

    /// @brief Copies device candidates (from find()) to the host.
    static CandidatePairs download(const DeviceCandidates& candidates);

    const BroadPhaseTiming& timing() const;
    int dim() const;
    int num_vertices() const;
    /// The uploaded mesh's index data (device pointers), for kernels of other passes (the CCD, the barrier).
    struct MeshPointers {
        const int* vertices;
        const int* edges;
        const int* faces;
        int num_collision_vertices, num_edges, num_faces;
    };
    MeshPointers mesh_pointers() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc::gpu
