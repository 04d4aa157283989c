#pragma once
/// @file amg_setup.hpp
/// The symbolic, host-side part of a smoothed-aggregation algebraic multigrid for the device's
/// block-sparse elasticity matrices, used by plan_amg (amg_hierarchy.hpp) for DeviceAmg
/// (device_amg.hpp). Built once per mesh pattern: it depends on the graph and the positions, not on
/// the matrix values.
///
/// - aggregate_vertices(): Vanek, Mandel and Brezina's greedy aggregation of the vertex graph
///   ("Algebraic multigrid by smoothed aggregation for second and fourth order elliptic problems",
///   Computing 56, 1996): phase 1 makes an aggregate of every vertex whose whole neighbourhood is
///   still free, phase 2 adds each left-over vertex to a neighbour's aggregate, phase 3 groups
///   what remains with its free neighbours. Natural order throughout: the result is deterministic.
/// - tentative_prolongator(): the near-null space of linear elasticity, the rigid-body modes
///   (2 translations and 1 rotation in 2D, 3 and 3 in 3D), restricted to each aggregate's free
///   dofs and orthonormalized there (B_a = Q_a R_a); the tentative prolongator's block rows are
///   Q_a's, the coarse level's modes R_a's, so that T R reproduces the fine modes exactly.
///
/// Plain C++ (no CUDA, no Eigen): compiled into diffipc_cuda, tested on the host.

#include <vector>

namespace diffipc::gpu {

struct Aggregation {
    /// Per vertex: its aggregate in [0, num_aggregates), or -1 for an excluded vertex.
    std::vector<int> aggregate_of;
    int num_aggregates = 0;
};

/// @brief Aggregates the vertices of a symmetric block pattern (BSR row offsets and column indices
/// over vertices, diagonal included, as ElementBsrPattern's).
/// @param excluded per vertex: left out of every aggregate (a vertex whose dofs are all fixed), or empty
/// @throws std::invalid_argument if the offsets, indices or flags do not fit num_vertices
Aggregation aggregate_vertices(int num_vertices, const std::vector<int>& row_offsets,
    const std::vector<int>& col_indices, const std::vector<char>& excluded = {});

/// The near-null space per dof: mode j's value at dof (v, i) is modes[(v dim + i) k + j].
/// Rigid-body modes of the positions (#V dim, vertex-major): k = 3 in 2D, 6 in 3D; rotations
/// about each aggregate's centroid are the caller's choice (here about the origin `center`).
std::vector<double> rigid_body_modes(int dim, const std::vector<double>& positions, const double* center = nullptr);

struct TentativeProlongator {
    int dim = 0; ///< fine block size
    int modes = 0; ///< k: coarse block size (columns per aggregate)
    int num_aggregates = 0;
    /// Per fine vertex one dim x k block (row-major) in its aggregate's block column; zero for an
    /// excluded vertex and in the rows of fixed dofs.
    std::vector<double> blocks;
    /// Per aggregate its k x k R factor (row-major, upper triangular): the coarse modes.
    std::vector<double> coarse_modes;
    /// Per aggregate and mode: 0 where the aggregate's free dofs do not determine the mode
    /// (its pivot fell below the tolerance: the column is zero and the coarse dof is to be fixed).
    std::vector<char> coarse_active;
};

/// @brief T and the coarse modes from the aggregation and the fine modes (rigid_body_modes' layout,
/// k per dof) with the fixed dofs' rows zeroed: per aggregate, a QR factorization of its rows by
/// modified Gram-Schmidt, applied twice (deterministic, in vertex order).
/// @param fixed per dof, or empty
/// @param threads threads for the aggregates' factorizations (the result does not depend on it)
/// @throws std::invalid_argument on a size mismatch
TentativeProlongator tentative_prolongator(const Aggregation& aggregation, int dim, int modes,
    const std::vector<double>& fine_modes, const std::vector<char>& fixed = {}, int threads = 1);

} // namespace diffipc::gpu
