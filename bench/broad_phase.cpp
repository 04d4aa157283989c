// Broad-phase benchmark: swept candidate pairs on box-mesh surfaces, brute force (when small enough) against the
// hash grid and the BVH. Prints figures, asserts nothing except that the methods agree.
//
//   bench_broad_phase [repeats] [threads]

#include "forward/contact/broad_phase/broad_phase.hpp"
#include "forward/common/timer.hpp"
#include "forward/mesh/mesh.hpp"

#include <Eigen/Geometry>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace diffipc;

namespace {

/// Collision mesh of the boundary of a volume mesh: boundary faces, their unique edges, group = body.
CollisionMesh surface_of(const Mesh& m, const std::vector<char>& self_contact, const std::vector<char>& kinematic)
{
    CollisionMesh c;
    c.dim = 3;
    c.num_vertices = m.num_vertices();
    c.faces = m.boundary_facets;
    std::set<std::array<int, 2>> edges;
    std::set<int> vertices;
    for (Index f = 0; f < c.faces.rows(); ++f)
        for (int a = 0; a < 3; ++a) {
            const int u = c.faces(f, a), v = c.faces(f, (a + 1) % 3);
            edges.insert({ std::min(u, v), std::max(u, v) });
            vertices.insert(u);
        }
    c.edges.resize(Index(edges.size()), 2);
    Index r = 0;
    for (const auto& e : edges) {
        c.edges(r, 0) = e[0];
        c.edges(r, 1) = e[1];
        ++r;
    }
    c.vertices.resize(Index(vertices.size()));
    r = 0;
    for (int v : vertices)
        c.vertices[r++] = v;
    c.vertex_group.assign(size_t(m.num_vertices()), -1);
    for (int v : vertices)
        c.vertex_group[size_t(v)] = m.vertex_body[v];
    c.group_self_contact = self_contact;
    c.group_kinematic = kinematic;
    return c;
}

Mesh box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const Eigen::Vector3i& cells)
{
    Mesh m = box_mesh(3, lo, hi, cells);
    compute_boundary(m);
    m.vertex_body.setZero(m.num_vertices());
    return m;
}

/// Twist about the vertical axis through (0.5, 0.5), growing with height up to `angle` (rad), a drop `dz` of the
/// vertices of `moving_body` (all bodies if -1), and a uniform random wiggle of amplitude `noise` (m).
Positions twist(const Mesh& m, double angle, double dz, int moving_body, double noise, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-noise, noise);
    Positions x1 = m.rest_positions;
    const double z_lo = m.rest_positions.col(2).minCoeff(), z_hi = m.rest_positions.col(2).maxCoeff();
    for (Index v = 0; v < m.num_vertices(); ++v) {
        if (moving_body >= 0 && m.vertex_body[v] != moving_body)
            continue;
        const Eigen::Vector3d p = m.rest_positions.row(v).transpose();
        const double a = angle * (p.z() - z_lo) / std::max(z_hi - z_lo, 1e-12);
        const Eigen::Vector3d c(0.5, 0.5, 0);
        const Eigen::Vector3d q = c + Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()) * (p - c);
        x1.row(v) = (q + Eigen::Vector3d(u(rng), u(rng), u(rng) - dz)).transpose();
    }
    return x1;
}

double median_time(int repeats, const std::function<void()>& f)
{
    std::vector<double> t;
    for (int r = 0; r < repeats; ++r) {
        Timer timer;
        f();
        t.push_back(timer.seconds());
    }
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
}

void run(const std::string& name, const Mesh& m, const CollisionMesh& c, const Positions& x0, const Positions& x1,
    double inflation, int repeats)
{
    const double cv = double(c.vertices.size()), cf = double(c.faces.rows()), ce = double(c.edges.rows());
    std::printf("\n%s: %ld tets, %ld surface vertices, %ld faces, %ld edges, inflation %.3g m\n", name.c_str(),
        long(m.num_elements()), long(cv), long(cf), long(ce), inflation);

    Candidates reference;
    const bool brute = cv * cf + 0.5 * ce * ce < 4e8;
    if (brute) {
        const double t = median_time(1, [&] { reference = brute_force_candidates(c, x0, x1, inflation); });
        std::printf("  %-12s %10.2f ms\n", "brute force", 1e3 * t);
    } else {
        std::printf("  %-12s    skipped (%.2g box tests)\n", "brute force", cv * cf + 0.5 * ce * ce);
    }
    for (BroadPhaseMethod method : { BroadPhaseMethod::HASH, BroadPhaseMethod::BVH }) {
        Candidates fast;
        const double t = median_time(repeats, [&] { fast = broad_phase_candidates(c, x0, x1, inflation, method); });
        std::printf("  %-12s %10.2f ms   %zu vertex-face + %zu edge-edge = %zu candidates%s\n",
            method == BroadPhaseMethod::HASH ? "hash grid" : "bvh", 1e3 * t, fast.vertex_face.size(),
            fast.edge_edge.size(), fast.size(), brute ? (fast == reference ? "  (== brute force)" : "  MISMATCH") : "");
        if (brute && fast != reference)
            std::exit(1);
    }
}

} // namespace

int main(int argc, char** argv)
{
    const int repeats = argc > 1 ? std::max(1, std::atoi(argv[1])) : 7;
    const int threads = argc > 2 ? std::max(1, std::atoi(argv[2])) : tbb::info::default_concurrency();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    std::printf("broad phase benchmark, %d TBB threads, median of %d runs\n", threads, repeats);

    // Per-step motions: static, a moderate twist (the top face turns 3 degrees, its corners move ~1 cell of the
    // 15^3 box), and a large one (30 degrees, ~10 cells).
    const double inflation = 1e-3;
    for (const int n : { 15, 30 }) {
        // 15^3 cubes x 6 = 20k tets; 30^3 x 6 = 162k tets with ~10k surface triangles and ~16k edges.
        const Mesh m = box({ 0, 0, 0 }, { 1, 1, 1 }, { n, n, n });
        const CollisionMesh c = surface_of(m, { 1 }, { 0 });
        const std::string name = "box " + std::to_string(n) + "^3";
        run(name + ", static", m, c, m.rest_positions, m.rest_positions, inflation, repeats);
        run(name + ", twist 3 deg", m, c, m.rest_positions, twist(m, 0.052, 0, -1, 1e-4, 1), inflation, repeats);
        run(name + ", twist 30 deg", m, c, m.rest_positions, twist(m, 0.52, 0, -1, 1e-3, 1), inflation, repeats);
    }
    {
        // ~20k tets in a thin slab: more surface per tet.
        const Mesh m = box({ 0, 0, 0 }, { 1, 1, 0.05 }, { 40, 40, 2 });
        const CollisionMesh c = surface_of(m, { 1 }, { 0 });
        run("slab 40x40x2, twist 3 deg", m, c, m.rest_positions, twist(m, 0.052, 0, -1, 1e-4, 2), inflation, repeats);
    }
    {
        // Two bodies and a kinematic floor: the upper box falls 0.3 m (4 cells) onto the lower one in one step.
        Mesh m = box({ 0, 0, 0 }, { 1, 1, 1 }, { 12, 12, 12 });
        append_mesh(m, box({ 0.1, 0.1, 1.05 }, { 0.9, 0.9, 1.85 }, { 12, 12, 12 }), 1);
        append_mesh(m, box({ -1, -1, -0.2 }, { 2, 2, -0.01 }, { 20, 20, 1 }), 2);
        const CollisionMesh c = surface_of(m, { 1, 1, 0 }, { 0, 0, 1 });
        run("two boxes 12^3 + floor, drop 0.3 m", m, c, m.rest_positions, twist(m, 0.2, 0.3, 1, 1e-3, 4), inflation,
            repeats);
    }
    return 0;
}
