#include "cuda/linalg/amg_setup.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

namespace diffipc::gpu {

namespace {

    void check_pattern(int num_vertices, const std::vector<int>& row_offsets, const std::vector<int>& col_indices,
        const std::vector<char>& excluded)
    {
        if (num_vertices < 0 || row_offsets.size() != size_t(num_vertices) + 1 || row_offsets.front() != 0
            || size_t(row_offsets.back()) != col_indices.size())
            throw std::invalid_argument("aggregate_vertices: the row offsets do not fit " + std::to_string(num_vertices)
                + " vertices and " + std::to_string(col_indices.size()) + " column indices");
        for (int v = 0; v < num_vertices; ++v)
            if (row_offsets[size_t(v) + 1] < row_offsets[size_t(v)])
                throw std::invalid_argument("aggregate_vertices: row offsets decrease at vertex " + std::to_string(v));
        for (const int c : col_indices)
            if (c < 0 || c >= num_vertices)
                throw std::invalid_argument("aggregate_vertices: column index " + std::to_string(c) + " out of range");
        if (!excluded.empty() && excluded.size() != size_t(num_vertices))
            throw std::invalid_argument("aggregate_vertices: " + std::to_string(excluded.size())
                + " exclusion flags for " + std::to_string(num_vertices) + " vertices");
    }

} // namespace

Aggregation aggregate_vertices(int num_vertices, const std::vector<int>& row_offsets,
    const std::vector<int>& col_indices, const std::vector<char>& excluded)
{
    check_pattern(num_vertices, row_offsets, col_indices, excluded);
    const auto is_excluded = [&](int v) { return !excluded.empty() && excluded[size_t(v)] != 0; };
    Aggregation a;
    a.aggregate_of.assign(size_t(num_vertices), -1);
    std::vector<int>& of = a.aggregate_of;
    // Phase 1: a vertex whose neighbourhood is all free becomes an aggregate with its neighbours.
    for (int v = 0; v < num_vertices; ++v) {
        if (is_excluded(v) || of[size_t(v)] >= 0)
            continue;
        bool free = true;
        for (int k = row_offsets[size_t(v)]; free && k < row_offsets[size_t(v) + 1]; ++k) {
            const int u = col_indices[size_t(k)];
            free = is_excluded(u) || of[size_t(u)] < 0;
        }
        if (!free)
            continue;
        const int id = a.num_aggregates++;
        of[size_t(v)] = id;
        for (int k = row_offsets[size_t(v)]; k < row_offsets[size_t(v) + 1]; ++k) {
            const int u = col_indices[size_t(k)];
            if (!is_excluded(u))
                of[size_t(u)] = id;
        }
    }
    // Phase 2: a left-over vertex joins the aggregate of its first neighbour (in column order) that
    // phase 1 placed; the phase's own assignments do not propagate.
    const std::vector<int> first = of;
    for (int v = 0; v < num_vertices; ++v) {
        if (is_excluded(v) || first[size_t(v)] >= 0)
            continue;
        for (int k = row_offsets[size_t(v)]; k < row_offsets[size_t(v) + 1]; ++k) {
            const int u = col_indices[size_t(k)];
            if (first[size_t(u)] >= 0) {
                of[size_t(v)] = first[size_t(u)];
                break;
            }
        }
    }
    // Phase 3: what remains forms aggregates with its still free neighbours.
    for (int v = 0; v < num_vertices; ++v) {
        if (is_excluded(v) || of[size_t(v)] >= 0)
            continue;
        const int id = a.num_aggregates++;
        of[size_t(v)] = id;
        for (int k = row_offsets[size_t(v)]; k < row_offsets[size_t(v) + 1]; ++k) {
            const int u = col_indices[size_t(k)];
            if (!is_excluded(u) && of[size_t(u)] < 0)
                of[size_t(u)] = id;
        }
    }
    return a;
}

std::vector<double> rigid_body_modes(int dim, const std::vector<double>& positions, const double* center)
{
    if ((dim != 2 && dim != 3) || positions.size() % size_t(dim) != 0)
        throw std::invalid_argument("rigid_body_modes: " + std::to_string(positions.size()) + " position entries in "
            + std::to_string(dim) + "D");
    const int k = dim == 2 ? 3 : 6;
    const size_t nv = positions.size() / size_t(dim);
    std::vector<double> modes(positions.size() * size_t(k), 0.0);
    for (size_t v = 0; v < nv; ++v) {
        double p[3] = { 0, 0, 0 };
        for (int i = 0; i < dim; ++i)
            p[i] = positions[v * size_t(dim) + size_t(i)] - (center ? center[i] : 0.0);
        double* row[3];
        for (int i = 0; i < dim; ++i)
            row[i] = modes.data() + (v * size_t(dim) + size_t(i)) * size_t(k);
        for (int i = 0; i < dim; ++i)
            row[i][i] = 1; // translations
        if (dim == 2) { // the rotation (-y, x)
            row[0][2] = -p[1];
            row[1][2] = p[0];
        } else { // rotations about x, y, z: e_a x p
            row[1][3] = -p[2];
            row[2][3] = p[1];
            row[0][4] = p[2];
            row[2][4] = -p[0];
            row[0][5] = -p[1];
            row[1][5] = p[0];
        }
    }
    return modes;
}

TentativeProlongator tentative_prolongator(const Aggregation& aggregation, int dim, int modes,
    const std::vector<double>& fine_modes, const std::vector<char>& fixed, int threads)
{
    const size_t nv = aggregation.aggregate_of.size(), n = nv * size_t(dim);
    if (dim < 1 || modes < 1 || fine_modes.size() != n * size_t(modes) || (!fixed.empty() && fixed.size() != n))
        throw std::invalid_argument("tentative_prolongator: " + std::to_string(fine_modes.size()) + " mode values and "
            + std::to_string(fixed.size()) + " fixed flags for " + std::to_string(nv) + " vertices in "
            + std::to_string(dim) + "D with " + std::to_string(modes) + " modes");
    const int na = aggregation.num_aggregates;
    const size_t k = size_t(modes), d = size_t(dim);
    TentativeProlongator t;
    t.dim = dim;
    t.modes = modes;
    t.num_aggregates = na;
    t.blocks.assign(n * k, 0.0);
    t.coarse_modes.assign(size_t(na) * k * k, 0.0);
    t.coarse_active.assign(size_t(na) * k, 1);
    // Each aggregate's vertices in increasing order.
    std::vector<int> offsets(size_t(na) + 1, 0), members(nv);
    for (const int a : aggregation.aggregate_of) {
        if (a >= na)
            throw std::invalid_argument("tentative_prolongator: aggregate " + std::to_string(a) + " out of range");
        if (a >= 0)
            ++offsets[size_t(a) + 1];
    }
    for (int a = 0; a < na; ++a)
        offsets[size_t(a) + 1] += offsets[size_t(a)];
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (size_t v = 0; v < nv; ++v)
        if (aggregation.aggregate_of[v] >= 0)
            members[size_t(fill[size_t(aggregation.aggregate_of[v])]++)] = int(v);
    // The fine modes, fixed rows zeroed, copied into T's blocks; then Gram-Schmidt per aggregate in place.
    for (size_t r = 0; r < n; ++r)
        if (aggregation.aggregate_of[r / d] >= 0 && (fixed.empty() || !fixed[r]))
            for (size_t j = 0; j < k; ++j)
                t.blocks[r * k + j] = fine_modes[r * k + j];
    constexpr double TOLERANCE = 1e-10; // of a column's norm before orthogonalization
    // Each aggregate's rows, R and flags are its own: chunks of aggregates run on their own threads with
    // the same arithmetic, so the result does not depend on the number of threads.
    const auto factorize = [&](int a) {
        const auto rows = [&](auto visit) {
            for (int m = offsets[size_t(a)]; m < offsets[size_t(a) + 1]; ++m)
                for (size_t i = 0; i < d; ++i)
                    visit(size_t(members[size_t(m)]) * d + i);
        };
        double* R = t.coarse_modes.data() + size_t(a) * k * k;
        for (size_t j = 0; j < k; ++j) {
            double original = 0;
            rows([&](size_t r) { original += t.blocks[r * k + j] * t.blocks[r * k + j]; });
            original = std::sqrt(original);
            for (int pass = 0; pass < 2; ++pass)
                for (size_t l = 0; l < j; ++l) {
                    if (!t.coarse_active[size_t(a) * k + l])
                        continue;
                    double dot = 0;
                    rows([&](size_t r) { dot += t.blocks[r * k + l] * t.blocks[r * k + j]; });
                    rows([&](size_t r) { t.blocks[r * k + j] -= dot * t.blocks[r * k + l]; });
                    R[l * k + j] += dot;
                }
            double norm = 0;
            rows([&](size_t r) { norm += t.blocks[r * k + j] * t.blocks[r * k + j]; });
            norm = std::sqrt(norm);
            if (!(norm > TOLERANCE * original)) {
                t.coarse_active[size_t(a) * k + j] = 0;
                rows([&](size_t r) { t.blocks[r * k + j] = 0; });
                continue;
            }
            R[j * k + j] = norm;
            rows([&](size_t r) { t.blocks[r * k + j] /= norm; });
        }
    };
    // Worker w factorizes the aggregates [w na / workers, (w + 1) na / workers); the calling thread takes
    // chunk 0 and any chunk whose thread could not be started.
    const int workers = std::max(1, std::min(threads > 0 ? threads : 1, (na + 255) / 256));
    const auto chunk = [&](int w) {
        for (int a = int(long(w) * na / workers); a < int(long(w + 1) * na / workers); ++a)
            factorize(a);
    };
    std::vector<std::thread> pool;
    int started = 1;
    for (; started < workers; ++started)
        try {
            pool.emplace_back(chunk, started);
        } catch (...) {
            break;
        }
    chunk(0);
    for (int w = started; w < workers; ++w)
        chunk(w);
    for (std::thread& worker : pool)
        worker.join();
    return t;
}

} // namespace diffipc::gpu
