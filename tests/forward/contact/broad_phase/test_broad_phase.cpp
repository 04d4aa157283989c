#include "forward/contact/broad_phase/broad_phase.hpp"
#include "forward/contact/broad_phase/bvh.hpp"
#include "forward/contact/broad_phase/hash_grid.hpp"
#include "forward/contact/distance/distance.hpp"
#include "forward/mesh/mesh.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>

using namespace diffipc;

namespace {

using Pair = std::array<Index, 2>;
using Pairs = std::vector<Pair>;

constexpr BroadPhaseMethod FAST_METHODS[] = { BroadPhaseMethod::HASH, BroadPhaseMethod::BVH };

const char* method_name(BroadPhaseMethod m)
{
    return m == BroadPhaseMethod::HASH ? "HASH" : (m == BroadPhaseMethod::BVH ? "BVH" : "BRUTE_FORCE");
}

/// Unique undirected edges of a triangle list, each as (min, max), sorted.
MatrixXi unique_edges(const MatrixXi& faces)
{
    std::set<std::array<int, 2>> edges;
    for (Index f = 0; f < faces.rows(); ++f)
        for (int a = 0; a < 3; ++a) {
            const int u = faces(f, a), v = faces(f, (a + 1) % 3);
            edges.insert({ std::min(u, v), std::max(u, v) });
        }
    MatrixXi E(Index(edges.size()), 2);
    Index r = 0;
    for (const auto& e : edges) {
        E(r, 0) = e[0];
        E(r, 1) = e[1];
        ++r;
    }
    return E;
}

/// Collision mesh with the given surface; vertices are those used by the edges (and faces).
/// group: #V group per vertex (entries of vertices not on the surface are set to -1).
CollisionMesh make_collision_mesh(int dim, Index num_vertices, const MatrixXi& edges, const MatrixXi& faces,
    std::vector<int> group, std::vector<char> self_contact, std::vector<char> kinematic)
{
    CollisionMesh mesh;
    mesh.dim = dim;
    mesh.num_vertices = num_vertices;
    mesh.edges = edges;
    mesh.faces = dim == 3 ? faces : MatrixXi(0, 3);
    std::set<int> used(edges.data(), edges.data() + edges.size());
    used.insert(faces.data(), faces.data() + faces.size());
    mesh.vertices.resize(Index(used.size()));
    Index k = 0;
    for (int v : used)
        mesh.vertices[k++] = v;
    for (Index v = 0; v < num_vertices; ++v)
        if (!used.count(int(v)))
            group[size_t(v)] = -1;
    mesh.vertex_group = std::move(group);
    mesh.group_self_contact = std::move(self_contact);
    mesh.group_kinematic = std::move(kinematic);
    return mesh;
}

/// Collision mesh of the boundary of a (multi-body) volume mesh; the group of a vertex is its body.
CollisionMesh boundary_collision_mesh(
    const Mesh& m, const std::vector<char>& self_contact, const std::vector<char>& kinematic)
{
    std::vector<int> group(m.vertex_body.data(), m.vertex_body.data() + m.vertex_body.size());
    if (m.dim == 2)
        return make_collision_mesh(
            2, m.num_vertices(), m.boundary_facets, MatrixXi(0, 3), group, self_contact, kinematic);
    return make_collision_mesh(
        3, m.num_vertices(), unique_edges(m.boundary_facets), m.boundary_facets, group, self_contact, kinematic);
}

Positions random_positions(Index n, int dim, double lo, double hi, std::mt19937& rng)
{
    std::uniform_real_distribution<double> u(lo, hi);
    Positions x(n, dim);
    for (Index i = 0; i < x.size(); ++i)
        x.data()[i] = u(rng);
    return x;
}

/// n independent triangles (3n vertices) of size ~`size` in the unit cube, vertex groups drawn from [0, num_groups).
struct Soup {
    CollisionMesh mesh;
    Positions x;
};

Soup triangle_soup(int n, double size, int num_groups, unsigned seed, std::vector<char> self_contact = {},
    std::vector<char> kinematic = {})
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::uniform_int_distribution<int> g(0, num_groups - 1);
    Soup s;
    s.x.resize(3 * n, 3);
    MatrixXi faces(n, 3);
    std::vector<int> group(size_t(3 * n));
    for (int f = 0; f < n; ++f) {
        const Eigen::RowVector3d c(u(rng), u(rng), u(rng));
        const int gf = g(rng);
        for (int a = 0; a < 3; ++a) {
            s.x.row(3 * f + a) = c + size * Eigen::RowVector3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
            faces(f, a) = 3 * f + a;
            group[size_t(3 * f + a)] = gf;
        }
    }
    if (self_contact.empty())
        self_contact.assign(size_t(num_groups), 1);
    if (kinematic.empty())
        kinematic.assign(size_t(num_groups), 0);
    s.mesh = make_collision_mesh(3, 3 * n, unique_edges(faces), faces, group, self_contact, kinematic);
    return s;
}

/// Two parallel n x n triangulated unit squares at z = 0 and z = gap (groups 0 and 1, no self-contact).
Soup stacked_grids(int n, double gap)
{
    const int side = n + 1, per_sheet = side * side;
    Soup s;
    s.x.resize(2 * per_sheet, 3);
    MatrixXi faces(2 * 2 * n * n, 3);
    std::vector<int> group(size_t(2 * per_sheet));
    Index f = 0;
    for (int sheet = 0; sheet < 2; ++sheet) {
        const int v0 = sheet * per_sheet;
        for (int j = 0; j < side; ++j)
            for (int i = 0; i < side; ++i) {
                s.x.row(v0 + j * side + i) << double(i) / n, double(j) / n, sheet * gap;
                group[size_t(v0 + j * side + i)] = sheet;
            }
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const int a = v0 + j * side + i, b = a + 1, c = a + side, d = c + 1;
                faces.row(f++) << a, b, d;
                faces.row(f++) << a, d, c;
            }
    }
    s.mesh = make_collision_mesh(3, 2 * per_sheet, unique_edges(faces), faces, group, { 0, 0 }, { 0, 0 });
    return s;
}

/// Two concentric closed polygons in 2D (n and n + 3 vertices), group 0 and 1, self-contact on.
Soup polygon_rings(int n, double r_outer, double r_inner, double noise, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-noise, noise);
    const int m = n + 3;
    Soup s;
    s.x.resize(n + m, 2);
    MatrixXi edges(n + m, 2);
    std::vector<int> group(size_t(n + m));
    for (int ring = 0, v0 = 0; ring < 2; v0 += (ring == 0 ? n : m), ++ring) {
        const int k = ring == 0 ? n : m;
        const double r = ring == 0 ? r_outer : r_inner;
        for (int i = 0; i < k; ++i) {
            const double t = 2 * M_PI * i / k;
            s.x.row(v0 + i) << (r + u(rng)) * std::cos(t), (r + u(rng)) * std::sin(t);
            edges.row(v0 + i) << v0 + i, v0 + (i + 1) % k;
            group[size_t(v0 + i)] = ring;
        }
    }
    s.mesh = make_collision_mesh(2, n + m, edges, MatrixXi(0, 3), group, { 1, 1 }, { 0, 0 });
    return s;
}

Eigen::Vector3d point(const Positions& x, Index v)
{
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    p.head(x.cols()) = x.row(v).transpose();
    return p;
}

bool shares_vertex(const std::vector<Index>& a, const std::vector<Index>& b)
{
    for (Index u : a)
        if (std::find(b.begin(), b.end(), u) != b.end())
            return true;
    return false;
}

void expect_sorted_unique(const Pairs& p, const char* what)
{
    EXPECT_TRUE(std::is_sorted(p.begin(), p.end())) << what;
    EXPECT_TRUE(std::adjacent_find(p.begin(), p.end()) == p.end()) << what;
}

/// Every candidate shares no vertex and passes the group filter.
void expect_filtered(const CollisionMesh& mesh, const Candidates& c)
{
    for (const Pair& p : c.vertex_edge) {
        EXPECT_FALSE(shares_vertex({ p[0] }, { mesh.edges(p[1], 0), mesh.edges(p[1], 1) }));
        EXPECT_TRUE(mesh.groups_can_collide(p[0], mesh.edges(p[1], 0)));
    }
    for (const Pair& p : c.vertex_face) {
        EXPECT_FALSE(shares_vertex({ p[0] }, { mesh.faces(p[1], 0), mesh.faces(p[1], 1), mesh.faces(p[1], 2) }));
        EXPECT_TRUE(mesh.groups_can_collide(p[0], mesh.faces(p[1], 0)));
    }
    for (const Pair& p : c.edge_edge) {
        EXPECT_LT(p[0], p[1]);
        EXPECT_FALSE(
            shares_vertex({ mesh.edges(p[0], 0), mesh.edges(p[0], 1) }, { mesh.edges(p[1], 0), mesh.edges(p[1], 1) }));
        EXPECT_TRUE(mesh.groups_can_collide(mesh.edges(p[0], 0), mesh.edges(p[1], 0)));
    }
}

/// Brute force and every fast method give identical, sorted, filtered lists; returns the brute-force result.
Candidates expect_methods_agree(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation)
{
    const Candidates reference = brute_force_candidates(mesh, x_t0, x_t1, inflation);
    expect_sorted_unique(reference.vertex_edge, "vertex_edge");
    expect_sorted_unique(reference.vertex_face, "vertex_face");
    expect_sorted_unique(reference.edge_edge, "edge_edge");
    expect_filtered(mesh, reference);
    if (mesh.dim == 2) {
        EXPECT_TRUE(reference.vertex_face.empty() && reference.edge_edge.empty());
    } else {
        EXPECT_TRUE(reference.vertex_edge.empty());
    }
    for (BroadPhaseMethod method : FAST_METHODS) {
        const Candidates fast = broad_phase_candidates(mesh, x_t0, x_t1, inflation, method);
        EXPECT_EQ(fast.vertex_edge, reference.vertex_edge) << method_name(method);
        EXPECT_EQ(fast.vertex_face, reference.vertex_face) << method_name(method);
        EXPECT_EQ(fast.edge_edge, reference.edge_edge) << method_name(method);
    }
    return reference;
}

bool contains(const Pairs& p, const Pair& q) { return std::binary_search(p.begin(), p.end(), q); }

/// Independent check of conservativeness: every allowed pair whose distance, sampled along the linear motion,
/// is <= inflation is a candidate. Returns the number of such close pairs (so that callers can check the test is
/// not vacuous).
size_t expect_conservative(
    const CollisionMesh& mesh, const Positions& x_t0, const Positions& x_t1, double inflation, const Candidates& c)
{
    constexpr int SAMPLES = 8;
    const auto positions = [&](double t) -> Positions { return (1 - t) * x_t0 + t * x_t1; };
    std::vector<Positions> xs;
    for (int s = 0; s <= SAMPLES; ++s)
        xs.push_back(positions(double(s) / SAMPLES));
    const double inflation2 = inflation * inflation;
    size_t close = 0;
    const auto min_over_time = [&](auto&& distance2) {
        double d = std::numeric_limits<double>::infinity();
        for (const Positions& x : xs)
            d = std::min(d, distance2(x));
        return d;
    };
    if (mesh.dim == 2) {
        for (Index i = 0; i < mesh.vertices.size(); ++i)
            for (Index e = 0; e < mesh.edges.rows(); ++e) {
                const Index v = mesh.vertices[i], e0 = mesh.edges(e, 0), e1 = mesh.edges(e, 1);
                if (v == e0 || v == e1 || !mesh.groups_can_collide(v, e0))
                    continue;
                const double d2 = min_over_time(
                    [&](const Positions& x) { return point_edge_distance(point(x, v), point(x, e0), point(x, e1)); });
                if (d2 <= inflation2) {
                    ++close;
                    EXPECT_TRUE(contains(c.vertex_edge, { v, e })) << "vertex " << v << " edge " << e;
                }
            }
        return close;
    }
    for (Index i = 0; i < mesh.vertices.size(); ++i)
        for (Index f = 0; f < mesh.faces.rows(); ++f) {
            const Index v = mesh.vertices[i], f0 = mesh.faces(f, 0), f1 = mesh.faces(f, 1), f2 = mesh.faces(f, 2);
            if (v == f0 || v == f1 || v == f2 || !mesh.groups_can_collide(v, f0))
                continue;
            const double d2 = min_over_time([&](const Positions& x) {
                return point_triangle_distance(point(x, v), point(x, f0), point(x, f1), point(x, f2));
            });
            if (d2 <= inflation2) {
                ++close;
                EXPECT_TRUE(contains(c.vertex_face, { v, f })) << "vertex " << v << " face " << f;
            }
        }
    for (Index a = 0; a < mesh.edges.rows(); ++a)
        for (Index b = a + 1; b < mesh.edges.rows(); ++b) {
            const Index a0 = mesh.edges(a, 0), a1 = mesh.edges(a, 1), b0 = mesh.edges(b, 0), b1 = mesh.edges(b, 1);
            if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1 || !mesh.groups_can_collide(a0, b0))
                continue;
            const double d2 = min_over_time([&](const Positions& x) {
                return edge_edge_distance(point(x, a0), point(x, a1), point(x, b0), point(x, b1));
            });
            if (d2 <= inflation2) {
                ++close;
                EXPECT_TRUE(contains(c.edge_edge, { a, b })) << "edges " << a << ", " << b;
            }
        }
    return close;
}

} // namespace

// ---------------------------------------------------------------------------------------------------------------
// Hand-checked small cases: adjacency exclusion and the group filter.

TEST(BroadPhase, AdjacentTrianglesExcludeSharedVertices)
{
    // Two triangles sharing the edge (1, 2); with a large inflation every box overlaps every other.
    Positions x(4, 3);
    x << 0, 0, 0, //
        1, 0, 0, //
        0, 1, 0, //
        1, 1, 0.1;
    MatrixXi faces(2, 3);
    faces << 0, 1, 2, //
        1, 3, 2;
    const MatrixXi edges = unique_edges(faces); // (0,1) (0,2) (1,2) (1,3) (2,3)
    const CollisionMesh mesh = make_collision_mesh(3, 4, edges, faces, { 0, 0, 0, 0 }, { 1 }, { 0 });
    const Candidates c = expect_methods_agree(mesh, x, x, 10.0);
    EXPECT_EQ(c.vertex_face, (Pairs { { 0, 1 }, { 3, 0 } }));
    // Edge pairs without a shared vertex: (0,1)-(2,3) and (0,2)-(1,3).
    EXPECT_EQ(c.edge_edge, (Pairs { { 0, 4 }, { 1, 3 } }));

    // Without self-contact the single group has no candidates at all.
    const CollisionMesh no_self = make_collision_mesh(3, 4, edges, faces, { 0, 0, 0, 0 }, { 0 }, { 0 });
    EXPECT_TRUE(expect_methods_agree(no_self, x, x, 10.0).empty());
}

TEST(BroadPhase, GroupFilter)
{
    // Two disjoint triangles, one per group, overlapping boxes.
    Positions x(6, 3);
    x << 0, 0, 0, 1, 0, 0, 0, 1, 0, //
        0, 0, 0.01, 1, 0, 0.01, 0, 1, 0.01;
    MatrixXi faces(2, 3);
    faces << 0, 1, 2, 3, 4, 5;
    const MatrixXi edges = unique_edges(faces);
    const std::vector<int> groups = { 0, 0, 0, 1, 1, 1 };

    // Body against body, and body against an obstacle: all 6 vertex-face and 9 edge-edge pairs.
    for (const std::vector<char>& kin : { std::vector<char> { 0, 0 }, { 1, 0 }, { 0, 1 } }) {
        const CollisionMesh mesh = make_collision_mesh(3, 6, edges, faces, groups, { 0, 0 }, kin);
        const Candidates c = expect_methods_agree(mesh, x, x, 0.1);
        EXPECT_EQ(c.vertex_face.size(), 6u);
        EXPECT_EQ(c.edge_edge.size(), 9u);
    }
    // Two obstacles never collide, whatever their self-contact flag.
    EXPECT_TRUE(
        expect_methods_agree(make_collision_mesh(3, 6, edges, faces, groups, { 1, 1 }, { 1, 1 }), x, x, 0.1).empty());
    // Vertices outside every group (-1) never collide.
    EXPECT_TRUE(expect_methods_agree(
        make_collision_mesh(3, 6, edges, faces, { -1, -1, -1, 1, 1, 1 }, { 1, 1 }, { 0, 0 }), x, x, 0.1)
                    .empty());
    // Too far apart for the inflation: nothing.
    EXPECT_TRUE(
        expect_methods_agree(make_collision_mesh(3, 6, edges, faces, groups, { 0, 0 }, { 0, 0 }), x, x, 0.009).empty());
}

TEST(BroadPhase, RandomSoupGroups)
{
    // Group 0 self-contact, group 1 none, groups 2 and 3 kinematic (2 with self-contact, which is allowed).
    Soup s = triangle_soup(300, 0.15, 4, 7, { 1, 0, 1, 0 }, { 0, 0, 1, 1 });
    const Candidates c = expect_methods_agree(s.mesh, s.x, s.x, 0.02);
    size_t per_group_pair[4][4] = {};
    for (const Pair& p : c.vertex_face)
        ++per_group_pair[s.mesh.vertex_group[size_t(p[0])]][s.mesh.vertex_group[size_t(s.mesh.faces(p[1], 0))]];
    for (const Pair& p : c.edge_edge) {
        const int ga = s.mesh.vertex_group[size_t(s.mesh.edges(p[0], 0))];
        const int gb = s.mesh.vertex_group[size_t(s.mesh.edges(p[1], 0))];
        ++per_group_pair[std::min(ga, gb)][std::max(ga, gb)];
    }
    EXPECT_GT(per_group_pair[0][0], 0u);
    EXPECT_EQ(per_group_pair[1][1], 0u);
    EXPECT_GT(per_group_pair[2][2], 0u); // self-contact of an obstacle with itself is allowed by the flag
    EXPECT_EQ(per_group_pair[3][3], 0u);
    EXPECT_EQ(per_group_pair[2][3] + per_group_pair[3][2], 0u);
    EXPECT_GT(per_group_pair[0][1] + per_group_pair[1][0], 0u);
    EXPECT_GT(per_group_pair[1][2] + per_group_pair[2][1], 0u);
    EXPECT_GT(expect_conservative(s.mesh, s.x, s.x, 0.02, c), 0u);
}

// ---------------------------------------------------------------------------------------------------------------
// Structured scenes.

TEST(BroadPhase, StackedGridsInflationIsTheReportedDistance)
{
    // Sheets at distance gap: vertices straight above each other are at exactly gap, so pairs appear once the
    // inflation reaches the gap, and the flat boxes (inflated by inflation / 2 per side) separate just above it.
    const int n = 12;
    const double gap = 0.01;
    for (double inflation : { 1.001 * gap, 1.5 * gap, 0.25 }) {
        Soup s = stacked_grids(n, gap);
        const Candidates c = expect_methods_agree(s.mesh, s.x, s.x, inflation);
        EXPECT_GE(c.vertex_face.size(), size_t(2 * (n + 1) * (n + 1))) << inflation;
        EXPECT_GT(expect_conservative(s.mesh, s.x, s.x, inflation, c), 0u);
    }
    Soup s = stacked_grids(n, gap);
    EXPECT_TRUE(expect_methods_agree(s.mesh, s.x, s.x, 0.999 * gap).empty());

    // Swept: the upper sheet moves down through the lower one (static boxes far apart, swept boxes overlap).
    Soup far = stacked_grids(n, 0.5);
    Positions x1 = far.x;
    x1.bottomRows(x1.rows() / 2).col(2).array() -= 1.0;
    EXPECT_TRUE(expect_methods_agree(far.mesh, far.x, far.x, 0.01).empty());
    const Candidates swept = expect_methods_agree(far.mesh, far.x, x1, 0.01);
    EXPECT_GT(swept.size(), 0u);
    EXPECT_GT(expect_conservative(far.mesh, far.x, x1, 0.01, swept), 0u);
}

TEST(BroadPhase, DenseRandomSoup)
{
    for (unsigned seed : { 1u, 2u, 3u }) {
        Soup s = triangle_soup(400, 0.1, 3, seed, { 1, 0, 1 }, { 0, 0, 1 });
        const Candidates c = expect_methods_agree(s.mesh, s.x, s.x, 0.01);
        EXPECT_GT(c.vertex_face.size(), 0u);
        EXPECT_GT(c.edge_edge.size(), 0u);
        if (seed == 1) // the all-pairs distance check is the slow part
            EXPECT_GT(expect_conservative(s.mesh, s.x, s.x, 0.01, c), 0u);
    }
    // CollisionMesh::vertices is documented as sorted; an unsorted list must still give sorted results.
    Soup s = triangle_soup(200, 0.1, 2, 4);
    std::mt19937 rng(6);
    std::shuffle(s.mesh.vertices.data(), s.mesh.vertices.data() + s.mesh.vertices.size(), rng);
    const Candidates c = expect_methods_agree(s.mesh, s.x, s.x, 0.01);
    EXPECT_GT(c.vertex_face.size(), 0u);
}

TEST(BroadPhase, SweptRandomSoupSmallAndLargeDisplacement)
{
    for (double displacement : { 0.02, 0.5 }) {
        Soup s = triangle_soup(200, 0.08, 2, 11, { 1, 1 }, { 0, 1 });
        std::mt19937 rng(5);
        const Positions x1 = s.x + random_positions(s.x.rows(), 3, -displacement, displacement, rng);
        const Candidates c = expect_methods_agree(s.mesh, s.x, x1, 0.005);
        EXPECT_GT(expect_conservative(s.mesh, s.x, x1, 0.005, c), 0u) << displacement;
        // The swept set contains the static sets at both ends.
        const Candidates c0 = brute_force_candidates(s.mesh, s.x, s.x, 0.005);
        const Candidates c1 = brute_force_candidates(s.mesh, x1, x1, 0.005);
        for (const Candidates* end : { &c0, &c1 }) {
            EXPECT_TRUE(std::includes(
                c.vertex_face.begin(), c.vertex_face.end(), end->vertex_face.begin(), end->vertex_face.end()));
            EXPECT_TRUE(
                std::includes(c.edge_edge.begin(), c.edge_edge.end(), end->edge_edge.begin(), end->edge_edge.end()));
        }
    }
}

TEST(BroadPhase, OneHugeSweptBoxAmongSmallOnes)
{
    // A single triangle travelling across the whole scene: its box covers everything, which the hash grid must
    // handle without listing it in millions of cells.
    Soup s = triangle_soup(500, 0.02, 1, 13);
    Positions x1 = s.x;
    x1.topRows(3).rowwise() += Eigen::RowVector3d(1000, -500, 200);
    const Candidates c = expect_methods_agree(s.mesh, s.x, x1, 1e-3);
    EXPECT_GT(c.size(), 0u);
}

TEST(BroadPhase, BoxBodiesWithRotation)
{
    // Three box bodies: two deformable (self-contact on / off) stacked with a small gap, one kinematic floor.
    Mesh m = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(4, 4, 4));
    compute_boundary(m);
    m.vertex_body.setZero(m.num_vertices());
    Mesh upper = box_mesh(3, Eigen::Vector3d(0.2, 0.1, 1.02), Eigen::Vector3d(1.1, 0.9, 1.6), Eigen::Vector3i(3, 3, 2));
    compute_boundary(upper);
    append_mesh(m, upper, 1);
    Mesh floor = box_mesh(3, Eigen::Vector3d(-1, -1, -0.3), Eigen::Vector3d(2, 2, -0.01), Eigen::Vector3i(3, 3, 1));
    compute_boundary(floor);
    append_mesh(m, floor, 2);
    const CollisionMesh mesh = boundary_collision_mesh(m, { 1, 0, 0 }, { 0, 0, 1 });

    // Rigid rotation of everything but the floor about the z axis plus a drop, and a small random wiggle.
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    std::mt19937 rng(3);
    Positions x1 = m.rest_positions + random_positions(m.num_vertices(), 3, -0.01, 0.01, rng);
    for (Index v = 0; v < m.num_vertices(); ++v)
        if (m.vertex_body[v] != 2)
            x1.row(v) = (R * m.rest_positions.row(v).transpose()).transpose() - Eigen::RowVector3d(0, 0, 0.05);
    for (double inflation : { 1e-3, 0.03 }) {
        const Candidates c_static = expect_methods_agree(mesh, m.rest_positions, m.rest_positions, inflation);
        const Candidates c_swept = expect_methods_agree(mesh, m.rest_positions, x1, inflation);
        EXPECT_GE(c_swept.size(), c_static.size());
        EXPECT_GT(expect_conservative(mesh, m.rest_positions, x1, inflation, c_swept), 0u);
        EXPECT_EQ(candidates_near(mesh, m.rest_positions, inflation), c_static);
        for (BroadPhaseMethod method : FAST_METHODS)
            EXPECT_EQ(candidates_near(mesh, m.rest_positions, inflation, method), c_static);
    }
}

TEST(BroadPhase, FineBodyOnAFloorOfTwoTriangles)
{
    // A typical IPC scene: a finely meshed body above a ground plane made of two huge triangles. The floor boxes are
    // kept out of the hash grid (its cell size follows the body), and the floor edges, as queries, cover the whole
    // grid.
    Mesh m = box_mesh(3, Eigen::Vector3d(0, 0, 0.001), Eigen::Vector3d(0.2, 0.2, 0.2), Eigen::Vector3i(6, 6, 6));
    compute_boundary(m);
    m.vertex_body.setZero(m.num_vertices());
    const Index nb = m.num_vertices();
    Mesh floor;
    floor.dim = 3;
    floor.rest_positions.resize(4, 3);
    floor.rest_positions << -100, -100, 0, 100, -100, 0, 100, 100, 0, -100, 100, 0;
    floor.elements.resize(0, 4);
    floor.boundary_facets.resize(2, 3);
    floor.boundary_facets << 0, 1, 2, 0, 2, 3;
    floor.facet_body.setZero(2);
    floor.vertex_body.setZero(4);
    append_mesh(m, floor, 1);
    const CollisionMesh mesh = boundary_collision_mesh(m, { 1, 0 }, { 0, 1 });
    Positions x1 = m.rest_positions;
    x1.topRows(nb).col(2).array() -= 0.01;
    const Candidates c = expect_methods_agree(mesh, m.rest_positions, x1, 1e-3);
    EXPECT_GT(c.vertex_face.size(), 0u);
    EXPECT_GT(expect_conservative(mesh, m.rest_positions, x1, 1e-3, c), 0u);
}

TEST(BroadPhase, AccelerationStructuresFindEveryIntersectingBox)
{
    // Boxes with log-uniform sizes over four decades, queried with each other: the hash grid (including its list of
    // large boxes) and the BVH report exactly the intersecting boxes, each once.
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(0, 1);
    for (int dim : { 2, 3 }) {
        std::vector<AABB> boxes(3000);
        for (AABB& b : boxes) {
            const double size = std::pow(10.0, -3 + 4 * u(rng) * u(rng));
            for (int k = 0; k < 3; ++k) {
                const double c = u(rng);
                b.min[k] = k < dim ? c - size * u(rng) : 0;
                b.max[k] = k < dim ? c + size * u(rng) : 0;
            }
        }
        HashGrid grid;
        grid.build(boxes, dim);
        EXPECT_GT(grid.num_large(), 0u);
        BVH bvh;
        bvh.build(boxes);
        for (size_t i = 0; i < boxes.size(); i += 7) {
            std::vector<Index> expected, from_grid, from_bvh;
            for (size_t j = 0; j < boxes.size(); ++j)
                if (boxes[i].intersects(boxes[j]))
                    expected.push_back(Index(j));
            grid.query(boxes[i], [&](Index j) { from_grid.push_back(j); });
            bvh.query(boxes[i], [&](Index j) { from_bvh.push_back(j); });
            std::sort(from_grid.begin(), from_grid.end());
            std::sort(from_bvh.begin(), from_bvh.end());
            EXPECT_EQ(from_grid, expected) << "dim " << dim << " box " << i;
            EXPECT_EQ(from_bvh, expected) << "dim " << dim << " box " << i;
        }
    }
}

// ---------------------------------------------------------------------------------------------------------------
// 2D.

TEST(BroadPhase, PolygonRings2D)
{
    for (double noise : { 0.0, 0.05 }) {
        Soup s = polygon_rings(60, 1.0, 0.95, noise, 21);
        for (double inflation : { 0.06, 0.2 }) { // the rings are 0.05 apart
            const Candidates c = expect_methods_agree(s.mesh, s.x, s.x, inflation);
            EXPECT_GT(c.vertex_edge.size(), 0u);
            EXPECT_GT(expect_conservative(s.mesh, s.x, s.x, inflation, c), 0u);
        }
        // Swept: the inner ring translates across the outer one.
        Positions x1 = s.x;
        x1.bottomRows(63).col(0).array() += 0.5;
        const Candidates c = expect_methods_agree(s.mesh, s.x, x1, 0.01);
        EXPECT_GT(expect_conservative(s.mesh, s.x, x1, 0.01, c), 0u);
    }
}

TEST(BroadPhase, BoxBodies2D)
{
    Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(8, 8));
    compute_boundary(m);
    m.vertex_body.setZero(m.num_vertices());
    Mesh other = box_mesh(2, Eigen::Vector2d(0.3, 1.01), Eigen::Vector2d(0.9, 1.5), Eigen::Vector2i(5, 4));
    compute_boundary(other);
    append_mesh(m, other, 1);
    const CollisionMesh mesh = boundary_collision_mesh(m, { 1, 1 }, { 0, 1 });
    std::mt19937 rng(8);
    const Positions x1 = m.rest_positions + random_positions(m.num_vertices(), 2, -0.05, 0.05, rng);
    const Candidates c = expect_methods_agree(mesh, m.rest_positions, x1, 0.02);
    EXPECT_GT(expect_conservative(mesh, m.rest_positions, x1, 0.02, c), 0u);
}

TEST(BroadPhase, RandomSegmentSoup2D)
{
    std::mt19937 rng(4);
    const int n = 500;
    Positions x = random_positions(2 * n, 2, 0, 1, rng);
    x.bottomRows(n) = x.topRows(n) + random_positions(n, 2, -0.05, 0.05, rng);
    MatrixXi edges(n, 2);
    std::vector<int> group(size_t(2 * n));
    for (int e = 0; e < n; ++e) {
        edges.row(e) << e, n + e;
        group[size_t(e)] = group[size_t(n + e)] = e % 3;
    }
    const CollisionMesh mesh = make_collision_mesh(2, 2 * n, edges, MatrixXi(0, 3), group, { 1, 0, 0 }, { 0, 1, 1 });
    const Positions x1 = x + random_positions(2 * n, 2, -0.1, 0.1, rng);
    const Candidates c = expect_methods_agree(mesh, x, x1, 0.003);
    EXPECT_GT(expect_conservative(mesh, x, x1, 0.003, c), 0u);
}

// ---------------------------------------------------------------------------------------------------------------
// Degenerate inputs and errors.

TEST(BroadPhase, DegenerateInputs)
{
    // Every vertex at one point with zero inflation: all boxes are that point and all allowed pairs overlap.
    Soup s = triangle_soup(30, 0.1, 1, 9);
    const Positions same = Positions::Zero(s.x.rows(), 3);
    const Candidates c = expect_methods_agree(s.mesh, same, same, 0.0);
    EXPECT_EQ(c.vertex_face.size(), size_t(90 * 29));

    // Empty surfaces.
    CollisionMesh empty
        = make_collision_mesh(3, 5, MatrixXi(0, 2), MatrixXi(0, 3), std::vector<int>(5, 0), { 1 }, { 0 });
    const Positions x5 = Positions::Zero(5, 3);
    EXPECT_TRUE(expect_methods_agree(empty, x5, x5, 1.0).empty());

    // Surface vertices without faces or edges (a point cloud) collide with nothing.
    CollisionMesh points = empty;
    points.vertices = VectorXi::LinSpaced(5, 0, 4);
    EXPECT_TRUE(expect_methods_agree(points, x5, x5, 1.0).empty());
}

TEST(BroadPhase, InvalidInputsThrow)
{
    Soup s = triangle_soup(10, 0.1, 1, 2);
    for (BroadPhaseMethod method : { BroadPhaseMethod::BRUTE_FORCE, BroadPhaseMethod::HASH, BroadPhaseMethod::BVH }) {
        EXPECT_THROW(broad_phase_candidates(s.mesh, s.x, s.x, -1.0, method), std::invalid_argument);
        EXPECT_THROW(broad_phase_candidates(s.mesh, s.x, s.x, std::nan(""), method), std::invalid_argument);
        EXPECT_THROW(broad_phase_candidates(s.mesh, s.x, s.x.topRows(5), 0.1, method), std::invalid_argument);
        EXPECT_THROW(broad_phase_candidates(s.mesh, s.x, s.x.leftCols(2), 0.1, method), std::invalid_argument);
        Positions bad = s.x;
        bad(4, 1) = std::numeric_limits<double>::quiet_NaN();
        EXPECT_THROW(broad_phase_candidates(s.mesh, s.x, bad, 0.1, method), std::invalid_argument);
        bad(4, 1) = std::numeric_limits<double>::infinity();
        EXPECT_THROW(broad_phase_candidates(s.mesh, bad, s.x, 0.1, method), std::invalid_argument);
        CollisionMesh out_of_range = s.mesh;
        out_of_range.faces(0, 0) = int(s.x.rows());
        EXPECT_THROW(broad_phase_candidates(out_of_range, s.x, s.x, 0.1, method), std::invalid_argument);
        CollisionMesh unknown_group = s.mesh;
        unknown_group.vertex_group[3] = 1; // only group 0 has flags
        EXPECT_THROW(broad_phase_candidates(unknown_group, s.x, s.x, 0.1, method), std::invalid_argument);
    }
}

TEST(BroadPhase, CandidatesHelpers)
{
    Candidates c;
    EXPECT_EQ(c.size(), 0u);
    c.vertex_face.push_back({ 0, 1 });
    c.edge_edge.push_back({ 0, 1 });
    c.vertex_edge.push_back({ 2, 3 });
    EXPECT_EQ(c.size(), 3u);
    c.clear();
    EXPECT_TRUE(c.empty());
}

TEST(BroadPhase, HashGridRefusesBoxesNoGridCanCoverInsteadOfLoopingForever)
{
    // Before: a box at +-1e308 (an obstacle scaled past the range of doubles) made the
    // cell-size search double forever. Now it ends with an error; finite boxes still build.
    for (double far : { 1.7e308, std::numeric_limits<double>::infinity() }) {
        std::vector<AABB> boxes(3);
        for (int i = 0; i < 3; ++i) {
            boxes[size_t(i)].min = Eigen::Array3d(i, 0, 0);
            boxes[size_t(i)].max = Eigen::Array3d(i + 0.5, 0.5, 0.5);
        }
        boxes[2].min = Eigen::Array3d(-far, 0, 0);
        boxes[2].max = Eigen::Array3d(far, 0.5, 0.5);
        HashGrid grid;
        EXPECT_THROW(grid.build(boxes, 3), std::runtime_error) << far;
        boxes[2].min = Eigen::Array3d(-1e12, 0, 0);
        boxes[2].max = Eigen::Array3d(1e12, 0.5, 0.5);
        EXPECT_NO_THROW(grid.build(boxes, 3));
    }
}
