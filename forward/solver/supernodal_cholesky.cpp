#include "forward/solver/supernodal_cholesky.hpp"

#include "forward/common/threads.hpp"

#include <cholmod.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <vector>

extern "C" {
void dgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k, const double* alpha,
    const double* a, const int* lda, const double* b, const int* ldb, const double* beta, double* c, const int* ldc);
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha, const double* a,
    const int* lda, const double* beta, double* c, const int* ldc);
void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m, const int* n,
    const double* alpha, const double* a, const int* lda, double* b, const int* ldb);
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info);
void dtrsv_(const char* uplo, const char* trans, const char* diag, const int* n, const double* a, const int* lda,
    double* x, const int* incx);
void dgemv_(const char* trans, const int* m, const int* n, const double* alpha, const double* a, const int* lda,
    const double* x, const int* incx, const double* beta, double* y, const int* incy);
}

namespace diffipc {

namespace {

    // Tile sizes of a large supernode. Fixed (not derived from the thread count), so that
    // the operations, and their rounding, are the same for any number of threads.
    constexpr int COLUMN_BLOCK = 64;
    constexpr int ROW_BLOCK = 256;
    /// A supernode whose work exceeds this many flops splits it into tiles.
    constexpr double TILED_FLOPS = 2e7;

    const double ONE = 1, ZERO = 0, MINUS_ONE = -1;

    /// C (m x n, leading dimension ldc) = A B^T, A m x k, B n x k (column-major).
    void gemm_nt(int m, int n, int k, const double* a, int lda, const double* b, int ldb, double* c, int ldc)
    {
        dgemm_("N", "T", &m, &n, &k, &ONE, a, &lda, b, &ldb, &ZERO, c, &ldc);
    }

    /// C -= A B^T in place.
    void gemm_nt_sub(int m, int n, int k, const double* a, int lda, const double* b, int ldb, double* c, int ldc)
    {
        dgemm_("N", "T", &m, &n, &k, &MINUS_ONE, a, &lda, b, &ldb, &ONE, c, &ldc);
    }

    /// Solves X L^T = B for X in place (B m x n, L n x n lower).
    void trsm_right_lower_t(int m, int n, const double* l, int ldl, double* b, int ldb)
    {
        dtrsm_("R", "L", "T", "N", &m, &n, &ONE, l, &ldl, b, &ldb);
    }

    struct Workspace {
        /// factor_supernode: global row -> local row of its supernode (n entries);
        /// a tile: local rows of the descendant rows it updates
        std::vector<int> map;
        std::vector<double> c; ///< update matrix
    };

    /// A descendant d whose rows p1..p2 (offsets into its row list) are columns of supernode s.
    struct Update {
        int d, p1, p2;
    };

} // namespace

struct SupernodalCholesky::Impl {
    cholmod_common common;
    cholmod_factor* factor = nullptr;
    Index n = 0;
    int nsuper = 0;
    const int* super = nullptr; // first column of each supernode (nsuper + 1)
    const int* lpi = nullptr; // row-index pointers
    const int* lpx = nullptr; // value pointers
    const int* ls = nullptr; // row indices
    std::vector<int> parent; // supernodal elimination tree
    std::vector<int> children_count;
    std::vector<int> leaves, roots;
    std::vector<int> children_ptr, children; // children of s: children[children_ptr[s] .. children_ptr[s+1])
    std::vector<int> below_ptr; // forward solve: L21 x_s of supernode s at below[below_ptr[s] ..]
    std::vector<int> update_ptr; // updates of supernode s: updates[update_ptr[s] .. update_ptr[s+1])
    std::vector<Update> updates;
    std::vector<char> tiled;
    // Assembly of A: entry k of A's values goes to value assembly_offset[e] of supernode s,
    // for e in assembly_ptr[s] .. assembly_ptr[s+1], k = assembly_entry[e].
    std::vector<int> assembly_ptr, assembly_entry, assembly_offset;
    std::vector<int> assembled_outer, assembled_inner; // the pattern the assembly map is for
    std::vector<int> pinv;
    std::vector<int> supermap; // column -> supernode
    tbb::enumerable_thread_specific<Workspace> workspaces;
    std::atomic<Index> minor { 0 };
    Statistics stats;

    Impl()
    {
        cholmod_start(&common);
        common.print = 0;
        common.supernodal = CHOLMOD_SUPERNODAL;
    }
    ~Impl()
    {
        if (factor)
            cholmod_free_factor(&factor, &common);
        cholmod_finish(&common);
    }

    int nscol(int s) const { return super[s + 1] - super[s]; }
    int nsrow(int s) const { return lpi[s + 1] - lpi[s]; }
    double* values(int s) const { return static_cast<double*>(factor->x) + lpx[s]; }
    const int* rows(int s) const { return ls + lpi[s]; }

    void build_schedule();
    /// Runs f(s) for every supernode after f ran for all its children (independent subtrees
    /// concurrently): each leaf starts a chain, and a supernode runs on the thread that
    /// finished its last child.
    template <typename F> void bottom_up(const F& f) const;
    /// Runs f(s) for every supernode after f ran for its parent.
    template <typename F> void top_down(const F& f) const;
    void build_assembly(const SparseMatrixd& lower);
    void factor_supernode(int s, const double* a);
    void factor_supernode_tiled(int s, const double* a);
    /// The solves with a supernode by column blocks: L y_s = y_s and below = L21 y_s
    /// (forward); y_s -= L21^T g (g: the solution at the rows below, or null) and
    /// L^T y_s = y_s (backward). The updates of each block step run concurrently.
    void forward_blocked(int s, double* ys, double* below) const;
    /// Whether the solves with s go by column blocks: a tiled supernode at least 4 blocks wide,
    /// where the chain of diagonal blocks is long enough to pay for the steps' tasks.
    bool blocked_solve(int s) const { return tiled[size_t(s)] && nscol(s) >= 4 * COLUMN_BLOCK; }
    void backward_blocked(int s, double* ys, const double* g) const;
    void fail(Index column)
    {
        Index m = minor.load();
        while (column < m && !minor.compare_exchange_weak(m, column)) { }
    }
    bool failed() const { return minor.load(std::memory_order_relaxed) < n; }
};

SupernodalCholesky::SupernodalCholesky()
    : m_impl(std::make_unique<Impl>())
{
}
SupernodalCholesky::~SupernodalCholesky() = default;

bool SupernodalCholesky::analyzed() const { return m_impl->factor != nullptr; }
Index SupernodalCholesky::minor_column() const { return m_impl->minor.load(); }
const SupernodalCholesky::Statistics& SupernodalCholesky::statistics() const { return m_impl->stats; }

namespace {
    cholmod_sparse view_lower(const SparseMatrixd& lower)
    {
        cholmod_sparse a {};
        a.nrow = size_t(lower.rows());
        a.ncol = size_t(lower.cols());
        a.nzmax = size_t(lower.nonZeros());
        a.p = const_cast<int*>(lower.outerIndexPtr());
        a.i = const_cast<int*>(lower.innerIndexPtr());
        a.x = const_cast<double*>(lower.valuePtr());
        a.stype = -1;
        a.itype = CHOLMOD_INT;
        a.xtype = CHOLMOD_REAL;
        a.dtype = CHOLMOD_DOUBLE;
        a.sorted = 1;
        a.packed = 1;
        return a;
    }
} // namespace

void SupernodalCholesky::analyze(const SparseMatrixd& lower)
{
    Impl& m = *m_impl;
    if (!lower.isCompressed())
        throw std::invalid_argument("SupernodalCholesky: the matrix must be compressed");
    if (m.factor)
        cholmod_free_factor(&m.factor, &m.common);
    cholmod_sparse a = view_lower(lower);
    m.factor = cholmod_analyze(&a, &m.common);
    if (!m.factor || m.common.status < CHOLMOD_OK)
        throw std::runtime_error("CHOLMOD's symbolic analysis failed (status " + std::to_string(m.common.status) + ")");
    if (!m.factor->is_super)
        throw std::logic_error("CHOLMOD's analysis did not give a supernodal factor");
    m.n = lower.rows();
    m.minor = m.n;
    m.nsuper = int(m.factor->nsuper);
    m.super = static_cast<const int*>(m.factor->super);
    m.lpi = static_cast<const int*>(m.factor->pi);
    m.lpx = static_cast<const int*>(m.factor->px);
    m.ls = static_cast<const int*>(m.factor->s);
    const int* perm = static_cast<const int*>(m.factor->Perm);
    m.pinv.assign(size_t(m.n), 0);
    for (Index k = 0; k < m.n; ++k)
        m.pinv[size_t(perm[k])] = int(k);
    m.build_schedule();
    m.assembled_outer.clear();
    m.assembled_inner.clear();
}

void SupernodalCholesky::Impl::build_schedule()
{
    supermap.assign(size_t(n), 0);
    for (int s = 0; s < nsuper; ++s) {
        for (int j = super[s]; j < super[s + 1]; ++j)
            supermap[size_t(j)] = s;
        // The binary searches below need each supernode's rows sorted (CHOLMOD sorts them).
        const int* r = rows(s);
        if (!std::is_sorted(r, r + nsrow(s)) || r[0] != super[s])
            throw std::logic_error("CHOLMOD's supernodal pattern is not sorted");
    }
    parent.assign(size_t(nsuper), -1);
    children_count.assign(size_t(nsuper), 0);
    update_ptr.assign(size_t(nsuper) + 1, 0);
    // Pass 1 counts the updates of each supernode, pass 2 stores them (ordered by descendant).
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<int> fill;
        if (pass == 1) {
            for (int s = 0; s < nsuper; ++s)
                update_ptr[size_t(s) + 1] += update_ptr[size_t(s)];
            updates.resize(size_t(update_ptr[size_t(nsuper)]));
            fill.assign(update_ptr.begin(), update_ptr.end() - 1);
        }
        for (int d = 0; d < nsuper; ++d) {
            const int* r = rows(d);
            const int ndrow = nsrow(d);
            for (int p = nscol(d); p < ndrow;) {
                const int s = supermap[size_t(r[p])];
                int p2 = p;
                while (p2 < ndrow && r[p2] < super[s + 1])
                    ++p2;
                if (pass == 0)
                    ++update_ptr[size_t(s) + 1];
                else
                    updates[size_t(fill[size_t(s)]++)] = { d, p, p2 };
                p = p2;
            }
        }
    }
    leaves.clear();
    stats = {};
    stats.supernodes = nsuper;
    stats.factor_entries = double(factor->xsize);
    tiled.assign(size_t(nsuper), 0);
    for (int s = 0; s < nsuper; ++s) {
        const int k = nscol(s), m = nsrow(s);
        if (m > k) {
            parent[size_t(s)] = supermap[size_t(rows(s)[k])];
            ++children_count[size_t(parent[size_t(s)])];
        }
        double flops = double(k) * k * k / 3 + double(m - k) * k * k;
        for (int u = update_ptr[size_t(s)]; u < update_ptr[size_t(s) + 1]; ++u) {
            const Update& up = updates[size_t(u)];
            const double n1 = up.p2 - up.p1, n2 = nsrow(up.d) - up.p1;
            flops += double(nscol(up.d)) * n1 * (2 * n2 - n1);
        }
        stats.flops += flops;
        tiled[size_t(s)] = flops > TILED_FLOPS;
        stats.tiled_supernodes += tiled[size_t(s)];
    }
    roots.clear();
    children_ptr.assign(size_t(nsuper) + 1, 0);
    below_ptr.assign(size_t(nsuper) + 1, 0);
    for (int s = 0; s < nsuper; ++s) {
        if (children_count[size_t(s)] == 0)
            leaves.push_back(s);
        if (parent[size_t(s)] < 0)
            roots.push_back(s);
        children_ptr[size_t(s) + 1] = children_ptr[size_t(s)] + children_count[size_t(s)];
        below_ptr[size_t(s) + 1] = below_ptr[size_t(s)] + nsrow(s) - nscol(s);
    }
    children.resize(size_t(children_ptr[size_t(nsuper)]));
    std::vector<int> fill(children_ptr.begin(), children_ptr.end() - 1);
    for (int s = 0; s < nsuper; ++s)
        if (parent[size_t(s)] >= 0)
            children[size_t(fill[size_t(parent[size_t(s)])]++)] = s;
}

template <typename F> void SupernodalCholesky::Impl::bottom_up(const F& f) const
{
    std::vector<std::atomic<int>> pending(static_cast<size_t>(nsuper));
    for (int s = 0; s < nsuper; ++s)
        pending[size_t(s)].store(children_count[size_t(s)], std::memory_order_relaxed);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i < range.end(); ++i)
            for (int s = leaves[i]; s >= 0;) {
                f(s);
                const int p = parent[size_t(s)];
                if (p < 0 || pending[size_t(p)].fetch_sub(1, std::memory_order_acq_rel) != 1)
                    break;
                s = p;
            }
    });
}

template <typename F> void SupernodalCholesky::Impl::top_down(const F& f) const
{
    // No recursion: a tree of 31,000 levels (a long thin mesh) overflowed the stack when
    // every branching node nested a parallel loop. A task follows its first child in a loop
    // and hands the others to the task group; tasks do not nest.
    tbb::task_group group;
    const auto visit = [&](const auto& self, int s) -> void {
        while (true) {
            f(s);
            const int first = children_ptr[size_t(s)], end = children_ptr[size_t(s) + 1];
            if (first == end)
                return;
            for (int c = first + 1; c < end; ++c) {
                const int child = children[size_t(c)];
                group.run([&self, child] { self(self, child); });
            }
            s = children[size_t(first)];
        }
    };
    for (const int root : roots)
        group.run([&visit, root] { visit(visit, root); });
    group.wait();
}

void SupernodalCholesky::Impl::build_assembly(const SparseMatrixd& lower)
{
    const int* op = lower.outerIndexPtr();
    const int* ip = lower.innerIndexPtr();
    const size_t nnz = size_t(lower.nonZeros());
    std::vector<int> target(nnz), offset(nnz);
    tbb::parallel_for(tbb::blocked_range<Index>(0, lower.cols(), 256), [&](const tbb::blocked_range<Index>& range) {
        for (Index c = range.begin(); c < range.end(); ++c)
            for (int k = op[c]; k < op[c + 1]; ++k) {
                if (ip[k] < c)
                    throw std::invalid_argument("SupernodalCholesky: entry above the diagonal");
                const int i = pinv[size_t(ip[k])], j = pinv[size_t(c)];
                const int col = std::min(i, j), row = std::max(i, j);
                const int s = supermap[size_t(col)];
                const int* r = rows(s);
                const int* at = std::lower_bound(r, r + nsrow(s), row);
                if (at == r + nsrow(s) || *at != row)
                    throw std::invalid_argument("SupernodalCholesky: the matrix is outside the analyzed pattern");
                target[size_t(k)] = s;
                offset[size_t(k)] = (col - super[s]) * nsrow(s) + int(at - r);
            }
    });
    assembly_ptr.assign(size_t(nsuper) + 1, 0);
    for (size_t k = 0; k < nnz; ++k)
        ++assembly_ptr[size_t(target[k]) + 1];
    for (int s = 0; s < nsuper; ++s)
        assembly_ptr[size_t(s) + 1] += assembly_ptr[size_t(s)];
    assembly_entry.resize(nnz);
    assembly_offset.resize(nnz);
    std::vector<int> fill(assembly_ptr.begin(), assembly_ptr.end() - 1);
    for (size_t k = 0; k < nnz; ++k) {
        const int e = fill[size_t(target[k])]++;
        assembly_entry[size_t(e)] = int(k);
        assembly_offset[size_t(e)] = offset[k];
    }
    assembled_outer.assign(op, op + lower.cols() + 1);
    assembled_inner.assign(ip, ip + nnz);
}

void SupernodalCholesky::Impl::factor_supernode(int s, const double* a)
{
    const int k1 = super[s], ncol = nscol(s), nrow = nsrow(s);
    double* x = values(s);
    std::fill(x, x + size_t(ncol) * size_t(nrow), 0.0);
    for (int e = assembly_ptr[size_t(s)]; e < assembly_ptr[size_t(s) + 1]; ++e)
        x[assembly_offset[size_t(e)]] = a[assembly_entry[size_t(e)]];

    Workspace& w = workspaces.local();
    if (w.map.size() < size_t(n))
        w.map.resize(size_t(n));
    const int* r = rows(s);
    for (int i = 0; i < nrow; ++i)
        w.map[size_t(r[i])] = i;
    for (int u = update_ptr[size_t(s)]; u < update_ptr[size_t(s) + 1]; ++u) {
        const Update& up = updates[size_t(u)];
        const int ndrow = nsrow(up.d), ndcol = nscol(up.d);
        const int n1 = up.p2 - up.p1, n2 = ndrow - up.p1;
        const double* ld = values(up.d);
        const int* rd = rows(up.d);
        if (w.c.size() < size_t(n1) * size_t(n2))
            w.c.resize(size_t(n1) * size_t(n2));
        double* c = w.c.data();
        dsyrk_("L", "N", &n1, &ndcol, &ONE, ld + up.p1, &ndrow, &ZERO, c, &n2);
        if (n2 > n1)
            gemm_nt(n2 - n1, n1, ndcol, ld + up.p2, ndrow, ld + up.p1, ndrow, c + n1, n2);
        for (int jj = 0; jj < n1; ++jj) {
            double* column = x + size_t(rd[up.p1 + jj] - k1) * size_t(nrow);
            const double* cj = c + size_t(jj) * size_t(n2);
            for (int ii = jj; ii < n2; ++ii)
                column[w.map[size_t(rd[up.p1 + ii])]] -= cj[ii];
        }
    }
    int info = 0;
    dpotrf_("L", &ncol, x, &nrow, &info);
    if (info != 0) {
        fail(k1 + info - 1);
        return;
    }
    if (nrow > ncol)
        trsm_right_lower_t(nrow - ncol, ncol, x, nrow, x + ncol, nrow);
}

void SupernodalCholesky::Impl::factor_supernode_tiled(int s, const double* a)
{
    // A graph of tile tasks, with no barrier between the steps of the blocked algorithm: the
    // chain of diagonal factorizations, which decides the time on many threads, advances as
    // soon as its own inputs are ready.
    //
    // Column blocks of B = COLUMN_BLOCK columns; row blocks of B rows over the supernode's
    // columns (so the diagonal tiles are square) and of ROW_BLOCK rows below them (fewer,
    // larger BLAS calls where no diagonal waits). Tile (i, j), i >= j, goes through stages
    // 0, 1, ..., j:
    // - stage k < j subtracts L(i, k) L(j, k)^T (syrk on a diagonal tile);
    // - stage j factors it: potrf on a diagonal tile, trsm with L(j, j) otherwise.
    // A stage runs when the previous stage of its tile is done (for stage 0: the
    // descendants' updates of its rows and columns, which run on update tiles of one column
    // block and about ROW_BLOCK rows, so that each one finds its descendants' rows once for
    // several tiles) and the tiles it reads are final. Each tile takes the same BLAS calls in the same order for any
    // thread count, so the factor does not depend on it.
    const int k1 = super[s], ncol = nscol(s), nrow = nsrow(s);
    double* x = values(s);
    const int* r = rows(s);
    tbb::parallel_for(tbb::blocked_range<int>(0, ncol, 16), [&](const tbb::blocked_range<int>& range) {
        std::fill(x + size_t(range.begin()) * size_t(nrow), x + size_t(range.end()) * size_t(nrow), 0.0);
    });
    for (int e = assembly_ptr[size_t(s)]; e < assembly_ptr[size_t(s) + 1]; ++e)
        x[assembly_offset[size_t(e)]] = a[assembly_entry[size_t(e)]];

    constexpr int B = COLUMN_BLOCK;
    const int ncb = (ncol + B - 1) / B, nrb = ncb + (nrow - ncol + ROW_BLOCK - 1) / ROW_BLOCK;
    const auto row_start = [&](int i) { return i < ncb ? i * B : ncol + (i - ncb) * ROW_BLOCK; };
    const auto row_end = [&](int i) {
        return i < ncb ? std::min((i + 1) * B, ncol) : std::min(ncol + (i - ncb + 1) * ROW_BLOCK, nrow);
    };
    const auto column_width = [&](int j) { return std::min((j + 1) * B, ncol) - j * B; };
    const auto at = [&](int i, int j) { return x + size_t(j) * B * size_t(nrow) + size_t(row_start(i)); };
    // Column j's tiles are rows j .. nrb - 1; tile t = (i, j) has its stage counters at
    // pending[stage_base[t] ..]: what each stage still waits for.
    std::vector<int> column_base(size_t(ncb) + 1, 0);
    for (int j = 0; j < ncb; ++j)
        column_base[size_t(j) + 1] = column_base[size_t(j)] + nrb - j;
    const auto tile_index = [&](int i, int j) { return column_base[size_t(j)] + i - j; };
    std::vector<int> stage_base(size_t(column_base[size_t(ncb)]) + 1, 0);
    for (int j = 0; j < ncb; ++j)
        for (int i = j; i < nrb; ++i)
            stage_base[size_t(tile_index(i, j)) + 1] = stage_base[size_t(tile_index(i, j))] + j + 1;
    std::vector<std::atomic<int>> pending(size_t(stage_base.back()));
    for (int j = 0; j < ncb; ++j)
        for (int i = j; i < nrb; ++i) {
            const int base = stage_base[size_t(tile_index(i, j))];
            // Each stage waits for the stage before (stage 0: the descendants' updates), and
            // for its sources: L(i, k) and L(j, k) at stage k < j, L(j, j) at stage j.
            for (int k = 0; k < j; ++k)
                pending[size_t(base + k)].store((i == j ? 1 : 2) + 1, std::memory_order_relaxed);
            pending[size_t(base + j)].store((i == j ? 0 : 1) + 1, std::memory_order_relaxed);
        }
    // The descendants' update tiles: column block j, the tiles' row blocks first .. last
    // (rows r1 .. r2: whole tiles, about ROW_BLOCK rows).
    struct UpdateTile {
        int c1, c2, r1, r2, j, first, last;
    };
    std::vector<UpdateTile> update_tiles;
    for (int j = 0; j < ncb; ++j)
        for (int i = j; i < nrb;) {
            int last = i;
            while (last + 1 < nrb && row_end(last + 1) - row_start(i) <= ROW_BLOCK)
                ++last;
            update_tiles.push_back({ j * B, j * B + column_width(j), row_start(i), row_end(last), j, i, last });
            i = last + 1;
        }

    // A task: stage k of tile (i, j), or (k < 0) the update tile i.
    struct Task {
        int i, j, k;
    };
    const auto descendant_updates = [&](const UpdateTile& tile) {
        Workspace& w = workspaces.local();
        const int first_row = r[tile.r1], last_row = r[tile.r2 - 1];
        for (int u = update_ptr[size_t(s)]; u < update_ptr[size_t(s) + 1]; ++u) {
            const Update& up = updates[size_t(u)];
            const int* rd = rows(up.d);
            const int ndrow = nsrow(up.d);
            const int q1 = int(std::lower_bound(rd + up.p1, rd + up.p2, k1 + tile.c1) - rd);
            const int q2 = int(std::lower_bound(rd + q1, rd + up.p2, k1 + tile.c2) - rd);
            if (q1 == q2)
                continue;
            const int t1 = std::max(q1, int(std::lower_bound(rd + up.p1, rd + ndrow, first_row) - rd));
            const int t2 = int(std::upper_bound(rd + t1, rd + ndrow, last_row) - rd);
            if (t1 >= t2)
                continue;
            const int m = t2 - t1, nn = q2 - q1;
            if (w.c.size() < size_t(m) * size_t(nn))
                w.c.resize(size_t(m) * size_t(nn));
            const double* ld = values(up.d);
            gemm_nt(m, nn, nscol(up.d), ld + t1, ndrow, ld + q1, ndrow, w.c.data(), m);
            // Local rows of d's rows t1..t2 in s: both lists are sorted and every row of
            // d below its columns is a row of s, so one merge over the tile's rows finds them.
            if (w.map.size() < size_t(m))
                w.map.resize(size_t(m));
            for (int ii = 0, j = tile.r1; ii < m; ++ii) {
                while (r[j] < rd[t1 + ii])
                    ++j;
                w.map[size_t(ii)] = j;
            }
            for (int jj = 0; jj < nn; ++jj) {
                double* column = x + size_t(rd[q1 + jj] - k1) * size_t(nrow);
                const double* cj = w.c.data() + size_t(jj) * size_t(m);
                for (int ii = std::max(0, q1 + jj - t1); ii < m; ++ii)
                    column[w.map[size_t(ii)]] -= cj[ii];
            }
        }
    };
    // Runs a task; appends the stages it made ready.
    const auto run = [&](const Task& t, std::vector<Task>& ready) {
        const auto release = [&](int i, int j, int stage) {
            if (pending[size_t(stage_base[size_t(tile_index(i, j))] + stage)].fetch_sub(1, std::memory_order_acq_rel)
                == 1)
                ready.push_back({ i, j, stage });
        };
        if (t.k < 0) {
            const UpdateTile& tile = update_tiles[size_t(t.i)];
            descendant_updates(tile);
            for (int i = tile.first; i <= tile.last; ++i)
                release(i, tile.j, 0);
            return;
        }
        const int i = t.i, j = t.j, k = t.k;
        const int height = row_end(i) - row_start(i), width = column_width(j);
        if (k < j) {
            const int kw = column_width(k);
            const double* li = at(i, k);
            const double* lj = at(j, k);
            double* target = at(i, j);
            if (i == j) // square
                dsyrk_("L", "N", &width, &kw, &MINUS_ONE, lj, &nrow, &ONE, target, &nrow);
            else
                gemm_nt_sub(height, width, kw, li, nrow, lj, nrow, target, nrow);
            release(i, j, k + 1);
            return;
        }
        double* tile = at(i, j);
        if (i == j) {
            int info = 0;
            dpotrf_("L", &width, tile, &nrow, &info);
            if (info != 0) {
                fail(k1 + j * B + info - 1);
                return;
            }
            for (int below = i + 1; below < nrb; ++below) // their final stage waits for L(j, j)
                release(below, j, j);
        } else {
            trsm_right_lower_t(height, width, at(j, j), nrow, tile, nrow);
            // L(i, j) is final: stage j of the tiles that read it.
            for (int c = j + 1; c <= std::min(i, ncb - 1); ++c)
                release(i, c, j);
            if (i < ncb)
                for (int below = i + 1; below < nrb; ++below)
                    release(below, i, j);
        }
    };
    tbb::task_group group;
    const auto launch = [&](const auto& self, Task t) -> void {
        std::vector<Task> ready;
        while (!failed()) {
            ready.clear();
            run(t, ready);
            if (ready.empty())
                return;
            for (size_t next = 1; next < ready.size(); ++next)
                group.run([&self, task = ready[next]] { self(self, task); });
            t = ready.front();
        }
    };
    for (size_t u = 0; u < update_tiles.size(); ++u)
        group.run([&launch, u] { launch(launch, { int(u), 0, -1 }); });
    group.wait();
}

bool SupernodalCholesky::factorize(const SparseMatrixd& lower)
{
    Impl& m = *m_impl;
    if (!m.factor)
        analyze(lower);
    if (lower.rows() != m.n || lower.cols() != m.n)
        throw std::invalid_argument("SupernodalCholesky: the matrix size changed since the analysis");
    if (m.factor->xtype == CHOLMOD_PATTERN) {
        m.factor->is_ll = 1;
        if (!cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1, m.factor, &m.common) || !m.factor->x)
            throw std::runtime_error(
                "CHOLMOD could not allocate the factor (status " + std::to_string(m.common.status) + ")");
        m.lpx = static_cast<const int*>(m.factor->px);
    }
    const size_t nnz = size_t(lower.nonZeros());
    if (m.assembled_outer.size() != size_t(m.n) + 1 || m.assembled_inner.size() != nnz
        || !std::equal(m.assembled_outer.begin(), m.assembled_outer.end(), lower.outerIndexPtr())
        || !std::equal(m.assembled_inner.begin(), m.assembled_inner.end(), lower.innerIndexPtr()))
        m.build_assembly(lower);

    m.minor = m.n;
    const double* a = lower.valuePtr();
    {
        // Our tasks are the parallelism: BLAS runs each call on the calling thread.
        const BlasThreadsScope single_threaded_blas(1);
        m.bottom_up([&](int s) {
            if (m.failed())
                return;
            if (m.tiled[size_t(s)])
                m.factor_supernode_tiled(s, a);
            else
                m.factor_supernode(s, a);
        });
    }
    m.factor->minor = size_t(m.minor.load());
    return !m.failed();
}

void SupernodalCholesky::Impl::forward_blocked(int s, double* ys, double* below) const
{
    const int ncol = nscol(s), nrow = nsrow(s), rows_below = nrow - ncol, one = 1;
    const double* x = values(s);
    constexpr int B = COLUMN_BLOCK;
    const int ncb = (ncol + B - 1) / B, nbb = (rows_below + ROW_BLOCK - 1) / ROW_BLOCK;
    std::fill(below, below + rows_below, 0.0);
    for (int j = 0; j < ncb; ++j) {
        const int w = std::min(B, ncol - j * B);
        const double* ljj = x + size_t(j) * B * size_t(nrow) + size_t(j) * B;
        double* yj = ys + j * B;
        dtrsv_("L", "N", "N", &w, ljj, &nrow, yj, &one);
        // y_i -= L(i, j) y_j for the blocks i > j; below += L21(:, j) y_j. One BLAS call per
        // block and step, in step order: the same for any thread count.
        const int later = ncb - j - 1;
        tbb::parallel_for(
            tbb::blocked_range<int>(0, later + nbb, 1),
            [&](const tbb::blocked_range<int>& range) {
                for (int t = range.begin(); t < range.end(); ++t) {
                    const int r1 = t < later ? (j + 1 + t) * B : ncol + (t - later) * ROW_BLOCK;
                    const int h = t < later ? std::min(B, ncol - r1) : std::min(ROW_BLOCK, nrow - r1);
                    double* target = t < later ? ys + r1 : below + (r1 - ncol);
                    const double* alpha = t < later ? &MINUS_ONE : &ONE;
                    dgemv_("N", &h, &w, alpha, x + size_t(j) * B * size_t(nrow) + size_t(r1), &nrow, yj, &one, &ONE,
                        target, &one);
                }
            },
            tbb::simple_partitioner());
    }
}

void SupernodalCholesky::Impl::backward_blocked(int s, double* ys, const double* g) const
{
    const int ncol = nscol(s), nrow = nsrow(s), rows_below = nrow - ncol, one = 1;
    const double* x = values(s);
    constexpr int B = COLUMN_BLOCK;
    const int ncb = (ncol + B - 1) / B;
    if (g && rows_below > 0)
        tbb::parallel_for(
            tbb::blocked_range<int>(0, ncb, 1),
            [&](const tbb::blocked_range<int>& range) {
                for (int k = range.begin(); k < range.end(); ++k) {
                    const int w = std::min(B, ncol - k * B);
                    dgemv_("T", &rows_below, &w, &MINUS_ONE, x + size_t(k) * B * size_t(nrow) + size_t(ncol), &nrow, g,
                        &one, &ONE, ys + k * B, &one);
                }
            },
            tbb::simple_partitioner());
    for (int j = ncb - 1; j >= 0; --j) {
        const int w = std::min(B, ncol - j * B);
        double* yj = ys + j * B;
        dtrsv_("L", "T", "N", &w, x + size_t(j) * B * size_t(nrow) + size_t(j) * B, &nrow, yj, &one);
        // y_k -= L(j, k)^T y_j for the blocks k < j.
        tbb::parallel_for(
            tbb::blocked_range<int>(0, j, 1),
            [&](const tbb::blocked_range<int>& range) {
                for (int k = range.begin(); k < range.end(); ++k)
                    dgemv_("T", &w, &B, &MINUS_ONE, x + size_t(k) * B * size_t(nrow) + size_t(j) * B, &nrow, yj, &one,
                        &ONE, ys + k * B, &one);
            },
            tbb::simple_partitioner());
    }
}

VectorXd SupernodalCholesky::solve(const VectorXd& b) const
{
    const Impl& m = *m_impl;
    if (!m.factor || m.factor->xtype != CHOLMOD_REAL || m.failed())
        throw std::logic_error("SupernodalCholesky::solve without a successful factorization");
    if (b.size() != m.n)
        throw std::invalid_argument("SupernodalCholesky::solve: right-hand side of the wrong size");
    const int* perm = static_cast<const int*>(m.factor->Perm);
    VectorXd y(m.n);
    for (Index k = 0; k < m.n; ++k)
        y[k] = b[perm[k]];
    // Forward, L y = P b, bottom-up: supernode s takes its descendants' L21 y_d terms for its
    // columns (in descendant order), solves with its diagonal block, and leaves L21 y_s for
    // its ancestors. Backward, L^T x = y, top-down: s subtracts L21^T x of its rows below
    // (its ancestors' columns, final by then) and solves with the transposed diagonal block.
    // Each supernode writes only its own columns, in an order fixed by the tree: the result
    // is the same for any thread count.
    std::vector<double> below(size_t(m.below_ptr[size_t(m.nsuper)]));
    const int one = 1;
    const BlasThreadsScope single_threaded_blas(1);
    m.bottom_up([&](int s) {
        const int k1 = m.super[s], ncol = m.nscol(s), nrow = m.nsrow(s);
        for (int u = m.update_ptr[size_t(s)]; u < m.update_ptr[size_t(s) + 1]; ++u) {
            const Update& up = m.updates[size_t(u)];
            const int* rd = m.rows(up.d);
            const double* bd = below.data() + m.below_ptr[size_t(up.d)] - m.nscol(up.d);
            for (int i = up.p1; i < up.p2; ++i)
                y[rd[i]] -= bd[i];
        }
        const double* x = m.values(s);
        if (m.blocked_solve(s)) {
            m.forward_blocked(s, y.data() + k1, below.data() + m.below_ptr[size_t(s)]);
            return;
        }
        dtrsv_("L", "N", "N", &ncol, x, &nrow, y.data() + k1, &one);
        if (nrow > ncol) {
            const int rows_below = nrow - ncol;
            dgemv_("N", &rows_below, &ncol, &ONE, x + ncol, &nrow, y.data() + k1, &one, &ZERO,
                below.data() + m.below_ptr[size_t(s)], &one);
        }
    });
    // Backward, s gathers the solution at its rows below into its own slot of `below` (the
    // forward pass is done with it): no scratch is shared between supernodes, so none can be
    // overwritten by another supernode's step that this thread runs while it waits for tasks.
    m.top_down([&](int s) {
        const int k1 = m.super[s], ncol = m.nscol(s), nrow = m.nsrow(s);
        const double* x = m.values(s);
        const bool blocked = m.blocked_solve(s);
        const int rows_below = nrow - ncol;
        double* g = rows_below > 0 ? below.data() + m.below_ptr[size_t(s)] : nullptr;
        if (g) {
            const int* r = m.rows(s) + ncol;
            for (int i = 0; i < rows_below; ++i)
                g[i] = y[r[i]];
        }
        if (blocked) {
            m.backward_blocked(s, y.data() + k1, g);
            return;
        }
        if (g)
            dgemv_("T", &rows_below, &ncol, &MINUS_ONE, x + ncol, &nrow, g, &one, &ONE, y.data() + k1, &one);
        dtrsv_("L", "T", "N", &ncol, x, &nrow, y.data() + k1, &one);
    });
    VectorXd result(m.n);
    for (Index k = 0; k < m.n; ++k)
        result[perm[k]] = y[k];
    return result;
}

} // namespace diffipc
