// cuda/contact/barrier_pairs: the contact BSR pattern and the incidence lists of a pair list, and
// the checks of its input.

#include "cuda/contact/barrier_pairs.hpp"

#include <gtest/gtest.h>

#include <set>
#include <stdexcept>
#include <utility>

using namespace diffipc;

namespace {

std::vector<gpu::BarrierPair> some_pairs()
{
    // 8 vertices in 3D: a vertex-face, an edge-edge, a vertex-plane and a vertex-edge pair.
    return { { 1, { 0, 1, 2, 3 }, -1 }, { 2, { 4, 5, 1, 2 }, -1 }, { 3, { 6, 7, -1, -1 }, 0 },
        { 0, { 2, 4, 5, -1 }, -1 } };
}

} // namespace

TEST(GpuBarrierPairs, PatternHoldsEveryVertexPairOnceInOrder)
{
    std::vector<double> rest(8 * 3);
    for (size_t k = 0; k < rest.size(); ++k)
        rest[k] = 0.1 * double(k % 7) + 0.01 * double(k);
    const std::vector<gpu::BarrierPair> pairs = some_pairs();
    const gpu::BarrierPairs P = gpu::prepare_barrier_pairs(3, rest, 1, pairs);
    ASSERT_EQ(P.num_pairs, 4);
    ASSERT_EQ(P.row_offsets.size(), 9u);
    // Expected blocks: all (va, vb) of every pair.
    std::set<std::pair<int, int>> expected;
    for (const gpu::BarrierPair& p : pairs)
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b)
                if (p.vertices[a] >= 0 && p.vertices[b] >= 0)
                    expected.insert({ p.vertices[a], p.vertices[b] });
    std::set<std::pair<int, int>> got;
    for (int r = 0; r < 8; ++r)
        for (int k = P.row_offsets[size_t(r)]; k < P.row_offsets[size_t(r) + 1]; ++k) {
            if (k > P.row_offsets[size_t(r)])
                EXPECT_LT(P.col_indices[size_t(k) - 1], P.col_indices[size_t(k)]);
            got.insert({ r, P.col_indices[size_t(k)] });
            // Every code of the slot names this block, in increasing order.
            for (int c = P.slot_offsets[size_t(k)]; c < P.slot_offsets[size_t(k) + 1]; ++c) {
                const int code = P.slot_codes[size_t(c)], p = code / 16, a = (code / 4) % 4, b = code % 4;
                EXPECT_EQ(pairs[size_t(p)].vertices[a], r);
                EXPECT_EQ(pairs[size_t(p)].vertices[b], P.col_indices[size_t(k)]);
                if (c > P.slot_offsets[size_t(k)])
                    EXPECT_LT(P.slot_codes[size_t(c) - 1], code);
            }
        }
    EXPECT_EQ(got, expected);
    EXPECT_EQ(P.num_slots(), int(expected.size()));
    // Vertex 2 is in pairs 0 (slot 2), 1 (slot 3) and 3 (slot 0), in that order.
    const std::vector<int> codes(
        P.vertex_codes.begin() + P.vertex_offsets[2], P.vertex_codes.begin() + P.vertex_offsets[3]);
    EXPECT_EQ(codes, (std::vector<int> { 0 * 4 + 2, 1 * 4 + 3, 3 * 4 + 0 }));
    EXPECT_EQ(P.rows, (std::vector<int> { 0, 1, 2, 3, 4, 5, 6, 7 }));
    // Only the edge-edge pair has a mollifier threshold: 1e-3 |ea|^2 |eb|^2 at rest.
    EXPECT_EQ(P.eps_x[0], 0.0);
    EXPECT_GT(P.eps_x[1], 0.0);
    EXPECT_EQ(P.plane[2], 0);
    EXPECT_EQ(P.vertices[2 * 4 + 2], -1); // slot 2 of the vertex-plane pair
}

TEST(GpuBarrierPairs, EmptyListHasAnEmptyPattern)
{
    const gpu::BarrierPairs P = gpu::prepare_barrier_pairs(2, std::vector<double>(10, 0.0), 0, {});
    EXPECT_EQ(P.num_pairs, 0);
    EXPECT_EQ(P.num_slots(), 0);
    EXPECT_EQ(P.row_offsets, std::vector<int>(6, 0));
    EXPECT_TRUE(P.rows.empty());
}

TEST(GpuBarrierPairs, RejectsBadPairs)
{
    const std::vector<double> rest(8 * 3, 0.0);
    auto bad = [&](gpu::BarrierPair p, int dim = 3) {
        EXPECT_THROW(gpu::prepare_barrier_pairs(dim, std::vector<double>(size_t(8 * dim), 0.0), 1, { p }),
            std::invalid_argument);
    };
    bad({ 7, { 0, 1, 2, 3 }, -1 }); // unknown kind
    bad({ 1, { 0, 1, 2, 8 }, -1 }); // vertex out of range
    bad({ 1, { 0, 1, 2, -1 }, -1 }); // missing vertex
    bad({ 2, { 0, 1, 1, 3 }, -1 }); // repeated vertex
    bad({ 3, { 0, 1, -1, -1 }, 1 }); // plane out of range
    bad({ 1, { 0, 1, 2, 3 }, -1 }, 2); // vertex-face in 2D
    bad({ 2, { 0, 1, 2, 3 }, -1 }, 2); // edge-edge in 2D
    EXPECT_THROW(gpu::prepare_barrier_pairs(4, rest, 0, {}), std::invalid_argument);
    EXPECT_NO_THROW(gpu::prepare_barrier_pairs(2, std::vector<double>(16, 0.0), 1, { { 0, { 0, 1, 2, -1 }, -1 } }));
}
