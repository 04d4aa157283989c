#include "cuda/linalg/device_amg.hpp"

#include "cuda/common/device.hpp"
#include "cuda/linalg/block_diagonal.cuh"
#include "cuda/linalg/reduction.hpp"

#include <cuda_runtime.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;
    constexpr int MAX_COARSEST_DOFS = 4000;
    /// The smoother's weight is 1 / (SAFETY rho_est). Power iteration usually estimates rho from below
    /// (by 6-10% in the tests); the V-cycle stays positive definite while rho_est > rho / (2 SAFETY).
    constexpr double SAFETY = 1.1;

    int grid(long n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    __device__ inline int global_index() { return blockIdx.x * blockDim.x + threadIdx.x; }

    /// Fixed dofs' rows and columns of A (B x B blocks) made identity ones; one thread per block row.
    template <int B>
    __global__ void mask_matrix(int rows, const int* __restrict__ offsets, const int* __restrict__ cols,
        const unsigned char* __restrict__ fixed, double* __restrict__ values)
    {
        const int r = global_index();
        if (r >= rows)
            return;
        for (int e = offsets[r]; e < offsets[r + 1]; ++e) {
            const int c = cols[e];
            double* block = values + size_t(e) * (B * B);
            for (int i = 0; i < B; ++i)
                for (int j = 0; j < B; ++j)
                    if (fixed[r * B + i] || fixed[c * B + j])
                        block[i * B + j] = r == c && i == j ? 1.0 : 0.0;
        }
    }

    /// The inverse of each diagonal block (Gauss-Jordan on the symmetric positive definite block); a
    /// block with a pivot that is not positive gets its inverted diagonal (1 where that is not positive).
    template <int B>
    __global__ void invert_diagonal(
        int rows, const int* __restrict__ diagonal, const double* __restrict__ values, double* __restrict__ inverses)
    {
        const int r = global_index();
        if (r >= rows)
            return;
        const double* block = values + size_t(diagonal[r]) * (B * B);
        double M[B * B];
        for (int q = 0; q < B * B; ++q)
            M[q] = block[q];
        bool ok = true;
        for (int k = 0; k < B && ok; ++k) {
            const double p = M[k * B + k];
            ok = p > 0 && isfinite(p);
            if (!ok)
                break;
            for (int i = 0; i < B; ++i)
                for (int j = 0; j < B; ++j)
                    if (i != k && j != k)
                        M[i * B + j] -= M[i * B + k] * M[k * B + j] / p;
            for (int j = 0; j < B; ++j)
                if (j != k)
                    M[k * B + j] = -M[k * B + j] / p;
            for (int i = 0; i < B; ++i)
                if (i != k)
                    M[i * B + k] = M[i * B + k] / p;
            M[k * B + k] = 1.0 / p;
        }
        for (int q = 0; q < B * B && ok; ++q)
            ok = isfinite(M[q]);
        double* out = inverses + size_t(r) * (B * B);
        for (int i = 0; i < B; ++i)
            for (int j = 0; j < B; ++j) {
                const double d = block[i * B + i];
                out[i * B + j] = ok ? M[i * B + j] : (i != j ? 0.0 : d > 0 ? 1.0 / d : 1.0);
            }
    }

    /// y = A x (ADD: y += A x) for R x C blocks (row-major; A: #block rows x #block columns), one thread
    /// per scalar row, the row's blocks in column order: the fine level's product (R = C = B) and the
    /// prolongation x += P xc (R = B, C = K).
    template <int R, int C, bool ADD>
    __global__ void multiply(int n, const int* __restrict__ offsets, const int* __restrict__ cols,
        const double* __restrict__ values, const double* __restrict__ x, double* __restrict__ y)
    {
        const int row = global_index();
        if (row >= n)
            return;
        const int r = row / R, i = row % R;
        double acc = 0;
        for (int e = offsets[r]; e < offsets[r + 1]; ++e) {
            const double* block = values + size_t(e) * (R * C) + i * C;
            const double* xc = x + size_t(cols[e]) * C;
            for (int j = 0; j < C; ++j)
                acc += block[j] * xc[j];
        }
        y[row] = ADD ? y[row] + acc : acc;
    }

    constexpr int WARP = 32;

    /// The sum of v over the warp's lanes, in a fixed butterfly order (the same bits every run).
    __device__ inline double warp_sum(double v)
    {
        for (int offset = WARP / 2; offset > 0; offset /= 2)
            v += __shfl_xor_sync(0xffffffffu, v, offset);
        return v;
    }

    /// y = A x with one warp per block row (the coarse levels' rows hold many blocks): lane l takes the
    /// row's blocks l, l + 32, ..., then the lanes' sums are added by warp_sum.
    template <int B>
    __global__ void multiply_by_warps(int rows, const int* __restrict__ offsets, const int* __restrict__ cols,
        const double* __restrict__ values, const double* __restrict__ x, double* __restrict__ y)
    {
        const int r = global_index() / WARP, lane = threadIdx.x % WARP;
        if (r >= rows)
            return; // the whole warp
        double acc[B] = {};
        for (int e = offsets[r] + lane; e < offsets[r + 1]; e += WARP) {
            const double* block = values + size_t(e) * (B * B);
            const double* xc = x + size_t(cols[e]) * B;
            for (int i = 0; i < B; ++i)
                for (int j = 0; j < B; ++j)
                    acc[i] += block[i * B + j] * xc[j];
        }
        for (int i = 0; i < B; ++i) {
            const double sum = warp_sum(acc[i]);
            if (lane == i)
                y[size_t(r) * B + i] = sum;
        }
    }

    /// x = (first ? 0 : x) + s D^-1 (b - y), y = A x (ignored when first), s = 1 / (SAFETY rho) with
    /// rho^2 at *rho2.
    template <int B>
    __global__ void jacobi_sweep(int n, const double* __restrict__ inverses, const double* __restrict__ b,
        const double* __restrict__ y, const double* __restrict__ rho2, bool first, double* __restrict__ x)
    {
        const int row = global_index();
        if (row >= n)
            return;
        const int r = row / B, i = row % B;
        const double* m = inverses + size_t(r) * (B * B) + i * B;
        double acc = 0;
        for (int j = 0; j < B; ++j)
            acc += m[j] * (first ? b[r * B + j] : b[r * B + j] - y[r * B + j]);
        const double rho = sqrt(*rho2);
        const double s = rho > 0 && isfinite(rho) ? 1.0 / (SAFETY * rho) : 0.0;
        x[row] = (first ? 0.0 : x[row]) + s * acc;
    }

    /// v = the free dofs' indicator (power iteration's start).
    __global__ void power_start(int n, const unsigned char* __restrict__ fixed, double* __restrict__ v)
    {
        const int k = global_index();
        if (k < n)
            v[k] = fixed[k] ? 0.0 : 1.0;
    }

    /// v = w / sqrt(*ww) (or 0 if w is 0).
    __global__ void normalize(
        int n, const double* __restrict__ w, const double* __restrict__ ww, double* __restrict__ v)
    {
        const int k = global_index();
        if (k >= n)
            return;
        const double s = *ww;
        v[k] = s > 0 && isfinite(s) ? w[k] / sqrt(s) : 0.0;
    }

    /// The index of `column` in cols[first, last) (increasing), or -1.
    __device__ inline int find_column(const int* __restrict__ cols, int first, int last, int column)
    {
        int lo = first, hi = last;
        while (lo < hi) {
            const int mid = (lo + hi) / 2;
            if (cols[mid] < column)
                lo = mid + 1;
            else
                hi = mid;
        }
        return lo < last && cols[lo] == column ? lo : -1;
    }

    /// P = T - 4/(3 rho) D^-1 (A T), one thread per (P block (v, a), column j): (A T)'s column j sums
    /// A_vw T_w's over A's row v, w in aggregate a, in column order.
    template <int B, int K>
    __global__ void smooth_prolongator(int blocks, const int* __restrict__ block_row, const int* __restrict__ p_cols,
        const int* __restrict__ a_offsets, const int* __restrict__ a_cols, const double* __restrict__ a_values,
        const double* __restrict__ tentative, const int* __restrict__ aggregate_of, const double* __restrict__ inverses,
        const double* __restrict__ rho2, double* __restrict__ p_values)
    {
        const int t = global_index();
        if (t >= blocks * K)
            return;
        const int f = t / K, j = t % K, v = block_row[f], a = p_cols[f];
        double at[B] = {};
        for (int e = a_offsets[v]; e < a_offsets[v + 1]; ++e) {
            const int w = a_cols[e];
            if (aggregate_of[w] != a)
                continue;
            const double* m = a_values + size_t(e) * (B * B);
            const double* tw = tentative + size_t(w) * (B * K);
            for (int i = 0; i < B; ++i)
                for (int c = 0; c < B; ++c)
                    at[i] += m[i * B + c] * tw[c * K + j];
        }
        const double rho = sqrt(*rho2);
        const double omega = rho > 0 && isfinite(rho) ? 4.0 / (3.0 * rho) : 0.0;
        const bool own = aggregate_of[v] == a;
        const double* tv = tentative + size_t(v) * (B * K);
        const double* m = inverses + size_t(v) * (B * B);
        double* out = p_values + size_t(f) * (B * K);
        for (int i = 0; i < B; ++i) {
            double dat = 0;
            for (int c = 0; c < B; ++c)
                dat += m[i * B + c] * at[c];
            out[i * K + j] = (own ? tv[i * K + j] : 0.0) - omega * dat;
        }
    }

    /// W = A P, one thread per (W block (v, c), column j): the sum over A's row v of A_vw P_wc's column
    /// j, where P's row w has a block in column c.
    template <int B, int K>
    __global__ void multiply_ap(int blocks, const int* __restrict__ w_row, const int* __restrict__ w_cols,
        const int* __restrict__ a_offsets, const int* __restrict__ a_cols, const double* __restrict__ a_values,
        const int* __restrict__ p_offsets, const int* __restrict__ p_cols, const double* __restrict__ p_values,
        double* __restrict__ w_values)
    {
        const int t = global_index();
        if (t >= blocks * K)
            return;
        const int g = t / K, j = t % K, v = w_row[g], c = w_cols[g];
        double acc[B] = {};
        for (int e = a_offsets[v]; e < a_offsets[v + 1]; ++e) {
            const int w = a_cols[e];
            const int f = find_column(p_cols, p_offsets[w], p_offsets[w + 1], c);
            if (f < 0)
                continue;
            const double* m = a_values + size_t(e) * (B * B);
            const double* p = p_values + size_t(f) * (B * K);
            for (int i = 0; i < B; ++i)
                for (int r = 0; r < B; ++r)
                    acc[i] += m[i * B + r] * p[r * K + j];
        }
        double* out = w_values + size_t(g) * (B * K);
        for (int i = 0; i < B; ++i)
            out[i * K + j] = acc[i];
    }

    /// A_c = P^T W, one thread per (coarse block (a, c), column j): the sum over P's column a (fine
    /// nodes v increasing) of P_va^T W_vc's column j, where W's row v has a block in column c.
    template <int B, int K>
    __global__ void multiply_ptw(int blocks, const int* __restrict__ c_row, const int* __restrict__ c_cols,
        const int* __restrict__ r_offsets, const int* __restrict__ r_p, const int* __restrict__ r_v,
        const double* __restrict__ p_values, const int* __restrict__ w_offsets, const int* __restrict__ w_cols,
        const double* __restrict__ w_values, double* __restrict__ c_values)
    {
        const int t = global_index();
        if (t >= blocks * K)
            return;
        const int h = t / K, j = t % K, a = c_row[h], c = c_cols[h];
        double acc[K] = {};
        for (int s = r_offsets[a]; s < r_offsets[a + 1]; ++s) {
            const int v = r_v[s];
            const int g = find_column(w_cols, w_offsets[v], w_offsets[v + 1], c);
            if (g < 0)
                continue;
            const double* p = p_values + size_t(r_p[s]) * (B * K);
            const double* w = w_values + size_t(g) * (B * K);
            for (int r = 0; r < B; ++r) {
                const double wr = w[r * K + j];
                for (int i = 0; i < K; ++i)
                    acc[i] += p[r * K + i] * wr;
            }
        }
        double* out = c_values + size_t(h) * (K * K);
        for (int i = 0; i < K; ++i)
            out[i * K + j] = acc[i];
    }

    /// bc = P^T (b - y), one warp per aggregate: lane l takes the list's entries l, l + 32, ... (fine nodes
    /// in increasing order), then warp_sum adds the lanes' sums.
    template <int B, int K>
    __global__ void restrict_residual(int aggregates, const int* __restrict__ list_offsets,
        const int* __restrict__ list_p, const int* __restrict__ list_v, const double* __restrict__ p_values,
        const double* __restrict__ b, const double* __restrict__ y, double* __restrict__ bc)
    {
        const int a = global_index() / WARP, lane = threadIdx.x % WARP;
        if (a >= aggregates)
            return; // the whole warp
        double acc[K] = {};
        for (int e = list_offsets[a] + lane; e < list_offsets[a + 1]; e += WARP) {
            const double* p = p_values + size_t(list_p[e]) * (B * K);
            const int v = list_v[e];
            for (int r = 0; r < B; ++r) {
                const double res = b[v * B + r] - y[v * B + r];
                for (int i = 0; i < K; ++i)
                    acc[i] += p[r * K + i] * res;
            }
        }
        for (int i = 0; i < K; ++i) {
            const double sum = warp_sum(acc[i]);
            if (lane == i)
                bc[size_t(a) * K + i] = sum;
        }
    }

    /// The coarsest matrix (masked BSR) as a dense row-major N x N matrix (zeroed first).
    template <int B>
    __global__ void densify(int rows, const int* __restrict__ offsets, const int* __restrict__ cols,
        const double* __restrict__ values, double* __restrict__ dense)
    {
        const int row = global_index();
        const int N = rows * B;
        if (row >= N)
            return;
        const int r = row / B, i = row % B;
        for (int e = offsets[r]; e < offsets[r + 1]; ++e)
            for (int j = 0; j < B; ++j)
                dense[size_t(row) * N + size_t(cols[e]) * B + j] = values[size_t(e) * (B * B) + i * B + j];
    }

    /// One principal pivot transform of the dense N x N matrix on pivot k (in to out); after all N
    /// pivots the matrix is its inverse. failed is set if the pivot is not positive and finite.
    __global__ void pivot_step(int N, int k, const double* __restrict__ in, double* __restrict__ out, int* failed)
    {
        const long t = long(blockIdx.x) * blockDim.x + threadIdx.x;
        if (t >= long(N) * N)
            return;
        const int i = int(t / N), j = int(t % N);
        const double p = in[size_t(k) * N + k];
        if (t == 0 && !(p > 0 && isfinite(p)))
            *failed = 1;
        double value;
        if (i == k && j == k)
            value = 1.0 / p;
        else if (i == k)
            value = -in[size_t(k) * N + j] / p;
        else if (j == k)
            value = in[size_t(i) * N + k] / p;
        else
            value = in[t] - in[size_t(i) * N + k] * in[size_t(k) * N + j] / p;
        out[t] = value;
    }

    /// x = M b for the dense N x N M, one warp per row (coalesced reads along the row).
    __global__ void dense_multiply(
        int N, const double* __restrict__ M, const double* __restrict__ b, double* __restrict__ x)
    {
        const int i = global_index() / WARP, lane = threadIdx.x % WARP;
        if (i >= N)
            return; // the whole warp
        double acc = 0;
        for (int j = lane; j < N; j += WARP)
            acc += M[size_t(i) * N + j] * b[j];
        acc = warp_sum(acc);
        if (lane == 0)
            x[i] = acc;
    }

    template <typename T> DeviceArray<T> upload(const std::vector<T>& host)
    {
        DeviceArray<T> d;
        d.upload(host);
        return d;
    }

    std::vector<unsigned char> flags(const std::vector<char>& fixed)
    {
        std::vector<unsigned char> out(fixed.size());
        for (size_t k = 0; k < fixed.size(); ++k)
            out[k] = fixed[k] ? 1 : 0;
        return out;
    }

    /// The block row of each block of a pattern.
    std::vector<int> row_of_blocks(const BlockPattern& pattern)
    {
        std::vector<int> row(pattern.cols.size());
        for (int r = 0; r < pattern.rows(); ++r)
            for (int e = pattern.offsets[size_t(r)]; e < pattern.offsets[size_t(r) + 1]; ++e)
                row[size_t(e)] = r;
        return row;
    }

    /// Calls f(std::integral_constant<int, B>{}) for B in {2, 3, 6}.
    template <typename F> void with_block(int b, F&& f)
    {
        switch (b) {
        case 2:
            return f(std::integral_constant<int, 2> {});
        case 3:
            return f(std::integral_constant<int, 3> {});
        case 6:
            return f(std::integral_constant<int, 6> {});
        default:
            throw std::logic_error("DeviceAmg: block size " + std::to_string(b));
        }
    }

    /// Calls f(B, K constants) for (B, K) in {(2, 3), (3, 3), (3, 6), (6, 6)}.
    template <typename F> void with_blocks(int b, int k, F&& f)
    {
        if (b == 2 && k == 3)
            return f(std::integral_constant<int, 2> {}, std::integral_constant<int, 3> {});
        if (b == 3 && k == 3)
            return f(std::integral_constant<int, 3> {}, std::integral_constant<int, 3> {});
        if (b == 3 && k == 6)
            return f(std::integral_constant<int, 3> {}, std::integral_constant<int, 6> {});
        if (b == 6 && k == 6)
            return f(std::integral_constant<int, 6> {}, std::integral_constant<int, 6> {});
        throw std::logic_error("DeviceAmg: block sizes " + std::to_string(b) + " x " + std::to_string(k));
    }

} // namespace

struct DeviceAmg::Impl {
    struct Level {
        int b = 0, k = 0, rows = 0, coarse_rows = 0;
        std::vector<int> host_offsets, host_cols; // A_l's pattern (to check the fine matrix against)
        DeviceArray<int> offsets, cols, diagonal, aggregate_of;
        DeviceArray<unsigned char> fixed;
        DeviceArray<double> values, inverses, tentative;
        DeviceArray<int> p_offsets, p_cols, p_row, w_offsets, w_cols, w_row, c_row, c_cols;
        DeviceArray<double> p_values, w_values;
        DeviceArray<int> r_offsets, r_p, r_v;
        int p_blocks = 0, w_blocks = 0, c_blocks = 0;
        mutable DeviceArray<double> x, b_vec, y;
        int size() const { return rows * b; }
        /// y = A_l x on `stream`: a thread per scalar row on the fine level (few blocks per row), a warp per
        /// block row on the coarse ones.
        void multiply(bool fine, const double* x, double* y, cudaStream_t stream) const;
    };
    AmgSettings settings;
    std::vector<Level> levels;
    // The coarsest level.
    int cb = 0, crows = 0;
    std::vector<int> host_c_offsets, host_c_cols; // the coarsest's pattern (the fine one without levels)
    DeviceArray<int> c_offsets, c_cols;
    DeviceArray<unsigned char> c_fixed;
    DeviceArray<double> c_values, dense, dense_other;
    mutable DeviceArray<double> cx, cb_vec;
    DeviceArray<double> rho2, partials;
    DeviceArray<int> failed;
    int coarsest_size() const { return cb * crows; }

    /// The coarse matrix values of level l (the next level's, or the coarsest's).
    DeviceArray<double>& coarse_values(size_t l) { return l + 1 < levels.size() ? levels[l + 1].values : c_values; }
    /// One V-cycle from level l down, its kernels queued on `stream`.
    void cycle(size_t l, const double* b, double* x, cudaStream_t stream) const;
    // apply()'s V-cycle as a CUDA graph (one launch instead of a dozen), captured for one pair of
    // vectors: every other pointer it uses is fixed at construction, and the values it reads are in
    // device memory, so setup() does not invalidate it.
    mutable cudaStream_t capture_stream = nullptr;
    mutable cudaGraphExec_t graph = nullptr;
    mutable const double* graph_r = nullptr;
    mutable double* graph_z = nullptr;
    mutable bool graphs_failed = false;
    ~Impl()
    {
        if (graph)
            cudaGraphExecDestroy(graph);
        if (capture_stream)
            cudaStreamDestroy(capture_stream);
    }
};

DeviceAmg::DeviceAmg(const AmgPlan& plan, const AmgSettings& settings)
    : m_impl(std::make_unique<Impl>())
{
    if (settings.smoothing_sweeps < 1 || settings.power_iterations < 1)
        throw std::invalid_argument("DeviceAmg: smoothing_sweeps and power_iterations must be >= 1");
    if (plan.coarsest_size() > MAX_COARSEST_DOFS)
        throw std::invalid_argument("DeviceAmg: the coarsest level has " + std::to_string(plan.coarsest_size())
            + " dofs, more than the dense solve takes (" + std::to_string(MAX_COARSEST_DOFS) + ")");
    Impl& m = *m_impl;
    m.settings = settings;
    for (const AmgLevelPlan& p : plan.levels) {
        Impl::Level L;
        L.b = p.block;
        L.k = p.coarse_block;
        L.rows = p.matrix.rows();
        L.coarse_rows = int(p.restriction.offsets.size()) - 1;
        L.host_offsets = p.matrix.offsets;
        L.host_cols = p.matrix.cols;
        L.offsets = upload(p.matrix.offsets);
        L.cols = upload(p.matrix.cols);
        L.diagonal = upload(p.diagonal);
        L.aggregate_of = upload(p.aggregate_of);
        L.fixed = upload(flags(p.fixed));
        L.values.resize(p.matrix.cols.size() * size_t(L.b * L.b));
        L.inverses.resize(size_t(L.rows) * size_t(L.b * L.b));
        L.tentative = upload(p.tentative);
        L.p_offsets = upload(p.prolongator.offsets);
        L.p_cols = upload(p.prolongator.cols);
        L.p_row = upload(row_of_blocks(p.prolongator));
        L.w_offsets = upload(p.product.offsets);
        L.w_cols = upload(p.product.cols);
        L.w_row = upload(row_of_blocks(p.product));
        const BlockPattern& coarse = &p == &plan.levels.back() ? plan.coarsest : (&p + 1)->matrix;
        L.c_row = upload(row_of_blocks(coarse));
        L.c_cols = upload(coarse.cols);
        L.r_offsets = upload(p.restriction.offsets);
        L.r_p = upload(p.restriction.first);
        L.r_v = upload(p.restriction.second);
        L.p_blocks = p.prolongator.blocks();
        L.w_blocks = p.product.blocks();
        L.c_blocks = coarse.blocks();
        L.p_values.resize(size_t(L.p_blocks) * size_t(L.b * L.k));
        L.w_values.resize(size_t(L.w_blocks) * size_t(L.b * L.k));
        for (auto* v : { &L.x, &L.b_vec, &L.y })
            v->resize(size_t(L.size()));
        m.levels.push_back(std::move(L));
    }
    m.cb = plan.coarsest_block;
    m.crows = plan.coarsest.rows();
    m.host_c_offsets = plan.coarsest.offsets;
    m.host_c_cols = plan.coarsest.cols;
    m.c_offsets = upload(plan.coarsest.offsets);
    m.c_cols = upload(plan.coarsest.cols);
    m.c_fixed = upload(flags(plan.coarsest_fixed));
    m.c_values.resize(plan.coarsest.cols.size() * size_t(m.cb * m.cb));
    const size_t N = size_t(m.coarsest_size());
    m.dense.resize(N * N);
    m.dense_other.resize(N * N);
    m.cx.resize(N);
    m.cb_vec.resize(N);
    m.rho2.resize(m.levels.size() + 1);
    m.partials.resize(REDUCTION_PARTIALS);
    m.failed.resize(1);
}

DeviceAmg::~DeviceAmg() = default;

int DeviceAmg::size() const { return m_impl->levels.empty() ? m_impl->coarsest_size() : m_impl->levels.front().size(); }

int DeviceAmg::num_levels() const { return int(m_impl->levels.size()); }

int DeviceAmg::level_size(int l) const
{
    if (l < 0 || l > num_levels())
        throw std::out_of_range("DeviceAmg::level_size: level " + std::to_string(l));
    return l < num_levels() ? m_impl->levels[size_t(l)].size() : m_impl->coarsest_size();
}

std::vector<double> DeviceAmg::matrix_values(int l) const
{
    if (l < 0 || l > num_levels())
        throw std::out_of_range("DeviceAmg::matrix_values: level " + std::to_string(l));
    return l < num_levels() ? m_impl->levels[size_t(l)].values.download() : m_impl->c_values.download();
}

std::vector<double> DeviceAmg::prolongator_values(int l) const
{
    if (l < 0 || l >= num_levels())
        throw std::out_of_range("DeviceAmg::prolongator_values: level " + std::to_string(l));
    return m_impl->levels[size_t(l)].p_values.download();
}

bool DeviceAmg::setup(const DeviceBsrMatrix& A)
{
    Impl& m = *m_impl;
    const auto t0 = std::chrono::steady_clock::now();
    // The fine level: the first level's pattern, or the coarsest's if there is no level.
    const bool has_levels = !m.levels.empty();
    const int b0 = has_levels ? m.levels.front().b : m.cb;
    const int rows0 = has_levels ? m.levels.front().rows : m.crows;
    const std::vector<int>& offsets0 = has_levels ? m.levels.front().host_offsets : m.host_c_offsets;
    const std::vector<int>& cols0 = has_levels ? m.levels.front().host_cols : m.host_c_cols;
    if (A.block_size() != b0 || A.num_block_rows() != rows0 || A.row_offsets() != offsets0 || A.col_indices() != cols0)
        throw std::invalid_argument("DeviceAmg::setup: the matrix is not on the hierarchy's fine pattern");
    DeviceArray<double>& fine_values = has_levels ? m.levels.front().values : m.c_values;
    detail::copy_device_to_device(
        fine_values.data(), A.device_values(), size_t(A.num_blocks()) * size_t(b0 * b0) * sizeof(double));

    for (size_t l = 0; l < m.levels.size(); ++l) {
        Impl::Level& L = m.levels[l];
        const int n = L.size();
        double* rho2 = m.rho2.data() + l;
        with_block(L.b, [&](auto Bc) {
            constexpr int B = decltype(Bc)::value;
            mask_matrix<B>
                <<<grid(L.rows), THREADS>>>(L.rows, L.offsets.data(), L.cols.data(), L.fixed.data(), L.values.data());
            check_launch("launch of the AMG's masking");
            invert_diagonal<B>
                <<<grid(L.rows), THREADS>>>(L.rows, L.diagonal.data(), L.values.data(), L.inverses.data());
            check_launch("launch of the AMG's diagonal inverses");
            // rho(D^-1 A) by power iteration from the free dofs' indicator: x holds v, y A v, b_vec D^-1 A v.
            power_start<<<grid(n), THREADS>>>(n, L.fixed.data(), L.x.data());
            for (int it = 0; it <= m.settings.power_iterations; ++it) {
                L.multiply(l == 0, L.x.data(), L.y.data(), 0);
                apply_block_diagonal<B><<<grid(n), THREADS>>>(n, L.inverses.data(), L.y.data(), L.b_vec.data());
                check_launch("launch of the AMG's power iteration");
                deterministic_dot(L.b_vec.data(), L.b_vec.data(), size_t(n), m.partials.data(), rho2);
                if (it < m.settings.power_iterations) {
                    normalize<<<grid(n), THREADS>>>(n, L.b_vec.data(), rho2, L.x.data());
                    check_launch("launch of the AMG's power iteration");
                }
            }
        });
        with_blocks(L.b, L.k, [&](auto Bc, auto Kc) {
            constexpr int B = decltype(Bc)::value, K = decltype(Kc)::value;
            smooth_prolongator<B, K><<<grid(long(L.p_blocks) * K), THREADS>>>(L.p_blocks, L.p_row.data(),
                L.p_cols.data(), L.offsets.data(), L.cols.data(), L.values.data(), L.tentative.data(),
                L.aggregate_of.data(), L.inverses.data(), rho2, L.p_values.data());
            check_launch("launch of the AMG's prolongator smoothing");
            multiply_ap<B, K><<<grid(long(L.w_blocks) * K), THREADS>>>(L.w_blocks, L.w_row.data(), L.w_cols.data(),
                L.offsets.data(), L.cols.data(), L.values.data(), L.p_offsets.data(), L.p_cols.data(),
                L.p_values.data(), L.w_values.data());
            check_launch("launch of the AMG's A P");
            multiply_ptw<B, K><<<grid(long(L.c_blocks) * K), THREADS>>>(L.c_blocks, L.c_row.data(), L.c_cols.data(),
                L.r_offsets.data(), L.r_p.data(), L.r_v.data(), L.p_values.data(), L.w_offsets.data(), L.w_cols.data(),
                L.w_values.data(), m.coarse_values(l).data());
            check_launch("launch of the AMG's Galerkin product");
        });
    }

    // The coarsest level: masked (its inactive modes), densified and inverted.
    static const bool trace = std::getenv("DIFFIPC_NEWTON_TRACE") != nullptr;
    if (trace)
        check_cuda(cudaDeviceSynchronize(), "AMG trace");
    const auto t1 = std::chrono::steady_clock::now();
    const int N = m.coarsest_size();
    if (N == 0)
        return true; // nothing to solve (every level above is empty too)
    with_block(m.cb, [&](auto Bc) {
        constexpr int B = decltype(Bc)::value;
        mask_matrix<B><<<grid(m.crows), THREADS>>>(
            m.crows, m.c_offsets.data(), m.c_cols.data(), m.c_fixed.data(), m.c_values.data());
        m.dense.set_zero();
        densify<B>
            <<<grid(N), THREADS>>>(m.crows, m.c_offsets.data(), m.c_cols.data(), m.c_values.data(), m.dense.data());
        check_launch("launch of the AMG's coarsest matrix");
    });
    m.failed.set_zero();
    // Ping-pong between the two buffers, the inverse ending in `dense`: apply()'s graph reads it there.
    double *from = m.dense.data(), *to = m.dense_other.data();
    for (int k = 0; k < N; ++k) {
        pivot_step<<<grid(long(N) * N), THREADS>>>(N, k, from, to, m.failed.data());
        std::swap(from, to);
    }
    check_launch("launch of the AMG's coarsest inverse");
    if (from != m.dense.data())
        detail::copy_device_to_device(m.dense.data(), from, size_t(N) * size_t(N) * sizeof(double));
    int failed = 0;
    detail::copy_device_to_host(&failed, m.failed.data(), sizeof(int));
    if (trace)
        std::fprintf(stderr, "AMG set-up: levels %.4f s, coarsest (%d dofs) %.4f s\n",
            std::chrono::duration<double>(t1 - t0).count(), N,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
    return failed == 0;
}

void DeviceAmg::Impl::Level::multiply(bool fine, const double* x, double* y, cudaStream_t stream) const
{
    with_block(b, [&](auto Bc) {
        constexpr int B = decltype(Bc)::value;
        if (fine)
            gpu::multiply<B, B, false>
                <<<grid(size()), THREADS, 0, stream>>>(size(), offsets.data(), cols.data(), values.data(), x, y);
        else
            multiply_by_warps<B><<<grid(long(rows) * WARP), THREADS, 0, stream>>>(
                rows, offsets.data(), cols.data(), values.data(), x, y);
    });
    check_launch("launch of the AMG's matrix product");
}

void DeviceAmg::Impl::cycle(size_t l, const double* b, double* x, cudaStream_t stream) const
{
    if (l == levels.size()) {
        const int N = coarsest_size();
        if (N == 0)
            return;
        dense_multiply<<<grid(long(N) * WARP), THREADS, 0, stream>>>(N, dense.data(), b, x);
        check_launch("launch of the AMG's coarsest solve");
        return;
    }
    const Level& L = levels[l];
    const int n = L.size();
    const double* rho = rho2.data() + l;
    const Level* next = l + 1 < levels.size() ? &levels[l + 1] : nullptr;
    double* bc = next ? next->b_vec.data() : cb_vec.data();
    double* xc = next ? next->x.data() : cx.data();
    const auto residual = [&] { L.multiply(l == 0, x, L.y.data(), stream); };
    const auto sweep = [&](bool first) {
        with_block(L.b, [&](auto Bc) {
            constexpr int B = decltype(Bc)::value;
            jacobi_sweep<B><<<grid(n), THREADS, 0, stream>>>(n, L.inverses.data(), b, L.y.data(), rho, first, x);
        });
        check_launch("launch of the AMG's smoother");
    };
    sweep(true);
    for (int s = 1; s < settings.smoothing_sweeps; ++s) {
        residual();
        sweep(false);
    }
    residual();
    with_blocks(L.b, L.k, [&](auto Bc, auto Kc) {
        constexpr int B = decltype(Bc)::value, K = decltype(Kc)::value;
        restrict_residual<B, K><<<grid(long(L.coarse_rows) * WARP), THREADS, 0, stream>>>(
            L.coarse_rows, L.r_offsets.data(), L.r_p.data(), L.r_v.data(), L.p_values.data(), b, L.y.data(), bc);
        check_launch("launch of the AMG's restriction");
    });
    cycle(l + 1, bc, xc, stream);
    with_blocks(L.b, L.k, [&](auto Bc, auto Kc) {
        constexpr int B = decltype(Bc)::value, K = decltype(Kc)::value;
        multiply<B, K, true>
            <<<grid(n), THREADS, 0, stream>>>(n, L.p_offsets.data(), L.p_cols.data(), L.p_values.data(), xc, x);
        check_launch("launch of the AMG's prolongation");
    });
    for (int s = 0; s < settings.smoothing_sweeps; ++s) {
        residual();
        sweep(false);
    }
}

void DeviceAmg::apply(const double* d_r, double* d_z) const
{
    Impl& m = *m_impl;
    if (!m.graphs_failed && (!m.graph || m.graph_r != d_r || m.graph_z != d_z)) {
        if (m.graph) {
            cudaGraphExecDestroy(m.graph);
            m.graph = nullptr;
        }
        cudaGraph_t captured = nullptr;
        bool ok
            = (m.capture_stream || cudaStreamCreateWithFlags(&m.capture_stream, cudaStreamNonBlocking) == cudaSuccess)
            && cudaStreamBeginCapture(m.capture_stream, cudaStreamCaptureModeThreadLocal) == cudaSuccess;
        if (ok) {
            try {
                m.cycle(0, d_r, d_z, m.capture_stream);
            } catch (...) { // end the capture, or this thread's later allocations are refused
                cudaStreamEndCapture(m.capture_stream, &captured);
                if (captured)
                    cudaGraphDestroy(captured);
                throw;
            }
            ok = cudaStreamEndCapture(m.capture_stream, &captured) == cudaSuccess && captured
                && cudaGraphInstantiate(&m.graph, captured, 0) == cudaSuccess;
        }
        if (captured)
            cudaGraphDestroy(captured);
        if (!ok) { // run without graphs from now on
            cudaGetLastError();
            m.graph = nullptr;
            m.graphs_failed = true;
        }
        m.graph_r = d_r;
        m.graph_z = d_z;
    }
    if (m.graph) {
        check_cuda(cudaGraphLaunch(m.graph, 0), "launch of the AMG's V-cycle graph");
        return;
    }
    m.cycle(0, d_r, d_z, 0);
}

} // namespace diffipc::gpu
