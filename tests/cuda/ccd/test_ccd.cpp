// GPU CCD (cuda/ccd/ccd.cuh) against the CPU CCD (forward/contact/ccd/ccd.hpp): the same results bit for bit
// (collision, toi, iterations, budget_exhausted) on the CCD sample queries (Wang et al. 2021, with their exact
// ground truth: no false negatives), on point-edge and point-point queries cut from them, and on hand-made
// degenerate trajectories. The GpuCCDHost tests run the __host__ __device__ code on the CPU and need no GPU
// (CI checks the port's logic there); the GpuCCD tests run the kernels and skip without a GPU.

#include "cuda/ccd/ccd.cuh"
#include "cuda/common/device.hpp"

#include "forward/common/error.hpp"
#include "forward/contact/ccd/ccd.hpp"
#include "forward/contact/ccd/ccd_sample_queries.hpp"
#include "forward/contact/ccd/check_ccd_settings.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

using namespace diffipc;
using V = Eigen::Vector3d;

namespace {

const std::string kSampleQueries = DIFFIPC_SOURCE_DIR "/tests/data/ccd-sample-queries";

const char* const kKernelTestNote
    = " (this test runs the CCD kernels; the GpuCCDHost tests run the same code on the CPU)";

#define SKIP_WITHOUT_GPU()                                                                                             \
    do {                                                                                                               \
        if (!gpu::cuda_device_available())                                                                             \
            GTEST_SKIP() << gpu::cuda_device_description() << kKernelTestNote;                                         \
    } while (0)

std::vector<std::string> sample_query_folders() { return ccd_query_folders(kSampleQueries); }

std::uint64_t bits(double x)
{
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
}

/// Positions xyz after xyz (the batch layout of cuda/ccd/ccd.cuh).
std::vector<double> flatten(const std::vector<V>& x)
{
    std::vector<double> flat;
    for (const V& p : x)
        flat.insert(flat.end(), { p.x(), p.y(), p.z() });
    return flat;
}

/// Queries of one kind in the batch layout (cuda/ccd/ccd.cuh), with the CPU's results and, where known, the truth.
struct Batch {
    gpu::CCDKind kind;
    std::vector<double> vertices; ///< 6 * ccd_vertex_count(kind) doubles per query
    std::vector<std::string> names;
    std::vector<int> ground_truth; ///< 1 touch, 0 no touch (for min_distance 0), -1 unknown
    std::vector<CCDResult> cpu;

    std::size_t size() const { return names.size(); }
    const double* query(std::size_t q) const { return vertices.data() + q * 6 * gpu::ccd_vertex_count(kind); }
};

/// The CPU CCD of one query of the batch layout.
CCDResult cpu_ccd(gpu::CCDKind kind, const double* q, const CCDSettings& s)
{
    auto x = [q](int i) { return V(q[3 * i], q[3 * i + 1], q[3 * i + 2]); };
    switch (kind) {
    case gpu::CCDKind::POINT_TRIANGLE:
        return point_triangle_ccd(x(0), x(1), x(2), x(3), x(4), x(5), x(6), x(7), s);
    case gpu::CCDKind::EDGE_EDGE:
        return edge_edge_ccd(x(0), x(1), x(2), x(3), x(4), x(5), x(6), x(7), s);
    case gpu::CCDKind::POINT_EDGE:
        return point_edge_ccd(x(0), x(1), x(2), x(3), x(4), x(5), s);
    case gpu::CCDKind::POINT_POINT:
        return point_point_ccd(x(0), x(1), x(2), x(3), s);
    }
    throw std::logic_error("not a CCD kind");
}

void add(Batch& b, const std::vector<V>& x, const std::string& name, int truth)
{
    EXPECT_EQ(int(x.size()), 2 * gpu::ccd_vertex_count(b.kind)) << name;
    const std::vector<double> flat = flatten(x);
    b.vertices.insert(b.vertices.end(), flat.begin(), flat.end());
    b.names.push_back(name);
    b.ground_truth.push_back(truth);
}

void run_cpu(Batch& b, const CCDSettings& s)
{
    b.cpu.clear();
    for (std::size_t q = 0; q < b.size(); ++q)
        b.cpu.push_back(cpu_ccd(b.kind, b.query(q), s));
}

const char* kind_name(gpu::CCDKind kind)
{
    switch (kind) {
    case gpu::CCDKind::POINT_TRIANGLE:
        return "point-triangle";
    case gpu::CCDKind::EDGE_EDGE:
        return "edge-edge";
    case gpu::CCDKind::POINT_EDGE:
        return "point-edge";
    case gpu::CCDKind::POINT_POINT:
        return "point-point";
    }
    return "?";
}

/// The sample queries as point-triangle and edge-edge batches, and point-edge (3D and, flattened to z = 0, 2D)
/// and point-point batches cut from the vertex-face queries (point against the triangle's first edge and first
/// corner; no ground truth for those).
std::vector<Batch> sample_batches()
{
    EXPECT_TRUE(std::filesystem::is_directory(kSampleQueries))
        << "the CCD sample queries are missing: expected them at " << kSampleQueries;
    std::vector<Batch> batches(4);
    batches[0].kind = gpu::CCDKind::POINT_TRIANGLE;
    batches[1].kind = gpu::CCDKind::EDGE_EDGE;
    batches[2].kind = gpu::CCDKind::POINT_EDGE;
    batches[3].kind = gpu::CCDKind::POINT_POINT;
    for (const std::string& folder : sample_query_folders()) {
        const std::string set = std::filesystem::path(folder).filename().string();
        long index = 0;
        for (const CCDQuery& q : read_ccd_query_folder(folder)) {
            const std::string name = set + (q.edge_edge ? " edge-edge #" : " vertex-face #") + std::to_string(index++);
            const auto& v = q.vertices;
            add(batches[q.edge_edge ? 1 : 0], { v.begin(), v.end() }, name, q.ground_truth ? 1 : 0);
            if (q.edge_edge)
                continue;
            add(batches[2], { v[0], v[1], v[2], v[4], v[5], v[6] }, name + " (p, e0, e1)", -1);
            auto flat = [](V p) {
                p.z() = 0;
                return p;
            };
            add(batches[2], { flat(v[0]), flat(v[1]), flat(v[2]), flat(v[4]), flat(v[5]), flat(v[6]) },
                name + " (p, e0, e1 in z = 0)", -1);
            add(batches[3], { v[0], v[1], v[4], v[5] }, name + " (p, t0)", -1);
        }
    }
    return batches;
}

/// The settings the comparisons run under: the CPU test's (plain and refined ACCD), a minimum separation with
/// another rescaling, a time window, and a tiny budget.
std::vector<std::pair<std::string, CCDSettings>> settings_variants()
{
    std::vector<std::pair<std::string, CCDSettings>> variants;
    CCDSettings s;
    variants.push_back({ "plain", s });
    s.refine = true;
    variants.push_back({ "refined", s });
    s = {};
    s.min_distance = 1e-4;
    s.conservative_rescaling = 0.8;
    variants.push_back({ "dmin 1e-4, s 0.8", s });
    s = {};
    s.t_max = 0.75;
    variants.push_back({ "t_max 0.75", s });
    s = {};
    s.max_iterations = 3;
    variants.push_back({ "budget 3", s });
    return variants;
}

/// Compares results with the CPU's, query by query; counts false negatives against the ground truth.
struct Comparison {
    long queries = 0, collisions = 0, disagreements = 0, false_negatives = 0, budget_exhausted = 0;
    long long iterations = 0;
};

Comparison compare(
    const Batch& b, const std::vector<gpu::CCDResult>& results, const CCDSettings& settings, const std::string& what)
{
    // The ground truth is about contact on [0, 1]: it says nothing of a shorter window.
    const bool truth_applies = settings.t_max >= 1;
    Comparison c;
    EXPECT_EQ(results.size(), b.size()) << what;
    for (std::size_t q = 0; q < std::min(results.size(), b.size()); ++q) {
        const gpu::CCDResult& r = results[q];
        const CCDResult& e = b.cpu[q];
        ++c.queries;
        c.collisions += r.collision;
        c.budget_exhausted += r.budget_exhausted;
        c.iterations += r.iterations;
        if (truth_applies && b.ground_truth[q] == 1 && !r.collision) {
            ++c.false_negatives;
            ADD_FAILURE() << what << ": false negative on " << b.names[q];
        }
        const bool same = r.collision == e.collision && bits(r.toi) == bits(e.toi) && r.iterations == e.iterations
            && r.budget_exhausted == e.budget_exhausted;
        if (!same && ++c.disagreements <= 5)
            ADD_FAILURE() << what << ": " << b.names[q] << " differs from the CPU CCD: collision " << r.collision
                          << " vs " << e.collision << ", toi " << r.toi << " vs " << e.toi << " (difference "
                          << r.toi - e.toi << "), iterations " << r.iterations << " vs " << e.iterations
                          << ", budget_exhausted " << r.budget_exhausted << " vs " << e.budget_exhausted;
    }
    return c;
}

std::vector<gpu::CCDResult> run_on_host(const Batch& b, const CCDSettings& s)
{
    const gpu::CCDSettings g = (s);
    std::vector<gpu::CCDResult> results;
    for (std::size_t q = 0; q < b.size(); ++q)
        results.push_back(gpu::ccd_query(b.kind, b.query(q), g));
    return results;
}

void print(const std::string& where, const Batch& b, const std::string& settings, const Comparison& c,
    const gpu::CCDBatchTiming* timing = nullptr)
{
    std::printf("[ %s, %s, %s ] %ld queries, %ld collisions, %ld false negatives, %ld budget exhaustions, %lld "
                "iterations; %ld disagree with the CPU CCD",
        where.c_str(), kind_name(b.kind), settings.c_str(), c.queries, c.collisions, c.false_negatives,
        c.budget_exhausted, c.iterations, c.disagreements);
    if (timing)
        std::printf("; kernel %.3f ms (%.3f us per query), with copies %.3f ms", timing->kernel_ms,
            c.queries > 0 ? 1e3 * timing->kernel_ms / double(c.queries) : 0.0, timing->total_ms);
    std::printf("\n");
}

// ---------------------------------------------------------------------------------------------------------------
// Hand-made degenerate trajectories: touching at t = 0 and t = 1, grazing, parallel and collinear edges,
// degenerate primitives, minimum separations, time windows, budgets, non-finite coordinates.

struct Case {
    gpu::CCDKind kind;
    std::vector<V> x; ///< the batch layout: vertices at t = 0, then at t = 1
    CCDSettings settings;
    int expect_collision; ///< 1, 0, or -1 (not asserted)
    std::string name;
};

CCDSettings with(double dmin, double t_max = 1, int max_iterations = 10000000)
{
    CCDSettings s;
    s.min_distance = dmin;
    s.t_max = t_max;
    s.max_iterations = max_iterations;
    return s;
}

std::vector<Case> degenerate_cases()
{
    using K = gpu::CCDKind;
    const V T0(0, 0, 0), T1(1, 0, 0), T2(0, 1, 0), up(0, 0, 1);
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    CCDSettings refined;
    refined.refine = true;
    return {
        // Point-triangle.
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 0), T0, T1, T2, V(0.25, 0.25, 1), T0, T1, T2 }, {}, 1,
            "touching at t = 0" },
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, 0), T0, T1, T2 }, {}, 1,
            "lands on the interior at t = 1" },
        { K::POINT_TRIANGLE, { V(1, 1, 1), T0, T1, T2, V(0.5, 0.5, 0), T0, T1, T2 }, {}, 1,
            "lands on the hypotenuse at t = 1" },
        { K::POINT_TRIANGLE, { V(-1, -1, 0), T0, T1, T2, V(0, 0, 0), T0, T1, T2 }, {}, 1,
            "slides in the plane onto a corner" },
        { K::POINT_TRIANGLE, { V(-1, 0.5, 0), T0, T1, T2, V(0.5, 0.25, 0), T0, T1, T2 }, {}, 1, "in-plane grazing" },
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, -1), T0, T1, T2 }, with(0.2), 1,
            "head-on, dmin 0.2" },
        { K::POINT_TRIANGLE, { V(0.2, 0.3, 1), T0, T1, T2, V(0.2, 0.3, 0), T0 + up, T1 + up, T2 + up }, {}, 1,
            "both moving" },
        { K::POINT_TRIANGLE, { V(0.1, 0.1, 1e-3), T0, T1, T2, V(0.6, 0.3, 1e-3), T0, T1, T2 }, with(1e-2), 1,
            "sliding below dmin from the start" },
        { K::POINT_TRIANGLE, { V(0.1, 0.1, 1e-3), T0, T1, T2, V(0.6, 0.3, 1e-3), T0, T1, T2 }, with(5e-4), 0,
            "sliding at 1e-3 above dmin 5e-4" },
        { K::POINT_TRIANGLE, { V(0.1, 0.1, 1e-3), T0, T1, T2, V(0.6, 0.3, 1e-3), T0, T1, T2 }, with(0, 1, 10), 1,
            "sliding, budget 10" },
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, 0.005), T0, T1, T2 }, refined, 0,
            "near miss, refined" },
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, -1), T0, T1, T2 }, with(0, 0.4), 0,
            "impact after t_max" },
        { K::POINT_TRIANGLE, { V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, 0.5), T0, T1, T2 }, with(0, 3), 1,
            "impact at t = 2, t_max 3" },
        { K::POINT_TRIANGLE,
            { V(0.2, 0.2, 0.1), T0, T1, T2, V(3.2, -1.8, 1.1), T0 + V(3, -2, 1), T1 + V(3, -2, 1), T2 + V(3, -2, 1) },
            with(0.05), 0, "rigid translation" },
        { K::POINT_TRIANGLE,
            { V(0, 0, 1), V(0.5, 0.5, 0), V(0.5, 0.5, 0), V(0.5, 0.5, 0), V(1, 1, -1), V(0.5, 0.5, 0), V(0.5, 0.5, 0),
                V(0.5, 0.5, 0) },
            {}, 1, "triangle collapsed to a point, hit" },
        { K::POINT_TRIANGLE, { V(0, 0, 1), T0, T1, V(2, 0, 0), V(0.5, 0, -1), T0, T1, V(2, 0, 0) }, {}, 1,
            "collinear (flat) triangle, hit" },
        { K::POINT_TRIANGLE, { V(0.2, 0.2, 1), T0, T1, T2, V(nan, 0, 0), T0, T1, T2 }, {}, 1, "NaN coordinate" },
        // Edge-edge.
        { K::EDGE_EDGE,
            { V(0, 0, 0), V(1, 0, 0), V(-0.5, 0, 1e-3), V(0.5, 0, 1e-3), V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 1e-3),
                V(1.5, 0, 1e-3) },
            with(1e-2), 1, "parallel edges sliding inside dmin" },
        { K::EDGE_EDGE,
            { V(0, 0, 0), V(1, 0, 0), V(-0.5, 0, 1e-3), V(0.5, 0, 1e-3), V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 1e-3),
                V(1.5, 0, 1e-3) },
            with(5e-4), 0, "parallel edges sliding outside dmin" },
        { K::EDGE_EDGE,
            { V(0, 0, 1), V(1, 0, 1), V(0, 0, 0), V(1, 0, 0), V(0, 0, 0), V(1, 0, 0), V(0, 0, 0), V(1, 0, 0) }, {}, 1,
            "parallel edges meeting along their length at t = 1" },
        { K::EDGE_EDGE,
            { V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 0), V(1.5, 0, 0), V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 1), V(1.5, 0, 1) },
            {}, 1, "collinear overlapping at t = 0" },
        { K::EDGE_EDGE,
            { V(0, 0, 0), V(1, 0, 0), V(3, 0, 0), V(4, 0, 0), V(0, 0, 0), V(1, 0, 0), V(1, 0, 0), V(2, 0, 0) }, {}, 1,
            "collinear, end to end at t = 1" },
        { K::EDGE_EDGE,
            { V(0, 0, 1), V(1, 0, 1), V(0.5, -1, 0), V(0.5, 1, 0), V(0, 0, 0), V(1, 0, 0), V(0.5, -1, 0),
                V(0.5, 1, 0) },
            {}, 1, "crossing at t = 1" },
        { K::EDGE_EDGE,
            { V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0), V(-1, 0, -1), V(1, 0, -1), V(0, -1, 0), V(0, 1, 0) },
            with(0.1), 1, "crossing, dmin 0.1" },
        { K::EDGE_EDGE,
            { V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0), V(-1, 0, 0.5), V(1, 0, 0.5), V(0, -1, 0), V(0, 1, 0) },
            {}, 0, "approaching to 0.5" },
        { K::EDGE_EDGE,
            { V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0), V(-1, 0, -1), V(1, 0, -1), V(0, -1, 0), V(0, 1, 0) },
            with(0, 1, 1), 1, "crossing, budget 1" },
        { K::EDGE_EDGE,
            { V(0, 0, 1), V(0, 0, 1), V(0, 0, 0), V(0, 0, 0), V(0, 0, -1), V(0, 0, -1), V(0, 0, 0), V(0, 0, 0) }, {}, 1,
            "both edges points, passing through each other" },
        { K::EDGE_EDGE,
            { V(0, 0, 0), V(1, 0, 0), V(0, 1, 1), V(0, 1, 2), V(0, 0, 0), V(1, 0, 0), V(0, 1, 1), V(0, inf, 2) }, {}, 1,
            "infinite coordinate" },
        // Point-edge, 2D (z = 0) and 3D.
        { K::POINT_EDGE, { V(0.5, 1, 0), T0, T1, V(0.5, -1, 0), T0, T1 }, with(0.25), 1, "2D head-on, dmin 0.25" },
        { K::POINT_EDGE, { V(0.5, 1, 0), T0, T1, V(0.5, 0, 0), T0, T1 }, {}, 1, "2D, lands on the edge at t = 1" },
        { K::POINT_EDGE, { V(0.5, 0.5, 0), T0, V(1, 0, 0), V(0.5, 0.5, 0), T0, V(0, 1, 0) }, {}, 1,
            "2D rotating edge" },
        { K::POINT_EDGE, { V(-1, 0, 0), T0, T1, V(0, 0, 0), T0, T1 }, {}, 1, "2D collinear, meets the end at t = 1" },
        { K::POINT_EDGE, { V(0, 0, 0), T0, T1, V(0, 1, 0), T0, T1 }, {}, 1, "2D, on the end point at t = 0" },
        { K::POINT_EDGE, { V(2, 1, 0), T0, T1, V(2, -1, 0), T0, T1 }, {}, 0, "2D, passing beyond the end" },
        { K::POINT_EDGE, { V(0.3, 1, 1), T0, T1, V(0.3, -1, -1), T0, T1 }, {}, 1, "3D head-on" },
        { K::POINT_EDGE, { V(0.5, 1, 0), V(0.5, 0, 0), V(0.5, 0, 0), V(0.5, -1, 0), V(0.5, 0, 0), V(0.5, 0, 0) }, {}, 1,
            "edge collapsed to a point" },
        // Point-point.
        { K::POINT_POINT, { V(-1, 0, 0), V(1, 0, 0), V(1, 0, 0), V(-1, 0, 0) }, with(0.5), 1,
            "opposite points, dmin 0.5" },
        { K::POINT_POINT, { V(0, 0, 0), V(1, 0, 0), V(1, 0, 0), V(1, 0, 0) }, {}, 1, "coincide at t = 1" },
        { K::POINT_POINT, { V(0, 0, 0), V(0.5, 0, 0), V(0, 1, 0), V(0.5, 1, 0) }, with(0.5), 1,
            "starting exactly at dmin" },
        { K::POINT_POINT, { V(-1, 1, 0), V(1, 0, 0), V(1, 1, 0), V(-1, 0, 0) }, {}, 0, "passing at distance 1" },
        { K::POINT_POINT, { V(-1, 1, 0), V(1, 0, 0), V(1, 1, 0), V(-1, 0, 0) }, with(1 - 1e-12), -1,
            "passing 1e-12 outside dmin (a collision is a permitted false positive)" },
    };
}

/// Checks one case's result: the CPU's bit for bit and, where known, the expected collision flag.
void check_case(const Case& c, const gpu::CCDResult& r, const std::string& where)
{
    const CCDResult e = cpu_ccd(c.kind, flatten(c.x).data(), c.settings);
    SCOPED_TRACE(where + ": " + kind_name(c.kind) + ", " + c.name);
    EXPECT_EQ(r.collision, e.collision);
    EXPECT_EQ(bits(r.toi), bits(e.toi)) << "toi " << r.toi << " vs " << e.toi;
    EXPECT_EQ(r.iterations, e.iterations);
    EXPECT_EQ(r.budget_exhausted, e.budget_exhausted);
    if (c.expect_collision >= 0)
        EXPECT_EQ(r.collision, c.expect_collision == 1);
}

} // namespace

// ---------------------------------------------------------------------------------------------------------------
// The __host__ __device__ code on the CPU (no GPU needed).

TEST(GpuCCDHost, SampleQueriesGiveTheCPUResultsBitForBit)
{
    std::vector<Batch> batches = sample_batches();
    EXPECT_EQ(batches[0].size() + batches[1].size(), 7279u);
    for (const auto& [name, settings] : settings_variants())
        for (Batch& b : batches) {
            run_cpu(b, settings);
            const Comparison c = compare(b, run_on_host(b, settings), settings, std::string("host, ") + name);
            print("host", b, name, c);
            EXPECT_EQ(c.false_negatives, 0);
            EXPECT_EQ(c.disagreements, 0);
        }
}

TEST(GpuCCDHost, DegenerateCasesGiveTheCPUResultsBitForBit)
{
    for (const Case& c : degenerate_cases())
        check_case(c, gpu::ccd_query(c.kind, flatten(c.x).data(), (c.settings)), "host");
}

TEST(GpuCCDHost, SettingsAreCheckedLikeTheCPU)
{
    auto invalid = [](const std::function<void(gpu::CCDSettings&)>& change) {
        gpu::CCDSettings s;
        change(s);
        return s;
    };
    const double inf = std::numeric_limits<double>::infinity();
    const std::vector<gpu::CCDSettings> bad = {
        invalid([](gpu::CCDSettings& s) { s.min_distance = -1; }),
        invalid([](gpu::CCDSettings& s) { s.conservative_rescaling = 1; }),
        invalid([](gpu::CCDSettings& s) { s.conservative_rescaling = 0; }),
        invalid([&](gpu::CCDSettings& s) { s.t_max = inf; }),
        invalid([](gpu::CCDSettings& s) { s.max_iterations = 0; }),
        invalid([](gpu::CCDSettings& s) { s.refine_tolerance = 0; }),
    };
    const std::vector<double> query(24, 0.0);
    for (const gpu::CCDSettings& s : bad) {
        EXPECT_THROW(check_ccd_settings(s), InputError);
        // Checked before any device call, so this holds without a GPU too.
        EXPECT_THROW(gpu::ccd_batch(gpu::CCDKind::POINT_TRIANGLE, query.data(), 1, s), InputError);
    }
    EXPECT_NO_THROW(check_ccd_settings(gpu::CCDSettings()));
    EXPECT_TRUE(gpu::ccd_batch(gpu::CCDKind::EDGE_EDGE, nullptr, 0, {}).empty()); // no device call
    if (!gpu::cuda_device_available()) {
        try {
            gpu::ccd_batch(gpu::CCDKind::POINT_TRIANGLE, query.data(), 1, {});
            ADD_FAILURE() << "ccd_batch ran without a GPU";
        } catch (const std::runtime_error& e) {
            EXPECT_EQ(std::string(e.what()).rfind("no CUDA device: ", 0), 0u) << e.what();
        }
    }
}

// ---------------------------------------------------------------------------------------------------------------
// The kernels (a GPU needed).

TEST(GpuCCD, DeviceIsReported)
{
    std::printf("[ device ] %s\n", gpu::cuda_device_description().c_str());
    SKIP_WITHOUT_GPU();
    EXPECT_TRUE(gpu::cuda_device_available());
}

TEST(GpuCCD, SampleQueriesGiveTheCPUResultsBitForBit)
{
    SKIP_WITHOUT_GPU();
    std::vector<Batch> batches = sample_batches();
    EXPECT_EQ(batches[0].size() + batches[1].size(), 7279u);
    // A first batch loads the module (lazy loading), so that the timings below are the kernels'.
    gpu::ccd_batch(batches[0].kind, batches[0].vertices.data(), batches[0].size(), {});
    for (const auto& [name, settings] : settings_variants())
        for (Batch& b : batches) {
            run_cpu(b, settings);
            gpu::CCDBatchTiming timing;
            const auto results = gpu::ccd_batch(b.kind, b.vertices.data(), b.size(), (settings), &timing);
            const Comparison c = compare(b, results, settings, std::string("GPU, ") + name);
            print("GPU", b, name, c, &timing);
            EXPECT_EQ(c.false_negatives, 0);
            EXPECT_EQ(c.disagreements, 0);
        }
}

TEST(GpuCCD, DegenerateCasesGiveTheCPUResultsBitForBit)
{
    SKIP_WITHOUT_GPU();
    for (const Case& c : degenerate_cases()) {
        const auto r = gpu::ccd_batch(c.kind, flatten(c.x).data(), 1, (c.settings));
        ASSERT_EQ(r.size(), 1u);
        check_case(c, r[0], "GPU");
    }
}
