// Results do not depend on the thread count: the same scenes with 1 and 4 threads agree
// to the bit. Every parallel sum in diffipc is taken over a fixed tree or per vertex in a
// fixed order (forward/common/parallel.hpp), and the Cholesky factorization and solves
// (forward/solver/supernodal_cholesky.hpp) run single-threaded BLAS calls on fixed
// tiles, so OpenBLAS's own thread count does not reach the results either. (With
// CHOLMOD's numeric factorization, OpenBLAS rounded differently per thread count and the
// head-on boxes took 21 and 22 Newton iterations at step 3, 7.5e-4 apart after 8 steps.)

#include "forward/common/threads.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <string>

using namespace diffipc;

namespace {

struct Run {
    std::vector<VectorXd> positions;
    std::vector<int> iterations;
    int concurrency = 0;
};

/// Runs `steps` steps of a study with `threads` threads inside an arena of that many slots
/// (so that 4 threads really run, also on a 2-core machine).
Run run(const std::string& study, int steps, int threads)
{
    set_threads(threads, ThreadSource::EXPLICIT, "test");
    Run out;
    tbb::task_arena arena(threads);
    arena.execute([&] {
        out.concurrency = tbb::this_task_arena::max_concurrency();
        Simulator sim(load_scene(std::string(DIFFIPC_SOURCE_DIR) + "/studies/" + study + "/scene.json"));
        for (int k = 0; k < steps; ++k) {
            if (sim.step() != StepStatus::CONVERGED)
                break;
            out.positions.push_back(sim.positions());
            out.iterations.push_back(sim.trajectory().steps.back().newton_iterations);
        }
    });
    set_threads(0, ThreadSource::EXPLICIT, "test");
    return out;
}

/// @param blas_fixed hold OpenBLAS at one thread in both runs (a user setting wins over set_threads)
void expect_same(const std::string& study, int steps, bool blas_fixed)
{
    if (blas_fixed)
        setenv("OPENBLAS_NUM_THREADS", "1", 1);
    const Run one = run(study, steps, 1), four = run(study, steps, 4);
    if (blas_fixed)
        unsetenv("OPENBLAS_NUM_THREADS");
    EXPECT_EQ(one.concurrency, 1);
    EXPECT_EQ(four.concurrency, 4);
    ASSERT_EQ(one.positions.size(), size_t(steps)) << study;
    ASSERT_EQ(four.positions.size(), size_t(steps)) << study;
    double worst = 0;
    for (int k = 0; k < steps; ++k) {
        EXPECT_EQ(one.iterations[size_t(k)], four.iterations[size_t(k)]) << study << " step " << k + 1;
        const double scale = one.positions[size_t(k)].lpNorm<Eigen::Infinity>();
        worst
            = std::max(worst, (one.positions[size_t(k)] - four.positions[size_t(k)]).lpNorm<Eigen::Infinity>() / scale);
    }
    EXPECT_EQ(worst, 0.0) << study; // bitwise
    std::printf("%s: %d steps, largest relative difference of the positions between 1 and 4 threads %.3g\n",
        study.c_str(), steps, worst);
}

} // namespace

// diffipc's own parallel code, BLAS held fixed: bitwise the same.
TEST(ThreadDeterminism, ContactBetweenBodiesIn3DBitwise) { expect_same("202_boxes_head_on", 8, true); }
TEST(ThreadDeterminism, FrictionOnASlopeBitwise) { expect_same("207_block_on_slope", 10, true); }
TEST(ThreadDeterminism, SelfContactIn2DBitwise) { expect_same("204_ring_pile", 20, true); }
TEST(ThreadDeterminism, ElasticSwingBitwise) { expect_same("101_cantilever", 5, true); }

// Every pool following the count, BLAS included: still bitwise.
TEST(ThreadDeterminism, ContactBetweenBodiesIn3D) { expect_same("202_boxes_head_on", 8, false); }
TEST(ThreadDeterminism, FrictionOnASlope) { expect_same("207_block_on_slope", 10, false); }
TEST(ThreadDeterminism, SelfContactIn2D) { expect_same("204_ring_pile", 20, false); }
TEST(ThreadDeterminism, ElasticSwing) { expect_same("101_cantilever", 5, false); }
