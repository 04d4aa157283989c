#include "forward/common/threads.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <dlfcn.h>
#include <sched.h>

#include <cstdlib>

using namespace diffipc;

namespace {

/// Each library's own setting, read through its own API (not through ThreadConfig).
int tbb_limit() { return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)); }
int blas_threads()
{
    auto f = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
    return f ? f() : -1;
}
int openmp_threads()
{
    auto f = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_threads"));
    return f ? f() : -1;
}

/// Removes the per-library variables a user could have set, for the duration of a test.
class ThreadsTest : public ::testing::Test {
protected:
    void SetUp() override
    {
        for (const char* v : { "OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS" }) {
            if (const char* old = std::getenv(v))
                m_saved.emplace_back(v, old);
            unsetenv(v);
        }
    }
    void TearDown() override
    {
        unsetenv("OPENBLAS_NUM_THREADS");
        for (const auto& [k, v] : m_saved)
            setenv(k.c_str(), v.c_str(), 1);
        set_threads(0, ThreadSource::EXPLICIT, "test teardown");
    }
    std::vector<std::pair<std::string, std::string>> m_saved;
};

} // namespace

TEST_F(ThreadsTest, CountReachesAllThreePools)
{
    if (blas_threads() < 0 || openmp_threads() < 0)
        GTEST_SKIP() << "OpenBLAS or the OpenMP runtime is not loaded in this process";
    for (int n : { 3, 1, 2 }) {
        const ThreadConfig c = set_threads(n, ThreadSource::EXPLICIT, "test");
        EXPECT_EQ(tbb_limit(), n);
        EXPECT_EQ(blas_threads(), n);
        EXPECT_EQ(openmp_threads(), n);
        EXPECT_EQ(c.threads, n);
        EXPECT_EQ(c.tbb, n);
        EXPECT_EQ(c.blas, n);
        EXPECT_EQ(c.openmp, n);
    }
}

TEST_F(ThreadsTest, HigherPriorityRequestsWin)
{
    set_threads(4, ThreadSource::ENVIRONMENT, "DIFFIPC_THREADS");
    EXPECT_EQ(set_threads(2, ThreadSource::SCENE_FILE, "solver.threads").threads, 4);
    EXPECT_EQ(set_threads(2, ThreadSource::PROBLEM_FILE, "threads").threads, 4);
    EXPECT_EQ(tbb_limit(), 4);
    const ThreadConfig c = set_threads(3, ThreadSource::EXPLICIT, "--threads");
    EXPECT_EQ(c.threads, 3);
    EXPECT_EQ(c.origin, "--threads");
    EXPECT_EQ(tbb_limit(), 3);
    // Back to the default: the files' keys apply again.
    set_threads(0, ThreadSource::EXPLICIT, "test");
    EXPECT_EQ(set_threads(2, ThreadSource::SCENE_FILE, "solver.threads").threads, 2);
    EXPECT_EQ(tbb_limit(), 2);
}

TEST_F(ThreadsTest, UserLibrarySettingWins)
{
    if (blas_threads() < 0)
        GTEST_SKIP() << "OpenBLAS is not loaded in this process";
    set_threads(1, ThreadSource::EXPLICIT, "test");
    setenv("OPENBLAS_NUM_THREADS", "1", 1);
    const ThreadConfig c = set_threads(3, ThreadSource::EXPLICIT, "test");
    EXPECT_EQ(blas_threads(), 1); // left alone
    EXPECT_EQ(tbb_limit(), 3);
    bool listed = false;
    for (const auto& s : c.user_environment)
        listed = listed || s.rfind("OPENBLAS_NUM_THREADS=1", 0) == 0;
    EXPECT_TRUE(listed);
}

TEST_F(ThreadsTest, DefaultIsTheAffinityOfTheProcess)
{
    cpu_set_t saved;
    ASSERT_EQ(sched_getaffinity(0, sizeof saved, &saved), 0);
    const CoreBudget all = core_budget();
    EXPECT_EQ(all.affinity, CPU_COUNT(&saved));
    EXPECT_LE(all.usable, all.affinity);
    EXPECT_GE(all.usable, 1);
    cpu_set_t one;
    CPU_ZERO(&one);
    for (int c = 0; c < CPU_SETSIZE; ++c)
        if (CPU_ISSET(c, &saved)) {
            CPU_SET(c, &one);
            break;
        }
    ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);
    EXPECT_EQ(core_budget().affinity, 1);
    EXPECT_EQ(core_budget().usable, 1);
    EXPECT_EQ(set_threads(0, ThreadSource::EXPLICIT, "test").threads, 1);
    ASSERT_EQ(sched_setaffinity(0, sizeof saved, &saved), 0);
    EXPECT_EQ(core_budget().affinity, CPU_COUNT(&saved));
}

TEST_F(ThreadsTest, NegativeCountIsAnInputError)
{
    try {
        set_threads(-2, ThreadSource::EXPLICIT, "--threads");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "--threads");
    }
}
