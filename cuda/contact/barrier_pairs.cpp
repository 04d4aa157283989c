#include "cuda/contact/barrier_pairs.hpp"

#include "cuda/contact/pair_barrier.cuh"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    vec3 rest_point(const std::vector<double>& rest, int dim, int v)
    {
        const double* p = rest.data() + size_t(v) * size_t(dim);
        return vec3(p[0], p[1], dim == 3 ? p[2] : 0.0);
    }

    [[noreturn]] void bad_pair(size_t p, const std::string& why)
    {
        throw std::invalid_argument("BarrierPairs: pair " + std::to_string(p) + " " + why);
    }

} // namespace

void check_barrier_pair(int dim, int num_vertices, int num_planes, const BarrierPair& c, size_t p)
{
    if (c.kind < 0 || c.kind > 3)
        bad_pair(p, "has kind " + std::to_string(c.kind) + " (expected 0..3, as diffipc::ContactKind)");
    const ContactKind kind = ContactKind(c.kind);
    if (dim == 2 && (kind == ContactKind::VERTEX_FACE || kind == ContactKind::EDGE_EDGE))
        bad_pair(p, "is vertex-face or edge-edge in 2D");
    const int n = contact_num_vertices(kind);
    for (int a = 0; a < n; ++a) {
        const int v = c.vertices[a];
        if (v < 0 || v >= num_vertices)
            bad_pair(p, "has vertex " + std::to_string(v) + " out of range [0, " + std::to_string(num_vertices) + ")");
        for (int b = 0; b < a; ++b)
            if (c.vertices[b] == v)
                bad_pair(p, "repeats vertex " + std::to_string(v));
    }
    if (kind == ContactKind::VERTEX_PLANE && (c.plane < 0 || c.plane >= num_planes))
        bad_pair(p, "has plane " + std::to_string(c.plane) + " of " + std::to_string(num_planes));
}

BarrierPairs prepare_barrier_pairs(
    int dim, const std::vector<double>& rest_positions, int num_planes, const std::vector<BarrierPair>& pairs)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("BarrierPairs: dim must be 2 or 3, not " + std::to_string(dim));
    if (rest_positions.size() % size_t(dim) != 0)
        throw std::invalid_argument("BarrierPairs: rest_positions must hold #V * dim values");
    if (pairs.size() > size_t(INT_MAX / 16))
        throw std::invalid_argument("BarrierPairs: " + std::to_string(pairs.size()) + " pairs are more than "
            + std::to_string(INT_MAX / 16) + " (the incidence codes are ints)");
    const size_t np = pairs.size();
    const int nv = int(rest_positions.size() / size_t(dim));
    BarrierPairs out;
    out.dim = dim;
    out.num_vertices = nv;
    out.num_pairs = int(np);
    out.kind.resize(np);
    out.vertices.assign(4 * np, -1);
    out.plane.assign(np, -1);
    out.eps_x.assign(np, 0.0);
    for (size_t p = 0; p < np; ++p) {
        const BarrierPair& c = pairs[p];
        check_barrier_pair(dim, nv, num_planes, c, p);
        const ContactKind kind = ContactKind(c.kind);
        for (int a = 0; a < contact_num_vertices(kind); ++a)
            out.vertices[size_t(a) * np + p] = c.vertices[a];
        if (kind == ContactKind::VERTEX_PLANE)
            out.plane[p] = c.plane;
        if (kind == ContactKind::EDGE_EDGE)
            out.eps_x[p] = edge_edge_mollifier_threshold(rest_point(rest_positions, dim, c.vertices[0]),
                rest_point(rest_positions, dim, c.vertices[1]), rest_point(rest_positions, dim, c.vertices[2]),
                rest_point(rest_positions, dim, c.vertices[3]));
        out.kind[p] = c.kind;
    }

    // Gradient incidences: counting sort by vertex, codes increasing within a vertex.
    out.vertex_offsets.assign(size_t(nv) + 1, 0);
    for (size_t p = 0; p < np; ++p)
        for (int a = 0; a < 4; ++a) {
            const int v = out.vertices[size_t(a) * np + p];
            if (v >= 0)
                ++out.vertex_offsets[size_t(v) + 1];
        }
    for (int v = 0; v < nv; ++v)
        out.vertex_offsets[size_t(v) + 1] += out.vertex_offsets[size_t(v)];
    out.vertex_codes.resize(size_t(out.vertex_offsets.back()));
    {
        std::vector<int> fill(out.vertex_offsets.begin(), out.vertex_offsets.end() - 1);
        for (size_t p = 0; p < np; ++p)
            for (int a = 0; a < 4; ++a) {
                const int v = out.vertices[size_t(a) * np + p];
                if (v >= 0)
                    out.vertex_codes[size_t(fill[size_t(v)]++)] = int(p) * 4 + a;
            }
    }

    // Blocks: (row, column, code) for every local block, stably sorted by (row, column) so that
    // the codes of one block stay in increasing order.
    struct Entry {
        int64_t key;
        int code;
    };
    std::vector<Entry> entries;
    entries.reserve(out.vertex_codes.size() * 4);
    for (size_t p = 0; p < np; ++p)
        for (int a = 0; a < 4; ++a) {
            const int va = out.vertices[size_t(a) * np + p];
            if (va < 0)
                continue;
            for (int b = 0; b < 4; ++b) {
                const int vb = out.vertices[size_t(b) * np + p];
                if (vb >= 0)
                    entries.push_back({ int64_t(va) * nv + vb, int(p) * 16 + a * 4 + b });
            }
        }
    std::stable_sort(entries.begin(), entries.end(), [](const Entry& x, const Entry& y) { return x.key < y.key; });
    out.row_offsets.assign(size_t(nv) + 1, 0);
    out.slot_offsets.push_back(0);
    for (size_t k = 0; k < entries.size(); ++k) {
        if (k == 0 || entries[k].key != entries[k - 1].key) {
            if (k > 0)
                out.slot_offsets.push_back(int(out.slot_codes.size()));
            const int row = int(entries[k].key / nv), col = int(entries[k].key % nv);
            out.col_indices.push_back(col);
            ++out.row_offsets[size_t(row) + 1];
        }
        out.slot_codes.push_back(entries[k].code);
    }
    if (!entries.empty())
        out.slot_offsets.push_back(int(out.slot_codes.size()));
    for (int v = 0; v < nv; ++v) {
        if (out.row_offsets[size_t(v) + 1] > 0)
            out.rows.push_back(v);
        out.row_offsets[size_t(v) + 1] += out.row_offsets[size_t(v)];
    }
    return out;
}

} // namespace diffipc::gpu
