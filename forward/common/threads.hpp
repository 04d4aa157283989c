#pragma once
/// @file threads.hpp
/// One thread configuration for the whole process, owned by diffipc.
///
/// Three thread pools work inside diffipc and none knows about the others:
/// TBB (assembly, contact, CCD), OpenBLAS's pthreads (the dense kernels inside
/// CHOLMOD's supernodal factorization) and the OpenMP runtime that SuiteSparse
/// links (libgomp; CHOLMOD opens teams of 4 threads per supernode). Left alone,
/// each sizes itself to the whole machine and libgomp's idle threads spin
/// between regions, so on a many-core machine they fight for the cores (a
/// factorization 10 times slower on 16 cores than on 2). This module sets one
/// count on all three: a TBB global limit, openblas_set_num_threads and
/// omp_set_num_threads, and makes libgomp's idle threads sleep
/// (OMP_WAIT_POLICY=PASSIVE, which libgomp reads only when it is loaded: see
/// prepare_process_environment()).
///
/// The count comes, by rising priority, from: the default (the cores this process
/// may use: CPU affinity and cgroup quota), a scene's `solver.threads`, a problem
/// file's `threads`, the
/// DIFFIPC_THREADS environment variable, an explicit request (CLI `--threads`,
/// Python `diffipc.set_threads`). A user's own environment settings for one
/// library (OPENBLAS_NUM_THREADS / GOTO_NUM_THREADS / OMP_NUM_THREADS for
/// OpenBLAS, OMP_NUM_THREADS for OpenMP, OMP_WAIT_POLICY / GOMP_SPINCOUNT) win
/// over diffipc's for that library.

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace diffipc {

/// Where a thread count came from, by rising priority.
enum class ThreadSource { DEFAULT = 0, SCENE_FILE = 1, PROBLEM_FILE = 2, ENVIRONMENT = 3, EXPLICIT = 4 };

std::string to_string(ThreadSource source);

/// The cores this process may use, and why.
struct CoreBudget {
    int affinity = 0; ///< CPUs in the process's affinity mask (sched_getaffinity)
    double quota = 0; ///< cgroup CPU quota in cores (cpu.max or cfs_quota/cfs_period); 0 if none
    int hardware = 0; ///< std::thread::hardware_concurrency()
    int usable = 1; ///< min(affinity, ceil(quota)), at least 1
};

/// Reads the affinity mask and the cgroup (v2, then v1) quota of this process.
CoreBudget core_budget();

/// The effective configuration of the three pools, read back from each library.
struct ThreadConfig {
    int threads = 0; ///< the count diffipc asked for
    ThreadSource source = ThreadSource::DEFAULT;
    std::string origin; ///< where the count came from, in words ("--threads", "DIFFIPC_THREADS", "solver.threads", ...)
    CoreBudget cores;
    int tbb = 0; ///< tbb::global_control::active_value(max_allowed_parallelism)
    int blas = 0; ///< openblas_get_num_threads(); 1 for a BLAS without threads control
    std::string blas_library; ///< openblas_get_config(), or what was found instead
    int openmp = 0; ///< omp_get_max_threads() of the configuring thread; 0 if no OpenMP runtime is loaded
    std::string openmp_wait; ///< "passive", "active" or "spinning (libgomp default)", and who set it
    std::vector<std::string> user_environment; ///< VAR=value settings of the user that won over diffipc's
};

/// @brief Applies `count` threads from `source` to TBB, OpenBLAS and OpenMP unless a
/// request of higher priority is in force (an equal one replaces it).
/// @param count  threads, >= 1; 0 means the default (core_budget().usable)
/// @param source priority of the request
/// @param origin where it came from, in words (shown by describe() and summary.json)
/// @return the effective configuration
/// @throws InputError if count < 0 (field `origin`)
ThreadConfig set_threads(int count, ThreadSource source, const std::string& origin);

/// @brief The first call configures the pools from DIFFIPC_THREADS or, if nothing was
/// configured yet, the default; later calls do nothing. Called by Simulator, the CLI and Python.
/// @throws InputError naming DIFFIPC_THREADS if it is not an integer from 0 to 4096
void ensure_threads_configured();

/// The configuration in force, read back from the libraries now.
ThreadConfig thread_config();

/// Multi-line description for `diffipc info` / `--version`.
std::string describe(const ThreadConfig& config);

/// JSON for summary.json and Python.
nlohmann::json to_json(const ThreadConfig& config);

/// @brief For executables, first thing in main(): libgomp reads OMP_WAIT_POLICY only when
/// it is loaded, before main(). If neither OMP_WAIT_POLICY nor GOMP_SPINCOUNT is set,
/// re-executes the program (/proc/self/exe, same arguments) once with
/// OMP_WAIT_POLICY=PASSIVE; returns if it is set already or the re-execution fails.
void prepare_process_environment(char** argv);

/// @brief Sets OpenBLAS's thread count for a scope and restores it after: code that runs
/// BLAS calls from its own tasks (the parallel Cholesky) wants each call on its caller's
/// thread. Does nothing for a BLAS without thread control.
class BlasThreadsScope {
public:
    explicit BlasThreadsScope(int count);
    ~BlasThreadsScope();
    BlasThreadsScope(const BlasThreadsScope&) = delete;
    BlasThreadsScope& operator=(const BlasThreadsScope&) = delete;

private:
    int m_previous = 0;
};

} // namespace diffipc
