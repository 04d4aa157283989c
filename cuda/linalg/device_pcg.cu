#include "cuda/linalg/device_pcg.hpp"

#include "cuda/common/device.hpp"
#include "cuda/common/kernels.cuh"
#include "cuda/linalg/block_diagonal.cuh"
#include "cuda/linalg/reduction.hpp"
#include "forward/kernels/project_psd.hpp"
#include "forward/kernels/small_matrix.hpp"

#include <cuda_runtime.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;

    int grid(int n) { return (n + THREADS - 1) / THREADS; }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// Per block row: the inverse of its diagonal block (blocks: #block rows * B^2, dense) with the
    /// fixed rows and columns made identity ones; a block without a Cholesky factorization gets its
    /// inverted diagonal.
    template <int B>
    __global__ void invert_diagonal_blocks(int block_rows, const double* __restrict__ blocks,
        const unsigned char* __restrict__ fixed, double* __restrict__ inverses)
    {
        const int br = blockIdx.x * blockDim.x + threadIdx.x;
        if (br >= block_rows)
            return;
        double D[B * B];
        for (int q = 0; q < B * B; ++q)
            D[q] = blocks[size_t(br) * (B * B) + q];
        if (fixed)
            for (int i = 0; i < B; ++i)
                if (fixed[br * B + i])
                    for (int j = 0; j < B; ++j)
                        D[i * B + j] = D[j * B + i] = i == j ? 1.0 : 0.0;
        double* out = inverses + size_t(br) * (B * B);
        double Dinv[B * B];
        bool ok = cholesky_succeeds<B>(D);
        if (ok) {
            inverse<B>(D, Dinv);
            for (int q = 0; q < B * B; ++q)
                ok = ok && isfinite(Dinv[q]);
        }
        for (int i = 0; i < B; ++i)
            for (int j = 0; j < B; ++j) {
                const double d = D[i * B + i];
                out[i * B + j] = ok ? Dinv[i * B + j] : (i != j ? 0.0 : d > 0 ? 1.0 / d : 1.0);
            }
    }

    /// r = P b (x = 0 at the start).
    __global__ void masked_copy(int n, const double* __restrict__ b, const unsigned char* __restrict__ fixed,
        double* __restrict__ r, double* __restrict__ x)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        r[k] = fixed && fixed[k] ? 0.0 : b[k];
        x[k] = 0;
    }

    /// x += alpha p, r -= alpha q with alpha = rz / pAp, or alpha = 0 on a breakdown (pAp not positive).
    __global__ void update_solution(int n, const double* __restrict__ scalars, int rz_slot, int pap_slot,
        const double* __restrict__ p, const double* __restrict__ q, double* __restrict__ x, double* __restrict__ r)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        const double pap = scalars[pap_slot];
        const double alpha = pap > 0 && isfinite(pap) ? scalars[rz_slot] / pap : 0.0;
        x[k] += alpha * p[k];
        r[k] -= alpha * q[k];
    }

    /// p = z + beta p with beta = rz_new / rz_old.
    __global__ void update_direction(int n, const double* __restrict__ scalars, int new_slot, int old_slot,
        const double* __restrict__ z, double* __restrict__ p)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        const double beta = scalars[new_slot] / scalars[old_slot];
        p[k] = z[k] + beta * p[k];
    }

    /// r = P (b - q).
    __global__ void masked_residual(int n, const double* __restrict__ b, const double* __restrict__ q,
        const unsigned char* __restrict__ fixed, double* __restrict__ r)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        r[k] = fixed && fixed[k] ? 0.0 : b[k] - q[k];
    }

    /// v -= (scalars[slot] * inverse) d: removes v's component along the constraint (d = a, inverse =
    /// 1 / a.a, scalars[slot] = a.v) or the preconditioner's (d = M a, inverse = 1 / a.M a, scalars[slot] =
    /// M a . r).
    __global__ void remove_component(int n, const double* __restrict__ scalars, int slot, double inverse,
        const double* __restrict__ d, double* __restrict__ v)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        v[k] -= scalars[slot] * inverse * d[k];
    }

    // Device scalars: (r.z, r.r) of even iterates at 0, 1, of odd ones at 2, 3; p.Ap at 4; the
    // true residual's r.r at 5; a constraint's products at 6 (and 7 for its set-up's a.a, a.M a).
    constexpr int PAP = 4, TRUE_RR = 5, PROJECTION = 6, NUM_SCALARS = 8;

} // namespace

void DevicePCG::set_fixed_dofs(const std::vector<char>& fixed)
{
    std::vector<unsigned char> flags(fixed.size());
    for (size_t k = 0; k < flags.size(); ++k)
        flags[k] = fixed[k] ? 1 : 0;
    m_fixed.upload(flags);
}

void DevicePCG::prepare(int n, int block_size, int num_block_rows)
{
    if (m_fixed.size() != 0 && m_fixed.size() != size_t(n))
        throw std::invalid_argument("DevicePCG: " + std::to_string(m_fixed.size()) + " fixed-dof flags for a matrix of "
            + std::to_string(n) + " rows");
    for (auto* v : { &m_r, &m_z, &m_p, &m_q })
        v->resize(size_t(n));
    m_inverse_diagonal.resize(size_t(num_block_rows) * size_t(block_size * block_size));
    m_diagonal.resize(size_t(num_block_rows) * size_t(block_size * block_size));
    m_partials.resize(2 * REDUCTION_PARTIALS);
    m_scalars.resize(NUM_SCALARS);
}

PcgResult DevicePCG::solve_device(
    const DeviceLinearOperator& A, const double* d_b, double* d_x, const DevicePreconditioner* preconditioner)
{
    if (!(m_settings.relative_tolerance > 0) || m_settings.max_iterations < 0)
        throw std::invalid_argument("DevicePCG: relative_tolerance must be > 0 and max_iterations >= 0");
    const int n = A.size(), B = A.block_size(), rows = A.num_block_rows();
    PcgResult result;
    if (n == 0) {
        result.converged = true;
        return result;
    }
    prepare(n, B, rows);
    const unsigned char* fixed = m_fixed.size() ? m_fixed.data() : nullptr;
    double *r = m_r.data(), *z = m_z.data(), *p = m_p.data(), *q = m_q.data(), *s = m_scalars.data();
    double* partials = m_partials.data();

    if (preconditioner && preconditioner->size() != n)
        throw std::invalid_argument("DevicePCG: a preconditioner of " + std::to_string(preconditioner->size())
            + " rows for a matrix of " + std::to_string(n));
    if (!preconditioner) {
        A.diagonal_blocks(m_diagonal.data());
        if (B == 2)
            invert_diagonal_blocks<2>
                <<<grid(rows), THREADS>>>(rows, m_diagonal.data(), fixed, m_inverse_diagonal.data());
        else
            invert_diagonal_blocks<3>
                <<<grid(rows), THREADS>>>(rows, m_diagonal.data(), fixed, m_inverse_diagonal.data());
        check_launch("launch of the block-Jacobi setup");
    }
    // A constraint (set_constraint): M a, a.a and a.M a once per solve.
    const double* a = m_constraint;
    double inverse_aa = 0, inverse_ama = 0;
    auto apply_preconditioner = [&](const double* from, double* to) {
        if (preconditioner)
            preconditioner->apply(from, to);
        else if (B == 2)
            apply_block_diagonal<2><<<grid(n), THREADS>>>(n, m_inverse_diagonal.data(), from, to);
        else
            apply_block_diagonal<3><<<grid(n), THREADS>>>(n, m_inverse_diagonal.data(), from, to);
        check_launch("launch of the preconditioner");
    };
    if (a) {
        m_constraint_image.resize(size_t(n));
        apply_preconditioner(a, m_constraint_image.data());
        deterministic_dot2(a, a, a, m_constraint_image.data(), size_t(n), partials, s + PROJECTION);
        double products[2];
        detail::copy_device_to_host(products, s + PROJECTION, sizeof(products));
        if (!(products[0] > 0) || !(products[1] > 0) || !std::isfinite(products[0]) || !std::isfinite(products[1]))
            throw std::invalid_argument("DevicePCG: the constraint direction is zero or not finite (a.a = "
                + std::to_string(products[0]) + ", a.M a = " + std::to_string(products[1]) + ")");
        inverse_aa = 1 / products[0];
        inverse_ama = 1 / products[1];
    }
    // Without the component along a (the constraint's multiplier times a).
    auto project = [&](double* v) {
        if (!a)
            return;
        deterministic_dot(a, v, size_t(n), partials, s + PROJECTION);
        remove_component<<<grid(n), THREADS>>>(n, s, PROJECTION, inverse_aa, a, v);
        check_launch("launch of the constraint's projection");
    };
    auto precondition = [&]() {
        apply_preconditioner(r, z);
        if (!a)
            return;
        // z = M r - (M a . r / a.M a) M a, orthogonal to a.
        deterministic_dot(m_constraint_image.data(), r, size_t(n), partials, s + PROJECTION);
        remove_component<<<grid(n), THREADS>>>(n, s, PROJECTION, inverse_ama, m_constraint_image.data(), z);
        check_launch("launch of the constrained preconditioner");
    };

    masked_copy<<<grid(n), THREADS>>>(n, d_b, fixed, r, d_x);
    check_launch("launch of the PCG start");
    project(r);
    precondition();
    detail::copy_device_to_device(p, z, size_t(n) * sizeof(double));
    deterministic_dot2(r, z, r, r, size_t(n), partials, s + 0);
    double host[NUM_SCALARS];
    detail::copy_device_to_host(host, s, sizeof(host));
    const double bnorm = std::sqrt(host[1]);
    if (!(bnorm > 0)) {
        result.converged = bnorm == 0;
        result.breakdown = !(bnorm == 0);
        return result;
    }
    const double target = m_settings.relative_tolerance * bnorm;
    if (std::sqrt(host[1]) <= target)
        result.converged = true;

    for (int it = 0; it < m_settings.max_iterations && !result.converged; ++it) {
        const int old_slot = (it % 2) * 2, new_slot = ((it + 1) % 2) * 2;
        A.multiply(p, q, fixed);
        deterministic_dot(p, q, size_t(n), partials, s + PAP);
        update_solution<<<grid(n), THREADS>>>(n, s, old_slot, PAP, p, q, d_x, r);
        check_launch("launch of the PCG update");
        project(r);
        precondition();
        deterministic_dot2(r, z, r, r, size_t(n), partials, s + new_slot);
        update_direction<<<grid(n), THREADS>>>(n, s, new_slot, old_slot, z, p);
        check_launch("launch of the PCG update");
        detail::copy_device_to_host(host, s, sizeof(host));
        const double pap = host[PAP];
        if (!(pap > 0) || !std::isfinite(pap)) {
            result.breakdown = true;
            break;
        }
        result.iterations = it + 1;
        const double rr = host[new_slot + 1];
        if (!std::isfinite(rr)) {
            result.breakdown = true;
            break;
        }
        if (std::sqrt(rr) <= target)
            result.converged = true;
    }

    // The true residual at the returned x (kept on the hyperplane against the drift of round-off).
    project(d_x);
    A.multiply(d_x, q, fixed);
    masked_residual<<<grid(n), THREADS>>>(n, d_b, q, fixed, r);
    check_launch("launch of the PCG residual");
    project(r);
    deterministic_dot(r, r, size_t(n), partials, s + TRUE_RR);
    detail::copy_device_to_host(host, s, sizeof(host));
    result.relative_residual = std::sqrt(host[TRUE_RR]) / bnorm;
    return result;
}

PcgResult DevicePCG::solve(const DeviceBsrMatrix& A, const std::vector<double>& b, std::vector<double>& x)
{
    if (b.size() != size_t(A.size()))
        throw std::invalid_argument("DevicePCG::solve: b has " + std::to_string(b.size()) + " entries, the matrix "
            + std::to_string(A.size()) + " rows");
    DeviceArray<double> d_b(b), d_x(b.size());
    const PcgResult result = solve_device(A, d_b.data(), d_x.data());
    x = d_x.download();
    return result;
}

} // namespace diffipc::gpu
