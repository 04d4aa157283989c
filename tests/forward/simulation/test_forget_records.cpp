// A streamed run drops each step's record once written (Simulator::forget_records): the
// states, the count and the summary totals must be those of a run that kept them, and
// everything that needs a record must refuse, not read a dropped one.

#include "forward/io/output.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

using namespace diffipc;

namespace {
Scene study(const std::string& name)
{
    return load_scene(std::string(DIFFIPC_SOURCE_DIR) + "/studies/" + name + "/scene.json");
}
} // namespace

TEST(ForgetRecords, SameStatesCountAndTotalsAsKeepingThem)
{
    for (const char* name : { "202_boxes_head_on", "101_cantilever" }) {
        Simulator kept(study(name)), streamed(study(name));
        const int steps = 6;
        for (int k = 0; k < steps; ++k) {
            ASSERT_EQ(kept.step(), StepStatus::CONVERGED);
            ASSERT_EQ(streamed.step(), StepStatus::CONVERGED);
            streamed.forget_records();
        }
        EXPECT_EQ(streamed.steps_done(), steps);
        EXPECT_TRUE(streamed.trajectory().steps.empty());
        EXPECT_EQ(kept.positions(), streamed.positions()) << name;
        EXPECT_EQ(kept.velocities(), streamed.velocities()) << name;
        // The summary of the streamed run equals the one computed from every record.
        nlohmann::json a = summary_json(kept), b = summary_json(streamed);
        for (auto* j : { &a, &b }) {
            j->erase("wall_time");
            for (auto& [name, work] : (*j)["potentials"].items())
                work.erase("time");
        }
        EXPECT_EQ(a, b) << name;
        double min_ratio = 1, max_residual = 0;
        for (const StepRecord& r : kept.trajectory().steps) {
            min_ratio = std::min(min_ratio, r.min_volume_ratio);
            max_residual = std::max(max_residual, r.residual);
        }
        EXPECT_EQ(b["min_volume_ratio"].get<double>(), min_ratio);
        EXPECT_EQ(b["max_residual"].get<double>(), max_residual);
        EXPECT_EQ(b["steps_committed"].get<int>(), steps);
        // The records are gone: whatever needs one refuses.
        EXPECT_THROW(streamed.step_problem(steps), std::logic_error);
        EXPECT_THROW(streamed.restore_state(steps - 1), std::logic_error);
        EXPECT_THROW(streamed.release_state(1), std::logic_error);
        // And the run goes on.
        ASSERT_EQ(streamed.step(), StepStatus::CONVERGED);
        EXPECT_EQ(streamed.steps_done(), steps + 1);
        EXPECT_EQ(streamed.trajectory().step(steps + 1).index, steps + 1);
    }
}
