// history.h5 / history.csv and optimizer_state.h5 (shape_opt/optimization_history.hpp): what is
// written is read back exactly, a resumed writer starts from the given rows, the CSV agrees
// with the HDF5 file, and files that are missing or not ours are refused naming the file.

#include "forward/common/error.hpp"
#include "shape_opt/optimization_history.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace diffipc;

namespace {

/// A fresh directory under the system's temporary one, removed at the end.
class TempDir {
public:
    explicit TempDir(const std::string& name)
        : m_path(fs::temp_directory_path() / ("diffipc_test_history_" + name + "_" + std::to_string(::getpid())))
    {
        fs::remove_all(m_path);
        fs::create_directories(m_path);
    }
    ~TempDir()
    {
        std::error_code ec;
        fs::remove_all(m_path, ec);
    }
    std::string file(const std::string& name) const { return (m_path / name).string(); }
    std::string str() const { return m_path.string(); }

private:
    fs::path m_path;
};

HistoryRow random_row(int iteration, Index n, Index m, std::mt19937& rng)
{
    std::uniform_real_distribution<double> u(-1, 1);
    HistoryRow r;
    r.iteration = iteration;
    r.x = VectorXd::NullaryExpr(n, [&]() { return u(rng) * 1e3; });
    r.J = std::exp(u(rng) * 30); // values whose last bits matter
    r.constraints = VectorXd::NullaryExpr(m, [&]() { return u(rng); });
    r.gradient_norm = std::abs(u(rng));
    r.step_norm = iteration == 0 ? 0 : std::abs(u(rng));
    r.evaluations = 2 * iteration + 1;
    r.rejected = iteration / 3;
    r.evaluation_seconds = 0.1 * iteration + std::abs(u(rng));
    r.optimizer_seconds = 1e-3 * iteration;
    r.wall_seconds = 0.2 * iteration + 1;
    return r;
}

void expect_same(const HistoryRow& a, const HistoryRow& b)
{
    EXPECT_EQ(a.iteration, b.iteration);
    EXPECT_TRUE(a.x == b.x);
    EXPECT_EQ(a.J, b.J);
    EXPECT_TRUE(a.constraints == b.constraints);
    EXPECT_EQ(a.gradient_norm, b.gradient_norm);
    EXPECT_EQ(a.step_norm, b.step_norm);
    EXPECT_EQ(a.evaluations, b.evaluations);
    EXPECT_EQ(a.rejected, b.rejected);
    EXPECT_EQ(a.evaluation_seconds, b.evaluation_seconds);
    EXPECT_EQ(a.optimizer_seconds, b.optimizer_seconds);
    EXPECT_EQ(a.wall_seconds, b.wall_seconds);
}

std::vector<std::string> lines(const std::string& path)
{
    std::ifstream in(path);
    std::vector<std::string> out;
    for (std::string line; std::getline(in, line);)
        out.push_back(line);
    return out;
}

/// The CSV row's fields (no quoted fields in the data rows).
std::vector<double> numbers(const std::string& line)
{
    std::vector<double> out;
    std::stringstream in(line);
    for (std::string field; std::getline(in, field, ',');)
        out.push_back(std::strtod(field.c_str(), nullptr));
    return out;
}

std::string error_field(const std::function<void()>& f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.field();
    }
    return "(no InputError)";
}

TEST(OptimizationHistory, RowsAreReadBackExactlyAndTheCsvAgrees)
{
    for (const Index m : { Index(0), Index(2) }) {
        SCOPED_TRACE(std::to_string(m) + " constraints");
        TempDir dir("rows" + std::to_string(m));
        HistoryHeader header { "/some/problem.json", "ipopt", 5, {} };
        if (m == 2)
            header.constraint_names = { "material", "a, \"quoted\" name" };
        std::mt19937 rng(3);
        std::vector<HistoryRow> rows;
        {
            HistoryWriter writer(dir.str(), header);
            for (int k = 0; k < 7; ++k) {
                rows.push_back(random_row(k, 5, m, rng));
                writer.append(rows.back());
                // Every appended row is in the file at once (flushed), while the writer is open.
                EXPECT_EQ(read_history(dir.file("history.h5")).rows.size(), size_t(k + 1));
            }
            writer.close();
        }
        const StoredHistory stored = read_history(dir.file("history.h5"));
        EXPECT_EQ(stored.header.problem, header.problem);
        EXPECT_EQ(stored.header.algorithm, header.algorithm);
        EXPECT_EQ(stored.header.design_size, 5);
        EXPECT_EQ(stored.header.constraint_names, header.constraint_names);
        ASSERT_EQ(stored.rows.size(), rows.size());
        for (size_t k = 0; k < rows.size(); ++k)
            expect_same(stored.rows[k], rows[k]);

        const std::vector<std::string> csv = lines(dir.file("history.csv"));
        ASSERT_EQ(csv.size(), rows.size() + 1);
        EXPECT_EQ(csv[0],
            "iteration,J" + std::string(m == 2 ? ",material,\"a, \"\"quoted\"\" name\"" : "")
                + ",gradient_norm,step_norm,evaluations,rejected,evaluation_seconds,optimizer_seconds,wall_seconds");
        for (size_t k = 0; k < rows.size(); ++k) {
            const std::vector<double> v = numbers(csv[k + 1]);
            ASSERT_EQ(v.size(), size_t(9 + m));
            EXPECT_EQ(v[0], rows[k].iteration);
            EXPECT_EQ(v[1], rows[k].J); // %.17g: every bit
            for (Index i = 0; i < m; ++i)
                EXPECT_EQ(v[size_t(2 + i)], rows[k].constraints[i]);
            EXPECT_EQ(v[size_t(2 + m)], rows[k].gradient_norm);
            EXPECT_EQ(v[size_t(8 + m)], rows[k].wall_seconds);
        }
    }
}

TEST(OptimizationHistory, AResumedWriterStartsWithTheGivenRows)
{
    TempDir dir("resume");
    const HistoryHeader header { "p.json", "lbfgsb", 3, { "c" } };
    std::mt19937 rng(5);
    std::vector<HistoryRow> rows;
    {
        HistoryWriter writer(dir.str(), header);
        for (int k = 0; k < 6; ++k) {
            rows.push_back(random_row(k, 3, 1, rng));
            writer.append(rows.back());
        }
        writer.close();
    }
    // The run goes on after iteration 3: rows 4 and 5 are dropped and written again (new ones).
    std::vector<HistoryRow> kept(rows.begin(), rows.begin() + 4);
    {
        HistoryWriter writer(dir.str(), header, kept);
        EXPECT_EQ(writer.rows(), 4);
        for (int k = 4; k < 8; ++k) {
            kept.push_back(random_row(k, 3, 1, rng));
            writer.append(kept.back());
        }
        writer.close();
    }
    const StoredHistory stored = read_history(dir.file("history.h5"));
    ASSERT_EQ(stored.rows.size(), 8u);
    for (size_t k = 0; k < 8; ++k)
        expect_same(stored.rows[k], kept[k]);
    EXPECT_EQ(lines(dir.file("history.csv")).size(), 9u);
    EXPECT_FALSE(fs::exists(dir.file("history.h5.tmp")));
}

TEST(OptimizationHistory, ARowThatDoesNotFitTheHeaderIsALogicError)
{
    TempDir dir("fit");
    HistoryWriter writer(dir.str(), { "p.json", "lbfgsb", 3, { "c" } });
    std::mt19937 rng(1);
    EXPECT_THROW(writer.append(random_row(0, 4, 1, rng)), std::logic_error);
    EXPECT_THROW(writer.append(random_row(0, 3, 2, rng)), std::logic_error);
}

TEST(OptimizationHistory, RunStateRoundTrip)
{
    TempDir dir("state");
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const auto vec = [&](Index n) { return VectorXd(VectorXd::NullaryExpr(n, [&]() { return u(rng); })); };
    const auto mat = [&](Index r, Index c) { return MatrixXd(MatrixXd::NullaryExpr(r, c, [&]() { return u(rng); })); };
    const Index n = 4;
    const auto values = [&](int mc, int mh) {
        OptimizationValues v;
        v.f = u(rng);
        v.gradient = vec(n);
        v.inequality = vec(mc);
        v.inequality_jacobian = mat(mc, n);
        v.equality = vec(mh);
        v.equality_jacobian = mat(mh, n);
        return v;
    };
    for (const bool constrained : { false, true }) {
        RunState s;
        OptimizerCheckpoint& c = s.checkpoint;
        c.algorithm = constrained ? OptimizerAlgorithm::IPOPT : OptimizerAlgorithm::LBFGSB;
        c.iteration = 12;
        c.x = vec(n);
        c.values = constrained ? values(2, 1) : values(0, 0);
        if (!constrained) { // as DesignProblem gives them: 0 x n Jacobians
            c.values.inequality_jacobian.resize(0, n);
            c.values.equality_jacobian.resize(0, n);
        }
        c.gradient_norm = 0.25;
        c.step_norm = 1e-3;
        c.previous_f = constrained ? std::nan("") : 0.5;
        c.initial_gradient_norm = 3;
        c.evaluations = 20;
        c.rejected = 2;
        c.evaluation_seconds = 1.5;
        c.optimizer_seconds = 0.01;
        c.elapsed_seconds = 1.7;
        c.has_best = constrained;
        if (constrained) {
            c.best_x = vec(n);
            c.best_values = values(2, 1);
            c.best_evaluation = 7;
            c.best_iteration = -1; // a trial point
            c.jumps.push_back({ 4, -0.3, 1e-3, 2e-3, 0.05 });
            c.steps_checked = 11;
            c.jumps_found = 23; // more than the list keeps
        } else {
            for (int i = 0; i < 3; ++i)
                c.lbfgs_pairs.push_back({ vec(n), vec(n) });
        }
        s.objective_scale = 2.5e5;
        s.last_rejection = constrained ? "invalid rest mesh: element 3 inverted" : "";
        const std::string path = dir.file("optimizer_state.h5");
        write_run_state(path, s);
        EXPECT_FALSE(fs::exists(path + ".tmp"));
        const RunState r = read_run_state(path);
        const OptimizerCheckpoint& d = r.checkpoint;
        EXPECT_EQ(d.algorithm, c.algorithm);
        EXPECT_EQ(d.iteration, 12);
        EXPECT_TRUE(d.x == c.x);
        const auto same = [](const OptimizationValues& a, const OptimizationValues& b) {
            EXPECT_EQ(a.f, b.f);
            EXPECT_TRUE(a.gradient == b.gradient);
            EXPECT_TRUE(a.inequality == b.inequality);
            EXPECT_TRUE(a.equality == b.equality);
            EXPECT_EQ(a.inequality_jacobian.rows(), b.inequality_jacobian.rows());
            EXPECT_EQ(a.inequality_jacobian.cols(), b.inequality_jacobian.cols());
            EXPECT_TRUE(a.inequality_jacobian == b.inequality_jacobian);
            EXPECT_EQ(a.equality_jacobian.rows(), b.equality_jacobian.rows());
            EXPECT_TRUE(a.equality_jacobian == b.equality_jacobian);
        };
        same(d.values, c.values);
        EXPECT_EQ(d.gradient_norm, c.gradient_norm);
        EXPECT_EQ(d.step_norm, c.step_norm);
        EXPECT_EQ(std::isnan(d.previous_f), std::isnan(c.previous_f));
        if (!constrained)
            EXPECT_EQ(d.previous_f, c.previous_f);
        EXPECT_EQ(d.initial_gradient_norm, 3);
        EXPECT_EQ(d.evaluations, 20);
        EXPECT_EQ(d.rejected, 2);
        EXPECT_EQ(d.evaluation_seconds, 1.5);
        EXPECT_EQ(d.optimizer_seconds, 0.01);
        EXPECT_EQ(d.elapsed_seconds, 1.7);
        EXPECT_EQ(d.has_best, c.has_best);
        if (constrained) {
            EXPECT_TRUE(d.best_x == c.best_x);
            same(d.best_values, c.best_values);
        }
        EXPECT_EQ(d.best_evaluation, c.best_evaluation);
        EXPECT_EQ(d.best_iteration, c.best_iteration);
        EXPECT_EQ(d.steps_checked, c.steps_checked);
        EXPECT_EQ(d.jumps_found, c.jumps_found);
        ASSERT_EQ(d.jumps.size(), c.jumps.size());
        for (size_t i = 0; i < c.jumps.size(); ++i) {
            EXPECT_EQ(d.jumps[i].iteration, c.jumps[i].iteration);
            EXPECT_EQ(d.jumps[i].change, c.jumps[i].change);
            EXPECT_EQ(d.jumps[i].predicted, c.jumps[i].predicted);
            EXPECT_EQ(d.jumps[i].first_order, c.jumps[i].first_order);
            EXPECT_EQ(d.jumps[i].step_norm, c.jumps[i].step_norm);
        }
        ASSERT_EQ(d.lbfgs_pairs.size(), c.lbfgs_pairs.size());
        for (size_t i = 0; i < c.lbfgs_pairs.size(); ++i) {
            EXPECT_TRUE(d.lbfgs_pairs[i].s == c.lbfgs_pairs[i].s);
            EXPECT_TRUE(d.lbfgs_pairs[i].y == c.lbfgs_pairs[i].y);
        }
        EXPECT_EQ(r.objective_scale, 2.5e5);
        EXPECT_EQ(r.last_rejection, s.last_rejection);
    }
}

TEST(OptimizationHistory, FilesThatAreMissingOrNotOursAreRefusedNamingTheFile)
{
    TempDir dir("bad");
    const std::string missing = dir.file("history.h5");
    EXPECT_EQ(error_field([&] { read_history(missing); }), missing);
    EXPECT_EQ(error_field([&] { read_run_state(dir.file("optimizer_state.h5")); }), dir.file("optimizer_state.h5"));
    const std::string text = dir.file("text.h5");
    std::ofstream(text) << "not HDF5\n";
    EXPECT_EQ(error_field([&] { read_history(text); }), text);
    EXPECT_EQ(error_field([&] { read_run_state(text); }), text);
    // An HDF5 file of another kind: the state file is not a history, and the other way round.
    RunState s;
    s.checkpoint.x = VectorXd::Zero(2);
    s.checkpoint.values.gradient = VectorXd::Zero(2);
    const std::string state = dir.file("optimizer_state.h5");
    write_run_state(state, s);
    EXPECT_EQ(error_field([&] { read_history(state); }), state);
    {
        HistoryWriter writer(dir.str(), { "p.json", "lbfgsb", 2, {} });
        writer.close();
    }
    EXPECT_EQ(error_field([&] { read_run_state(missing); }), missing);
}

} // namespace
