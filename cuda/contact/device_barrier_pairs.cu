// DeviceBarrier::set_pairs_device: prepare_barrier_pairs (barrier_pairs.cpp) on the GPU, for pair lists
// that are already in GPU memory (DeviceContact's active set). The same outputs:
//  - per pair (structure of arrays): kind, vertices[a #P + p] (-1 unused), plane, eps_x (the edge-edge
//    mollifier threshold at rest, the host's formula without FMA: this file is compiled with -fmad=false);
//  - gradient incidences: the codes p 4 + a grouped by vertex, increasing within a vertex (a stable radix
//    sort of (vertex, code) pairs emitted in code order), and #V + 1 offsets (binary searches);
//  - the contact pattern and block incidences: the codes p 16 + a 4 + b sorted stably by the 64-bit key
//    v_a #V + v_b; each run of equal keys is a block slot (its columns increasing within a row), the
//    slot offsets are the runs' starts and the row offsets binary searches over the slots' keys.
// Every step is a stable sort, a scan-free compaction or an order-independent search: deterministic, and
// the arrays equal the host's element for element (tests/cuda/contact/test_device_barrier.cpp).

#include "cuda/common/device.hpp"
#include "cuda/contact/device_barrier.hpp"
#include "cuda/contact/pair_barrier.cuh"

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_select.cuh>
#include <cuda_runtime.h>
#include <thrust/iterator/counting_iterator.h>

#include <climits>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    template <typename T> void ensure(DeviceArray<T>& a, size_t n)
    {
        if (a.size() < n)
            a.resize(n + n / 2 + 64);
    }

    /// Bits that hold every value in [0, n].
    int bits_for(unsigned long long n)
    {
        int b = 1;
        while (b < 64 && (n >> b) != 0)
            ++b;
        return b;
    }

    __device__ vec3 rest_point(const double* rest, int dim, int v)
    {
        const double* q = rest + size_t(v) * dim;
        return vec3(q[0], q[1], dim == 3 ? q[2] : 0.0);
    }

    /// Per pair: the structure of arrays, and the sort inputs in code order (invalid: key nv / nv^2).
    __global__ void unpack_pairs(int np, int nv, int dim, const int* __restrict__ in, const double* __restrict__ rest,
        int* __restrict__ kind, int* __restrict__ vertices, int* __restrict__ plane, double* __restrict__ eps_x,
        int* __restrict__ vertex_keys, int* __restrict__ vertex_codes, long long* __restrict__ block_keys,
        int* __restrict__ block_codes)
    {
        const int p = blockIdx.x * blockDim.x + threadIdx.x;
        if (p >= np)
            return;
        const int* o = in + size_t(p) * 6;
        kind[p] = o[0];
        plane[p] = o[5];
        int v[4];
        for (int a = 0; a < 4; ++a) {
            v[a] = o[1 + a];
            vertices[size_t(a) * np + p] = v[a];
            vertex_keys[size_t(p) * 4 + a] = v[a] >= 0 ? v[a] : nv;
            vertex_codes[size_t(p) * 4 + a] = p * 4 + a;
        }
        eps_x[p] = ContactKind(o[0]) == ContactKind::EDGE_EDGE
            ? edge_edge_mollifier_threshold(rest_point(rest, dim, v[0]), rest_point(rest, dim, v[1]),
                rest_point(rest, dim, v[2]), rest_point(rest, dim, v[3]))
            : 0.0;
        const long long invalid = (long long)nv * nv;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                const size_t k = size_t(p) * 16 + a * 4 + b;
                block_keys[k] = v[a] >= 0 && v[b] >= 0 ? (long long)v[a] * nv + v[b] : invalid;
                block_codes[k] = p * 16 + a * 4 + b;
            }
    }

    /// offsets[v] = the first position of a key >= v in the sorted keys (v = 0 .. nv).
    template <typename Key>
    __global__ void lower_bounds(int count, const Key* __restrict__ sorted, size_t n, Key scale, int* __restrict__ out)
    {
        const int v = blockIdx.x * blockDim.x + threadIdx.x;
        if (v >= count)
            return;
        const Key target = Key(v) * scale;
        size_t lo = 0, hi = n;
        while (lo < hi) {
            const size_t mid = (lo + hi) / 2;
            if (sorted[mid] < target)
                lo = mid + 1;
            else
                hi = mid;
        }
        out[v] = int(lo);
    }

    /// flags[v] = vertex v has incidences.
    __global__ void nonempty(int nv, const int* __restrict__ offsets, unsigned char* __restrict__ flags)
    {
        const int v = blockIdx.x * blockDim.x + threadIdx.x;
        if (v < nv)
            flags[v] = offsets[v + 1] > offsets[v] ? 1 : 0;
    }

    /// flags[i] = entry i starts a run of equal valid keys.
    __global__ void run_starts(
        size_t n, long long invalid, const long long* __restrict__ keys, unsigned char* __restrict__ flags)
    {
        const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (i < n)
            flags[i] = keys[i] < invalid && (i == 0 || keys[i] != keys[i - 1]) ? 1 : 0;
    }

    /// Per slot: its key and its column.
    __global__ void slot_columns(int slots, int nv, const int* __restrict__ heads, const long long* __restrict__ keys,
        long long* __restrict__ head_keys, int* __restrict__ columns)
    {
        const int s = blockIdx.x * blockDim.x + threadIdx.x;
        if (s >= slots)
            return;
        const long long key = keys[heads[s]];
        head_keys[s] = key;
        columns[s] = int(key % nv);
    }

    /// The stable compaction of the indices whose flag is set; returns their count.
    int select_flagged(
        const unsigned char* flags, int n, int* out, DeviceArray<int>& count, DeviceArray<unsigned char>& temp)
    {
        thrust::counting_iterator<int> indices(0);
        size_t bytes = 0;
        check_cuda(cub::DeviceSelect::Flagged(nullptr, bytes, indices, flags, out, count.data(), n),
            "cub::DeviceSelect::Flagged (size query)");
        ensure(temp, bytes);
        check_cuda(cub::DeviceSelect::Flagged(temp.data(), bytes, indices, flags, out, count.data(), n),
            "cub::DeviceSelect::Flagged");
        int c = 0;
        detail::copy_device_to_host(&c, count.data(), sizeof(int));
        return c;
    }

} // namespace

void DeviceBarrier::set_pairs_device(const int* d_pairs, int np)
{
    if (m_dim == 0)
        throw std::logic_error("DeviceBarrier::set_pairs_device: call upload() first");
    if (np < 0 || np > INT_MAX / 16)
        throw std::invalid_argument("DeviceBarrier::set_pairs_device: " + std::to_string(np) + " pairs");
    const int nv = m_num_vertices;
    m_pairs = BarrierPairs {};
    m_pairs.dim = m_dim;
    m_pairs.num_vertices = nv;
    m_pairs.num_pairs = np;
    m_pairs.row_offsets.assign(size_t(nv) + 1, 0);
    m_num_rows = 0;
    m_count.resize(1);
    if (np == 0) {
        for (auto* a : { &m_kind, &m_vertices, &m_plane, &m_rows, &m_vertex_codes, &m_slot_offsets, &m_slot_codes })
            a->resize(0);
        m_eps_x.resize(0);
        m_vertex_offsets.upload(m_pairs.row_offsets);
        m_pair_energy.resize(0);
        return;
    }
    const size_t n4 = size_t(np) * 4, n16 = size_t(np) * 16;
    m_kind.resize(size_t(np));
    m_plane.resize(size_t(np));
    m_eps_x.resize(size_t(np));
    m_vertices.resize(n4);
    m_pair_energy.resize(size_t(np));
    ensure(m_keys, n16);
    ensure(m_sorted_keys, n16);
    ensure(m_codes, n16);
    ensure(m_block_keys, n16);
    ensure(m_sorted_block_keys, n16);
    m_slot_codes.resize(n16);
    m_vertex_codes.resize(n4);
    // m_keys holds the vertex keys (4 per pair), m_codes the block codes (16 per pair), m_heads the vertex
    // codes before sorting.
    ensure(m_heads, n16);
    unpack_pairs<<<grid(size_t(np)), THREADS>>>(np, nv, m_dim, d_pairs, m_d_rest.data(), m_kind.data(),
        m_vertices.data(), m_plane.data(), m_eps_x.data(), m_keys.data(), m_heads.data(), m_block_keys.data(),
        m_codes.data());
    check_launch("launch of the pair unpacking");

    // Gradient incidences: (vertex, code) sorted stably by vertex.
    size_t bytes = 0;
    const int vertex_bits = bits_for((unsigned long long)nv);
    check_cuda(cub::DeviceRadixSort::SortPairs(nullptr, bytes, m_keys.data(), m_sorted_keys.data(), m_heads.data(),
                   m_vertex_codes.data(), int(n4), 0, vertex_bits),
        "cub::DeviceRadixSort::SortPairs (size query)");
    ensure(m_temp, bytes);
    check_cuda(cub::DeviceRadixSort::SortPairs(m_temp.data(), bytes, m_keys.data(), m_sorted_keys.data(),
                   m_heads.data(), m_vertex_codes.data(), int(n4), 0, vertex_bits),
        "cub::DeviceRadixSort::SortPairs of the vertex incidences");
    m_vertex_offsets.resize(size_t(nv) + 1);
    lower_bounds<int><<<grid(size_t(nv) + 1), THREADS>>>(nv + 1, m_sorted_keys.data(), n4, 1, m_vertex_offsets.data());
    check_launch("launch of the vertex offsets");
    ensure(m_flags, std::max(size_t(nv), n16));
    nonempty<<<grid(size_t(nv)), THREADS>>>(nv, m_vertex_offsets.data(), m_flags.data());
    check_launch("launch of the nonempty rows");
    m_rows.resize(size_t(nv));
    m_num_rows = select_flagged(m_flags.data(), nv, m_rows.data(), m_count, m_temp);

    // Blocks: (key, code) sorted stably by key; runs of equal keys are the slots.
    const long long invalid = (long long)nv * nv;
    const int block_bits = bits_for((unsigned long long)invalid);
    bytes = 0;
    check_cuda(cub::DeviceRadixSort::SortPairs(nullptr, bytes, m_block_keys.data(), m_sorted_block_keys.data(),
                   m_codes.data(), m_slot_codes.data(), int(n16), 0, block_bits),
        "cub::DeviceRadixSort::SortPairs (size query)");
    ensure(m_temp, bytes);
    check_cuda(cub::DeviceRadixSort::SortPairs(m_temp.data(), bytes, m_block_keys.data(), m_sorted_block_keys.data(),
                   m_codes.data(), m_slot_codes.data(), int(n16), 0, block_bits),
        "cub::DeviceRadixSort::SortPairs of the block incidences");
    run_starts<<<grid(n16), THREADS>>>(n16, invalid, m_sorted_block_keys.data(), m_flags.data());
    check_launch("launch of the slot starts");
    const int slots = select_flagged(m_flags.data(), int(n16), m_heads.data(), m_count, m_temp);
    // The valid entries: those before the first invalid key.
    m_bounds.resize(2); // lower bounds of 0 and of `invalid`
    lower_bounds<long long><<<1, 2>>>(2, m_sorted_block_keys.data(), n16, invalid, m_bounds.data());
    check_launch("launch of the valid entries' count");
    int num_valid = 0;
    detail::copy_device_to_host(&num_valid, m_bounds.data() + 1, sizeof(int));
    m_slot_offsets.resize(size_t(slots) + 1);
    detail::copy_device_to_device(m_slot_offsets.data(), m_heads.data(), size_t(slots) * sizeof(int));
    detail::copy_host_to_device(m_slot_offsets.data() + slots, &num_valid, sizeof(int));
    ensure(m_head_keys, size_t(slots));
    ensure(m_columns, size_t(slots));
    slot_columns<<<grid(size_t(slots)), THREADS>>>(
        slots, nv, m_heads.data(), m_sorted_block_keys.data(), m_head_keys.data(), m_columns.data());
    check_launch("launch of the slot columns");
    // Row offsets: the first slot whose key is >= r nv.
    m_block_rows.resize(size_t(nv) + 1);
    lower_bounds<long long><<<grid(size_t(nv) + 1), THREADS>>>(
        nv + 1, m_head_keys.data(), size_t(slots), (long long)nv, m_block_rows.data());
    check_launch("launch of the row offsets");
    // The pattern on the host (make_hessian_matrix, SumOperator::bind).
    m_pairs.row_offsets = m_block_rows.download();
    m_pairs.col_indices.resize(size_t(slots));
    if (slots > 0)
        detail::copy_device_to_host(m_pairs.col_indices.data(), m_columns.data(), size_t(slots) * sizeof(int));
}

} // namespace diffipc::gpu
