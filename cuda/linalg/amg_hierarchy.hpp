#pragma once
/// @file amg_hierarchy.hpp
/// The symbolic plan of a smoothed-aggregation multigrid hierarchy (Vanek, Mandel and Brezina 1996)
/// for a block-sparse matrix's pattern: per level its aggregation and tentative prolongator
/// (amg_setup.hpp), the patterns of the smoothed prolongator P = (I - w D^-1 A) T, of W = A P and of
/// the coarse matrix P^T W, and P's columns (for P^T). DeviceAmg (device_amg.hpp) recomputes the values
/// whenever the matrix changes, each block a sum in a fixed order (no atomics: deterministic): a P block
/// (v, a) over A's row v (the neighbours w in aggregate a), a W block (v, c) over A's row v (P's block
/// (w, c), found by binary search in P's row w), a coarse block (a, c) over P's column a (W's block
/// (v, c)). The patterns depend only on the fine pattern, the fixed dofs and the positions: built once.
///
/// Level l has n_l nodes with b_l dofs each (level 0: the vertices, b = dim; then the aggregates,
/// b = k = 3 in 2D, 6 in 3D rigid-body modes). A node's block row/column holds its b_l dofs. Every
/// rectangular block is row-major: a P block (v, a) is b_l x k, entry (i, j) at i k + j.
/// Plain C++: built on the host, tested there.

#include <vector>

namespace diffipc::gpu {

/// One block-sparse pattern: block row r's columns are cols[offsets[r] .. offsets[r + 1]) (increasing).
struct BlockPattern {
    std::vector<int> offsets;
    std::vector<int> cols;
    int rows() const { return offsets.empty() ? 0 : int(offsets.size()) - 1; }
    int blocks() const { return int(cols.size()); }
};

/// A list per output row: entries [offsets[o], offsets[o + 1]) are pairs (first[e], second[e]).
struct ProductList {
    std::vector<int> offsets;
    std::vector<int> first;
    std::vector<int> second;
};

struct AmgLevelPlan {
    int block = 0; ///< b_l
    int coarse_block = 0; ///< k (the next level's b)
    BlockPattern matrix; ///< A_l's pattern (n_l block rows, diagonal included)
    std::vector<int> diagonal; ///< per block row: the index of its diagonal block in matrix
    std::vector<char> fixed; ///< per dof (n_l b_l): fixed (identity row and column in A_l)
    std::vector<int> aggregate_of; ///< per node: its aggregate, -1 if excluded (all its dofs fixed)
    std::vector<double> tentative; ///< per node one b_l x k block of T (in its aggregate's column)
    BlockPattern prolongator; ///< P: n_l block rows, columns are aggregates
    BlockPattern product; ///< W = A P
    /// Per aggregate a: the P blocks (v, a) (first) and v (second), v increasing (P's columns: the
    /// restriction P^T r and the coarse matrix P^T W).
    ProductList restriction;
    int num_aggregates() const { return int(restriction.offsets.size()) - 1; }
};

struct AmgPlan {
    std::vector<AmgLevelPlan> levels; ///< the levels with a coarser one below
    /// The coarsest level (solved directly, as a dense matrix): its pattern and fixed dofs.
    int coarsest_block = 0;
    BlockPattern coarsest;
    std::vector<char> coarsest_fixed;
    int coarsest_size() const { return coarsest_block * coarsest.rows(); }
};

struct AmgPlanSettings {
    /// Stop coarsening once a level has at most this many dofs (it is solved densely).
    int max_coarsest_dofs = 400;
    /// At most this many levels with a coarser one below.
    int max_levels = 8;
    /// Threads for the patterns (0: the hardware's, at most 16). The plan does not depend on it.
    int threads = 0;
};

/// @brief Plans the hierarchy for a symmetric matrix of b x b blocks on `pattern` (every diagonal block
/// present). The near-null space is the rigid-body modes of `positions`.
/// @param block     b = dim, 2 or 3
/// @param pattern   the fine matrix's block pattern (vertices; symmetric, diagonal included)
/// @param positions #vertices * b, vertex-major (the state the rigid-body modes are taken at)
/// @param fixed     per dof (#vertices * b), nonzero = fixed; or empty
/// @throws std::invalid_argument on sizes that do not fit, or a block row without its diagonal block
AmgPlan plan_amg(int block, const BlockPattern& pattern, const std::vector<double>& positions,
    const std::vector<char>& fixed, const AmgPlanSettings& settings = {});

} // namespace diffipc::gpu
