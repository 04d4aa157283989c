#include "cli/study.hpp"

#include "forward/common/error.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace fs = std::filesystem;

namespace diffipc {

namespace {

    std::string env_or(const char* name, const std::string& fallback)
    {
        const char* v = std::getenv(name);
        return v && *v ? std::string(v) : fallback;
    }

    std::string joined(const std::vector<std::string>& names)
    {
        std::string out;
        for (const std::string& n : names)
            out += (out.empty() ? "" : ", ") + n;
        return out.empty() ? "none" : out;
    }

} // namespace

std::vector<std::string> runnable_studies(const std::string& studies)
{
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(studies, ec))
        if (entry.is_directory() && fs::exists(entry.path() / "run.py"))
            names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

int run_study(const StudyOptions& options)
{
    const std::string studies = env_or("DIFFIPC_STUDIES", std::string(DIFFIPC_SOURCE_DIR) + "/studies");
    if (!fs::is_directory(studies))
        throw InputError("study", "no studies folder at " + studies + " (set DIFFIPC_STUDIES)");
    const std::vector<std::string> names = runnable_studies(studies);
    if (options.list) {
        for (const std::string& n : names)
            std::printf("%s\n", n.c_str());
        return 0;
    }
    std::vector<std::string> match;
    for (const std::string& n : names)
        if (n == options.name || n.rfind(options.name + "_", 0) == 0)
            match.push_back(n);
    if (match.size() != 1)
        throw InputError("study",
            (match.empty() ? "no study '" : "ambiguous study '") + options.name + "' in " + studies
                + " (studies with a run.py: " + joined(match.empty() ? names : match) + ")");
    const fs::path folder = fs::path(studies) / match[0];
    const fs::path root = fs::path(studies).parent_path();
    std::error_code ec;
    const std::string self = fs::read_symlink("/proc/self/exe", ec).string();
    const std::string python = env_or("DIFFIPC_PYTHON", "/usr/bin/python3");
    const std::string module = std::string(DIFFIPC_BINARY_DIR) + "/python";
    const std::string path = env_or("PYTHONPATH", "");
    // The options a study's run.py declares (argparse) are passed: its results into its folder,
    // its runs under output/NAME, this CLI; --full when asked (a study without it refuses it).
    std::ifstream in(folder / "run.py");
    const std::string script((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    auto declares
        = [&](const char* option) { return script.find(std::string("\"") + option + "\"") != std::string::npos; };
    std::vector<std::string> args { python, (folder / "run.py").string() };
    if (declares("--results"))
        args.insert(args.end(), { "--results", folder.string() });
    if (declares("-o"))
        args.insert(args.end(), { "-o", (root / "output" / match[0]).string() });
    if (declares("--cli") && !self.empty())
        args.insert(args.end(), { "--cli", self });
    if (options.full)
        args.push_back("--full");
    std::string shown;
    for (const std::string& a : args)
        shown += (shown.empty() ? "" : " ") + a;
    std::printf("diffipc study: %s\n", shown.c_str());
    std::fflush(stdout);
    const pid_t pid = fork();
    if (pid < 0)
        throw InputError("study", "cannot start " + python);
    if (pid == 0) {
        setenv("PYTHONPATH", (path.empty() ? module : module + ":" + path).c_str(), 1);
        if (!self.empty())
            setenv("DIFFIPC_CLI", self.c_str(), 1);
        std::vector<char*> argv;
        for (const std::string& a : args)
            argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        execv(python.c_str(), argv.data());
        std::fprintf(stderr, "diffipc: error: study: cannot run %s\n", python.c_str());
        _exit(127);
    }
    int status = 0;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            throw InputError("study", "lost the study's process");
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

} // namespace diffipc
