// trajectory.h5 written step by step and read back (forward/io/trajectory_writer.hpp,
// forward/io/trajectory_reader.hpp):
// the stored states are the simulator's to the bit, and a run resumed from the file
// (simulate --restart) continues exactly as the uninterrupted run, for every integrator.

#include "forward/common/error.hpp"
#include "forward/io/trajectory_reader.hpp"
#include "forward/io/trajectory_writer.hpp"
#include "forward/simulation/simulator.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

using namespace diffipc;

namespace {
nlohmann::json moving_box(const std::string& integrator)
{
    nlohmann::json s = test::box_scene(2, { 0.5, 0.2 }, { 8, 4 }, "neo_hookean", 1e5, 0.3, 1000);
    s["bodies"][0]["initial_velocity"] = { 0.3, 0.1 };
    s["gravity"] = { 0, -9.81 };
    s["time"] = { { "integrator", integrator }, { "dt", 1e-3 }, { "steps", 40 } };
    return s;
}
} // namespace

class TrajectoryIO : public ::testing::TestWithParam<std::string> { };

TEST_P(TrajectoryIO, ResumedRunMatchesUninterruptedOne)
{
    const std::string path = (std::filesystem::temp_directory_path() / ("diffipc_io_" + GetParam() + ".h5")).string();
    const nlohmann::json scene = moving_box(GetParam());
    const int first = 17;
    Simulator full(test::make_scene(scene)), part(test::make_scene(scene));
    {
        TrajectoryWriter writer(path, part.mesh(), part.trajectory(), false);
        for (int k = 0; k < first; ++k) {
            ASSERT_EQ(part.step(), StepStatus::CONVERGED);
            writer.append(part.trajectory().steps.back());
            if (k % 5 == 0)
                writer.flush();
        }
        writer.close();
    }
    const StoredTrajectory stored = read_trajectory(path);
    ASSERT_EQ(stored.trajectory.committed(), first);
    for (int k = 1; k <= first; ++k) {
        EXPECT_EQ(stored.trajectory.step(k).positions, part.trajectory().step(k).positions);
        EXPECT_EQ(stored.trajectory.step(k).velocities, part.trajectory().step(k).velocities);
        EXPECT_EQ(stored.trajectory.step(k).accelerations, part.trajectory().step(k).accelerations);
        EXPECT_EQ(stored.trajectory.step(k).newton_iterations, part.trajectory().step(k).newton_iterations);
    }
    // The restart's reading: the diagnostics of every step, the states of the last two only
    // (memory does not grow with the stored run); the others read on demand, the same bits.
    StoredTrajectory tail = read_trajectory(path, 2);
    ASSERT_EQ(tail.trajectory.committed(), first);
    for (int k = 1; k <= first; ++k) {
        EXPECT_EQ(tail.trajectory.step(k).holds_state(), k > first - 2) << k;
        EXPECT_EQ(tail.trajectory.step(k).newton_iterations, part.trajectory().step(k).newton_iterations);
    }
    EXPECT_EQ(tail.trajectory.initial_positions, part.trajectory().initial_positions);
    read_states(tail, 3, 9);
    for (int k = 1; k <= first; ++k)
        if (k >= 3 && k <= 9)
            EXPECT_EQ(tail.trajectory.step(k).positions, part.trajectory().step(k).positions) << k;
        else
            EXPECT_EQ(tail.trajectory.step(k).holds_state(), k > first - 2) << k;
    EXPECT_EQ(tail.trajectory.step(9).accelerations, part.trajectory().step(9).accelerations);
    EXPECT_THROW(read_states(tail, 0, 3), std::out_of_range);
    EXPECT_THROW(read_states(tail, 5, first + 1), std::out_of_range);

    Simulator resumed(test::make_scene(scene));
    resumed.resume(tail.trajectory, tail.contact);
    EXPECT_EQ(resumed.steps_done(), first);
    EXPECT_EQ(resumed.positions(), part.positions());
    EXPECT_EQ(resumed.velocities(), part.velocities());
    while (full.steps_done() < 40)
        ASSERT_EQ(full.step(), StepStatus::CONVERGED);
    while (resumed.steps_done() < 40)
        ASSERT_EQ(resumed.step(), StepStatus::CONVERGED);
    EXPECT_EQ(resumed.positions(), full.positions()) << GetParam();
    EXPECT_EQ(resumed.velocities(), full.velocities()) << GetParam();
    EXPECT_EQ(resumed.trajectory().newton_iterations, full.trajectory().newton_iterations);
    std::remove(path.c_str());
}

INSTANTIATE_TEST_SUITE_P(Integrators, TrajectoryIO, ::testing::Values("implicit_euler", "bdf2", "newmark"));

TEST(TrajectoryIO, RefusesMissingAndForeignFiles)
{
    EXPECT_THROW(read_trajectory("/nonexistent/trajectory.h5"), InputError);
    const std::string path = (std::filesystem::temp_directory_path() / "diffipc_io_text.h5").string();
    std::FILE* f = std::fopen(path.c_str(), "w");
    std::fputs("not hdf5", f);
    std::fclose(f);
    EXPECT_THROW(read_trajectory(path), InputError);
    std::remove(path.c_str());
}
