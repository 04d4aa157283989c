// GPU step bound (cuda/broad_phase/step_bound.hpp) against the CPU's ContactPotential::max_step: the same alpha
// bit for bit, the same unresolved and budget flags, and the same swept candidates, on 2D and 3D scenes (with
// planes, self contact, periodic image surfaces) for steps that stay clear and steps that would cause
// intersections (alpha < 1), under several CCD settings. The host test checks the point-plane CCD port on the CPU
// (no GPU needed). A disabled test times the GPU broad phase and step bound against the CPU's on two slabs of
// about 200k tetrahedra (run it with --gtest_also_run_disabled_tests).

#include "tests/cuda/broad_phase/broad_phase_test_utils.hpp"

#include "cuda/linalg/device_array.hpp"
#include "forward/common/error.hpp"
#include "forward/contact/ccd/ccd.hpp"
#include "forward/contact/collision_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

using namespace diffipc;
using namespace diffipc::test;

namespace {

std::uint64_t bits(double x)
{
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
}

gpu::vec3 to_vec3(const Eigen::Vector3d& v) { return gpu::vec3(v.x(), v.y(), v.z()); }

double seconds_since(std::chrono::steady_clock::time_point start)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

/// The CPU's swept candidates of max_step, recomputed with its inflation.
Candidates cpu_swept_candidates(const ContactScene& s, const VectorXd& x, const VectorXd& p, double inflation)
{
    const VectorXd x1 = x + p;
    return broad_phase_candidates(s.mesh, as_positions(x, s.dim), as_positions(x1, s.dim), inflation);
}

/// Are the GPU candidates (from the device views) the CPU's?
::testing::AssertionResult same_pairs(const Candidates& cpu, const gpu::CandidatePairs& g)
{
    if (to_int_pairs(cpu.vertex_edge) != g.vertex_edge)
        return ::testing::AssertionFailure()
            << "vertex-edge: CPU " << cpu.vertex_edge.size() << ", GPU " << g.vertex_edge.size();
    if (to_int_pairs(cpu.vertex_face) != g.vertex_face)
        return ::testing::AssertionFailure()
            << "vertex-face: CPU " << cpu.vertex_face.size() << ", GPU " << g.vertex_face.size();
    if (to_int_pairs(cpu.edge_edge) != g.edge_edge)
        return ::testing::AssertionFailure()
            << "edge-edge: CPU " << cpu.edge_edge.size() << ", GPU " << g.edge_edge.size();
    return ::testing::AssertionSuccess();
}

/// Two slabs (contact_slabs of cli/bench_scenes.cpp scaled up): 52 x 6 x 52 and 46 x 8 x 46 cubes of 6 tets each,
/// 198,912 tetrahedra.
nlohmann::json big_slabs()
{
    auto slab = [](const std::string& name, std::vector<double> lo, std::vector<double> hi, std::vector<int> cells) {
        return nlohmann::json { { "name", name },
            { "mesh", { { "box", { { "min", lo }, { "max", hi }, { "cells", cells } } } } },
            { "material", { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 1000 } } },
            { "self_contact", false } };
    };
    nlohmann::json s;
    s["dimension"] = 3;
    s["bodies"] = { slab("base", { -1.2, -0.15, -1.2 }, { 1.2, 0.0, 1.2 }, { 52, 6, 52 }),
        slab("slab", { -1.0, 0.002, -1.0 }, { 1.0, 0.202, 1.0 }, { 46, 8, 46 }) };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e5 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.005 }, { "steps", 1 } };
    return s;
}

} // namespace

TEST(GpuStepBoundHost, PointPlaneCcdIsTheCpusBitForBit)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const auto random_point
        = [&](double scale) -> Eigen::Vector3d { return Eigen::Vector3d(u(rng), u(rng), u(rng)) * scale; };
    int collisions = 0;
    for (int k = 0; k < 20000; ++k) {
        CCDSettings settings;
        settings.min_distance = k % 3 == 0 ? 0.0 : 1e-3 * std::abs(u(rng));
        settings.conservative_rescaling = k % 2 ? 0.9 : 0.5;
        const Eigen::Vector3d normal = k % 5 == 0 ? Eigen::Vector3d(0, 1, 0) : random_point(1.0);
        const Eigen::Vector3d o0 = random_point(0.1), o1 = o0 + random_point(k % 4 == 0 ? 0.0 : 0.01);
        const Eigen::Vector3d p0 = o0 + random_point(0.05), p1 = p0 + random_point(0.1);
        const CCDResult cpu = point_plane_ccd(p0, p1, o0, o1, normal, settings);
        gpu::CCDSettings g;
        g.min_distance = settings.min_distance;
        g.conservative_rescaling = settings.conservative_rescaling;
        const gpu::CCDResult gpu_result
            = gpu::point_plane_ccd(to_vec3(p0), to_vec3(p1), to_vec3(o0), to_vec3(o1), to_vec3(normal), g);
        ASSERT_EQ(cpu.collision, gpu_result.collision) << "query " << k;
        ASSERT_EQ(bits(cpu.toi), bits(gpu_result.toi)) << "query " << k;
        ASSERT_EQ(cpu.iterations, gpu_result.iterations) << "query " << k;
        collisions += cpu.collision;
    }
    EXPECT_GT(collisions, 1000);
    EXPECT_LT(collisions, 19000);
}

TEST(GpuStepBound, EqualsTheCpuMaxStepBitForBit)
{
    REQUIRE_GPU_FOR_BROAD_PHASE();
    struct Variant {
        const char* what;
        double min_distance;
        double rescaling;
        int max_iterations;
    };
    const Variant variants[] = {
        { "scene settings", -1, 0, 0 },
        { "dmin 1e-4, s 0.5", 1e-4, 0.5, 1000000 },
        { "budget of 3 iterations", -1, 0.9, 3 },
    };
    int bounded = 0, exhausted = 0, unresolved = 0, total = 0;
    std::printf("  %-32s %-24s alpha of the steps (zero, small, drop 2e-3, drop 0.05, large, down 0.02, from "
                "intersecting)\n",
        "scene", "settings");
    for (const ContactScene& scene : broad_phase_scenes()) {
        for (const Variant& variant : variants) {
            ContactScene s = scene;
            if (variant.min_distance >= 0) {
                s.settings.min_distance = variant.min_distance;
                s.settings.ccd_rescaling = variant.rescaling;
            }
            if (variant.max_iterations > 0)
                s.settings.ccd_max_iterations = variant.max_iterations;
            // A potential on the collision mesh itself (with periodic images: the image surface), so that max_step
            // sees the positions the GPU gets.
            ContactPotential cpu(s.mesh, as_positions(s.x, s.dim), s.planes, s.settings);
            gpu::DeviceStepBound gpu_bound(to_gpu(s.mesh), to_gpu(s.planes), to_gpu(s.settings));
            struct Step {
                std::string what;
                VectorXd x, p;
            };
            const VectorXd x1 = perturbed(s.x, 1e-5 * s.size, 11);
            // Every body vertex 2 cm down (onto the planes, 1 cm below); the upper body 2 mm into the lower one.
            VectorXd down = VectorXd::Zero(s.x.size()), inside = s.x;
            for (Index v = 0; v < s.x.size() / s.dim; ++v) {
                const int g = s.mesh.vertex_group[size_t(v)];
                if (g >= 0 && !s.mesh.group_kinematic[size_t(g)])
                    down[v * s.dim + 1] = -0.02;
                if (g == 1)
                    inside[v * s.dim + 1] -= 2e-3;
            }
            const std::vector<Step> steps = {
                { "zero step", s.x, VectorXd::Zero(s.x.size()) },
                { "small random", s.x, scene_step(s, 1e-3 * s.size, 0, 21) },
                { "drop 2e-3", s.x, scene_step(s, 1e-4 * s.size, 2e-3, 22) },
                { "drop 0.05", x1, scene_step(s, 1e-2 * s.size, 0.05, 23) },
                { "large random", x1, scene_step(s, 0.3 * s.size, 0.1, 24) },
                { "all down 0.02", x1, down },
                { "from intersecting", inside, scene_step(s, 1e-4 * s.size, 0, 25) },
            };
            std::string alphas;
            for (const Step& step : steps) {
                const double cpu_alpha = cpu.max_step(step.x, step.p);
                const gpu::StepBoundResult g = gpu_bound.max_step(to_std(step.x), to_std(step.p));
                const std::string where = s.name + ", " + variant.what + ", " + step.what;
                EXPECT_EQ(bits(cpu_alpha), bits(g.alpha)) << where << ": CPU " << cpu_alpha << ", GPU " << g.alpha;
                EXPECT_EQ(cpu.step_unresolved(), g.unresolved) << where;
                EXPECT_EQ(cpu.ccd_budget_exhausted(), g.budget_exhausted) << where;
                // The candidates the CCD ran over are the CPU's swept candidates at the CPU's inflation.
                const double tolerance = 1e-12 * (step.x.lpNorm<Eigen::Infinity>() + step.p.lpNorm<Eigen::Infinity>());
                const double inflation = s.settings.min_distance + s.settings.dhat + 4 * tolerance;
                EXPECT_EQ(bits(inflation), bits(g.inflation)) << where;
                EXPECT_TRUE(same_pairs(cpu_swept_candidates(s, step.x, step.p, inflation),
                    gpu::DeviceBroadPhase::download(gpu_bound.segment_candidates())))
                    << where;
                bounded += g.alpha < 1;
                exhausted += g.budget_exhausted;
                unresolved += g.unresolved;
                ++total;
                char buffer[32];
                std::snprintf(buffer, sizeof buffer, " %.4g%s", g.alpha, g.budget_exhausted ? "*" : "");
                alphas += buffer;
            }
            std::printf("  %-32s %-24s%s\n", s.name.c_str(), variant.what, alphas.c_str());
        }
    }
    std::printf("  %d steps, %d bounded (alpha < 1), %d unresolved (alpha 0), %d with an exhausted CCD budget (*)\n",
        total, bounded, unresolved, exhausted);
    EXPECT_GT(bounded, total / 3); // steps that would intersect are among them
    EXPECT_GT(unresolved, 0);
    EXPECT_GT(exhausted, 0);
}

TEST(GpuStepBound, DevicePointersAndRepeatedCalls)
{
    REQUIRE_GPU_FOR_BROAD_PHASE();
    const ContactScene s = broad_phase_scenes()[4]; // 3D boxes with self contact and a plane
    ContactPotential cpu(s.mesh, as_positions(s.x, s.dim), s.planes, s.settings);
    gpu::DeviceStepBound bound(to_gpu(s.mesh), to_gpu(s.planes), to_gpu(s.settings));
    const VectorXd p = scene_step(s, 1e-3, 0.03, 5);
    gpu::DeviceArray<double> d_x(to_std(s.x)), d_p(to_std(p));
    const gpu::StepBoundResult a = bound.max_step(d_x.data(), d_p.data());
    const gpu::StepBoundResult b = bound.max_step(d_x.data(), d_p.data());
    const double cpu_alpha = cpu.max_step(s.x, p);
    EXPECT_LT(cpu_alpha, 1);
    EXPECT_EQ(bits(cpu_alpha), bits(a.alpha));
    EXPECT_EQ(bits(a.alpha), bits(b.alpha));
    EXPECT_GT(a.num_plane, 0u);
    // x + p stays on the device for the line search's trial points.
    const std::vector<double> x1 = [&] {
        gpu::DeviceArray<double> copy(s.x.size());
        gpu::detail::copy_device_to_device(copy.data(), bound.segment_end(), sizeof(double) * size_t(s.x.size()));
        return copy.download();
    }();
    const VectorXd expected = s.x + p;
    for (Index i = 0; i < s.x.size(); ++i)
        ASSERT_EQ(bits(expected[i]), bits(x1[size_t(i)]));
    // Invalid settings are refused as the CPU CCD refuses them.
    gpu::StepBoundSettings bad = to_gpu(s.settings);
    bad.ccd_rescaling = 1.5;
    EXPECT_THROW(bound.set_settings(bad), InputError);
    EXPECT_THROW(bound.max_step(std::vector<double>(3), std::vector<double>(3)), std::invalid_argument);
}

TEST(GpuBroadPhaseTiming, DISABLED_SlabsAt200kTets)
{
    REQUIRE_GPU_FOR_BROAD_PHASE();
    const auto setup_start = std::chrono::steady_clock::now();
    const Scene scene = make_scene(big_slabs());
    const Mesh& mesh = scene.mesh;
    const CollisionMesh cmesh = build_collision_mesh(mesh, { 0, 0 }, { 0, 0 });
    ContactSettings settings;
    settings.dhat = 1e-3;
    ContactPotential cpu(cmesh, mesh.rest_positions, {}, settings);
    // The slab 0.5 mm above the base (within dhat), then a step that drops it by 4 mm (alpha < 1).
    VectorXd x = flatten(mesh.rest_positions);
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        if (mesh.vertex_body[v] == 1)
            x[3 * v + 1] -= 1.5e-3;
    VectorXd p = 1e-4 * random_vector(x.size(), 3);
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        if (mesh.vertex_body[v] == 1)
            p[3 * v + 1] -= 4e-3;
    const Positions X = as_positions(x, 3);
    const VectorXd x1 = x + p;
    const Positions X1 = as_positions(x1, 3);
    std::printf(
        "  %lld tetrahedra, %lld vertices; collision mesh %lld vertices, %lld edges, %lld faces (setup %.1f s)\n",
        (long long)mesh.elements.rows(), (long long)mesh.num_vertices(), (long long)cmesh.vertices.size(),
        (long long)cmesh.edges.rows(), (long long)cmesh.faces.rows(), seconds_since(setup_start));
    std::printf("  %s\n", gpu::cuda_device_description().c_str());

    gpu::DeviceBroadPhase broad_phase(to_gpu(cmesh));
    gpu::DeviceStepBound bound(to_gpu(cmesh), {}, to_gpu(settings));
    gpu::DeviceArray<double> d_x(to_std(x)), d_x1(to_std(x1)), d_p(to_std(p));
    constexpr int GPU_RUNS = 20, CPU_RUNS = 5;

    // Static (active set at dhat) and swept (the step's candidates) queries: GPU wall time per call (device
    // pointers in, sorted pairs on the device, counts on the host) against the CPU broad phase (TBB, all cores).
    const double inflation_swept = bound.max_step(d_x.data(), d_p.data()).inflation;
    struct Case {
        const char* what;
        const double* d_x1;
        const Positions* X1;
        double inflation;
    };
    for (const Case& c : { Case { "static, dhat", d_x.data(), &X, settings.dhat },
             Case { "swept, step bound's inflation", d_x1.data(), &X1, inflation_swept } }) {
        std::vector<double> gpu_times, cpu_times;
        gpu::BroadPhaseTiming timing;
        gpu::DeviceCandidates found;
        for (int r = 0; r < GPU_RUNS; ++r) {
            const auto start = std::chrono::steady_clock::now();
            found = broad_phase.find(d_x.data(), c.d_x1, c.inflation);
            gpu_times.push_back(seconds_since(start));
            timing = broad_phase.timing();
        }
        Candidates cpu_candidates;
        for (int r = 0; r < CPU_RUNS; ++r) {
            const auto start = std::chrono::steady_clock::now();
            cpu_candidates = broad_phase_candidates(cmesh, X, *c.X1, c.inflation);
            cpu_times.push_back(seconds_since(start));
        }
        EXPECT_TRUE(same_pairs(cpu_candidates, gpu::DeviceBroadPhase::download(found))) << c.what;
        std::printf("  broad phase %-30s %8zu VF %8zu EE: GPU %7.3f ms (median of %d; events: boxes %.3f, build "
                    "%.3f, query %.3f, sort %.3f ms), CPU %8.3f ms (median of %d): %.1fx\n",
            c.what, found.num_vertex_face, found.num_edge_edge, 1e3 * median(gpu_times), GPU_RUNS, timing.boxes_ms,
            timing.build_ms, timing.query_ms, timing.sort_ms, 1e3 * median(cpu_times), CPU_RUNS,
            median(cpu_times) / median(gpu_times));
    }

    // The step bound: broad phase + CCD + min-reduction, device pointers in, alpha on the host.
    std::vector<double> gpu_times, cpu_times;
    gpu::StepBoundResult result;
    for (int r = 0; r < GPU_RUNS; ++r) {
        const auto start = std::chrono::steady_clock::now();
        result = bound.max_step(d_x.data(), d_p.data());
        gpu_times.push_back(seconds_since(start));
    }
    double cpu_alpha = 0;
    for (int r = 0; r < CPU_RUNS; ++r) {
        const auto start = std::chrono::steady_clock::now();
        cpu_alpha = cpu.max_step(x, p);
        cpu_times.push_back(seconds_since(start));
    }
    EXPECT_EQ(bits(cpu_alpha), bits(result.alpha));
    EXPECT_LT(result.alpha, 1);
    std::printf("  step bound: alpha %.17g (CPU %.17g), %zu pairs: GPU %7.3f ms (median of %d; events: broad phase "
                "%.3f, CCD %.3f ms), CPU %8.3f ms (median of %d): %.1fx\n",
        result.alpha, cpu_alpha, result.num_vertex_face + result.num_edge_edge, 1e3 * median(gpu_times), GPU_RUNS,
        result.broad_phase_ms, result.ccd_ms, 1e3 * median(cpu_times), CPU_RUNS, median(cpu_times) / median(gpu_times));
}
