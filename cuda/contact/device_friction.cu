#include "cuda/contact/device_friction.hpp"

#include "cuda/common/device.hpp"
#include "cuda/contact/pair_barrier.cuh"
#include "cuda/contact/pair_gather.hpp"
#include "cuda/linalg/reduction.hpp"

#include <cuda_runtime.h>

#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 128;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// The kernels' inputs: the pairs' frozen data and vertices (vertex a of pair p at a np + p).
    struct FrictionArrays {
        int np, dim;
        const FrictionPair* data;
        const int* vertices;
        const double* x_start;
        double eps;
    };

    /// The pair's vertices' displacements since the step's start (z = 0 in 2D).
    __device__ void load_displacements(const FrictionArrays& P, int p, const double* x, vec3* dx)
    {
        const int nv = P.data[p].num_vertices;
        for (int a = 0; a < nv; ++a) {
            const size_t v = size_t(P.vertices[size_t(a) * P.np + p]) * P.dim;
            dx[a] = vec3(
                x[v] - P.x_start[v], x[v + 1] - P.x_start[v + 1], P.dim == 3 ? x[v + 2] - P.x_start[v + 2] : 0.0);
        }
    }

    __global__ void pair_energies(FrictionArrays P, const double* __restrict__ x, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 dx[4];
        load_displacements(P, p, x, dx);
        out[p] = pair_friction(P.dim, P.data[p], dx, P.eps, nullptr, nullptr);
    }

    /// Local gradient k (= a dim + i) of pair p at k np + p.
    __global__ void pair_gradients(FrictionArrays P, const double* __restrict__ x, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 dx[4];
        load_displacements(P, p, x, dx);
        double g[CONTACT_MAX_DOFS];
        pair_friction(P.dim, P.data[p], dx, P.eps, g, nullptr);
        const int n = P.data[p].num_vertices * P.dim;
        for (int k = 0; k < n; ++k)
            out[size_t(k) * P.np + p] = g[k];
    }

    /// Local Hessian entry (r, c) of pair p, times scale, at (r L + c) np + p, L = 4 dim.
    __global__ void pair_hessians(
        FrictionArrays P, const double* __restrict__ x, double scale, double* __restrict__ out)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= P.np)
            return;
        vec3 dx[4];
        load_displacements(P, p, x, dx);
        double H[CONTACT_MAX_DOFS * CONTACT_MAX_DOFS];
        pair_friction(P.dim, P.data[p], dx, P.eps, nullptr, H);
        const int n = P.data[p].num_vertices * P.dim, L = 4 * P.dim;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                out[size_t(r * L + c) * P.np + p] = scale * H[r * n + c];
    }

} // namespace

void DeviceFriction::upload(int dim, const std::vector<double>& rest_positions, int num_planes)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("DeviceFriction: dim must be 2 or 3, not " + std::to_string(dim));
    if (rest_positions.size() % size_t(dim) != 0 || num_planes < 0)
        throw std::invalid_argument("DeviceFriction: rest_positions must hold #V * dim values, num_planes >= 0");
    m_dim = dim;
    m_num_vertices = int(rest_positions.size() / size_t(dim));
    m_num_planes = num_planes;
    // The layout's barrier is never evaluated: its plane normals are not needed.
    m_layout.upload(dim, rest_positions, std::vector<double>(3 * size_t(num_planes), 0.0));
    m_partials.resize(REDUCTION_PARTIALS);
    m_scalar.resize(1);
    m_x_start.resize(rest_positions.size());
    m_x_start.set_zero();
    set_pairs({}, {});
}

void DeviceFriction::set_pairs(const std::vector<BarrierPair>& pairs, const std::vector<FrictionPair>& data)
{
    if (m_dim == 0)
        throw std::logic_error("DeviceFriction::set_pairs: call upload() first");
    if (pairs.size() != data.size())
        throw std::invalid_argument("DeviceFriction::set_pairs: " + std::to_string(pairs.size()) + " pairs but "
            + std::to_string(data.size()) + " frozen data");
    if (pairs.size() > size_t(INT_MAX / 16))
        throw std::invalid_argument("DeviceFriction::set_pairs: too many pairs for int incidence codes");
    std::vector<int> packed(6 * pairs.size());
    for (size_t p = 0; p < data.size(); ++p) {
        check_barrier_pair(m_dim, m_num_vertices, m_num_planes, pairs[p], p);
        const FrictionPair& f = data[p];
        bool finite = std::isfinite(f.scale) && f.scale >= 0;
        for (double v : f.weights)
            finite = finite && std::isfinite(v);
        for (double v : f.tangent)
            finite = finite && std::isfinite(v);
        const ContactKind kind = ContactKind(pairs[p].kind);
        if (f.num_vertices != contact_num_vertices(kind) || !finite)
            throw std::invalid_argument("DeviceFriction::set_pairs: friction pair " + std::to_string(p)
                + " has data that does not fit its kind (vertex count) or is not finite (mu lambda >= 0)");
        int* q = packed.data() + 6 * p;
        q[0] = pairs[p].kind;
        for (int a = 0; a < 4; ++a)
            q[1 + a] = a < f.num_vertices ? pairs[p].vertices[a] : -1;
        q[5] = kind == ContactKind::VERTEX_PLANE ? pairs[p].plane : -1;
    }
    m_packed.upload(packed);
    m_layout.set_pairs_device(m_packed.data(), int(pairs.size()));
    m_data.upload(data);
    m_pair_energy.resize(pairs.size());
    m_hessian = make_hessian_matrix();
}

void DeviceFriction::assemble_hessian(const double* d_x, double weight)
{
    m_hessian.set_zero();
    add_hessian_device(d_x, weight, false, m_hessian);
}

void DeviceFriction::set_step_start(const std::vector<double>& x_start, double eps)
{
    if (x_start.size() != size_t(num_dofs()))
        throw std::invalid_argument("DeviceFriction::set_step_start: x_start has " + std::to_string(x_start.size())
            + " entries, expected #dofs = " + std::to_string(num_dofs()));
    if (!(eps > 0) || !std::isfinite(eps))
        throw std::invalid_argument("DeviceFriction::set_step_start: eps = eps_v h must be positive and finite");
    m_x_start.upload(x_start);
    m_eps = eps;
}

DeviceBsrMatrix DeviceFriction::make_hessian_matrix() const { return m_layout.make_hessian_matrix(); }

double DeviceFriction::energy_device(const double* d_x) const
{
    const DeviceBarrier::Layout L = m_layout.layout();
    const int np = L.num_pairs;
    if (np == 0)
        return 0.0;
    const FrictionArrays P { np, m_dim, m_data.data(), L.vertices, m_x_start.data(), m_eps };
    pair_energies<<<grid(size_t(np)), THREADS>>>(P, d_x, m_pair_energy.data());
    check_launch("launch of the pair friction energies");
    deterministic_sum(m_pair_energy.data(), size_t(np), m_partials.data(), m_scalar.data());
    double sum = 0;
    detail::copy_device_to_host(&sum, m_scalar.data(), sizeof(double));
    return sum;
}

void DeviceFriction::add_gradient_device(const double* d_x, double weight, double* d_g) const
{
    const DeviceBarrier::Layout L = m_layout.layout();
    const int np = L.num_pairs;
    if (np == 0)
        return;
    m_pair_gradient.resize(size_t(4 * m_dim) * size_t(np));
    const FrictionArrays P { np, m_dim, m_data.data(), L.vertices, m_x_start.data(), m_eps };
    pair_gradients<<<grid(size_t(np)), THREADS>>>(P, d_x, m_pair_gradient.data());
    check_launch("launch of the pair friction gradients");
    gather_pair_gradients(
        L.num_rows, m_dim, np, L.rows, L.vertex_offsets, L.vertex_codes, m_pair_gradient.data(), weight, d_g);
}

void DeviceFriction::add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const
{
    (void)project; // PSD by construction
    const BarrierPairs& pattern = m_layout.pairs();
    if (H.block_size() != m_dim || H.num_block_rows() != m_num_vertices || H.row_offsets() != pattern.row_offsets
        || H.col_indices() != pattern.col_indices)
        throw std::invalid_argument("DeviceFriction::add_hessian_device: the matrix does not have the current "
                                    "pairs' pattern (make it with make_hessian_matrix() after set_pairs())");
    const DeviceBarrier::Layout L = m_layout.layout();
    const int np = L.num_pairs;
    if (np == 0)
        return;
    const int local = 4 * m_dim;
    m_pair_hessian.resize(size_t(local * local) * size_t(np));
    const FrictionArrays P { np, m_dim, m_data.data(), L.vertices, m_x_start.data(), m_eps };
    pair_hessians<<<grid(size_t(np)), THREADS>>>(P, d_x, weight, m_pair_hessian.data());
    check_launch("launch of the pair friction Hessians");
    gather_pair_hessians(
        L.num_slots, m_dim, np, L.slot_offsets, L.slot_codes, m_pair_hessian.data(), H.device_values());
}

} // namespace diffipc::gpu
