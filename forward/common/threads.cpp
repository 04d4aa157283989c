#include "forward/common/threads.hpp"

#include "forward/common/error.hpp"

#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <dlfcn.h>
#include <link.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

namespace diffipc {

namespace {

    /// Marker that diffipc (not the user) set OMP_WAIT_POLICY, inherited by child processes.
    constexpr const char* WAIT_MARKER = "DIFFIPC_SET_OMP_WAIT_POLICY";
    /// Marker that diffipc set OPENBLAS_CORETYPE.
    constexpr const char* CORETYPE_MARKER = "DIFFIPC_SET_OPENBLAS_CORETYPE";
    /// Marker that this process is diffipc's re-execution (never twice).
    constexpr const char* REEXEC_MARKER = "DIFFIPC_REEXECUTED";

    std::string env(const char* name)
    {
        const char* v = std::getenv(name);
        return v ? std::string(v) : std::string();
    }

    /// The OpenMP settings as they were when this library was loaded: libgomp reads
    /// them once, at its own load, which comes before ours.
    struct LoadEnvironment {
        std::string wait_policy = env("OMP_WAIT_POLICY");
        std::string spin_count = env("GOMP_SPINCOUNT");
        bool set_by_diffipc = !env(WAIT_MARKER).empty();
        std::string coretype = env("OPENBLAS_CORETYPE");
        bool coretype_by_diffipc = !env(CORETYPE_MARKER).empty();
    };
    const LoadEnvironment g_load_environment;

    /// Looks a symbol up in the global scope, then in every loaded object: a Python
    /// extension's dependencies (CHOLMOD's BLAS and OpenMP) are loaded RTLD_LOCAL.
    void* find_symbol(const char* name)
    {
        if (void* s = dlsym(RTLD_DEFAULT, name))
            return s;
        struct Search {
            const char* name;
            void* found = nullptr;
        } search { name };
        dl_iterate_phdr(
            [](dl_phdr_info* info, size_t, void* data) -> int {
                auto* s = static_cast<Search*>(data);
                if (!info->dlpi_name || !info->dlpi_name[0])
                    return 0;
                void* handle = dlopen(info->dlpi_name, RTLD_LAZY | RTLD_NOLOAD);
                if (!handle)
                    return 0;
                s->found = dlsym(handle, s->name);
                dlclose(handle);
                return s->found ? 1 : 0;
            },
            &search);
        return search.found;
    }

    template <typename F> F symbol(const char* name) { return reinterpret_cast<F>(find_symbol(name)); }

    /// The first of `names` set (non-empty) in the environment, as "NAME=value"; empty if none.
    std::string user_setting(std::initializer_list<const char*> names)
    {
        for (const char* n : names) {
            const std::string v = env(n);
            if (!v.empty())
                return std::string(n) + "=" + v;
        }
        return {};
    }

    /// The OPENBLAS_CORETYPE to set: empty unless the user set none and the loaded OpenBLAS
    /// fell back to a pre-AVX kernel set on a CPU with AVX-512 (SkylakeX) or AVX2 (Haswell).
    std::string blas_coretype_override()
    {
        if (!env("OPENBLAS_CORETYPE").empty())
            return {};
        auto corename = symbol<char* (*)()>("openblas_get_corename");
        if (!corename)
            return {};
        const std::string core = corename();
        static const char* const old_cores[] = { "Prescott", "Core2", "Penryn", "Dunnington", "Nehalem", "Atom",
            "Katmai", "Coppermine", "Northwood", "Banias", "Barcelona", "Bobcat" };
        bool fallback = false;
        for (const char* c : old_cores)
            fallback = fallback || core == c;
        if (!fallback)
            return {};
        __builtin_cpu_init();
        if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl")
            && __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq"))
            return "SkylakeX";
        if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
            return "Haswell";
        return {};
    }

    std::string trim(std::string s)
    {
        while (!s.empty() && (s.back() == '\n' || s.back() == ' '))
            s.pop_back();
        return s;
    }

    /// Quota in cores from cgroup v2's cpu.max ("max 100000" or "200000 100000"); 0 if none.
    double read_cpu_max(const std::string& path)
    {
        std::ifstream in(path);
        std::string quota;
        double period = 0;
        if (!(in >> quota >> period) || quota == "max" || !(period > 0))
            return 0;
        const double q = std::atof(quota.c_str());
        return q > 0 ? q / period : 0;
    }

    /// Quota in cores from cgroup v1's cfs files in `dir`; 0 if none.
    double read_cfs(const std::string& dir)
    {
        std::ifstream q(dir + "/cpu.cfs_quota_us"), p(dir + "/cpu.cfs_period_us");
        double quota = 0, period = 0;
        if (!(q >> quota) || !(p >> period) || !(quota > 0) || !(period > 0))
            return 0;
        return quota / period;
    }

    /// The smallest quota on the way from the process's cgroup to the root (cgroup v2,
    /// then v1); 0 if none.
    double cgroup_quota()
    {
        std::ifstream in("/proc/self/cgroup");
        std::string line;
        double best = 0;
        auto take = [&](double q) {
            if (q > 0 && (best == 0 || q < best))
                best = q;
        };
        while (std::getline(in, line)) {
            // "hierarchy-id:controllers:path"
            const size_t a = line.find(':'), b = line.find(':', a + 1);
            if (a == std::string::npos || b == std::string::npos)
                continue;
            const std::string controllers = line.substr(a + 1, b - a - 1);
            std::string path = line.substr(b + 1);
            if (controllers.empty()) { // v2
                for (;;) {
                    take(read_cpu_max("/sys/fs/cgroup" + path + "/cpu.max"));
                    if (path.empty() || path == "/")
                        break;
                    path = path.substr(0, path.find_last_of('/'));
                }
            } else {
                std::stringstream list(controllers);
                std::string c;
                bool cpu = false;
                while (std::getline(list, c, ','))
                    cpu = cpu || c == "cpu";
                if (!cpu)
                    continue;
                for (const std::string mount : { "/sys/fs/cgroup/cpu,cpuacct", "/sys/fs/cgroup/cpu" }) {
                    take(read_cfs(mount + path));
                    take(read_cfs(mount)); // inside a container the process's cgroup is the mount's root
                }
            }
        }
        return best;
    }

    struct State {
        std::mutex mutex;
        bool configured = false;
        int threads = 0;
        ThreadSource source = ThreadSource::DEFAULT;
        std::string origin;
        std::unique_ptr<tbb::global_control> tbb_limit;
    };
    State& state()
    {
        static State s;
        return s;
    }

    /// Applies n to the three pools (the user's own per-library settings win). Caller holds the lock.
    void apply(State& s, int n)
    {
        s.tbb_limit.reset();
        s.tbb_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(n));
        if (user_setting({ "OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS" }).empty())
            if (auto set = symbol<void (*)(int)>("openblas_set_num_threads"))
                set(n);
        if (user_setting({ "OMP_NUM_THREADS" }).empty())
            if (auto set = symbol<void (*)(int)>("omp_set_num_threads"))
                set(n);
    }

    int parse_count(const std::string& text, const std::string& field)
    {
        char* end = nullptr;
        const long v = std::strtol(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0' || v < 0 || v > 4096)
            throw InputError(field,
                "expected a thread count (an integer from 1 to 4096, or 0 for the default), got \"" + text + "\"");
        return int(v);
    }

} // namespace

std::string to_string(ThreadSource source)
{
    switch (source) {
    case ThreadSource::DEFAULT:
        return "default";
    case ThreadSource::SCENE_FILE:
        return "scene file";
    case ThreadSource::PROBLEM_FILE:
        return "problem file";
    case ThreadSource::ENVIRONMENT:
        return "environment";
    case ThreadSource::EXPLICIT:
        return "explicit";
    }
    return "unknown";
}

CoreBudget core_budget()
{
    CoreBudget b;
    b.hardware = int(std::thread::hardware_concurrency());
    cpu_set_t* set = CPU_ALLOC(4096);
    const size_t size = CPU_ALLOC_SIZE(4096);
    if (set && sched_getaffinity(0, size, set) == 0)
        b.affinity = CPU_COUNT_S(size, set);
    if (set)
        CPU_FREE(set);
    if (b.affinity <= 0)
        b.affinity = std::max(1, b.hardware);
    b.quota = cgroup_quota();
    b.usable = b.affinity;
    if (b.quota > 0)
        b.usable = std::min(b.usable, int(std::ceil(b.quota - 1e-9)));
    b.usable = std::max(1, b.usable);
    return b;
}

ThreadConfig set_threads(int count, ThreadSource source, const std::string& origin)
{
    if (count < 0)
        throw InputError(
            origin, "expected a thread count of at least 1 (or 0 for the default), got " + std::to_string(count));
    {
        State& s = state();
        std::lock_guard<std::mutex> lock(s.mutex);
        if (!s.configured || source >= s.source) {
            const bool by_default = count == 0;
            const int n = by_default ? core_budget().usable : count;
            apply(s, n);
            s.configured = true;
            s.threads = n;
            s.source = by_default ? ThreadSource::DEFAULT : source;
            s.origin = by_default ? "the cores this process may use" : origin;
        }
    }
    return thread_config();
}

void ensure_threads_configured()
{
    static std::once_flag once;
    std::call_once(once, [] {
        const std::string v = env("DIFFIPC_THREADS");
        const int n = v.empty() ? 0 : parse_count(v, "DIFFIPC_THREADS");
        bool configured;
        {
            State& s = state();
            std::lock_guard<std::mutex> lock(s.mutex);
            configured = s.configured;
        }
        if (n > 0)
            set_threads(n, ThreadSource::ENVIRONMENT, "DIFFIPC_THREADS");
        else if (!configured)
            set_threads(0, ThreadSource::DEFAULT, "");
    });
}

ThreadConfig thread_config()
{
    ThreadConfig c;
    {
        State& s = state();
        std::lock_guard<std::mutex> lock(s.mutex);
        c.threads = s.threads;
        c.source = s.source;
        c.origin = s.origin;
    }
    c.cores = core_budget();
    c.tbb = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));

    auto blas_get = symbol<int (*)()>("openblas_get_num_threads");
    auto blas_config = symbol<char* (*)()>("openblas_get_config");
    auto blas_parallel = symbol<int (*)()>("openblas_get_parallel");
    if (blas_get) {
        c.blas = blas_get();
        c.blas_library = blas_config ? trim(blas_config()) : "OpenBLAS";
        const LoadEnvironment& e = g_load_environment;
        if (!e.coretype.empty())
            c.blas_library += e.coretype_by_diffipc
                ? " (OPENBLAS_CORETYPE=" + e.coretype + " set by diffipc: OpenBLAS took this CPU for an older one)"
                : " (the user's OPENBLAS_CORETYPE=" + e.coretype + ")";
        else if (const std::string better = blas_coretype_override(); !better.empty())
            c.blas_library += " (pre-AVX kernels on an AVX CPU: set OPENBLAS_CORETYPE=" + better
                + " before the program starts, as the diffipc CLI does)";
        if (blas_parallel)
            c.blas_library += blas_parallel() == 0 ? " (sequential)"
                : blas_parallel() == 1             ? " (pthreads)"
                                                   : " (OpenMP)";
    } else {
        c.blas = 1;
        c.blas_library = "not OpenBLAS (its threads are not controlled by diffipc)";
    }
    if (auto omp_max = symbol<int (*)()>("omp_get_max_threads"))
        c.openmp = omp_max();

    const std::string blas_user = user_setting({ "OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS" });
    if (!blas_user.empty())
        c.user_environment.push_back(blas_user + " (OpenBLAS)");
    if (!g_load_environment.coretype.empty() && !g_load_environment.coretype_by_diffipc)
        c.user_environment.push_back("OPENBLAS_CORETYPE=" + g_load_environment.coretype + " (OpenBLAS)");
    const std::string omp_user = user_setting({ "OMP_NUM_THREADS" });
    if (!omp_user.empty())
        c.user_environment.push_back(omp_user + " (OpenMP)");

    const LoadEnvironment& e = g_load_environment;
    if (c.openmp == 0)
        c.openmp_wait = "no OpenMP runtime loaded";
    else if (!e.wait_policy.empty() && e.set_by_diffipc)
        c.openmp_wait = "passive (OMP_WAIT_POLICY=" + e.wait_policy + " set by diffipc at start-up)";
    else if (!e.wait_policy.empty()) {
        std::string p = e.wait_policy;
        std::transform(p.begin(), p.end(), p.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
        c.openmp_wait = p + " (the user's OMP_WAIT_POLICY)";
        c.user_environment.push_back("OMP_WAIT_POLICY=" + e.wait_policy + " (OpenMP)");
    } else if (!e.spin_count.empty()) {
        c.openmp_wait = "spin count " + e.spin_count + " (the user's GOMP_SPINCOUNT)";
        c.user_environment.push_back("GOMP_SPINCOUNT=" + e.spin_count + " (OpenMP)");
    } else
        c.openmp_wait = "spinning (libgomp's default: idle threads spin after each region; set OMP_WAIT_POLICY=PASSIVE "
                        "before the program starts, as the diffipc CLI and Python module do)";
    return c;
}

std::string describe(const ThreadConfig& c)
{
    std::ostringstream o;
    o << "threads: " << c.threads << " (" << to_string(c.source) << ": " << c.origin << ")\n";
    o << "  cores this process may use: " << c.cores.usable << " (affinity " << c.cores.affinity << ", cgroup quota ";
    if (c.cores.quota > 0)
        o << c.cores.quota;
    else
        o << "none";
    o << ", hardware " << c.cores.hardware << ")\n";
    o << "  TBB:      " << c.tbb << " (global limit)\n";
    o << "  BLAS:     " << c.blas << " (" << c.blas_library << ")\n";
    o << "  OpenMP:   " << c.openmp << " max threads, wait policy " << c.openmp_wait << "\n";
    o << "  user environment: ";
    if (c.user_environment.empty())
        o << "none";
    for (size_t i = 0; i < c.user_environment.size(); ++i)
        o << (i ? ", " : "") << c.user_environment[i];
    o << "\n";
    return o.str();
}

nlohmann::json to_json(const ThreadConfig& c)
{
    return { { "threads", c.threads }, { "source", to_string(c.source) }, { "origin", c.origin },
        { "cores",
            { { "usable", c.cores.usable }, { "affinity", c.cores.affinity }, { "quota", c.cores.quota },
                { "hardware", c.cores.hardware } } },
        { "tbb", c.tbb }, { "blas", c.blas }, { "blas_library", c.blas_library }, { "openmp", c.openmp },
        { "openmp_wait_policy", c.openmp_wait }, { "user_environment", c.user_environment } };
}

void prepare_process_environment(char** argv)
{
    if (!argv || !argv[0] || !env(REEXEC_MARKER).empty())
        return;
    bool changed = false;
    // libgomp reads its wait policy once, at load: idle threads must sleep, not spin.
    if (env("OMP_WAIT_POLICY").empty() && env("GOMP_SPINCOUNT").empty() && find_symbol("omp_get_max_threads")) {
        setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
        setenv(WAIT_MARKER, "1", 1);
        changed = true;
    }
    // OpenBLAS 0.3.21 (Debian 12) does not know recent Intel server cores (Sapphire and
    // Emerald Rapids) and runs its Prescott (SSE3) kernels on them, several times slower:
    // name the kernels the CPU supports. OpenBLAS reads OPENBLAS_CORETYPE once, at load.
    const std::string coretype = blas_coretype_override();
    if (!coretype.empty()) {
        setenv("OPENBLAS_CORETYPE", coretype.c_str(), 1);
        setenv(CORETYPE_MARKER, "1", 1);
        changed = true;
    }
    if (!changed)
        return;
    setenv(REEXEC_MARKER, "1", 1);
    execv("/proc/self/exe", argv);
    // Not re-executed (no /proc?): run on with the libraries' defaults, and say so.
    unsetenv("OMP_WAIT_POLICY");
    unsetenv(WAIT_MARKER);
    if (!coretype.empty()) {
        unsetenv("OPENBLAS_CORETYPE");
        unsetenv(CORETYPE_MARKER);
    }
}

namespace {
    struct BlasControl {
        int (*get)() = symbol<int (*)()>("openblas_get_num_threads");
        void (*set)(int) = symbol<void (*)(int)>("openblas_set_num_threads");
    };
    const BlasControl& blas_control()
    {
        static const BlasControl control;
        return control;
    }
} // namespace

BlasThreadsScope::BlasThreadsScope(int count)
{
    const BlasControl& blas = blas_control();
    if (!blas.get || !blas.set)
        return;
    m_previous = blas.get();
    if (m_previous != count)
        blas.set(count);
    else
        m_previous = 0;
}

BlasThreadsScope::~BlasThreadsScope()
{
    if (m_previous > 0)
        blas_control().set(m_previous);
}

} // namespace diffipc
