// Conservative CCD: the sample-query benchmark against its exact ground truth,
// hand-made trajectories with known times of impact, a randomized comparison
// with densely sampled distances, and the certified distance lower bounds
// (forward/kernels/ccd/distance_lower_bound.hpp) on configurations whose exact
// distance is known. Independent distances come from forward/contact/distance.

#include "forward/common/error.hpp"
#include "forward/contact/ccd/ccd.hpp"
#include "forward/contact/ccd/ccd_sample_queries.hpp"
#include "forward/contact/distance/distance.hpp"
#include "forward/kernels/ccd/distance_lower_bound.hpp"
#include "forward/kernels/eigen_bridge.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

using namespace diffipc;
using V = Eigen::Vector3d;

namespace {

const std::string kSampleQueries = DIFFIPC_SOURCE_DIR "/tests/data/ccd-sample-queries";

V lerp(const V& a, const V& b, double t) { return a + t * (b - a); }

// The certified lower bounds under test, on Eigen points.
using kernels::to_vec3;
double point_point_distance_lower_bound(const V& p0, const V& p1)
{
    return kernels::point_point_distance_lower_bound(to_vec3(p0), to_vec3(p1));
}
double point_edge_distance_lower_bound(const V& p, const V& e0, const V& e1)
{
    return kernels::point_edge_distance_lower_bound(to_vec3(p), to_vec3(e0), to_vec3(e1));
}
double point_triangle_distance_lower_bound(const V& p, const V& t0, const V& t1, const V& t2)
{
    return kernels::point_triangle_distance_lower_bound(to_vec3(p), to_vec3(t0), to_vec3(t1), to_vec3(t2));
}
double edge_edge_distance_lower_bound(const V& ea0, const V& ea1, const V& eb0, const V& eb1)
{
    return kernels::edge_edge_distance_lower_bound(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1));
}

// Independent (unsquared) distances.
double pt_distance(const V& p, const V& t0, const V& t1, const V& t2)
{
    return std::sqrt(point_triangle_distance(p, t0, t1, t2));
}
double ee_distance(const V& ea0, const V& ea1, const V& eb0, const V& eb1)
{
    return std::sqrt(edge_edge_distance(ea0, ea1, eb0, eb1));
}
double pe_distance(const V& p, const V& e0, const V& e1) { return std::sqrt(point_edge_distance(p, e0, e1)); }
double pp_distance(const V& p0, const V& p1) { return std::sqrt(point_point_distance(p0, p1)); }

/// A CCD query over N vertices (first half at t0, second at t1) with its independent distance.
struct Trajectory {
    std::vector<V> x_t0, x_t1;
    std::function<double(const std::vector<V>&)> distance;
    std::function<CCDResult(const std::vector<V>&, const std::vector<V>&, const CCDSettings&)> ccd;

    double distance_at(double t) const
    {
        std::vector<V> x(x_t0.size());
        for (size_t i = 0; i < x.size(); ++i)
            x[i] = lerp(x_t0[i], x_t1[i], t);
        return distance(x);
    }
    CCDResult run(const CCDSettings& s) const { return ccd(x_t0, x_t1, s); }
};

Trajectory point_triangle(std::vector<V> t0, std::vector<V> t1)
{
    return { std::move(t0), std::move(t1), [](const std::vector<V>& x) { return pt_distance(x[0], x[1], x[2], x[3]); },
        [](const std::vector<V>& a, const std::vector<V>& b, const CCDSettings& s) {
            return point_triangle_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], s);
        } };
}
Trajectory edge_edge(std::vector<V> t0, std::vector<V> t1)
{
    return { std::move(t0), std::move(t1), [](const std::vector<V>& x) { return ee_distance(x[0], x[1], x[2], x[3]); },
        [](const std::vector<V>& a, const std::vector<V>& b, const CCDSettings& s) {
            return edge_edge_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], s);
        } };
}
Trajectory point_edge(std::vector<V> t0, std::vector<V> t1)
{
    return { std::move(t0), std::move(t1), [](const std::vector<V>& x) { return pe_distance(x[0], x[1], x[2]); },
        [](const std::vector<V>& a, const std::vector<V>& b, const CCDSettings& s) {
            return point_edge_ccd(a[0], a[1], a[2], b[0], b[1], b[2], s);
        } };
}
Trajectory point_point(std::vector<V> t0, std::vector<V> t1)
{
    return { std::move(t0), std::move(t1), [](const std::vector<V>& x) { return pp_distance(x[0], x[1]); },
        [](const std::vector<V>& a, const std::vector<V>& b, const CCDSettings& s) {
            return point_point_ccd(a[0], a[1], b[0], b[1], s);
        } };
}

CCDSettings with_min_distance(double dmin)
{
    CCDSettings s;
    s.min_distance = dmin;
    return s;
}

/// A reported impact must come no later than the true one, and the gap at toi
/// must be positive and at least (1 - s) of the starting gap (checked with
/// the independent distance, up to its round-off).
void expect_certified_impact(const Trajectory& q, const CCDSettings& s, double true_toi, const std::string& what)
{
    SCOPED_TRACE(what);
    const CCDResult r = q.run(s);
    EXPECT_TRUE(r.collision);
    EXPECT_FALSE(r.budget_exhausted);
    EXPECT_LE(r.toi, true_toi);
    EXPECT_GT(r.toi, 0.5 * true_toi); // not uselessly small for a clean impact
    const double gap0 = q.distance_at(0) - s.min_distance;
    const double gap = q.distance_at(r.toi) - s.min_distance;
    EXPECT_GT(gap, 0);
    EXPECT_GE(gap, (1 - s.conservative_rescaling) * gap0 * (1 - 1e-9));
}

void expect_no_collision(const Trajectory& q, const CCDSettings& s, const std::string& what)
{
    SCOPED_TRACE(what);
    const CCDResult r = q.run(s);
    EXPECT_FALSE(r.collision);
    EXPECT_FALSE(r.budget_exhausted);
    EXPECT_EQ(r.toi, s.t_max);
}

// Unit triangle in z = 0 and the corresponding static trajectory pieces.
const V T0(0, 0, 0), T1(1, 0, 0), T2(0, 1, 0);

std::vector<std::string> sample_query_folders() { return ccd_query_folders(kSampleQueries); }

} // namespace

// ---------------------------------------------------------------------------
// The peer benchmark (Wang et al. 2021): exact rational inputs and ground truth.

TEST(CCDSampleQueries, NoFalseNegativesOnAll7279Queries)
{
    ASSERT_TRUE(std::filesystem::is_directory(kSampleQueries))
        << "the CCD sample queries are missing: expected them at " << kSampleQueries;
    for (const bool refine : { false, true }) {
        CCDSettings settings; // min_distance 0
        settings.refine = refine;
        long total = 0, positives = 0, false_negatives = 0, false_positives = 0, inexact = 0, budget = 0;
        long contract_violations = 0;
        for (const std::string& folder : sample_query_folders()) {
            for (const CCDQuery& q : read_ccd_query_folder(folder, &inexact)) {
                ++total;
                positives += q.ground_truth;
                const CCDResult r = run_ccd_query(q, settings);
                budget += r.budget_exhausted;
                if (q.ground_truth && !r.collision) {
                    ++false_negatives;
                    ADD_FAILURE() << "false negative in " << folder << " (query " << total << ")";
                }
                false_positives += !q.ground_truth && r.collision;
                if (r.collision && r.toi > 0) {
                    // Certified free up to toi, with a gap of at least (1 - s) of the start.
                    const auto& v = q.vertices;
                    auto d = [&](double t) {
                        return q.edge_edge ? ee_distance(
                                   lerp(v[0], v[4], t), lerp(v[1], v[5], t), lerp(v[2], v[6], t), lerp(v[3], v[7], t))
                                           : pt_distance(lerp(v[0], v[4], t), lerp(v[1], v[5], t), lerp(v[2], v[6], t),
                                               lerp(v[3], v[7], t));
                    };
                    if (!(d(r.toi) >= 0.1 * d(0) - 1e-12))
                        ++contract_violations;
                }
            }
        }
        std::printf("[ sample queries, refine %d ] %ld queries (%ld positive), %ld false negatives, %ld false "
                    "positives, %ld budget exhaustions, %ld inexact coordinates\n",
            int(refine), total, positives, false_negatives, false_positives, budget, inexact);
        EXPECT_EQ(total, 7279);
        EXPECT_EQ(false_negatives, 0);
        EXPECT_EQ(inexact, 0); // every coordinate is a 53-bit integer over a power of two
        EXPECT_EQ(contract_violations, 0);
    }
}

TEST(CCDSampleQueries, NoFalseNegativesWithATinyBudget)
{
    // Running out of iterations must report a collision, never "no collision".
    ASSERT_TRUE(std::filesystem::is_directory(kSampleQueries)) << "missing " << kSampleQueries;
    CCDSettings settings;
    settings.max_iterations = 3;
    long false_negatives = 0, budget = 0;
    for (const std::string& folder : sample_query_folders())
        for (const CCDQuery& q : read_ccd_query_folder(folder)) {
            const CCDResult r = run_ccd_query(q, settings);
            false_negatives += q.ground_truth && !r.collision;
            budget += r.budget_exhausted;
            if (r.budget_exhausted)
                EXPECT_TRUE(r.collision);
        }
    EXPECT_EQ(false_negatives, 0);
    EXPECT_GT(budget, 0);
}

TEST(CCDSampleQueries, ReaderConvertsRationalsAndRejectsMalformedFiles)
{
    const auto dir = std::filesystem::temp_directory_path() / "diffipc_test_ccd_reader";
    std::filesystem::create_directories(dir);
    const std::string good = (dir / "good.csv").string(), bad = (dir / "bad.csv").string();
    {
        std::ofstream f(good);
        f << "9007199254740991,2596148429267413814265248164610048,-3,4,0,1,1\n";
        for (int i = 0; i < 6; ++i)
            f << "1,1,0,1,0,1,1\n";
        f << "1,3,0,1,0,1,1\n"; // 1/3 is not a double: counted as inexact
    }
    long inexact = 0;
    const std::vector<CCDQuery> q = read_ccd_queries(good, true, &inexact);
    ASSERT_EQ(q.size(), 1u);
    EXPECT_TRUE(q[0].edge_edge);
    EXPECT_TRUE(q[0].ground_truth);
    EXPECT_EQ(q[0].vertices[0][0], std::ldexp(9007199254740991.0, -111));
    EXPECT_EQ(q[0].vertices[0][1], -0.75);
    EXPECT_EQ(q[0].vertices[7][0], 1.0 / 3.0);
    EXPECT_EQ(inexact, 1);
    {
        std::ofstream f(bad);
        f << "1,1,0,1,0,1\n";
    }
    EXPECT_THROW(read_ccd_queries(bad, false), InputError);
    EXPECT_THROW(read_ccd_queries((dir / "missing.csv").string(), false), InputError);
    std::filesystem::remove_all(dir);
}

// ---------------------------------------------------------------------------
// Hand-made trajectories.

TEST(PointTriangleCCD, HeadOnImpacts)
{
    const auto falling = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, -1), T0, T1, T2 });
    expect_certified_impact(falling, {}, 0.5, "point through a static triangle");
    expect_certified_impact(falling, with_min_distance(0.2), 0.4, "dmin = 0.2");
    // Both move: the triangle rises from z = 0 to z = 1, the point falls from 1 to 0.
    const V up(0, 0, 1);
    const auto both = point_triangle({ V(0.2, 0.3, 1), T0, T1, T2 }, { V(0.2, 0.3, 0), T0 + up, T1 + up, T2 + up });
    expect_certified_impact(both, {}, 0.5, "both moving");
    // A tilted triangle hit near a corner, point moving along x.
    const auto corner = point_triangle({ V(-1, 0.01, 0.01), V(0, 0, 0), V(0, 1, 1), V(0, 1, -1) },
        { V(1, 0.01, 0.01), V(0, 0, 0), V(0, 1, 1), V(0, 1, -1) });
    expect_certified_impact(corner, {}, 0.5, "near a corner");
}

TEST(EdgeEdgeCCD, HeadOnImpacts)
{
    const auto crossing = edge_edge(
        { V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0) }, { V(-1, 0, -1), V(1, 0, -1), V(0, -1, 0), V(0, 1, 0) });
    expect_certified_impact(crossing, {}, 0.5, "crossing edges");
    expect_certified_impact(crossing, with_min_distance(0.1), 0.45, "dmin = 0.1");
    // Edge b, skew to a, sweeps along x at x = -1 + 3t; its midpoint (x, 0, 0) is on a's line and
    // reaches a's end (0.5, 0, 0) at t = 0.5.
    const auto sweeping = edge_edge({ V(0.5, 0, 0), V(1.5, 0, 0), V(-1, -1, 0.5), V(-1, 1, -0.5) },
        { V(0.5, 0, 0), V(1.5, 0, 0), V(2, -1, 0.5), V(2, 1, -0.5) });
    expect_certified_impact(sweeping, {}, 0.5, "sweeping skew edge hits an end point");
}

TEST(PointEdgeCCD, HeadOnImpactsIn2DAnd3D)
{
    const V e0(0, 0, 0), e1(1, 0, 0);
    const auto in_2d = point_edge({ V(0.5, 1, 0), e0, e1 }, { V(0.5, -1, 0), e0, e1 });
    expect_certified_impact(in_2d, {}, 0.5, "2D point through an edge");
    expect_certified_impact(in_2d, with_min_distance(0.25), 0.375, "2D, dmin = 0.25");
    // 2D: e1 moves from (1, 0) to (0, 1), e0 stays; the shrinking segment's end (1 - t, t) meets the
    // static point (0.5, 0.5) at t = 0.5.
    const auto rotating = point_edge({ V(0.5, 0.5, 0), e0, V(1, 0, 0) }, { V(0.5, 0.5, 0), e0, V(0, 1, 0) });
    expect_certified_impact(rotating, {}, 0.5, "2D rotating edge");
    const auto in_3d = point_edge({ V(0.3, 1, 1), e0, e1 }, { V(0.3, -1, -1), e0, e1 });
    expect_certified_impact(in_3d, {}, 0.5, "3D");
}

TEST(PointPointCCD, HeadOnImpact)
{
    const auto q = point_point({ V(-1, 0, 0), V(1, 0, 0) }, { V(1, 0, 0), V(-1, 0, 0) });
    expect_certified_impact(q, {}, 0.5, "opposite points");
    expect_certified_impact(q, with_min_distance(0.5), 0.375, "dmin = 0.5");
}

TEST(CCD, ClearMissesAreNotCollisions)
{
    expect_no_collision(
        point_triangle({ V(0.2, 0.2, 1), T0, T1, T2 }, { V(0.7, 0.1, 1), T0, T1, T2 }), {}, "point gliding above");
    expect_no_collision(point_triangle({ V(2, 0.2, 1), T0, T1, T2 }, { V(2, 0.2, -1), T0, T1, T2 }), {},
        "point crossing the plane beside the triangle");
    expect_no_collision(edge_edge({ V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0) },
                            { V(-1, 0, 0.5), V(1, 0, 0.5), V(0, -1, 0), V(0, 1, 0) }),
        {}, "edges approaching to 0.5");
    expect_no_collision(point_edge({ V(2, 1, 0), V(0, 0, 0), V(1, 0, 0) }, { V(2, -1, 0), V(0, 0, 0), V(1, 0, 0) }), {},
        "2D point passing beyond the edge's end");
    expect_no_collision(
        point_point({ V(-1, 1, 0), V(1, 0, 0) }, { V(1, 1, 0), V(-1, 0, 0) }), {}, "points passing at distance 1");
    // A rigid translation of the pair keeps the distance: one evaluation decides.
    const V shift(3, -2, 1);
    const CCDResult rigid = point_triangle_ccd(V(0.2, 0.2, 0.1), T0, T1, T2, V(0.2, 0.2, 0.1) + shift, T0 + shift,
        T1 + shift, T2 + shift, with_min_distance(0.05));
    EXPECT_FALSE(rigid.collision);
    EXPECT_EQ(rigid.iterations, 1);
}

TEST(CCD, SlidingContact)
{
    // A point sliding across the triangle at height 1e-3.
    const auto sliding = point_triangle({ V(0.1, 0.1, 1e-3), T0, T1, T2 }, { V(0.6, 0.3, 1e-3), T0, T1, T2 });
    const CCDResult below = sliding.run(with_min_distance(1e-2));
    EXPECT_TRUE(below.collision);
    EXPECT_EQ(below.toi, 0); // the start is already inside dmin
    const CCDResult above = sliding.run(with_min_distance(5e-4));
    EXPECT_FALSE(above.collision) << "a certified slide at gap 5e-4 needs about |v| / (s gap) steps";
    EXPECT_GT(above.iterations, 100);
    // Parallel edges sliding along each other at distance 1e-3.
    const auto edges = edge_edge({ V(0, 0, 0), V(1, 0, 0), V(-0.5, 0, 1e-3), V(0.5, 0, 1e-3) },
        { V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 1e-3), V(1.5, 0, 1e-3) });
    EXPECT_TRUE(edges.run(with_min_distance(1e-2)).collision);
    EXPECT_FALSE(edges.run(with_min_distance(5e-4)).collision);
    // A point descending slowly while sliding: from 2e-2 to 0 over the step, crossing dmin = 1e-2 at t = 0.5.
    const auto descending = point_triangle({ V(0.1, 0.1, 2e-2), T0, T1, T2 }, { V(0.6, 0.3, 0), T0, T1, T2 });
    expect_certified_impact(descending, with_min_distance(1e-2), 0.5, "slow descent while sliding");
}

TEST(CCD, ExactlyTouchingConfigurations)
{
    // Zero distance exactly at t = 1, or grazing inside the plane: always a collision.
    EXPECT_TRUE(point_triangle_ccd(V(0.25, 0.25, 1), T0, T1, T2, V(0.25, 0.25, 0), T0, T1, T2).collision);
    EXPECT_TRUE(point_triangle_ccd(V(1, 1, 1), T0, T1, T2, V(0.5, 0.5, 0), T0, T1, T2).collision); // edge at t = 1
    EXPECT_TRUE(point_triangle_ccd(V(-1, 0.5, 0), T0, T1, T2, V(0.5, 0.25, 0), T0, T1, T2).collision); // in-plane
    EXPECT_TRUE(point_triangle_ccd(V(-1, -1, 0), T0, T1, T2, V(0, 0, 0), T0, T1, T2).collision); // corner at t = 1
    EXPECT_TRUE(edge_edge_ccd(
        V(0, 0, 1), V(1, 0, 1), V(0.5, -1, 0), V(0.5, 1, 0), V(0, 0, 0), V(1, 0, 0), V(0.5, -1, 0), V(0.5, 1, 0))
                    .collision); // crossing at t = 1
    EXPECT_TRUE(
        edge_edge_ccd(V(0, 0, 0), V(1, 0, 0), V(3, 0, 0), V(4, 0, 0), V(0, 0, 0), V(1, 0, 0), V(1, 0, 0), V(2, 0, 0))
            .collision); // collinear, end to end at t = 1
    EXPECT_TRUE(point_edge_ccd(V(0.5, 1, 0), V(0, 0, 0), V(1, 0, 0), V(0.5, 0, 0), V(0, 0, 0), V(1, 0, 0)).collision);
    EXPECT_TRUE(point_point_ccd(V(0, 0, 0), V(1, 0, 0), V(1, 0, 0), V(1, 0, 0)).collision);
    // Starting in contact: toi = 0.
    const CCDResult start = point_triangle_ccd(V(0.25, 0.25, 0), T0, T1, T2, V(0.25, 0.25, 1), T0, T1, T2);
    EXPECT_TRUE(start.collision);
    EXPECT_EQ(start.toi, 0);
    // Starting exactly at dmin is not valid either.
    EXPECT_EQ(point_point_ccd(V(0, 0, 0), V(0.5, 0, 0), V(0, 1, 0), V(0.5, 1, 0), with_min_distance(0.5)).toi, 0);
}

TEST(CCD, BudgetExhaustionReturnsACertifiedEarlierTime)
{
    CCDSettings s;
    s.max_iterations = 2;
    const auto falling = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, -1), T0, T1, T2 });
    const CCDResult r = falling.run(s);
    EXPECT_TRUE(r.collision);
    EXPECT_TRUE(r.budget_exhausted);
    EXPECT_EQ(r.iterations, 2);
    EXPECT_LT(r.toi, 0.5);
    EXPECT_GT(falling.distance_at(r.toi), 0);
    // A near miss that needs many steps becomes a (false positive) collision, not "no collision".
    s.max_iterations = 10;
    const auto sliding = point_triangle({ V(0.1, 0.1, 1e-3), T0, T1, T2 }, { V(0.6, 0.3, 1e-3), T0, T1, T2 });
    const CCDResult miss = sliding.run(s);
    EXPECT_TRUE(miss.collision);
    EXPECT_TRUE(miss.budget_exhausted);
    EXPECT_LT(miss.toi, 1);
    EXPECT_GT(sliding.distance_at(miss.toi), 0);
    // Edge-edge too.
    const auto crossing = edge_edge(
        { V(-1, 0, 1), V(1, 0, 1), V(0, -1, 0), V(0, 1, 0) }, { V(-1, 0, -1), V(1, 0, -1), V(0, -1, 0), V(0, 1, 0) });
    s.max_iterations = 1;
    const CCDResult e = crossing.run(s);
    EXPECT_TRUE(e.collision && e.budget_exhausted);
    EXPECT_EQ(e.toi, 0);
}

TEST(CCD, RefinementTellsNearMissesFromImpacts)
{
    // Comes down to distance 0.005 at t = 1 from 1: plain ACCD stops once the gap is below 0.1 of the start
    // (its second step lands at t = 0.99 / 0.995 < 1 with a gap of 0.01).
    const auto near_miss = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, 0.005), T0, T1, T2 });
    CCDSettings plain, refined;
    refined.refine = true;
    EXPECT_TRUE(near_miss.run(plain).collision); // an allowed false positive
    EXPECT_FALSE(near_miss.run(refined).collision);
    // A true impact gives the same toi either way.
    const auto falling = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, -1), T0, T1, T2 });
    const CCDResult a = falling.run(plain), b = falling.run(refined);
    EXPECT_TRUE(a.collision && b.collision);
    EXPECT_EQ(a.toi, b.toi);
    EXPECT_GT(b.iterations, a.iterations);
}

TEST(CCD, TimeWindow)
{
    const auto falling = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, -1), T0, T1, T2 });
    CCDSettings s;
    s.t_max = 0.4;
    expect_no_collision(falling, s, "impact after t_max");
    s.t_max = 0.6;
    expect_certified_impact(falling, s, 0.5, "impact before t_max");
    // Beyond the unit step: the trajectory continues linearly.
    const auto slow = point_triangle({ V(0.25, 0.25, 1), T0, T1, T2 }, { V(0.25, 0.25, 0.5), T0, T1, T2 });
    s.t_max = 3;
    expect_certified_impact(slow, s, 2, "impact at t = 2");
}

TEST(CCD, InvalidSettingsThrowAndNonFiniteInputsCollide)
{
    const V p(0.2, 0.2, 1), q(0.2, 0.2, -1);
    auto run = [&](CCDSettings s) { return point_triangle_ccd(p, T0, T1, T2, q, T0, T1, T2, s); };
    CCDSettings s;
    s.min_distance = -1;
    EXPECT_THROW(run(s), InputError);
    s = {};
    s.conservative_rescaling = 1;
    EXPECT_THROW(run(s), InputError);
    s = {};
    s.t_max = std::numeric_limits<double>::infinity();
    EXPECT_THROW(run(s), InputError);
    s = {};
    s.max_iterations = 0;
    EXPECT_THROW(run(s), InputError);
    s = {};
    s.refine_tolerance = 0;
    EXPECT_THROW(run(s), InputError);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const CCDResult r = point_triangle_ccd(p, T0, T1, T2, V(nan, 0, 0), T0, T1, T2);
    EXPECT_TRUE(r.collision);
    EXPECT_EQ(r.toi, 0);
    EXPECT_TRUE(edge_edge_ccd(V(0, 0, 0), V(1, 0, 0), V(0, 1, 1), V(0, 1, 2), V(0, 0, 0), V(1, 0, 0), V(0, 1, 1),
        V(0, std::numeric_limits<double>::infinity(), 2))
                    .collision);
}

TEST(PointPlaneCCD, MovingPlane)
{
    const V n(0, 0, 3); // any length
    CCDSettings s;
    // Static point at z = 1, the plane rises from z = 0 to z = 2: contact at t = 0.5.
    CCDResult r = point_plane_ccd(V(0.3, 0.1, 1), V(0.3, 0.1, 1), V(5, 5, 0), V(-5, 2, 2), n, s);
    EXPECT_TRUE(r.collision);
    EXPECT_LE(r.toi, 0.5);
    EXPECT_NEAR(r.toi, 0.9 * 0.5, 1e-14); // analytic: s times the exact time of impact
    EXPECT_EQ(r.iterations, 1);
    // From below, both moving; dmin = 0.5: |h| = 2 - 3t reaches 0.5 at t = 0.5.
    s.min_distance = 0.5;
    r = point_plane_ccd(V(0, 0, -2), V(0, 0, 0), V(0, 0, 0), V(0, 0, -1), n, s);
    EXPECT_TRUE(r.collision);
    EXPECT_NEAR(r.toi, 0.45, 1e-14);
    // The gap at toi is (1 - s) of the starting gap: |h(0.45)| - 0.5 = 2 - 1.35 - 0.5 = 0.15 = 0.1 * 1.5.
    EXPECT_NEAR(std::abs(-2 + 3 * r.toi) - 0.5, 0.15, 1e-14);
    s.min_distance = 0;
    // Moving away, and moving together: no collision.
    EXPECT_FALSE(point_plane_ccd(V(0, 0, 1), V(0, 0, 2), V(0, 0, 0), V(0, 0, -1), n, s).collision);
    EXPECT_FALSE(point_plane_ccd(V(0, 0, 1), V(4, 0, 1.5), V(0, 0, 0), V(1, 1, 0.5), n, s).collision);
    // Tangential motion of the origin does not matter; a tilted normal does.
    EXPECT_FALSE(point_plane_ccd(V(0, 0, 1), V(0, 0, 1), V(0, 0, 0), V(100, 0, 0), n, s).collision);
    EXPECT_TRUE(point_plane_ccd(V(0, 0, 1), V(0, 0, 1), V(0, 0, 0), V(100, 0, 0), V(1, 0, 1), s).collision);
    // Exact contact at t = 1, at t = 0, and past t_max.
    EXPECT_TRUE(point_plane_ccd(V(0, 0, 1), V(0, 0, 0), V(0, 0, 0), V(0, 0, 0), n, s).collision);
    r = point_plane_ccd(V(0, 0, 0), V(0, 0, 1), V(0, 0, 0), V(0, 0, 0), n, s);
    EXPECT_TRUE(r.collision);
    EXPECT_EQ(r.toi, 0);
    s.t_max = 0.5;
    EXPECT_FALSE(point_plane_ccd(V(0, 0, 1), V(0, 0, 0), V(0, 0, 0), V(0, 0, 0), n, s).collision);
    EXPECT_THROW(point_plane_ccd(V(0, 0, 1), V(0, 0, 0), V(0, 0, 0), V(0, 0, 0), V(0, 0, 0), s), InputError);
}

// ---------------------------------------------------------------------------
// Randomized: CCD against densely sampled distances of independent code.

namespace {

struct SampledMinimum {
    double min_distance; ///< sampled (an upper bound of the true minimum)
    double first_crossing; ///< first time found with distance <= dmin, or +inf
};

/// Dense sampling (n + 1 times), then golden-section refinement around the
/// smallest sample, then (if the refined minimum crosses dmin before any
/// sample does) the refined time itself as a crossing.
SampledMinimum sample_minimum(const Trajectory& q, double dmin, int n = 4000)
{
    SampledMinimum m { std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity() };
    int best = 0;
    for (int k = 0; k <= n; ++k) {
        const double t = double(k) / n, d = q.distance_at(t);
        if (d < m.min_distance) {
            m.min_distance = d;
            best = k;
        }
        if (d <= dmin && m.first_crossing == std::numeric_limits<double>::infinity())
            m.first_crossing = t;
    }
    double a = std::max(0, best - 1) / double(n), b = std::min(n, best + 1) / double(n);
    const double g = (std::sqrt(5.0) - 1) / 2;
    for (int it = 0; it < 80; ++it) {
        const double c = b - g * (b - a), d = a + g * (b - a);
        if (q.distance_at(c) < q.distance_at(d))
            b = d;
        else
            a = c;
    }
    const double t_ref = 0.5 * (a + b), d_ref = q.distance_at(t_ref);
    if (d_ref < m.min_distance) {
        m.min_distance = d_ref;
        if (d_ref <= dmin)
            m.first_crossing = std::min(m.first_crossing, t_ref);
    }
    return m;
}

void random_trajectories(const std::string& name, int vertices, bool planar,
    const std::function<Trajectory(std::vector<V>, std::vector<V>)>& make, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(-1, 1);
    const double dmins[] = { 1e-3, 1e-2, 0.05, 0.2 };
    int impacts = 0, misses = 0, plain_false_positives = 0;
    for (int trial = 0; trial < 300; ++trial) {
        std::vector<V> x0(static_cast<size_t>(vertices)), x1(static_cast<size_t>(vertices));
        // Every other trial ends in a small box, so that impacts are common.
        const double end_box = trial % 2 ? 1 : 0.1;
        for (int i = 0; i < vertices; ++i) {
            x0[size_t(i)] = V(unit(rng), unit(rng), planar ? 0 : unit(rng));
            x1[size_t(i)] = end_box * V(unit(rng), unit(rng), planar ? 0 : unit(rng));
        }
        const Trajectory q = make(x0, x1);
        const double dmin = dmins[(trial / 2) % 4];
        if (q.distance_at(0) <= dmin + 1e-9)
            continue; // invalid start: toi = 0, tested elsewhere
        const SampledMinimum m = sample_minimum(q, dmin);
        // Sampling misses at most (max relative vertex speed) * (half the spacing) <= 4 sqrt(3) / 8000.
        const double sampling_margin = 1e-3;
        for (const bool refine : { false, true }) {
            CCDSettings s = with_min_distance(dmin);
            s.refine = refine;
            const CCDResult r = q.run(s);
            const std::string what = name + " trial " + std::to_string(trial) + (refine ? " refined" : " plain")
                + ": sampled min " + std::to_string(m.min_distance) + ", dmin " + std::to_string(dmin);
            ASSERT_FALSE(r.budget_exhausted) << what;
            if (m.min_distance <= dmin) {
                ASSERT_TRUE(r.collision) << what;
                EXPECT_LE(r.toi, m.first_crossing) << what;
            }
            if (r.collision) {
                EXPECT_GT(q.distance_at(r.toi), dmin) << what;
                EXPECT_LT(r.toi, 1) << what;
            } else {
                EXPECT_GT(m.min_distance, dmin) << what;
            }
            if (refine && m.min_distance > dmin + sampling_margin)
                EXPECT_FALSE(r.collision) << what << ": a refined search has no false positive this far from contact";
            if (!refine && r.collision && m.min_distance > dmin + sampling_margin)
                ++plain_false_positives;
            if (refine)
                (r.collision ? impacts : misses)++;
        }
    }
    std::printf("[ %s ] %d impacts, %d misses; plain ACCD flagged %d near misses\n", name.c_str(), impacts, misses,
        plain_false_positives);
    EXPECT_GT(impacts, 30);
    EXPECT_GT(misses, 30);
}

} // namespace

TEST(CCDRandom, NeverMissesASampledContact)
{
    random_trajectories("point-triangle", 4, false, point_triangle, 1);
    random_trajectories("edge-edge", 4, false, edge_edge, 2);
    random_trajectories("point-edge 3D", 3, false, point_edge, 3);
    random_trajectories("point-edge 2D", 3, true, point_edge, 4);
    random_trajectories("point-point 3D", 2, false, point_point, 5);
    random_trajectories("edge-edge 2D", 4, true, edge_edge, 6);
}

// ---------------------------------------------------------------------------
// Certified distance lower bounds on configurations with a known exact distance.

TEST(DistanceLowerBound, ExactContactsGiveZero)
{
    // Dyadic coordinates: every point below is exactly where it is said to be.
    EXPECT_EQ(point_triangle_distance_lower_bound(V(0.25, 0.25, 0), T0, T1, T2), 0); // interior
    EXPECT_EQ(point_triangle_distance_lower_bound(V(0.5, 0.5, 0), T0, T1, T2), 0); // on the hypotenuse
    EXPECT_EQ(point_triangle_distance_lower_bound(T1, T0, T1, T2), 0); // corner
    // In the tilted plane x + y + z = 0, inside a sliver (0,0,0), (1,-1,0), (2, -2 + e, -e).
    const double e = std::ldexp(1.0, -30);
    const V s0(0, 0, 0), s1(1, -1, 0), s2(2, -2 + e, -e);
    const V inside = 0.25 * s0 + 0.25 * s1 + 0.5 * s2; // exact in binary
    EXPECT_EQ(point_triangle_distance_lower_bound(inside, s0, s1, s2), 0);
    EXPECT_EQ(edge_edge_distance_lower_bound(V(-1, 0, 0), V(1, 0, 0), V(0.5, -1, 0), V(0.5, 1, 0)), 0);
    EXPECT_EQ(edge_edge_distance_lower_bound(V(0, 0, 0), V(2, 0, 0), V(1, 0, 0), V(3, 0, 0)), 0); // collinear overlap
    // Nearly parallel edges crossing at the origin.
    EXPECT_EQ(edge_edge_distance_lower_bound(V(-1, 1, 0), V(1, -1, 0), -V(1, -1 + e, -e), V(1, -1 + e, -e)), 0);
    EXPECT_EQ(point_edge_distance_lower_bound(V(0.75, 0, 0), V(0, 0, 0), V(1, 0, 0)), 0);
    EXPECT_EQ(point_point_distance_lower_bound(V(1, 2, 3), V(1, 2, 3)), 0);
}

TEST(DistanceLowerBound, BelowAndCloseToKnownDistances)
{
    // Offsets k (1, 1, 1) from the tilted plane x + y + z = 0 are at distance sqrt(3) |k|.
    const double e = std::ldexp(1.0, -30);
    const V n(1, 1, 1);
    struct Case {
        V t0, t1, t2;
        double tolerance; // how close the bound must be (relative)
    };
    const Case triangles[] = {
        { V(0, 0, 0), V(1, -1, 0), V(0, 1, -1), 1e-14 }, // well shaped
        { V(0, 0, 0), V(1, -1, 0), V(2, -2 + e, -e), 1e-8 }, // sliver: the inradius term decides
    };
    for (const Case& c : triangles) {
        const V q = 0.25 * c.t0 + 0.25 * c.t1 + 0.5 * c.t2;
        for (const double k : { 1.0, 1e-3, 1e-9, -0.5 }) {
            const double exact = std::sqrt(3.0) * std::abs(k);
            const double lb = point_triangle_distance_lower_bound(q + k * n, c.t0, c.t1, c.t2);
            EXPECT_LE(lb, exact * (1 + 1e-15));
            EXPECT_GE(lb, exact - c.tolerance * 3);
        }
    }
    // Nearly parallel crossing edges, b lifted by k (1, 1, 1): distance sqrt(3) |k|.
    for (const double k : { 1.0, 1e-6, 1e-12 }) {
        const double lb = edge_edge_distance_lower_bound(
            V(-1, 1, 0), V(1, -1, 0), -V(1, -1 + e, -e) + k * n, V(1, -1 + e, -e) + k * n);
        EXPECT_LE(lb, std::sqrt(3.0) * k * (1 + 1e-15));
        EXPECT_GE(lb, std::sqrt(3.0) * k - 1e-8);
    }
    // Random configurations against the independent squared distances.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> unit(-1, 1);
    auto r = [&] { return V(unit(rng), unit(rng), unit(rng)); };
    for (int k = 0; k < 2000; ++k) {
        const V a = r(), b = r(), c = r(), d = r();
        const double pt = pt_distance(a, b, c, d), ee = ee_distance(a, b, c, d), pe = pe_distance(a, b, c);
        EXPECT_LE(point_triangle_distance_lower_bound(a, b, c, d), pt + 1e-15);
        EXPECT_GE(point_triangle_distance_lower_bound(a, b, c, d), pt - 1e-12);
        EXPECT_LE(edge_edge_distance_lower_bound(a, b, c, d), ee + 1e-15);
        EXPECT_GE(edge_edge_distance_lower_bound(a, b, c, d), ee - 1e-12);
        EXPECT_LE(point_edge_distance_lower_bound(a, b, c), pe + 1e-15);
        EXPECT_GE(point_edge_distance_lower_bound(a, b, c), pe - 1e-13);
    }
}
