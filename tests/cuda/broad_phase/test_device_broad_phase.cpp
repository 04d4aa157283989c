// GPU broad phase (cuda/broad_phase/device_broad_phase.hpp) against the CPU broad phase
// (forward/contact/broad_phase/broad_phase.hpp): the same candidate sets, exactly, on 2D and 3D scenes (between
// bodies, self contact, planes, periodic images, kinematic groups), static and swept, with random perturbations;
// no pair closer than the inflation along the step is missed (checked with the CPU's exact distances, not with
// boxes). The GpuBroadPhaseHost tests run the ported __host__ __device__ code (boxes, exclusion rules) on the CPU
// and need no GPU; the GpuBroadPhase tests run the kernels and skip without one.

#include "cuda/broad_phase/candidate_filter.cuh"
#include "cuda/broad_phase/lbvh.cuh"
#include "cuda/common/kernels.cuh"
#include "forward/kernels/primitive_box.hpp"
#include "tests/cuda/broad_phase/broad_phase_test_utils.hpp"

#include "forward/contact/broad_phase/aabb.hpp"
#include "forward/contact/distance/distance.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

using namespace diffipc;
using namespace diffipc::test;

namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// The GPU box of every primitive of one kind, computed on the host with the ported code.
template <int N>
std::vector<gpu::Box> host_boxes(const CollisionMesh& mesh, const int* rows, Index count, const Positions& x_t0,
    const Positions& x_t1, double inflation)
{
    std::vector<gpu::Box> boxes(static_cast<size_t>(count));
    for (Index i = 0; i < count; ++i)
        boxes[size_t(i)] = mesh.dim == 3
            ? gpu::primitive_box<N, 3>(x_t0.data(), x_t1.data(), rows + N * i, 0.5 * inflation)
            : gpu::primitive_box<N, 2>(x_t0.data(), x_t1.data(), rows + N * i, 0.5 * inflation);
    return boxes;
}

/// Are the boxes the CPU's bit for bit (a non-finite CPU box must be a non-finite GPU box)?
::testing::AssertionResult same_boxes(const std::vector<AABB>& cpu, const std::vector<gpu::Box>& gpu_boxes)
{
    if (cpu.size() != gpu_boxes.size())
        return ::testing::AssertionFailure() << "sizes differ";
    for (size_t i = 0; i < cpu.size(); ++i) {
        if (!cpu[i].is_finite() || !gpu::box_is_finite(gpu_boxes[i])) {
            if (cpu[i].is_finite() || gpu::box_is_finite(gpu_boxes[i]))
                return ::testing::AssertionFailure() << "box " << i << ": finite on one side only";
            continue;
        }
        for (int k = 0; k < 3; ++k)
            if (!same_bits(cpu[i].min[k], gpu_boxes[i].min[k]) || !same_bits(cpu[i].max[k], gpu_boxes[i].max[k]))
                return ::testing::AssertionFailure()
                    << "box " << i << " axis " << k << ": CPU [" << cpu[i].min[k] << ", " << cpu[i].max[k] << "], GPU ["
                    << gpu_boxes[i].min[k] << ", " << gpu_boxes[i].max[k] << "]";
    }
    return ::testing::AssertionSuccess();
}

/// A host view of the mesh data (what the kernels see, with host pointers).
gpu::CollisionMeshView host_view(const gpu::CollisionMeshData& d)
{
    gpu::CollisionMeshView v;
    v.dim = d.dim;
    v.num_vertices = d.num_vertices;
    v.num_collision_vertices = int(d.vertices.size());
    v.num_edges = int(d.edges.size() / 2);
    v.num_faces = int(d.faces.size() / 3);
    v.vertices = d.vertices.data();
    v.edges = d.edges.data();
    v.faces = d.faces.data();
    v.vertex_group = d.vertex_group.data();
    v.group_self_contact = d.group_self_contact.data();
    v.group_kinematic = d.group_kinematic.data();
    v.point = d.point.empty() ? nullptr : d.point.data();
    v.edge_source = d.edge_source.empty() ? nullptr : d.edge_source.data();
    v.edge_shift_positive = d.edge_source.empty() ? nullptr : d.edge_shift_positive.data();
    return v;
}

/// A brute-force broad phase from the ported pieces alone (boxes, overlap test, exclusion rules), on the host.
gpu::CandidatePairs host_brute_force(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    const gpu::CollisionMeshData data = to_gpu(mesh);
    const gpu::CollisionMeshView view = host_view(data);
    const auto vb = host_boxes<1>(mesh, mesh.vertices.data(), mesh.vertices.size(), x_t0, x_t1, inflation);
    const auto eb = host_boxes<2>(mesh, mesh.edges.data(), mesh.edges.rows(), x_t0, x_t1, inflation);
    gpu::CandidatePairs out;
    if (mesh.dim == 2) {
        for (int i = 0; i < view.num_collision_vertices; ++i)
            for (int e = 0; e < view.num_edges; ++e)
                if (gpu::boxes_overlap(vb[size_t(i)], eb[size_t(e)]) && view.accept_vertex_edge(view.vertices[i], e))
                    out.vertex_edge.push_back({ view.vertices[i], e });
    } else {
        const auto fb = host_boxes<3>(mesh, mesh.faces.data(), mesh.faces.rows(), x_t0, x_t1, inflation);
        for (int i = 0; i < view.num_collision_vertices; ++i)
            for (int f = 0; f < view.num_faces; ++f)
                if (gpu::boxes_overlap(vb[size_t(i)], fb[size_t(f)]) && view.accept_vertex_face(view.vertices[i], f))
                    out.vertex_face.push_back({ view.vertices[i], f });
        for (int a = 0; a < view.num_edges; ++a)
            for (int b = a + 1; b < view.num_edges; ++b)
                if (gpu::boxes_overlap(eb[size_t(a)], eb[size_t(b)]) && view.accept_edge_edge(a, b))
                    out.edge_edge.push_back({ a, b });
    }
    std::sort(out.vertex_edge.begin(), out.vertex_edge.end());
    std::sort(out.vertex_face.begin(), out.vertex_face.end());
    std::sort(out.edge_edge.begin(), out.edge_edge.end());
    return out;
}

/// A linear BVH built on the host with the functions the kernels call (lbvh.cuh): Morton codes, a stable sort by
/// code (as CUB's radix sort), Karras' internal nodes, then the refit's "second child to arrive" rule run leaf by
/// leaf.
struct HostTree {
    int n = 0;
    std::vector<gpu::Box> nodes;
    std::vector<int> left, right, parent, ids;
    std::vector<std::uint64_t> codes;

    HostTree(const std::vector<gpu::Box>& boxes, int dim)
    {
        n = int(boxes.size());
        if (n == 0)
            return;
        gpu::Box bounds = gpu::lbvh::empty_box();
        for (const gpu::Box& b : boxes)
            bounds = gpu::lbvh::box_union(bounds, gpu::lbvh::centre_box(b));
        std::vector<std::uint64_t> unsorted(size_t(n), 0);
        for (int i = 0; i < n; ++i)
            unsorted[size_t(i)] = gpu::lbvh::morton_code(boxes[size_t(i)], bounds, dim);
        ids.resize(size_t(n));
        std::iota(ids.begin(), ids.end(), 0);
        std::stable_sort(
            ids.begin(), ids.end(), [&](int a, int b) { return unsorted[size_t(a)] < unsorted[size_t(b)]; });
        for (int id : ids)
            codes.push_back(unsorted[size_t(id)]);
        nodes.resize(size_t(2 * n - 1));
        for (int k = 0; k < n; ++k)
            nodes[size_t(n - 1 + k)] = boxes[size_t(ids[size_t(k)])];
        left.assign(size_t(std::max(n - 1, 1)), -2);
        right.assign(size_t(std::max(n - 1, 1)), -2);
        parent.assign(size_t(2 * n - 1), -2);
        parent[0] = -1;
        for (int i = 0; i < n - 1; ++i)
            gpu::lbvh::build_internal_node(codes.data(), n, i, left.data(), right.data(), parent.data());
        std::vector<int> visits(size_t(std::max(n - 1, 1)), 0);
        for (int k = 0; k < n; ++k)
            for (int node = parent[size_t(n - 1 + k)]; node >= 0; node = parent[size_t(node)]) {
                if (visits[size_t(node)]++ == 0)
                    break;
                nodes[size_t(node)]
                    = gpu::lbvh::box_union(nodes[size_t(left[size_t(node)])], nodes[size_t(right[size_t(node)])]);
            }
    }

    gpu::lbvh::TreeView view() const
    {
        gpu::lbvh::TreeView v;
        v.n = n;
        v.nodes = nodes.data();
        v.left = left.data();
        v.right = right.data();
        v.leaf_ids = ids.data();
        return v;
    }

    /// Is it a binary tree over all leaves (every node reached once from the root, parents consistent)?
    bool valid() const
    {
        if (n == 0)
            return true;
        std::vector<int> reached(size_t(2 * n - 1), 0);
        std::vector<int> stack = { 0 };
        int depth_guard = 0;
        while (!stack.empty() && depth_guard++ < 4 * n) {
            const int node = stack.back();
            stack.pop_back();
            if (node < 0 || node >= 2 * n - 1 || reached[size_t(node)]++)
                return false;
            if (node >= n - 1)
                continue;
            for (int child : { left[size_t(node)], right[size_t(node)] }) {
                if (child < 0 || child >= 2 * n - 1 || parent[size_t(child)] != node)
                    return false;
                stack.push_back(child);
            }
        }
        return std::all_of(reached.begin(), reached.end(), [](int r) { return r == 1; });
    }
};

/// The GPU broad phase's algorithm run on the host (the kernels' per-thread code in loops), sorted.
gpu::CandidatePairs host_lbvh(const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    const gpu::CollisionMeshData data = to_gpu(mesh);
    const gpu::CollisionMeshView view = host_view(data);
    const auto vb = host_boxes<1>(mesh, mesh.vertices.data(), mesh.vertices.size(), x_t0, x_t1, inflation);
    const auto eb = host_boxes<2>(mesh, mesh.edges.data(), mesh.edges.rows(), x_t0, x_t1, inflation);
    const HostTree edge_tree(eb, mesh.dim);
    EXPECT_TRUE(edge_tree.valid());
    gpu::CandidatePairs out;
    bool ok = true;
    if (mesh.dim == 2) {
        for (int i = 0; i < view.num_collision_vertices; ++i) {
            const int v = view.vertices[i];
            if (view.may_be_point(v))
                ok = ok && gpu::lbvh::traverse(edge_tree.view(), vb[size_t(i)], [&](int e) {
                    if (view.accept_vertex_edge(v, e))
                        out.vertex_edge.push_back({ v, e });
                });
        }
    } else {
        const auto fb = host_boxes<3>(mesh, mesh.faces.data(), mesh.faces.rows(), x_t0, x_t1, inflation);
        const HostTree face_tree(fb, 3);
        EXPECT_TRUE(face_tree.valid());
        for (int i = 0; i < view.num_collision_vertices; ++i) {
            const int v = view.vertices[i];
            if (view.may_be_point(v))
                ok = ok && gpu::lbvh::traverse(face_tree.view(), vb[size_t(i)], [&](int f) {
                    if (view.accept_vertex_face(v, f))
                        out.vertex_face.push_back({ v, f });
                });
        }
        for (int a = 0; a < view.num_edges; ++a)
            ok = ok && gpu::lbvh::traverse(edge_tree.view(), eb[size_t(a)], [&](int b) {
                if (b > a && view.accept_edge_edge(a, b))
                    out.edge_edge.push_back({ a, b });
            });
    }
    EXPECT_TRUE(ok) << "traversal stack overflow";
    std::sort(out.vertex_edge.begin(), out.vertex_edge.end());
    std::sort(out.vertex_face.begin(), out.vertex_face.end());
    std::sort(out.edge_edge.begin(), out.edge_edge.end());
    return out;
}

/// Does the GPU candidate set equal the CPU's (as sorted lists: the same set, sorted and unique on both sides)?
::testing::AssertionResult same_candidates(const Candidates& cpu, const gpu::CandidatePairs& gpu_pairs)
{
    const std::pair<const char*, std::pair<PairList, const PairList*>> lists[] = {
        { "vertex-edge", { to_int_pairs(cpu.vertex_edge), &gpu_pairs.vertex_edge } },
        { "vertex-face", { to_int_pairs(cpu.vertex_face), &gpu_pairs.vertex_face } },
        { "edge-edge", { to_int_pairs(cpu.edge_edge), &gpu_pairs.edge_edge } },
    };
    for (const auto& [name, pair] : lists) {
        const PairList& a = pair.first;
        const PairList& b = *pair.second;
        if (!std::is_sorted(b.begin(), b.end()) || std::adjacent_find(b.begin(), b.end()) != b.end())
            return ::testing::AssertionFailure() << name << ": the GPU list is not sorted and unique";
        if (a != b) {
            PairList only_cpu, only_gpu;
            std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(only_cpu));
            std::set_difference(b.begin(), b.end(), a.begin(), a.end(), std::back_inserter(only_gpu));
            auto failure = ::testing::AssertionFailure();
            failure << name << ": CPU " << a.size() << " pairs, GPU " << b.size() << "; only CPU " << only_cpu.size()
                    << ", only GPU " << only_gpu.size();
            if (!only_cpu.empty())
                failure << " (first only-CPU pair " << only_cpu[0][0] << ", " << only_cpu[0][1] << ")";
            if (!only_gpu.empty())
                failure << " (first only-GPU pair " << only_gpu[0][0] << ", " << only_gpu[0][1] << ")";
            return failure;
        }
    }
    return ::testing::AssertionSuccess();
}

/// One broad-phase query of a scene: start and end positions and an inflation.
struct Query {
    std::string what;
    VectorXd x_t0, x_t1;
    double inflation;
};

/// Static (at dhat + dmin and at larger radii) and swept queries, from the scene's state and perturbed ones.
std::vector<Query> queries_of(const ContactScene& s)
{
    const double active = s.settings.dhat + s.settings.min_distance;
    std::vector<Query> q;
    q.push_back({ "static, dhat + dmin", s.x, s.x, active });
    q.push_back({ "static, 0.2 size", s.x, s.x, 0.2 * s.size });
    q.push_back({ "static, 0 inflation", s.x, s.x, 0.0 });
    for (unsigned seed = 1; seed <= 3; ++seed) {
        const VectorXd x = perturbed(s.x, 2e-4 * seed, 100 + seed);
        q.push_back({ "perturbed " + std::to_string(seed) + ", static, dhat + dmin", x, x, active });
        q.push_back({ "perturbed " + std::to_string(seed) + ", static, 10 dhat", x, x, 10 * active });
        const VectorXd p = scene_step(s, 0.05 * s.size * seed, 2e-3 * seed, 200 + seed);
        q.push_back({ "perturbed " + std::to_string(seed) + ", swept", x, x + p, active });
    }
    // A large swept step: every box long, many overlaps.
    const VectorXd p = scene_step(s, 0.5 * s.size, 0.2, 300);
    q.push_back({ "large swept step", s.x, s.x + p, active });
    return q;
}

} // namespace

TEST(GpuBroadPhaseHost, BoxesAreTheCpuBoxesBitForBit)
{
    for (const ContactScene& s : broad_phase_scenes()) {
        for (const Query& q : queries_of(s)) {
            const Positions x0 = as_positions(q.x_t0, s.dim), x1 = as_positions(q.x_t1, s.dim);
            const CollisionMesh& m = s.mesh;
            EXPECT_TRUE(same_boxes(vertex_boxes(m, x0, x1, q.inflation),
                host_boxes<1>(m, m.vertices.data(), m.vertices.size(), x0, x1, q.inflation)))
                << s.name << ", " << q.what << ": vertex boxes";
            EXPECT_TRUE(same_boxes(edge_boxes(m, x0, x1, q.inflation),
                host_boxes<2>(m, m.edges.data(), m.edges.rows(), x0, x1, q.inflation)))
                << s.name << ", " << q.what << ": edge boxes";
            if (s.dim == 3)
                EXPECT_TRUE(same_boxes(face_boxes(m, x0, x1, q.inflation),
                    host_boxes<3>(m, m.faces.data(), m.faces.rows(), x0, x1, q.inflation)))
                    << s.name << ", " << q.what << ": face boxes";
        }
    }
    // Non-finite coordinates mark the box on both sides.
    ContactScene s = broad_phase_scenes()[3];
    Positions x = as_positions(s.x, 3);
    x(s.mesh.faces(0, 1), 2) = std::numeric_limits<double>::infinity();
    EXPECT_TRUE(same_boxes(
        face_boxes(s.mesh, x, x, 1e-3), host_boxes<3>(s.mesh, s.mesh.faces.data(), s.mesh.faces.rows(), x, x, 1e-3)));
    EXPECT_FALSE(gpu::box_is_finite(host_boxes<3>(s.mesh, s.mesh.faces.data(), 1, x, x, 1e-3)[0]));
}

TEST(GpuBroadPhaseHost, ExclusionRulesAreTheCpuRules)
{
    // The ported boxes, overlap test and exclusion rules in a brute-force loop on the host against the CPU's
    // brute force; a huge inflation makes every box overlap, so the rules alone decide.
    for (const ContactScene& s : broad_phase_scenes()) {
        const std::vector<Query> queries = queries_of(s);
        for (const Query& q : { queries[0], queries[1], queries[8], Query { "all boxes overlap", s.x, s.x, 1e3 } }) {
            const Positions x0 = as_positions(q.x_t0, s.dim), x1 = as_positions(q.x_t1, s.dim);
            const Candidates cpu = brute_force_candidates(s.mesh, x0, x1, q.inflation);
            EXPECT_TRUE(same_candidates(cpu, host_brute_force(s.mesh, x0, x1, q.inflation)))
                << s.name << ", " << q.what;
        }
    }
}

TEST(GpuBroadPhaseHost, LinearBvhFindsTheCpuPairs)
{
    // The kernels' tree construction and traversal, run on the host, against the CPU broad phase on every query
    // of the GPU comparison below (CI checks the algorithm here; the GPU test checks the kernels).
    for (const ContactScene& s : broad_phase_scenes())
        for (const Query& q : queries_of(s)) {
            const Positions x0 = as_positions(q.x_t0, s.dim), x1 = as_positions(q.x_t1, s.dim);
            EXPECT_TRUE(same_candidates(
                broad_phase_candidates(s.mesh, x0, x1, q.inflation), host_lbvh(s.mesh, x0, x1, q.inflation)))
                << s.name << ", " << q.what;
        }
}

TEST(GpuBroadPhaseHost, LinearBvhOnDegenerateBoxes)
{
    // Identical centres (equal Morton codes split by position), a handful of distinct boxes repeated, one and two
    // boxes, points, boxes spanning everything: every traversal reports exactly the overlapping boxes.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    for (int n : { 1, 2, 3, 7, 64, 1000 })
        for (int distinct : { 1, 3, 1000 })
            for (int dim : { 2, 3 }) {
                std::vector<gpu::Box> pool, boxes;
                for (int k = 0; k < distinct; ++k) {
                    gpu::Box b;
                    for (int a = 0; a < 3; ++a) {
                        const double c = a < dim ? u(rng) : 0, h = a < dim ? (k % 7 == 0 ? 0.0 : 0.05 * u(rng)) : 0;
                        b.min[a] = c - h;
                        b.max[a] = c + h;
                    }
                    if (k % 11 == 5)
                        for (int a = 0; a < dim; ++a) {
                            b.min[a] = -1;
                            b.max[a] = 2;
                        }
                    pool.push_back(b);
                }
                for (int i = 0; i < n; ++i)
                    boxes.push_back(pool[size_t(i % distinct)]);
                const HostTree tree(boxes, dim);
                ASSERT_TRUE(tree.valid()) << n << " boxes, " << distinct << " distinct, " << dim << "D";
                for (int i = 0; i < n; ++i) {
                    std::vector<int> found, expected;
                    ASSERT_TRUE(gpu::lbvh::traverse(tree.view(), boxes[size_t(i)], [&](int j) { found.push_back(j); }));
                    for (int j = 0; j < n; ++j)
                        if (gpu::boxes_overlap(boxes[size_t(i)], boxes[size_t(j)]))
                            expected.push_back(j);
                    std::sort(found.begin(), found.end());
                    ASSERT_EQ(found, expected)
                        << n << " boxes, " << distinct << " distinct, " << dim << "D, query " << i;
                }
            }
}

TEST(GpuBroadPhase, CandidatesEqualTheCpuCandidates)
{
    REQUIRE_GPU_FOR_BROAD_PHASE();
    std::printf("  %-34s %-40s %8s %8s %8s\n", "scene", "query", "VE", "VF", "EE");
    for (const ContactScene& s : broad_phase_scenes()) {
        gpu::DeviceBroadPhase broad_phase(to_gpu(s.mesh));
        for (const Query& q : queries_of(s)) {
            const Positions x0 = as_positions(q.x_t0, s.dim), x1 = as_positions(q.x_t1, s.dim);
            const gpu::CandidatePairs gpu_pairs = broad_phase.candidates(to_std(q.x_t0), to_std(q.x_t1), q.inflation);
            const Candidates hash = broad_phase_candidates(s.mesh, x0, x1, q.inflation, BroadPhaseMethod::HASH);
            EXPECT_TRUE(same_candidates(hash, gpu_pairs)) << s.name << ", " << q.what;
            EXPECT_TRUE(
                same_candidates(broad_phase_candidates(s.mesh, x0, x1, q.inflation, BroadPhaseMethod::BVH), gpu_pairs))
                << s.name << ", " << q.what << " (CPU BVH)";
            EXPECT_TRUE(same_candidates(brute_force_candidates(s.mesh, x0, x1, q.inflation), gpu_pairs))
                << s.name << ", " << q.what << " (CPU brute force)";
            std::printf("  %-34s %-40s %8zu %8zu %8zu\n", s.name.c_str(), q.what.c_str(), gpu_pairs.vertex_edge.size(),
                gpu_pairs.vertex_face.size(), gpu_pairs.edge_edge.size());
        }
    }
}

TEST(GpuBroadPhase, NoPairCloserThanTheInflationIsMissed)
{
    // Independently of any box: every admissible pair (the CPU's exclusion rules, from its brute force with an
    // inflation that makes all boxes overlap) whose exact distance (forward/contact/distance) at some sampled
    // time of the step is below the inflation must be a GPU candidate.
    REQUIRE_GPU_FOR_BROAD_PHASE();
    constexpr int SAMPLES = 17;
    size_t checked_close = 0;
    for (const ContactScene& s : broad_phase_scenes()) {
        const CollisionMesh& m = s.mesh;
        gpu::DeviceBroadPhase broad_phase(to_gpu(m));
        const Candidates admissible
            = brute_force_candidates(m, as_positions(s.x, s.dim), as_positions(s.x, s.dim), 1e6);
        const std::vector<Query> queries = queries_of(s);
        for (const Query& q : { queries[0], queries[3], queries[5], queries[8], queries[10] }) {
            const gpu::CandidatePairs found = broad_phase.candidates(to_std(q.x_t0), to_std(q.x_t1), q.inflation);
            const auto point = [&](Index v, double t) {
                const VectorXd x = (1 - t) * q.x_t0.segment(v * s.dim, s.dim) + t * q.x_t1.segment(v * s.dim, s.dim);
                Eigen::Vector3d p = Eigen::Vector3d::Zero();
                p.head(s.dim) = x;
                return p;
            };
            // Plain swept boxes of the vertices (no inflation, no rounding): the gap between two primitives' boxes
            // is a lower bound of their distance at every time, so pairs with a gap >= inflation need no sampling.
            const Index nv = q.x_t0.size() / s.dim;
            Eigen::MatrixXd lo = Eigen::MatrixXd::Zero(nv, 3), hi = Eigen::MatrixXd::Zero(nv, 3);
            for (Index v = 0; v < nv; ++v)
                for (int k = 0; k < s.dim; ++k) {
                    lo(v, k) = std::min(q.x_t0[v * s.dim + k], q.x_t1[v * s.dim + k]);
                    hi(v, k) = std::max(q.x_t0[v * s.dim + k], q.x_t1[v * s.dim + k]);
                }
            const auto box_gap = [&](std::initializer_list<Index> a, std::initializer_list<Index> b) {
                double gap = 0;
                for (int k = 0; k < 3; ++k) {
                    double alo = INFINITY, ahi = -INFINITY, blo = INFINITY, bhi = -INFINITY;
                    for (Index v : a) {
                        alo = std::min(alo, lo(v, k));
                        ahi = std::max(ahi, hi(v, k));
                    }
                    for (Index v : b) {
                        blo = std::min(blo, lo(v, k));
                        bhi = std::max(bhi, hi(v, k));
                    }
                    gap = std::max({ gap, alo - bhi, blo - ahi });
                }
                return gap;
            };
            const auto min_distance = [&](double gap, auto squared_distance) {
                double best = std::numeric_limits<double>::infinity();
                if (gap >= q.inflation)
                    return best;
                for (int k = 0; k < SAMPLES; ++k)
                    best = std::min(best, std::sqrt(squared_distance(double(k) / (SAMPLES - 1))));
                return best;
            };
            const auto require = [&](const PairList& list, std::array<int, 2> pair, double distance, const char* kind) {
                if (!(distance < q.inflation))
                    return;
                ++checked_close;
                EXPECT_TRUE(std::binary_search(list.begin(), list.end(), pair))
                    << s.name << ", " << q.what << ": " << kind << " pair (" << pair[0] << ", " << pair[1]
                    << ") at distance " << distance << " < inflation " << q.inflation << " is missing";
            };
            for (const auto& [v, e] : admissible.vertex_edge)
                require(found.vertex_edge, { int(v), int(e) },
                    min_distance(box_gap({ v }, { m.edges(e, 0), m.edges(e, 1) }),
                        [&](double t) {
                            return point_edge_distance(point(v, t), point(m.edges(e, 0), t), point(m.edges(e, 1), t));
                        }),
                    "vertex-edge");
            for (const auto& [v, f] : admissible.vertex_face)
                require(found.vertex_face, { int(v), int(f) },
                    min_distance(box_gap({ v }, { m.faces(f, 0), m.faces(f, 1), m.faces(f, 2) }),
                        [&](double t) {
                            return point_triangle_distance(
                                point(v, t), point(m.faces(f, 0), t), point(m.faces(f, 1), t), point(m.faces(f, 2), t));
                        }),
                    "vertex-face");
            for (const auto& [a, b] : admissible.edge_edge)
                require(found.edge_edge, { int(a), int(b) },
                    min_distance(box_gap({ m.edges(a, 0), m.edges(a, 1) }, { m.edges(b, 0), m.edges(b, 1) }),
                        [&](double t) {
                            return edge_edge_distance(point(m.edges(a, 0), t), point(m.edges(a, 1), t),
                                point(m.edges(b, 0), t), point(m.edges(b, 1), t));
                        }),
                    "edge-edge");
        }
    }
    std::printf("  %zu pairs closer than the inflation checked, none missed\n", checked_close);
    EXPECT_GT(checked_close, 1000u); // the check is not vacuous
}

TEST(GpuBroadPhase, GrowsItsPairBufferAndRepeatsItself)
{
    // An inflation that makes most boxes overlap: far more pairs than the first buffer holds, so the query runs
    // again with a larger one; the result is the CPU's, and the same on a second call and on a new object.
    REQUIRE_GPU_FOR_BROAD_PHASE();
    for (int index : { 0, 3 }) {
        const ContactScene s = broad_phase_scenes()[size_t(index)];
        const Positions x = as_positions(s.x, s.dim);
        gpu::DeviceBroadPhase a(to_gpu(s.mesh));
        const gpu::CandidatePairs first = a.candidates_near(to_std(s.x), 2.0);
        // More pairs than the first buffer of a kind holds (4 per query + 1024, device_broad_phase.cu).
        EXPECT_GT(first.size(), 4 * s.mesh.vertices.size() + 1024) << s.name;
        EXPECT_TRUE(same_candidates(broad_phase_candidates(s.mesh, x, x, 2.0), first)) << s.name;
        const gpu::CandidatePairs small = a.candidates_near(to_std(s.x), s.settings.dhat);
        EXPECT_TRUE(same_candidates(broad_phase_candidates(s.mesh, x, x, s.settings.dhat), small)) << s.name;
        const gpu::CandidatePairs again = a.candidates_near(to_std(s.x), 2.0);
        EXPECT_EQ(first.vertex_edge, again.vertex_edge);
        EXPECT_EQ(first.vertex_face, again.vertex_face);
        EXPECT_EQ(first.edge_edge, again.edge_edge);
        gpu::DeviceBroadPhase b(to_gpu(s.mesh));
        const gpu::CandidatePairs other = b.candidates_near(to_std(s.x), 2.0);
        EXPECT_EQ(first.vertex_face, other.vertex_face);
        EXPECT_EQ(first.edge_edge, other.edge_edge);
        EXPECT_EQ(first.vertex_edge, other.vertex_edge);
    }
}

TEST(GpuBroadPhase, RefusesWhatTheCpuRefuses)
{
    REQUIRE_GPU_FOR_BROAD_PHASE();
    const ContactScene s = broad_phase_scenes()[3];
    gpu::DeviceBroadPhase broad_phase(to_gpu(s.mesh));
    std::vector<double> x = to_std(s.x);
    EXPECT_THROW(broad_phase.candidates_near(x, -1.0), std::invalid_argument);
    EXPECT_THROW(broad_phase.candidates_near(x, std::numeric_limits<double>::infinity()), std::invalid_argument);
    EXPECT_THROW(broad_phase.candidates_near(std::vector<double>(3), 1e-3), std::invalid_argument);
    x[size_t(s.mesh.vertices[0]) * 3 + 1] = std::numeric_limits<double>::quiet_NaN();
    try {
        broad_phase.candidates_near(x, 1e-3);
        ADD_FAILURE() << "a NaN position was accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_STREQ(e.what(), "broad phase: non-finite position of a collision-mesh vertex");
    }
    // The object stays usable after a refused query.
    const Positions X = as_positions(s.x, 3);
    EXPECT_TRUE(
        same_candidates(broad_phase_candidates(s.mesh, X, X, 1e-3), broad_phase.candidates_near(to_std(s.x), 1e-3)));
    // An inconsistent mesh is refused at construction.
    gpu::CollisionMeshData bad = to_gpu(s.mesh);
    bad.edges[0] = int(s.mesh.num_vertices);
    EXPECT_THROW(gpu::DeviceBroadPhase { bad }, std::invalid_argument);
}
