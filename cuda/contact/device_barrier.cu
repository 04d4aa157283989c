#include "cuda/contact/device_barrier.hpp"

#include "cuda/common/device.hpp"
#include "cuda/contact/pair_barrier.cuh"
#include "cuda/contact/pair_gather.hpp"
#include "cuda/linalg/reduction.hpp"

#include <cuda_runtime.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 128;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// The per-pair inputs of the kernels (structure of arrays, barrier_pairs.hpp).
    struct PairArrays {
        int np, dim;
        const int* kind;
        const int* vertices; // vertex a of pair p at a np + p
        const int* plane;
        const double* eps_x;
        const double* normals; // #planes * 3
        PairModel model; // the barrier's dmin^2 and shat, or the penalty's dhat
    };

    __device__ ContactKind load_pair(const PairArrays& P, int p, const double* x, vec3* points, vec3& normal)
    {
        const ContactKind kind = ContactKind(P.kind[p]);
        const int nv = contact_num_vertices(kind);
        for (int a = 0; a < nv; ++a) {
            const int v = P.vertices[size_t(a) * P.np + p];
            const double* q = x + size_t(v) * P.dim;
            points[a] = vec3(q[0], q[1], P.dim == 3 ? q[2] : 0.0);
        }
        const int plane = P.plane[p];
        normal = plane >= 0 ? vec3::load(P.normals + 3 * size_t(plane)) : vec3();
        return kind;
    }

    __global__ void pair_energies(PairArrays P, const double* __restrict__ x, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 points[4], normal;
        const ContactKind kind = load_pair(P, p, x, points, normal);
        out[p] = pair_energy(kind, P.dim, points, normal, P.eps_x[p], -1, P.model, nullptr, nullptr);
    }

    /// Local gradient k (= a dim + i) of pair p at k np + p.
    __global__ void pair_gradients(PairArrays P, const double* __restrict__ x, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 points[4], normal;
        const ContactKind kind = load_pair(P, p, x, points, normal);
        double g[CONTACT_MAX_DOFS];
        pair_energy(kind, P.dim, points, normal, P.eps_x[p], -1, P.model, g, nullptr);
        const int n = contact_num_vertices(kind) * P.dim;
        for (int k = 0; k < n; ++k)
            out[size_t(k) * P.np + p] = g[k];
    }

    /// Local Hessian entry (r, c) of pair p at (r L + c) np + p, L = 4 dim.
    __global__ void pair_hessians(
        PairArrays P, const double* __restrict__ x, bool project, double scale, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 points[4], normal;
        const ContactKind kind = load_pair(P, p, x, points, normal);
        double H[CONTACT_MAX_DOFS * CONTACT_MAX_DOFS];
        pair_energy_hessian(kind, P.dim, points, normal, P.eps_x[p], P.model, project, scale, H);
        const int n = contact_num_vertices(kind) * P.dim, L = 4 * P.dim;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                out[size_t(r * L + c) * P.np + p] = H[r * n + c];
    }

} // namespace

void DeviceBarrier::upload(int dim, const std::vector<double>& rest_positions, const std::vector<double>& plane_normals)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("DeviceBarrier: dim must be 2 or 3, not " + std::to_string(dim));
    if (rest_positions.size() % size_t(dim) != 0 || plane_normals.size() % 3 != 0)
        throw std::invalid_argument(
            "DeviceBarrier: rest_positions must hold #V * dim values, plane_normals #planes * 3");
    m_dim = dim;
    m_num_vertices = int(rest_positions.size() / size_t(dim));
    m_rest = rest_positions;
    m_d_rest.upload(rest_positions);
    m_num_planes = int(plane_normals.size() / 3);
    m_normals.upload(plane_normals);
    m_partials.resize(REDUCTION_PARTIALS);
    m_scalar.resize(1);
    set_pairs({});
}

void DeviceBarrier::set_pairs(const std::vector<BarrierPair>& pairs)
{
    if (m_dim == 0)
        throw std::logic_error("DeviceBarrier::set_pairs: call upload() first");
    m_pairs = prepare_barrier_pairs(m_dim, m_rest, m_num_planes, pairs);
    m_kind.upload(m_pairs.kind);
    m_vertices.upload(m_pairs.vertices);
    m_plane.upload(m_pairs.plane);
    m_eps_x.upload(m_pairs.eps_x);
    m_rows.upload(m_pairs.rows);
    m_vertex_offsets.upload(m_pairs.vertex_offsets);
    m_vertex_codes.upload(m_pairs.vertex_codes);
    m_slot_offsets.upload(m_pairs.slot_offsets);
    m_slot_codes.upload(m_pairs.slot_codes);
    m_num_rows = int(m_pairs.rows.size());
    m_pair_energy.resize(size_t(m_pairs.num_pairs));
    // The gradient and Hessian scratch is sized on first use.
}

DeviceBarrier::Layout DeviceBarrier::layout() const
{
    return Layout { m_pairs.num_pairs, m_num_rows, m_pairs.num_slots(), m_vertices.data(), m_rows.data(),
        m_vertex_offsets.data(), m_vertex_codes.data(), m_slot_offsets.data(), m_slot_codes.data() };
}

DeviceBsrMatrix DeviceBarrier::make_hessian_matrix() const
{
    DeviceBsrMatrix H;
    H.set_pattern(m_dim, m_pairs.row_offsets, m_pairs.col_indices);
    return H;
}

namespace {
    PairArrays pair_arrays(const BarrierPairs& pairs, const BarrierSettings& s, const DeviceArray<int>& kind,
        const DeviceArray<int>& vertices, const DeviceArray<int>& plane, const DeviceArray<double>& eps_x,
        const DeviceArray<double>& normals)
    {
        return PairArrays { pairs.num_pairs, pairs.dim, kind.data(), vertices.data(), plane.data(), eps_x.data(),
            normals.data(), pair_model(s.penalty, s.dhat, s.dmin) };
    }
} // namespace

double DeviceBarrier::energy_device(const double* d_x) const
{
    const int np = m_pairs.num_pairs;
    if (np == 0)
        return 0.0;
    const PairArrays P = pair_arrays(m_pairs, m_settings, m_kind, m_vertices, m_plane, m_eps_x, m_normals);
    pair_energies<<<grid(size_t(np)), THREADS>>>(P, d_x, m_pair_energy.data());
    check_launch("launch of the pair barrier energies");
    deterministic_sum(m_pair_energy.data(), size_t(np), m_partials.data(), m_scalar.data());
    double sum = 0;
    detail::copy_device_to_host(&sum, m_scalar.data(), sizeof(double));
    return std::isfinite(sum) ? m_settings.kappa * sum : std::numeric_limits<double>::infinity();
}

void DeviceBarrier::add_gradient_device(const double* d_x, double weight, double* d_g) const
{
    const int np = m_pairs.num_pairs;
    if (np == 0)
        return;
    m_pair_gradient.resize(size_t(4 * m_dim) * size_t(np));
    const PairArrays P = pair_arrays(m_pairs, m_settings, m_kind, m_vertices, m_plane, m_eps_x, m_normals);
    pair_gradients<<<grid(size_t(np)), THREADS>>>(P, d_x, m_pair_gradient.data());
    check_launch("launch of the pair barrier gradients");
    gather_pair_gradients(m_num_rows, m_dim, np, m_rows.data(), m_vertex_offsets.data(), m_vertex_codes.data(),
        m_pair_gradient.data(), weight * m_settings.kappa, d_g);
}

void DeviceBarrier::add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const
{
    if (H.block_size() != m_dim || H.num_block_rows() != m_num_vertices || H.row_offsets() != m_pairs.row_offsets
        || H.col_indices() != m_pairs.col_indices)
        throw std::invalid_argument("DeviceBarrier::add_hessian_device: the matrix does not have the current pair "
                                    "list's contact pattern (make it with make_hessian_matrix() after set_pairs())");
    const int np = m_pairs.num_pairs;
    if (np == 0)
        return;
    const int L = 4 * m_dim;
    m_pair_hessian.resize(size_t(L * L) * size_t(np));
    const PairArrays P = pair_arrays(m_pairs, m_settings, m_kind, m_vertices, m_plane, m_eps_x, m_normals);
    pair_hessians<<<grid(size_t(np)), THREADS>>>(P, d_x, project, weight * m_settings.kappa, m_pair_hessian.data());
    check_launch("launch of the pair barrier Hessians");
    gather_pair_hessians(m_pairs.num_slots(), m_dim, np, m_slot_offsets.data(), m_slot_codes.data(),
        m_pair_hessian.data(), H.device_values());
}

} // namespace diffipc::gpu
