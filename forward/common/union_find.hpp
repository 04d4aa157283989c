#pragma once
/// @file union_find.hpp
/// Disjoint sets over 0..n-1 (path halving): vertex classes of a periodic mesh, orbits of a
/// cell's nodes under its symmetry, pieces of a mesh. The smaller index of two joined sets' roots
/// becomes the root, so a set's root is its smallest member.

#include "forward/common/types.hpp"

#include <algorithm>
#include <numeric>
#include <vector>

namespace diffipc {

struct UnionFind {
    std::vector<Index> parent;
    explicit UnionFind(Index n)
        : parent(static_cast<size_t>(n))
    {
        std::iota(parent.begin(), parent.end(), Index(0));
    }
    Index find(Index v)
    {
        while (parent[size_t(v)] != v) {
            parent[size_t(v)] = parent[size_t(parent[size_t(v)])];
            v = parent[size_t(v)];
        }
        return v;
    }
    void join(Index a, Index b)
    {
        a = find(a);
        b = find(b);
        if (a != b)
            parent[size_t(std::max(a, b))] = std::min(a, b);
    }
};

} // namespace diffipc
