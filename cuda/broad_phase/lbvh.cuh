#pragma once
/// @file lbvh.cuh
/// The linear BVH of the GPU broad phase (device_broad_phase.cu), per node and per query, on host and device:
/// Morton codes of box centres, Karras' construction of the internal nodes from the sorted codes (T. Karras 2012,
/// "Maximizing parallelism in the construction of BVHs, octrees, and k-d trees", Sec. 4 and Fig. 4), the refit of a
/// node from its children, and the depth-first traversal of a query box. The kernels call these functions one
/// thread per node or query; the host tests call them in loops, so the tree logic is checked without a GPU.
///
/// Tree layout for n primitives (n >= 1): 2n - 1 nodes; internal nodes 0 .. n - 2 (node 0 is the root when
/// n > 1), leaves n - 1 .. 2n - 2, leaf k holding the primitive at sorted position k. left[i], right[i] are the
/// children of internal node i, parent[node] its parent (-1 for the root).
///
/// Keys: (code, sorted position); codes are 63 bits in 3D (21 per axis) and 62 in 2D (31 per axis), so that equal
/// codes are split by position. Every internal node's children have longer common key prefixes than the node, so
/// the depth is at most 63 + 32 + 1 < STACK_SIZE, and a depth-first traversal holds at most one pending node per
/// level.

#include "cuda/common/kernels.cuh"
#include "forward/kernels/primitive_box.hpp"

#include <cstdint>

namespace diffipc {
namespace gpu {

    namespace lbvh {

        /// Capacity of the traversal stack (> the largest depth, 96).
        constexpr int STACK_SIZE = 128;

        /// The number of leading zero bits of a nonzero 64-bit (32-bit) value.
        DIFFIPC_HD inline int leading_zeros_64(std::uint64_t x)
        {
#if defined(__CUDA_ARCH__)
            return __clzll(static_cast<long long>(x));
#else
            return __builtin_clzll(x);
#endif
        }
        DIFFIPC_HD inline int leading_zeros_32(std::uint32_t x)
        {
#if defined(__CUDA_ARCH__)
            return __clz(static_cast<int>(x));
#else
            return __builtin_clz(x);
#endif
        }

        DIFFIPC_HD inline Box box_union(const Box& a, const Box& b)
        {
            Box u;
            for (int k = 0; k < 3; ++k) {
                u.min[k] = min_of(a.min[k], b.min[k]);
                u.max[k] = max_of(a.max[k], b.max[k]);
            }
            return u;
        }

        /// The box that contains nothing (the identity of box_union).
        DIFFIPC_HD inline Box empty_box()
        {
            Box b;
            for (int k = 0; k < 3; ++k) {
                b.min[k] = INFINITY;
                b.max[k] = -INFINITY;
            }
            return b;
        }

        /// The centre of a box as a degenerate box (for the bounds of the centres).
        DIFFIPC_HD inline Box centre_box(const Box& b)
        {
            Box c;
            for (int k = 0; k < 3; ++k)
                c.min[k] = c.max[k] = 0.5 * (b.min[k] + b.max[k]);
            return c;
        }

        /// Spreads the low 21 bits of x to every third bit (3D Morton codes).
        DIFFIPC_HD inline std::uint64_t spread_3(std::uint64_t x)
        {
            x &= 0x1fffffull;
            x = (x | x << 32) & 0x1f00000000ffffull;
            x = (x | x << 16) & 0x1f0000ff0000ffull;
            x = (x | x << 8) & 0x100f00f00f00f00full;
            x = (x | x << 4) & 0x10c30c30c30c30c3ull;
            x = (x | x << 2) & 0x1249249249249249ull;
            return x;
        }

        /// Spreads the low 31 bits of x to every second bit (2D Morton codes).
        DIFFIPC_HD inline std::uint64_t spread_2(std::uint64_t x)
        {
            x &= 0x7fffffffull;
            x = (x | x << 16) & 0x0000ffff0000ffffull;
            x = (x | x << 8) & 0x00ff00ff00ff00ffull;
            x = (x | x << 4) & 0x0f0f0f0f0f0f0f0full;
            x = (x | x << 2) & 0x3333333333333333ull;
            x = (x | x << 1) & 0x5555555555555555ull;
            return x;
        }

        /// The cell of coordinate c on a grid of `levels` cells over [lo, hi] (clamped; NaN goes to cell 0).
        DIFFIPC_HD inline std::uint64_t quantize(double c, double lo, double hi, double levels)
        {
            const double extent = hi - lo;
            const double s = extent > 0 ? (c - lo) / extent * levels : 0.0;
            if (!(s > 0))
                return 0;
            if (s >= levels - 1)
                return static_cast<std::uint64_t>(levels - 1);
            return static_cast<std::uint64_t>(s);
        }

        /// @brief The Morton code of a box's centre within the bounds of all centres.
        /// @param bounds  the bounds of the centres (min and max per axis)
        /// @param dim     2 or 3
        DIFFIPC_HD inline std::uint64_t morton_code(const Box& box, const Box& bounds, int dim)
        {
            const Box c = centre_box(box);
            if (dim == 3) {
                const double levels = double(1u << 21);
                return spread_3(quantize(c.min[0], bounds.min[0], bounds.max[0], levels)) << 2
                    | spread_3(quantize(c.min[1], bounds.min[1], bounds.max[1], levels)) << 1
                    | spread_3(quantize(c.min[2], bounds.min[2], bounds.max[2], levels));
            }
            const double levels = double(1u << 31);
            return spread_2(quantize(c.min[0], bounds.min[0], bounds.max[0], levels)) << 1
                | spread_2(quantize(c.min[1], bounds.min[1], bounds.max[1], levels));
        }

        /// Karras' delta: the length of the common prefix of the keys (code, position) at sorted positions i and j;
        /// -1 when j is outside [0, n).
        DIFFIPC_HD inline int common_prefix(const std::uint64_t* codes, int n, int i, long long j)
        {
            if (j < 0 || j >= n)
                return -1;
            const std::uint64_t a = codes[i], b = codes[j];
            if (a != b)
                return leading_zeros_64(a ^ b);
            return 64 + leading_zeros_32(static_cast<std::uint32_t>(i ^ int(j)));
        }

        /// @brief Internal node i (0 <= i < n - 1) of the tree over n sorted codes: its children and their parent
        /// links (Karras 2012, Fig. 4). Each node is independent of the others (one GPU thread each).
        DIFFIPC_HD inline void build_internal_node(
            const std::uint64_t* codes, int n, int i, int* left, int* right, int* parent)
        {
            // Direction of the node's range, from the neighbour with the longer common prefix.
            const int d = common_prefix(codes, n, i, i + 1) - common_prefix(codes, n, i, i - 1) > 0 ? 1 : -1;
            // Upper bound of the range's length, then its other end j by binary search.
            const int delta_min = common_prefix(codes, n, i, i - d);
            long long l_max = 2;
            while (common_prefix(codes, n, i, i + l_max * d) > delta_min)
                l_max *= 2;
            long long l = 0;
            for (long long t = l_max / 2; t >= 1; t /= 2)
                if (common_prefix(codes, n, i, i + (l + t) * d) > delta_min)
                    l += t;
            const long long j = i + l * d;
            // The split: the last position that shares more than the range's common prefix with i.
            const int delta_node = common_prefix(codes, n, i, j);
            long long s = 0;
            for (long long divisor = 2;; divisor *= 2) {
                const long long t = (l + divisor - 1) / divisor;
                if (common_prefix(codes, n, i, i + (s + t) * d) > delta_node)
                    s += t;
                if (t <= 1)
                    break;
            }
            const int gamma = int(i + s * d + (d < 0 ? d : 0));
            const int lo = int(i < j ? i : j), hi = int(i < j ? j : i);
            const int a = lo == gamma ? n - 1 + gamma : gamma;
            const int b = hi == gamma + 1 ? n - 1 + gamma + 1 : gamma + 1;
            left[i] = a;
            right[i] = b;
            parent[a] = i;
            parent[b] = i;
            if (i == 0)
                parent[0] = -1;
        }

        /// A built tree, by pointers (device pointers in kernels, host pointers in the host tests).
        struct TreeView {
            int n = 0; ///< primitives (leaves)
            const Box* nodes = nullptr; ///< 2n - 1 boxes: internal nodes, then leaves
            const int* left = nullptr;
            const int* right = nullptr;
            const int* leaf_ids = nullptr; ///< the primitive of leaf k
        };

        /// @brief Calls visit(j) once for every primitive j whose box overlaps `query` (the leaf's test is
        /// boxes_overlap on the primitive's own box, the CPU's test; internal boxes only prune).
        /// @return false if the stack would overflow (never for trees built here: see the file comment)
        template <typename Visit> DIFFIPC_HD bool traverse(const TreeView& tree, const Box& query, Visit&& visit)
        {
            if (tree.n == 0 || !boxes_overlap(tree.nodes[0], query))
                return true;
            int stack[STACK_SIZE];
            int top = 0;
            stack[top++] = 0;
            const int first_leaf = tree.n - 1;
            while (top > 0) {
                const int node = stack[--top];
                if (node >= first_leaf) {
                    visit(tree.leaf_ids[node - first_leaf]);
                    continue;
                }
                const int a = tree.left[node], b = tree.right[node];
                const bool hit_a = boxes_overlap(tree.nodes[a], query), hit_b = boxes_overlap(tree.nodes[b], query);
                if (top + 2 > STACK_SIZE)
                    return false;
                if (hit_b)
                    stack[top++] = b;
                if (hit_a)
                    stack[top++] = a;
            }
            return true;
        }

    } // namespace lbvh

} // namespace gpu
} // namespace diffipc
