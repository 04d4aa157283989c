#include "cuda/broad_phase/device_broad_phase.hpp"
#include "cuda/common/device_event.hpp"

#include "cuda/broad_phase/candidate_filter.cuh"
#include "cuda/broad_phase/lbvh.cuh"
#include "cuda/common/device.hpp"
#include "cuda/common/kernels.cuh"
#include "forward/common/error.hpp" // header-only, standard library only: format_number
#include "forward/kernels/primitive_box.hpp"

#include <cub/device/device_radix_sort.cuh>
#include <cuda_runtime.h>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;
    /// Blocks of the first stage of the bounds reduction (and the second stage's width).
    constexpr int BOUNDS_BLOCKS = 256;

    /// Status words, read back in one copy: pair counters per kind, non-finite flags per primitive kind, stack
    /// overflow.
    enum Status : int {
        COUNT_VE = 0,
        COUNT_VF,
        COUNT_EE,
        NONFINITE_VERTEX,
        NONFINITE_EDGE,
        NONFINITE_FACE,
        STACK_OVERFLOW,
        NUM_STATUS
    };

    enum ContactKind : int { VERTEX_EDGE = 0, VERTEX_FACE = 1, EDGE_EDGE = 2 };

    unsigned blocks_for(std::size_t n) { return unsigned((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    // ---- boxes ----

    template <int N, int DIM>
    __global__ void boxes_kernel(const double* x_t0, const double* x_t1, const int* ids, int count, double radius,
        Box* boxes, unsigned long long* nonfinite)
    {
        const int i = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (i >= count)
            return;
        const Box box = primitive_box<N, DIM>(x_t0, x_t1, ids + std::size_t(N) * i, radius);
        boxes[i] = box;
        if (!box_is_finite(box))
            atomicOr(nonfinite, 1ull);
    }

    template <int N>
    void launch_boxes(int dim, const double* x_t0, const double* x_t1, const int* ids, int count, double radius,
        Box* boxes, unsigned long long* nonfinite)
    {
        if (count == 0)
            return;
        if (dim == 3)
            boxes_kernel<N, 3><<<blocks_for(count), THREADS>>>(x_t0, x_t1, ids, count, radius, boxes, nonfinite);
        else
            boxes_kernel<N, 2><<<blocks_for(count), THREADS>>>(x_t0, x_t1, ids, count, radius, boxes, nonfinite);
        check_launch("the broad phase's box kernel");
    }

    // ---- linear BVH (the per-node and per-query logic is in lbvh.cuh) ----

    using lbvh::box_union;
    using lbvh::empty_box;

    /// The bounds of the box centres (min and max per axis; exact, so any reduction order gives the same bits).
    /// Stage 1: block b reduces a grid-stride share into partials[b]; stage 2 (one block) reduces the partials.
    __global__ void centre_bounds_kernel(const Box* boxes, int count, Box* partials)
    {
        __shared__ Box s[THREADS];
        Box acc = empty_box();
        for (int i = int(blockIdx.x) * THREADS + threadIdx.x; i < count; i += int(gridDim.x) * THREADS) {
            acc = box_union(acc, lbvh::centre_box(boxes[i]));
        }
        s[threadIdx.x] = acc;
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (int(threadIdx.x) < h)
                s[threadIdx.x] = box_union(s[threadIdx.x], s[threadIdx.x + h]);
        }
        if (threadIdx.x == 0)
            partials[blockIdx.x] = s[0];
    }

    __global__ void final_bounds_kernel(const Box* partials, int count, Box* bounds)
    {
        __shared__ Box s[THREADS];
        s[threadIdx.x] = int(threadIdx.x) < count ? partials[threadIdx.x] : empty_box();
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (int(threadIdx.x) < h)
                s[threadIdx.x] = box_union(s[threadIdx.x], s[threadIdx.x + h]);
        }
        if (threadIdx.x == 0)
            *bounds = s[0];
    }

    __global__ void morton_kernel(
        const Box* boxes, int count, int dim, const Box* bounds, std::uint64_t* codes, int* ids)
    {
        const int i = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (i >= count)
            return;
        codes[i] = lbvh::morton_code(boxes[i], *bounds, dim);
        ids[i] = i;
    }

    /// One thread per internal node.
    __global__ void topology_kernel(const std::uint64_t* codes, int n, int* left, int* right, int* parent)
    {
        const int i = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (i < n - 1)
            lbvh::build_internal_node(codes, n, i, left, right, parent);
    }

    /// Leaf k's box: the box of the primitive at sorted position k.
    __global__ void leaf_boxes_kernel(const Box* boxes, const int* sorted_ids, int n, Box* nodes)
    {
        const int k = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            nodes[n - 1 + k] = boxes[sorted_ids[k]];
    }

    __device__ inline Box load_box_l2(const Box* p)
    {
        // Written by another thread of this kernel: read through L2, past any stale L1 line.
        Box b;
        const double* q = reinterpret_cast<const double*>(p);
        for (int k = 0; k < 3; ++k) {
            b.min[k] = __ldcg(q + k);
            b.max[k] = __ldcg(q + 3 + k);
        }
        return b;
    }

    /// Bottom-up refit: the second of a node's children to arrive writes the node's box (an exact union).
    __global__ void refit_kernel(const int* left, const int* right, const int* parent, int n, Box* nodes, int* visits)
    {
        const int k = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        int node = parent[n - 1 + k];
        while (node >= 0) {
            __threadfence();
            if (atomicAdd(visits + node, 1) == 0)
                return;
            nodes[node] = box_union(load_box_l2(nodes + left[node]), load_box_l2(nodes + right[node]));
            node = parent[node];
        }
    }

    using lbvh::TreeView;

    /// One thread per query primitive q: emits the key (first << 32 | second) of every accepted pair.
    template <int KIND>
    __global__ void query_kernel(CollisionMeshView mesh, const Box* query_boxes, int n_queries, TreeView tree,
        unsigned long long* status, unsigned long long* keys, unsigned long long capacity)
    {
        const int q = int(blockIdx.x) * blockDim.x + threadIdx.x;
        if (q >= n_queries)
            return;
        int first = q;
        if (KIND != EDGE_EDGE) {
            first = mesh.vertices[q];
            if (!mesh.may_be_point(first))
                return;
        }
        const Box box = query_boxes[q];
        unsigned long long* counter = status
            + (KIND == VERTEX_EDGE        ? COUNT_VE
                    : KIND == VERTEX_FACE ? COUNT_VF
                                          : COUNT_EE);
        const bool ok = lbvh::traverse(tree, box, [&](int j) {
            bool accept;
            if (KIND == VERTEX_EDGE)
                accept = mesh.accept_vertex_edge(first, j);
            else if (KIND == VERTEX_FACE)
                accept = mesh.accept_vertex_face(first, j);
            else
                accept = j > q && mesh.accept_edge_edge(q, j);
            if (!accept)
                return;
            const unsigned long long slot = atomicAdd(counter, 1ull);
            if (slot < capacity)
                keys[slot] = (static_cast<unsigned long long>(first) << 32) | static_cast<unsigned int>(j);
        });
        if (!ok)
            atomicOr(status + STACK_OVERFLOW, 1ull);
    }

    __global__ void unpack_kernel(const unsigned long long* keys, std::size_t count, int* pairs)
    {
        const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= count)
            return;
        pairs[2 * k] = int(keys[k] >> 32);
        pairs[2 * k + 1] = int(keys[k] & 0xffffffffull);
    }

    /// Bits needed for values in [0, n).
    int bit_width(long long n)
    {
        int bits = 1;
        while (bits < 63 && (1ll << bits) < n)
            ++bits;
        return bits;
    }

    /// The device buffers of one tree, kept between calls.
    struct Tree {
        DeviceArray<std::uint64_t> codes, sorted_codes;
        DeviceArray<int> ids, sorted_ids, left, right, parent, visits;
        DeviceArray<Box> nodes;
        int n = 0;

        TreeView view() const
        {
            TreeView v;
            v.n = n;
            v.nodes = nodes.data();
            v.left = left.data();
            v.right = right.data();
            v.leaf_ids = sorted_ids.data();
            return v;
        }
    };

    /// The pair buffers of one kind.
    struct PairBuffer {
        DeviceArray<unsigned long long> keys, sorted_keys;
        DeviceArray<int> pairs;
        std::size_t count = 0;
    };

    template <typename T> void upload_or_empty(DeviceArray<T>& array, const std::vector<T>& host)
    {
        if (host.empty())
            array.resize(0);
        else
            array.upload(host);
    }

} // namespace

struct DeviceBroadPhase::Impl {
    int dim = 3;
    int num_vertices = 0;
    int num_groups = 0;
    DeviceArray<int> vertices, edges, faces, vertex_group, edge_source;
    DeviceArray<char> group_self_contact, group_kinematic, point, edge_shift_positive;
    CollisionMeshView view;

    DeviceArray<Box> vertex_boxes, edge_boxes, face_boxes, bounds_partials, bounds;
    Tree edge_tree, face_tree;
    PairBuffer pairs[3];
    DeviceArray<unsigned long long> status;
    DeviceArray<unsigned char> temp;
    DeviceArray<double> host_x_t0, host_x_t1; ///< uploads of the host variant

    DeviceEvent start, boxes_done, build_done, query_done, sort_done;
    BroadPhaseTiming timing;

    void ensure_temp(std::size_t bytes)
    {
        if (temp.size() < bytes)
            temp.resize(bytes);
    }

    /// Builds the tree over `boxes` (count primitives).
    void build(Tree& tree, const Box* boxes, int count)
    {
        tree.n = count;
        if (count == 0)
            return;
        tree.codes.resize(std::size_t(count));
        tree.sorted_codes.resize(std::size_t(count));
        tree.ids.resize(std::size_t(count));
        tree.sorted_ids.resize(std::size_t(count));
        tree.nodes.resize(std::size_t(2 * count - 1));
        tree.left.resize(std::size_t(std::max(count - 1, 1)));
        tree.right.resize(std::size_t(std::max(count - 1, 1)));
        tree.visits.resize(std::size_t(std::max(count - 1, 1)));
        tree.parent.resize(std::size_t(2 * count - 1));

        const int stage1 = int(std::min<unsigned>(blocks_for(std::size_t(count)), BOUNDS_BLOCKS));
        centre_bounds_kernel<<<stage1, THREADS>>>(boxes, count, bounds_partials.data());
        check_launch("the broad phase's bounds kernel");
        final_bounds_kernel<<<1, THREADS>>>(bounds_partials.data(), stage1, bounds.data());
        check_launch("the broad phase's bounds kernel");
        morton_kernel<<<blocks_for(std::size_t(count)), THREADS>>>(
            boxes, count, dim, bounds.data(), tree.codes.data(), tree.ids.data());
        check_launch("the broad phase's Morton code kernel");

        // (code, index) sorted by code; the LSD radix sort is stable, so equal codes stay in index order and the
        // tree depends on the input alone.
        const int end_bit = dim == 3 ? 63 : 62;
        std::size_t bytes = 0;
        check_cuda(cub::DeviceRadixSort::SortPairs(nullptr, bytes, tree.codes.data(), tree.sorted_codes.data(),
                       tree.ids.data(), tree.sorted_ids.data(), count, 0, end_bit),
            "cub::DeviceRadixSort::SortPairs (size query)");
        ensure_temp(bytes);
        check_cuda(cub::DeviceRadixSort::SortPairs(temp.data(), bytes, tree.codes.data(), tree.sorted_codes.data(),
                       tree.ids.data(), tree.sorted_ids.data(), count, 0, end_bit),
            "cub::DeviceRadixSort::SortPairs of the Morton codes");

        leaf_boxes_kernel<<<blocks_for(std::size_t(count)), THREADS>>>(
            boxes, tree.sorted_ids.data(), count, tree.nodes.data());
        check_launch("the broad phase's leaf kernel");
        if (count == 1) {
            int minus_one = -1;
            check_cuda(cudaMemcpy(tree.parent.data(), &minus_one, sizeof(int), cudaMemcpyHostToDevice),
                "cudaMemcpy of the tree's root");
            return;
        }
        topology_kernel<<<blocks_for(std::size_t(count - 1)), THREADS>>>(
            tree.sorted_codes.data(), count, tree.left.data(), tree.right.data(), tree.parent.data());
        check_launch("the broad phase's topology kernel");
        tree.visits.set_zero();
        refit_kernel<<<blocks_for(std::size_t(count)), THREADS>>>(
            tree.left.data(), tree.right.data(), tree.parent.data(), count, tree.nodes.data(), tree.visits.data());
        check_launch("the broad phase's refit kernel");
    }

    template <int KIND> void query(const Box* query_boxes, int n_queries, const Tree& tree)
    {
        PairBuffer& buffer = pairs[KIND];
        if (buffer.keys.size() == 0)
            buffer.keys.resize(std::size_t(4) * std::size_t(std::max(n_queries, 1)) + 1024);
        if (n_queries == 0 || tree.n == 0)
            return;
        query_kernel<KIND><<<blocks_for(std::size_t(n_queries)), THREADS>>>(
            view, query_boxes, n_queries, tree.view(), status.data(), buffer.keys.data(), buffer.keys.size());
        check_launch("the broad phase's query kernel");
    }

    void sort_pairs(int kind, int first_bound)
    {
        PairBuffer& buffer = pairs[kind];
        const std::size_t count = buffer.count;
        if (count == 0)
            return;
        buffer.sorted_keys.resize(std::max(buffer.sorted_keys.size(), count));
        buffer.pairs.resize(std::max(buffer.pairs.size(), 2 * count));
        const int end_bit = 32 + bit_width(first_bound);
        std::size_t bytes = 0;
        check_cuda(cub::DeviceRadixSort::SortKeys(
                       nullptr, bytes, buffer.keys.data(), buffer.sorted_keys.data(), count, 0, end_bit),
            "cub::DeviceRadixSort::SortKeys (size query)");
        ensure_temp(bytes);
        check_cuda(cub::DeviceRadixSort::SortKeys(
                       temp.data(), bytes, buffer.keys.data(), buffer.sorted_keys.data(), count, 0, end_bit),
            "cub::DeviceRadixSort::SortKeys of the candidate pairs");
        unpack_kernel<<<blocks_for(count), THREADS>>>(buffer.sorted_keys.data(), count, buffer.pairs.data());
        check_launch("the broad phase's unpack kernel");
    }
};

DeviceBroadPhase::DeviceBroadPhase(const CollisionMeshData& mesh)
{
    const auto fail = [](const std::string& what) { throw std::invalid_argument("broad phase: " + what); };
    if (mesh.dim != 2 && mesh.dim != 3)
        fail("collision mesh dimension must be 2 or 3, got " + std::to_string(mesh.dim));
    if (mesh.num_vertices < 0)
        fail("the number of vertices must be >= 0");
    if (mesh.edges.size() % 2 != 0)
        fail("collision edges must be #CE by 2");
    if (mesh.dim == 3 && mesh.faces.size() % 3 != 0)
        fail("collision faces must be #CF by 3");
    if (mesh.vertex_group.size() != std::size_t(mesh.num_vertices))
        fail("vertex_group must have #V entries");
    const std::size_t num_groups = std::min(mesh.group_self_contact.size(), mesh.group_kinematic.size());
    for (int g : mesh.vertex_group)
        if (g >= 0 && std::size_t(g) >= num_groups)
            fail("vertex group " + std::to_string(g) + " has no group_self_contact / group_kinematic entry");
    const auto in_range = [&](const std::vector<int>& indices) {
        for (int v : indices)
            if (v < 0 || v >= mesh.num_vertices)
                return false;
        return true;
    };
    if (!in_range(mesh.vertices) || !in_range(mesh.edges) || (mesh.dim == 3 && !in_range(mesh.faces)))
        fail("collision-mesh vertex index out of range [0, #V)");
    const int num_edges = int(mesh.edges.size() / 2);
    if (!mesh.point.empty() && mesh.point.size() != std::size_t(mesh.num_vertices))
        fail("point must be empty or have #V entries");
    if (!mesh.edge_source.empty()) {
        if (mesh.edge_source.size() != std::size_t(num_edges)
            || mesh.edge_shift_positive.size() != std::size_t(num_edges))
            fail("edge_source and edge_shift_positive must be empty or have #CE entries");
        for (int e : mesh.edge_source)
            if (e < 0 || e >= num_edges)
                fail("edge_source out of range [0, #CE)");
    }

    require_cuda_device("the GPU broad phase (gpu::DeviceBroadPhase)");
    m_impl = std::make_unique<Impl>();
    Impl& m = *m_impl;
    m.dim = mesh.dim;
    m.num_vertices = mesh.num_vertices;
    m.num_groups = int(num_groups);
    upload_or_empty(m.vertices, mesh.vertices);
    upload_or_empty(m.edges, mesh.edges);
    if (mesh.dim == 3)
        upload_or_empty(m.faces, mesh.faces);
    upload_or_empty(m.vertex_group, mesh.vertex_group);
    upload_or_empty(m.group_self_contact, mesh.group_self_contact);
    upload_or_empty(m.group_kinematic, mesh.group_kinematic);
    upload_or_empty(m.point, mesh.point);
    upload_or_empty(m.edge_source, mesh.edge_source);
    upload_or_empty(m.edge_shift_positive, mesh.edge_source.empty() ? std::vector<char>() : mesh.edge_shift_positive);

    CollisionMeshView& v = m.view;
    v.dim = mesh.dim;
    v.num_vertices = mesh.num_vertices;
    v.num_collision_vertices = int(mesh.vertices.size());
    v.num_edges = num_edges;
    v.num_faces = mesh.dim == 3 ? int(mesh.faces.size() / 3) : 0;
    v.vertices = m.vertices.data();
    v.edges = m.edges.data();
    v.faces = m.faces.data();
    v.vertex_group = m.vertex_group.data();
    v.group_self_contact = m.group_self_contact.data();
    v.group_kinematic = m.group_kinematic.data();
    v.point = mesh.point.empty() ? nullptr : m.point.data();
    v.edge_source = mesh.edge_source.empty() ? nullptr : m.edge_source.data();
    v.edge_shift_positive = mesh.edge_source.empty() ? nullptr : m.edge_shift_positive.data();

    m.vertex_boxes.resize(std::size_t(v.num_collision_vertices));
    m.edge_boxes.resize(std::size_t(v.num_edges));
    m.face_boxes.resize(std::size_t(v.num_faces));
    m.bounds_partials.resize(BOUNDS_BLOCKS);
    m.bounds.resize(1);
    m.status.resize(NUM_STATUS);
}

DeviceBroadPhase::~DeviceBroadPhase() = default;

DeviceCandidates DeviceBroadPhase::find(const double* d_x_t0, const double* d_x_t1, double inflation)
{
    if (!(inflation >= 0) || !is_finite(inflation))
        throw std::invalid_argument("broad phase: inflation must be finite and >= 0, got " + format_number(inflation));
    require_cuda_device("the GPU broad phase (gpu::DeviceBroadPhase)");
    Impl& m = *m_impl;
    const CollisionMeshView& v = m.view;
    const double radius = 0.5 * inflation;

    m.start.record();
    m.status.set_zero();
    unsigned long long* status = m.status.data();
    launch_boxes<1>(m.dim, d_x_t0, d_x_t1, m.vertices.data(), v.num_collision_vertices, radius, m.vertex_boxes.data(),
        status + NONFINITE_VERTEX);
    launch_boxes<2>(
        m.dim, d_x_t0, d_x_t1, m.edges.data(), v.num_edges, radius, m.edge_boxes.data(), status + NONFINITE_EDGE);
    if (m.dim == 3)
        launch_boxes<3>(
            m.dim, d_x_t0, d_x_t1, m.faces.data(), v.num_faces, radius, m.face_boxes.data(), status + NONFINITE_FACE);
    m.boxes_done.record();

    m.build(m.edge_tree, m.edge_boxes.data(), v.num_edges);
    if (m.dim == 3)
        m.build(m.face_tree, m.face_boxes.data(), v.num_faces);
    m.build_done.record();

    const auto run_queries = [&](int kind) {
        if (kind == VERTEX_EDGE)
            m.query<VERTEX_EDGE>(m.vertex_boxes.data(), v.num_collision_vertices, m.edge_tree);
        else if (kind == VERTEX_FACE)
            m.query<VERTEX_FACE>(m.vertex_boxes.data(), v.num_collision_vertices, m.face_tree);
        else
            m.query<EDGE_EDGE>(m.edge_boxes.data(), v.num_edges, m.edge_tree);
    };
    const int kinds[2] = { m.dim == 2 ? VERTEX_EDGE : VERTEX_FACE, m.dim == 2 ? -1 : EDGE_EDGE };
    for (int kind : kinds)
        if (kind >= 0)
            run_queries(kind);
    unsigned long long host_status[NUM_STATUS];
    check_cuda(cudaMemcpy(host_status, status, sizeof host_status, cudaMemcpyDeviceToHost),
        "the broad phase's kernels, or cudaMemcpy of their counts to the host");
    if (host_status[NONFINITE_VERTEX])
        throw std::invalid_argument("broad phase: non-finite position of a collision-mesh vertex");
    if (host_status[NONFINITE_EDGE])
        throw std::invalid_argument("broad phase: non-finite position of a collision-mesh edge");
    if (host_status[NONFINITE_FACE])
        throw std::invalid_argument("broad phase: non-finite position of a collision-mesh face");
    // A pair buffer that was too small: grow it and run that query again (the pairs are sorted afterwards, so
    // the result does not depend on which run found them).
    bool rerun = false;
    for (int kind : kinds) {
        if (kind < 0)
            continue;
        PairBuffer& buffer = m.pairs[kind];
        buffer.count = std::size_t(host_status[COUNT_VE + kind]);
        if (buffer.count > buffer.keys.size()) {
            buffer.keys.resize(buffer.count + buffer.count / 4 + 1024);
            check_cuda(cudaMemset(status + COUNT_VE + kind, 0, sizeof(unsigned long long)), "cudaMemset");
            run_queries(kind);
            rerun = true;
        }
    }
    if (rerun) {
        check_cuda(cudaMemcpy(host_status, status, sizeof host_status, cudaMemcpyDeviceToHost),
            "the broad phase's kernels, or cudaMemcpy of their counts to the host");
        for (int kind : kinds)
            if (kind >= 0 && std::size_t(host_status[COUNT_VE + kind]) != m.pairs[kind].count)
                throw std::runtime_error("broad phase: the pair count changed between two identical queries");
    }
    if (host_status[STACK_OVERFLOW])
        throw std::runtime_error("broad phase: the BVH traversal stack overflowed (a tree deeper than its bound)");
    m.query_done.record();

    for (int kind : kinds)
        if (kind >= 0)
            m.sort_pairs(kind, kind == EDGE_EDGE ? v.num_edges : v.num_vertices);
    m.sort_done.record();
    m.sort_done.synchronize("the broad phase's sort of the candidate pairs");

    m.timing.boxes_ms = m.boxes_done.ms_since(m.start);
    m.timing.build_ms = m.build_done.ms_since(m.boxes_done);
    m.timing.query_ms = m.query_done.ms_since(m.build_done);
    m.timing.sort_ms = m.sort_done.ms_since(m.query_done);
    m.timing.total_ms = m.sort_done.ms_since(m.start);

    DeviceCandidates out;
    const auto view_of = [&](int kind, const int*& data, std::size_t& count) {
        count = m.pairs[kind].count;
        data = count > 0 ? m.pairs[kind].pairs.data() : nullptr;
    };
    if (m.dim == 2) {
        view_of(VERTEX_EDGE, out.vertex_edge, out.num_vertex_edge);
    } else {
        view_of(VERTEX_FACE, out.vertex_face, out.num_vertex_face);
        view_of(EDGE_EDGE, out.edge_edge, out.num_edge_edge);
    }
    return out;
}

CandidatePairs DeviceBroadPhase::candidates(
    const std::vector<double>& x_t0, const std::vector<double>& x_t1, double inflation)
{
    Impl& m = *m_impl;
    const std::size_t n = std::size_t(m.num_vertices) * std::size_t(m.dim);
    for (const std::vector<double>* x : { &x_t0, &x_t1 })
        if (x->size() != n)
            throw std::invalid_argument("broad phase: positions have " + std::to_string(x->size())
                + " entries, expected #V * dim = " + std::to_string(n));
    require_cuda_device("the GPU broad phase (gpu::DeviceBroadPhase)");
    m.host_x_t0.upload(x_t0);
    const bool same = &x_t0 == &x_t1 || x_t0 == x_t1;
    if (!same)
        m.host_x_t1.upload(x_t1);
    const double* d_x_t0 = m.host_x_t0.data();
    return download(find(d_x_t0, same ? d_x_t0 : m.host_x_t1.data(), inflation));
}

CandidatePairs DeviceBroadPhase::candidates_near(const std::vector<double>& x, double inflation)
{
    return candidates(x, x, inflation);
}

CandidatePairs DeviceBroadPhase::download(const DeviceCandidates& c)
{
    CandidatePairs out;
    const auto copy = [](const int* data, std::size_t count, std::vector<std::array<int, 2>>& to) {
        to.resize(count);
        if (count > 0)
            check_cuda(cudaMemcpy(to.data(), data, count * 2 * sizeof(int), cudaMemcpyDeviceToHost),
                "cudaMemcpy of the candidate pairs to the host");
    };
    copy(c.vertex_edge, c.num_vertex_edge, out.vertex_edge);
    copy(c.vertex_face, c.num_vertex_face, out.vertex_face);
    copy(c.edge_edge, c.num_edge_edge, out.edge_edge);
    return out;
}

const BroadPhaseTiming& DeviceBroadPhase::timing() const { return m_impl->timing; }
int DeviceBroadPhase::dim() const { return m_impl->dim; }
int DeviceBroadPhase::num_vertices() const { return m_impl->num_vertices; }

DeviceBroadPhase::MeshPointers DeviceBroadPhase::mesh_pointers() const
{
    const CollisionMeshView& v = m_impl->view;
    return { v.vertices, v.edges, v.faces, v.num_collision_vertices, v.num_edges, v.num_faces };
}

} // namespace diffipc::gpu
