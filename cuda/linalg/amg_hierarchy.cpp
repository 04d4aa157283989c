#include "cuda/linalg/amg_hierarchy.hpp"

#include "cuda/linalg/amg_setup.hpp"

#include <algorithm>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace diffipc::gpu {

namespace {

    /// Rows [0, rows) of an output pattern: generate(row, add) calls add(column) for the row's candidate
    /// columns (repeats allowed); each row keeps them once, increasing. Chunks of rows run on up to
    /// max_threads threads into their own buffers, appended in row order: the result does not depend on
    /// the number of threads.
    template <typename Generate>
    BlockPattern emit_rows(int rows, int num_columns, int max_threads, const Generate& generate)
    {
        constexpr int ROWS_PER_CHUNK = 2048;
        const int chunks = (rows + ROWS_PER_CHUNK - 1) / ROWS_PER_CHUNK;
        std::vector<BlockPattern> parts(static_cast<size_t>(chunks));
        const auto run = [&](int first_chunk, int stride) {
            std::vector<int> stamp(size_t(num_columns), -1), columns;
            for (int c = first_chunk; c < chunks; c += stride) {
                BlockPattern& part = parts[size_t(c)];
                part.offsets.assign(1, 0);
                const int end = std::min(rows, (c + 1) * ROWS_PER_CHUNK);
                for (int r = c * ROWS_PER_CHUNK; r < end; ++r) {
                    columns.clear();
                    generate(r, [&](int column) {
                        if (stamp[size_t(column)] != r) {
                            stamp[size_t(column)] = r;
                            columns.push_back(column);
                        }
                    });
                    std::sort(columns.begin(), columns.end());
                    part.cols.insert(part.cols.end(), columns.begin(), columns.end());
                    part.offsets.push_back(int(part.cols.size()));
                }
            }
        };
        const int threads = std::max(1, std::min(chunks, max_threads));
        std::vector<std::thread> pool;
        std::exception_ptr failure;
        std::mutex failure_mutex;
        const auto guarded = [&](int first_chunk) {
            try {
                run(first_chunk, threads);
            } catch (...) {
                const std::lock_guard<std::mutex> lock(failure_mutex);
                failure = std::current_exception();
            }
        };
        for (int t = 1; t < threads && !failure; ++t)
            try {
                pool.emplace_back(guarded, t);
            } catch (...) { // no thread: the plan fails (its chunks are not built) after the others end
                const std::lock_guard<std::mutex> lock(failure_mutex);
                failure = std::current_exception();
            }
        guarded(0);
        for (std::thread& t : pool)
            t.join();
        if (failure)
            std::rethrow_exception(failure);
        BlockPattern out;
        out.offsets.assign(1, 0);
        out.offsets.reserve(size_t(rows) + 1);
        for (const BlockPattern& part : parts) {
            const int base = int(out.cols.size());
            out.cols.insert(out.cols.end(), part.cols.begin(), part.cols.end());
            for (size_t r = 1; r < part.offsets.size(); ++r)
                out.offsets.push_back(base + part.offsets[r]);
        }
        return out;
    }

    std::vector<int> diagonal_of(const BlockPattern& pattern, const char* who)
    {
        std::vector<int> diagonal(size_t(pattern.rows()), -1);
        for (int r = 0; r < pattern.rows(); ++r) {
            for (int k = pattern.offsets[size_t(r)]; k < pattern.offsets[size_t(r) + 1]; ++k)
                if (pattern.cols[size_t(k)] == r)
                    diagonal[size_t(r)] = k;
            if (diagonal[size_t(r)] < 0)
                throw std::invalid_argument(
                    std::string(who) + ": block row " + std::to_string(r) + " has no diagonal block");
        }
        return diagonal;
    }

    /// Fills a level's aggregation, T, P's, W's and the coarse pattern with their lists; returns the
    /// coarse pattern. `modes`: the near-null space per dof (k per dof).
    BlockPattern plan_level(
        AmgLevelPlan& level, int k, const std::vector<double>& modes, int threads, TentativeProlongator& t)
    {
        const BlockPattern& A = level.matrix;
        const int n = A.rows(), b = level.block;
        level.coarse_block = k;
        std::vector<char> excluded(size_t(n), 1);
        for (int v = 0; v < n; ++v)
            for (int i = 0; i < b; ++i)
                if (!level.fixed[size_t(v * b + i)])
                    excluded[size_t(v)] = 0;
        const Aggregation agg = aggregate_vertices(n, A.offsets, A.cols, excluded);
        level.aggregate_of = agg.aggregate_of;
        t = tentative_prolongator(agg, b, k, modes, level.fixed, threads);
        level.tentative = t.blocks;

        const int na = agg.num_aggregates;
        // P = the pattern of A T: (v, agg(w)) for the neighbours w of a non-excluded v.
        level.prolongator = emit_rows(n, na, threads, [&](int v, auto add) {
            if (excluded[size_t(v)])
                return;
            for (int e = A.offsets[size_t(v)]; e < A.offsets[size_t(v) + 1]; ++e) {
                const int a = agg.aggregate_of[size_t(A.cols[size_t(e)])];
                if (a >= 0)
                    add(a);
            }
        });
        // W = A P: (v, c) for c in P's row w, w a neighbour of v.
        const BlockPattern& P = level.prolongator;
        level.product = emit_rows(n, na, threads, [&](int v, auto add) {
            if (excluded[size_t(v)])
                return;
            for (int e = A.offsets[size_t(v)]; e < A.offsets[size_t(v) + 1]; ++e) {
                const int w = A.cols[size_t(e)];
                for (int f = P.offsets[size_t(w)]; f < P.offsets[size_t(w) + 1]; ++f)
                    add(P.cols[size_t(f)]);
            }
        });
        // P's columns (the restriction), v increasing; then the pattern of P^T W per aggregate.
        ProductList& R = level.restriction;
        R.offsets.assign(size_t(na) + 1, 0);
        for (const int a : P.cols)
            ++R.offsets[size_t(a) + 1];
        for (int a = 0; a < na; ++a)
            R.offsets[size_t(a) + 1] += R.offsets[size_t(a)];
        R.first.assign(P.cols.size(), 0);
        R.second.assign(P.cols.size(), 0);
        std::vector<int> fill(R.offsets.begin(), R.offsets.end() - 1);
        for (int v = 0; v < n; ++v)
            for (int f = P.offsets[size_t(v)]; f < P.offsets[size_t(v) + 1]; ++f) {
                const int slot = fill[size_t(P.cols[size_t(f)])]++;
                R.first[size_t(slot)] = f;
                R.second[size_t(slot)] = v;
            }
        const BlockPattern& W = level.product;
        BlockPattern coarse = emit_rows(na, na, threads, [&](int a, auto add) {
            for (int s = R.offsets[size_t(a)]; s < R.offsets[size_t(a) + 1]; ++s) {
                const int v = R.second[size_t(s)];
                for (int g = W.offsets[size_t(v)]; g < W.offsets[size_t(v) + 1]; ++g)
                    add(W.cols[size_t(g)]);
            }
        });
        return coarse;
    }

} // namespace

AmgPlan plan_amg(int block, const BlockPattern& pattern, const std::vector<double>& positions,
    const std::vector<char>& fixed, const AmgPlanSettings& settings)
{
    const int n = pattern.rows();
    if (block != 2 && block != 3)
        throw std::invalid_argument("plan_amg: block size " + std::to_string(block) + " (2 or 3)");
    if (n < 0 || pattern.offsets.empty() || pattern.offsets.front() != 0
        || size_t(pattern.offsets.back()) != pattern.cols.size() || positions.size() != size_t(n) * size_t(block)
        || (!fixed.empty() && fixed.size() != positions.size()))
        throw std::invalid_argument("plan_amg: the pattern, " + std::to_string(positions.size()) + " positions and "
            + std::to_string(fixed.size()) + " fixed flags do not fit " + std::to_string(n) + " block rows of size "
            + std::to_string(block));
    for (int r = 0; r < n; ++r)
        if (pattern.offsets[size_t(r) + 1] < pattern.offsets[size_t(r)])
            throw std::invalid_argument("plan_amg: row offsets decrease at block row " + std::to_string(r));
    for (const int c : pattern.cols)
        if (c < 0 || c >= n)
            throw std::invalid_argument("plan_amg: column index " + std::to_string(c) + " out of range");
    if (settings.max_coarsest_dofs < 1 || settings.max_levels < 0 || settings.threads < 0)
        throw std::invalid_argument("plan_amg: max_coarsest_dofs must be >= 1, max_levels and threads >= 0");

    AmgPlan plan;
    const int threads = settings.threads > 0 ? settings.threads
                                             : int(std::min(16u, std::max(1u, std::thread::hardware_concurrency())));
    const int k = block == 2 ? 3 : 6;
    BlockPattern current = pattern;
    std::vector<char> current_fixed = fixed.empty() ? std::vector<char>(positions.size(), 0) : fixed;
    int b = block;
    // Rotations about the centroid (the per-aggregate orthonormalization makes the choice immaterial
    // in exact arithmetic; the centroid keeps the columns' scales alike).
    double center[3] = { 0, 0, 0 };
    for (int v = 0; v < n; ++v)
        for (int i = 0; i < block; ++i)
            center[i] += positions[size_t(v * block + i)] / double(n);
    std::vector<double> modes = rigid_body_modes(block, positions, center);
    while (current.rows() * b > settings.max_coarsest_dofs && int(plan.levels.size()) < settings.max_levels) {
        AmgLevelPlan level;
        level.block = b;
        level.matrix = current;
        level.diagonal = diagonal_of(current, "plan_amg");
        level.fixed = current_fixed;
        TentativeProlongator t;
        BlockPattern coarse = plan_level(level, k, modes, threads, t);
        // A level that barely coarsens (a dense graph) would only cost time: stop above it.
        if (t.num_aggregates == 0 || double(t.num_aggregates) * k > 0.75 * double(current.rows()) * b)
            break;
        current = std::move(coarse);
        b = k;
        current_fixed.assign(size_t(t.num_aggregates) * size_t(k), 0);
        for (size_t c = 0; c < current_fixed.size(); ++c)
            current_fixed[c] = t.coarse_active[c] ? 0 : 1;
        modes = t.coarse_modes; // aggregate a's R_a: (a k + i) k + j, the fine-mode layout
        plan.levels.push_back(std::move(level));
    }
    plan.coarsest_block = b;
    plan.coarsest = std::move(current);
    plan.coarsest_fixed = std::move(current_fixed);
    diagonal_of(plan.coarsest, "plan_amg"); // checks the coarsest's diagonal too
    return plan;
}

} // namespace diffipc::gpu
