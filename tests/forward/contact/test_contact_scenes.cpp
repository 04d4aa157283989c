// The contact scenes of studies/2xx, in small versions, checked after every
// committed step by exact tests that share no code with the barrier, broad
// phase or CCD: GMP orientation predicates for edge-face (2D: edge-edge)
// intersections and element inversions, and the signed distance to planes.

#include "forward/contact/intersection.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <functional>
#include <string>

using namespace diffipc;
using nlohmann::json;

namespace {

std::string study(const std::string& name) { return std::string(DIFFIPC_SOURCE_DIR) + "/studies/" + name; }

json load_json(const std::string& dir)
{
    std::ifstream in(dir + "/scene.json");
    EXPECT_TRUE(bool(in)) << dir;
    return json::parse(in);
}

/// Exact validity of a state: no inverted element, no intersecting surface
/// primitives (every body also against itself), every body vertex strictly on
/// the free side of every plane. Returns "" or the first violation.
std::string check_state(const Simulator& sim, const VectorXd& x)
{
    const Scene& scene = sim.scene();
    const Positions X = unflatten(x, scene.dim);
    if (const Index inverted = count_inverted_elements(scene.mesh, X))
        return std::to_string(inverted) + " inverted elements";
    const std::string hit = find_intersection(sim.contact()->collision_mesh(), X, /*all_pairs=*/true);
    if (!hit.empty())
        return hit;
    for (const ObstacleSpec& o : scene.obstacles) {
        if (o.type != ObstacleType::PLANE)
            continue;
        const VectorXd origin = X.row(o.first_vertex).transpose();
        for (Index v = 0; v < scene.body_vertices; ++v)
            if (!((X.row(v).transpose() - origin).dot(o.normal) > 0))
                return "vertex " + std::to_string(v) + " is not above plane " + o.name;
    }
    return "";
}

struct RunSummary {
    int committed = 0;
    StepStatus status = StepStatus::CONVERGED;
    int max_active = 0;
    double min_distance = 1e300;
    VectorXd final_positions;
};

/// Runs the scene step by step, checking every committed state.
RunSummary run_checked(const json& j, const std::string& dir)
{
    Simulator sim(parse_scene(j, dir, dir));
    RunSummary out;
    EXPECT_EQ(check_state(sim, sim.positions()), "") << "initial state";
    while (sim.steps_done() < sim.scene().time.steps) {
        out.status = sim.step();
        if (out.status != StepStatus::CONVERGED)
            break;
        ++out.committed;
        const StepRecord& r = sim.trajectory().steps.back();
        out.max_active = std::max(out.max_active, r.active_contacts);
        out.min_distance = std::min(out.min_distance, r.min_distance);
        const std::string problem = check_state(sim, sim.positions());
        EXPECT_EQ(problem, "") << "after step " << r.index;
        if (!problem.empty())
            break;
    }
    out.final_positions = sim.positions();
    return out;
}

} // namespace

TEST(ContactScenes, RingDroppedOnPlane2D)
{
    json j = load_json(study("201_ring_on_plane"));
    j["bodies"][0]["mesh"]["annulus"]["segments"] = 32;
    j["bodies"][0]["mesh"]["annulus"]["layers"] = 2;
    j["time"]["steps"] = 40;
    const RunSummary r = run_checked(j, study("201_ring_on_plane"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 40);
    EXPECT_GT(r.max_active, 0) << "the ring never reached the plane";
}

TEST(ContactScenes, BoxesHeadOn3D)
{
    json j = load_json(study("202_boxes_head_on"));
    j["bodies"][0]["mesh"]["box"]["cells"] = { 4, 2, 2 };
    j["bodies"][1]["mesh"]["box"]["cells"] = { 4, 2, 2 };
    j["time"]["steps"] = 12;
    const RunSummary r = run_checked(j, study("202_boxes_head_on"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 12);
    EXPECT_GT(r.max_active, 0) << "the boxes never met";
}

TEST(ContactScenes, BoxSqueezedBetweenPlanes)
{
    json j = load_json(study("203_box_squeeze"));
    j["bodies"][0]["mesh"]["box"]["cells"] = { 3, 3, 3 };
    const RunSummary r = run_checked(j, study("203_box_squeeze"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 20);
    // Squeezed to half its height: every body vertex between the final planes (y = -0.002 and 0.5).
    const Index body_vertices = 4 * 4 * 4;
    double top = -1, bottom = 1;
    for (Index v = 0; v < body_vertices; ++v) {
        top = std::max(top, r.final_positions[v * 3 + 1]);
        bottom = std::min(bottom, r.final_positions[v * 3 + 1]);
    }
    EXPECT_LT(top - bottom, 0.502);
    EXPECT_GT(top - bottom, 0.49);
}

TEST(ContactScenes, RingPile2D)
{
    json j = load_json(study("204_ring_pile"));
    for (auto& b : j["bodies"]) {
        b["mesh"]["annulus"]["segments"] = 24;
        b["mesh"]["annulus"]["layers"] = 1;
    }
    j["time"]["steps"] = 60;
    const RunSummary r = run_checked(j, study("204_ring_pile"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 60);
}

TEST(ContactScenes, PlateOnSphereLargeSteps)
{
    json j = load_json(study("205_plate_on_sphere"));
    j["bodies"][0]["mesh"]["box"]["cells"] = { 6, 1, 6 };
    j["time"]["steps"] = 10;
    const RunSummary r = run_checked(j, study("205_plate_on_sphere"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 10);
    EXPECT_GT(r.max_active, 0) << "the plate never reached the sphere";
}

TEST(ContactScenes, ChainOfInterlinkedRings3D)
{
    json j = load_json(study("206_ring_chain"));
    for (auto& b : j["bodies"]) {
        b["mesh"]["torus"]["cells_across"] = 1;
        b["mesh"]["torus"]["segments"] = 16;
    }
    j["time"]["steps"] = 30;
    const RunSummary r = run_checked(j, study("206_ring_chain"));
    EXPECT_EQ(r.status, StepStatus::CONVERGED);
    EXPECT_EQ(r.committed, 30);
    EXPECT_GT(r.max_active, 0) << "the links never caught each other";
}
