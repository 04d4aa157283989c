// CCD on the sample queries of Wang et al. 2021 (tests/data/ccd-sample-queries, a copy of shared/data/ccd-sample-queries):
// correctness against the exact ground truth and time per query, one thread.
//
//   ./build/bench/bench_ccd_sample_queries [max_iterations [refine (0/1) [data_dir]]]
//
// Each query is timed with std::chrono::steady_clock in three batches; a
// query faster than 20 us is repeated in each batch (up to 1000 times) so
// that clock resolution does not dominate sub-microsecond queries. The time
// per query is the median of the three batch means. Prints, per folder
// and in total: queries, false negatives, false positives, budget
// exhaustions, mean / median / p99 time per query (us), the largest
// iteration count, and the slowest queries.

#include "forward/contact/ccd/ccd_sample_queries.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

using namespace diffipc;

namespace {

struct Timed {
    std::string folder;
    size_t index; // within the folder
    bool edge_edge, truth, collision, budget_exhausted;
    int iterations;
    double microseconds;
};

double percentile(std::vector<double> v, double q)
{
    if (v.empty())
        return 0;
    std::sort(v.begin(), v.end());
    // nearest rank
    const size_t k = size_t(std::ceil(q * double(v.size())));
    return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

void print_row(const std::string& name, const std::vector<const Timed*>& rows)
{
    long fn = 0, fp = 0, budget = 0;
    int max_iterations = 0;
    std::vector<double> times;
    for (const Timed* r : rows) {
        fn += r->truth && !r->collision;
        fp += !r->truth && r->collision;
        budget += r->budget_exhausted;
        max_iterations = std::max(max_iterations, r->iterations);
        times.push_back(r->microseconds);
    }
    const double mean = times.empty() ? 0 : std::accumulate(times.begin(), times.end(), 0.0) / double(times.size());
    std::printf("| %s | %zu | %ld | %ld | %ld | %.3g | %.3g | %.3g | %d |\n", name.c_str(), rows.size(), fn, fp, budget,
        mean, percentile(times, 0.5), percentile(times, 0.99), max_iterations);
}

} // namespace

int main(int argc, char** argv)
{
    namespace fs = std::filesystem;
    CCDSettings settings;
    if (argc > 1)
        settings.max_iterations = std::atoi(argv[1]);
    if (argc > 2)
        settings.refine = std::atoi(argv[2]) != 0;
    const std::string data
        = argc > 3 ? argv[3] : std::string(DIFFIPC_SOURCE_DIR) + "/tests/data/ccd-sample-queries";
    if (!fs::is_directory(data)) {
        std::fprintf(stderr, "no CCD sample queries at %s\n", data.c_str());
        return 1;
    }
    std::vector<std::string> folders;
    for (const auto& entry : fs::directory_iterator(data))
        if (entry.is_directory()
            && (fs::is_directory(entry.path() / "vertex-face") || fs::is_directory(entry.path() / "edge-edge")))
            folders.push_back(entry.path().filename().string());
    std::sort(folders.begin(), folders.end(), [](const std::string& a, const std::string& b) {
        // unit-tests first, then the erleben-* folders by name
        return (a != "unit-tests") == (b != "unit-tests") ? a < b : a == "unit-tests";
    });

    std::printf("CCD sample queries: %s\n", data.c_str());
    std::printf("settings: min_distance %g, conservative_rescaling %g, max_iterations %d, t_max %g, refine %d "
                "(tolerance %g)\n",
        settings.min_distance, settings.conservative_rescaling, settings.max_iterations, settings.t_max,
        int(settings.refine), settings.refine_tolerance);

    std::vector<Timed> all;
    long inexact = 0;
    volatile double sink = 0;
    using clock = std::chrono::steady_clock;
    for (const std::string& folder : folders) {
        const std::vector<CCDQuery> queries = read_ccd_query_folder((fs::path(data) / folder).string(), &inexact);
        for (size_t i = 0; i < queries.size(); ++i) {
            const CCDQuery& query = queries[i];
            auto time_batch = [&](int repeats) {
                const auto start = clock::now();
                for (int k = 0; k < repeats; ++k)
                    sink = sink + run_ccd_query(query, settings).toi;
                return std::chrono::duration<double, std::micro>(clock::now() - start).count() / repeats;
            };
            const CCDResult r = run_ccd_query(query, settings);
            const double first = time_batch(1);
            const int repeats = first < 20 ? std::min(1000, int(std::ceil(20 / std::max(first, 0.02)))) : 1;
            double batches[3] = { time_batch(repeats), time_batch(repeats), time_batch(repeats) };
            std::sort(batches, batches + 3);
            const double us = batches[1];
            all.push_back({ folder, i, queries[i].edge_edge, queries[i].ground_truth, r.collision, r.budget_exhausted,
                r.iterations, us });
        }
    }
    std::printf("coordinates not converted exactly: %ld\n\n", inexact);

    std::printf(
        "| folder | queries | false negatives | false positives | budget exhausted | mean (us) | median (us) | p99 "
        "(us) | max iterations |\n");
    std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for (const std::string& folder : folders) {
        std::vector<const Timed*> rows;
        for (const Timed& t : all)
            if (t.folder == folder)
                rows.push_back(&t);
        print_row(folder, rows);
    }
    for (const bool ee : { false, true }) {
        std::vector<const Timed*> rows;
        for (const Timed& t : all)
            if (t.edge_edge == ee)
                rows.push_back(&t);
        print_row(ee ? "all edge-edge" : "all vertex-face", rows);
    }
    std::vector<const Timed*> rows;
    for (const Timed& t : all)
        rows.push_back(&t);
    print_row("total", rows);

    // Where the time goes.
    std::vector<const Timed*> by_time = rows;
    std::sort(by_time.begin(), by_time.end(),
        [](const Timed* a, const Timed* b) { return a->microseconds > b->microseconds; });
    const double total
        = std::accumulate(rows.begin(), rows.end(), 0.0, [](double s, const Timed* t) { return s + t->microseconds; });
    double top = 0;
    const size_t n_top = std::max<size_t>(1, rows.size() / 100);
    for (size_t k = 0; k < n_top; ++k)
        top += by_time[k]->microseconds;
    std::printf("\ntotal time %.3f s; the slowest 1%% (%zu queries) take %.1f%% of it\n", total * 1e-6, n_top,
        100 * top / std::max(total, 1e-300));
    std::printf("slowest queries:\n");
    for (size_t k = 0; k < std::min<size_t>(10, by_time.size()); ++k) {
        const Timed& t = *by_time[k];
        std::printf("  %s #%zu (%s): %.1f us, %d iterations, truth %d, collision %d%s\n", t.folder.c_str(), t.index,
            t.edge_edge ? "edge-edge" : "vertex-face", t.microseconds, t.iterations, int(t.truth), int(t.collision),
            t.budget_exhausted ? ", budget exhausted" : "");
    }
    return 0;
}
