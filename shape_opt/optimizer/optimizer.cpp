#include "shape_opt/optimizer/optimizer.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/ipopt_driver.hpp"
#include "shape_opt/optimizer/lbfgsb.hpp"
#include "shape_opt/optimizer/nlopt_driver.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>

namespace diffipc {

namespace {

    constexpr double INF = std::numeric_limits<double>::infinity();

    double now_seconds()
    {
        return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    }

    /// CPU time of the calling thread, s (0 where the clock is not available).
    double thread_cpu_seconds()
    {
        timespec t;
        if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) != 0)
            return 0;
        return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
    }

    /// The names of the algorithms that have `takes`, as a message lists them: "ipopt, mma or slsqp".
    std::string algorithms_that(bool OptimizerAlgorithmInfo::*takes)
    {
        std::vector<std::string> names;
        for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms())
            if (info.*takes)
                names.push_back(info.name);
        std::string list;
        for (size_t i = 0; i < names.size(); ++i)
            list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
        return list;
    }

    /// x[i] for a message: "x0[3] = 2.5".
    std::string entry(const std::string& name, Index i, double value)
    {
        return name + "[" + std::to_string(i) + "] = " + format_number(value);
    }

    void check_bound_vector(const VectorXd& bound, Index n, const std::string& field)
    {
        if (bound.size() != 0 && bound.size() != n)
            throw InputError(field,
                "has " + std::to_string(bound.size()) + " entries, the problem has " + std::to_string(n)
                    + " variables (give one bound per variable, or none)");
        for (Index i = 0; i < bound.size(); ++i)
            if (std::isnan(bound[i]))
                throw InputError(field, entry("bound", i, bound[i]) + " is NaN (use -inf / +inf for a free side)");
    }

    void check_tolerance(double value, const std::string& field)
    {
        if (!(value >= 0) || std::isinf(value))
            throw InputError(field, format_number(value) + " must be a finite number >= 0 (0: off)");
    }

} // namespace

const std::vector<OptimizerAlgorithmInfo>& registered_optimizer_algorithms()
{
    using A = OptimizerAlgorithm;
    //                                              bounds inequalities equalities options library
    static const std::vector<OptimizerAlgorithmInfo> algorithms {
        { A::LBFGS, "lbfgs", false, false, false, false, "ours" },
        { A::LBFGSB, "lbfgsb", true, false, false, false, "ours" },
        { A::IPOPT, "ipopt", true, true, true, true, "Ipopt 3.11" },
        { A::MMA, "mma", true, true, false, true, "NLopt 2.7" },
        { A::CCSAQ, "ccsaq", true, true, false, true, "NLopt 2.7" },
        { A::SLSQP, "slsqp", true, true, true, true, "NLopt 2.7" },
    };
    return algorithms;
}

const OptimizerAlgorithmInfo& optimizer_algorithm_info(OptimizerAlgorithm algorithm)
{
    for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms())
        if (info.algorithm == algorithm)
            return info;
    throw std::logic_error("optimizer_algorithm_info: an algorithm missing from the table");
}

std::string to_string(OptimizerAlgorithm algorithm) { return optimizer_algorithm_info(algorithm).name; }

OptimizerAlgorithm parse_optimizer_algorithm(const std::string& name, const std::string& field)
{
    std::string lower = name;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    std::string known;
    for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms()) {
        if (lower == info.name)
            return info.algorithm;
        known += std::string(known.empty() ? "" : ", ") + "\"" + info.name + "\"";
    }
    throw InputError(field, "unknown optimizer \"" + name + "\" (known: " + known + ")");
}

std::string to_string(StopReason reason)
{
    switch (reason) {
    case StopReason::GRADIENT_TOLERANCE:
        return "gradient_tolerance";
    case StopReason::X_TOLERANCE:
        return "x_tolerance";
    case StopReason::F_TOLERANCE:
        return "f_tolerance";
    case StopReason::ITERATION_BUDGET:
        return "iteration_budget";
    case StopReason::TIME_BUDGET:
        return "time_budget";
    case StopReason::LINE_SEARCH_STALLED:
        return "line_search_stalled";
    case StopReason::USER_STOP:
        return "user_stop";
    case StopReason::OBJECTIVE_TARGET:
        return "objective_target";
    case StopReason::INFEASIBLE:
        return "infeasible";
    case StopReason::INVALID_START:
        return "invalid_start";
    case StopReason::FAILED:
        return "failed";
    }
    return "unknown";
}

namespace optimizer_detail {

    void validate(const OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings)
    {
        const Index n = problem.size();
        if (x0.size() != n)
            throw InputError("optimizer.x0",
                "has " + std::to_string(x0.size()) + " entries, the problem has " + std::to_string(n) + " variables");
        for (Index i = 0; i < n; ++i)
            if (!std::isfinite(x0[i]))
                throw InputError("optimizer.x0", entry("x0", i, x0[i]) + " is not a finite number");
        check_bound_vector(settings.lower, n, "optimizer.lower");
        check_bound_vector(settings.upper, n, "optimizer.upper");
        for (Index i = 0; i < n; ++i) {
            const double lo = settings.lower.size() ? settings.lower[i] : -INF;
            const double hi = settings.upper.size() ? settings.upper[i] : INF;
            if (lo > hi)
                throw InputError("optimizer.lower",
                    entry("lower", i, lo) + " is above " + entry("upper", i, hi) + " (an empty box)");
            if (lo == INF || hi == -INF)
                throw InputError(lo == INF ? "optimizer.lower" : "optimizer.upper",
                    "variable " + std::to_string(i) + " has no admissible value (lower = +inf or upper = -inf)");
            if (x0[i] < lo || x0[i] > hi)
                throw InputError("optimizer.x0",
                    entry("x0", i, x0[i]) + " is outside its bounds [" + format_number(lo) + ", " + format_number(hi)
                        + "]; start inside the box (the optimizers do not move the start for you)");
        }
        check_tolerance(settings.gradient_tolerance, "optimizer.gradient_tolerance");
        check_tolerance(settings.relative_gradient_tolerance, "optimizer.relative_gradient_tolerance");
        check_tolerance(settings.x_tolerance, "optimizer.x_tolerance");
        check_tolerance(settings.f_tolerance, "optimizer.f_tolerance");
        check_tolerance(settings.constraint_tolerance, "optimizer.constraint_tolerance");
        if (std::isnan(settings.max_seconds) || std::isinf(settings.max_seconds))
            throw InputError("optimizer.max_seconds",
                format_number(settings.max_seconds) + " must be a finite number (<= 0: no budget)");
        if (settings.lbfgs_memory < 1)
            throw InputError("optimizer.lbfgs_memory",
                std::to_string(settings.lbfgs_memory) + " must be at least 1 correction pair");
        if (problem.inequalities() < 0 || problem.equalities() < 0)
            throw InputError("optimizer.problem", "negative number of constraints");

        const OptimizerAlgorithm a = settings.algorithm;
        const OptimizerAlgorithmInfo& takes = optimizer_algorithm_info(a);
        if (!takes.inequalities && (problem.inequalities() > 0 || problem.equalities() > 0))
            throw InputError("optimizer.algorithm",
                "\"" + to_string(a) + "\" takes no constraints (the problem has "
                    + std::to_string(problem.inequalities()) + " inequalities and "
                    + std::to_string(problem.equalities()) + " equalities): use "
                    + algorithms_that(&OptimizerAlgorithmInfo::inequalities) + ", or a penalty in the objective");
        if (!takes.bounds)
            for (Index i = 0; i < n; ++i)
                if ((settings.lower.size() && std::isfinite(settings.lower[i]))
                    || (settings.upper.size() && std::isfinite(settings.upper[i])))
                    throw InputError("optimizer.algorithm",
                        "\"" + to_string(a) + "\" takes no bounds (variable " + std::to_string(i)
                            + " has a finite one): use " + algorithms_that(&OptimizerAlgorithmInfo::bounds));
        if (!takes.equalities && problem.equalities() > 0)
            throw InputError("optimizer.algorithm",
                "\"" + to_string(a) + "\" takes no equality constraints (the problem has "
                    + std::to_string(problem.equalities()) + "): use "
                    + algorithms_that(&OptimizerAlgorithmInfo::equalities) + ", or write h(x) = 0 as two inequalities");
        if (!takes.library_options && !settings.options.empty())
            throw InputError("optimizer.options." + settings.options.begin()->first,
                "\"" + to_string(a) + "\" takes no library options (its settings are the optimizer's own fields)");
        if (a == OptimizerAlgorithm::IPOPT)
            check_ipopt_options(settings);
        if (a == OptimizerAlgorithm::MMA || a == OptimizerAlgorithm::CCSAQ || a == OptimizerAlgorithm::SLSQP)
            check_nlopt_options(settings);
    }

    double projected_gradient_norm(
        const VectorXd& x, const VectorXd& gradient, const VectorXd& lower, const VectorXd& upper)
    {
        double norm = 0;
        for (Index i = 0; i < x.size(); ++i) {
            const double g = gradient[i];
            if ((x[i] <= lower[i] && g > 0) || (x[i] >= upper[i] && g < 0))
                continue;
            norm = std::max(norm, std::abs(g));
        }
        return norm;
    }

    double relative_change(double f0, double f1)
    {
        return std::abs(f1 - f0) / std::max({ std::abs(f0), std::abs(f1), 1e-300 });
    }

    Run::Run(OptimizationProblem& problem, const OptimizerSettings& settings, const OptimizerCheckpoint* resume)
        : m_problem(problem)
        , m_settings(settings)
        , m_resume(resume)
        , m_start(now_seconds())
        , m_cpu_start(thread_cpu_seconds())
        , m_best_f(INF)
    {
        const Index n = problem.size();
        m_lower = settings.lower.size() ? settings.lower : VectorXd::Constant(n, -INF);
        m_upper = settings.upper.size() ? settings.upper : VectorXd::Constant(n, INF);
        if (resume) {
            // The earlier part of the run as if it had been this one: its wall time, of which
            // the part neither in evaluations nor in the optimizer was spent in the callback.
            m_start -= resume->elapsed_seconds;
            m_evaluation_seconds = resume->evaluation_seconds;
            m_resumed_optimizer_cpu_seconds = resume->optimizer_cpu_seconds;
            m_callback_seconds
                = std::max(0.0, resume->elapsed_seconds - resume->evaluation_seconds - resume->optimizer_seconds);
            m_evaluations = resume->evaluations;
            m_rejected = resume->rejected;
            m_initial_gradient_norm = resume->initial_gradient_norm;
            m_first_x = resume->x;
            m_has_accepted = true;
            m_accepted_x = resume->x;
            m_accepted_values = resume->values;
            m_step_norm = resume->step_norm;
            m_has_best = resume->has_best;
            if (m_has_best) {
                m_best_x = resume->best_x;
                m_best_values = resume->best_values;
                m_best_f = resume->best_values.f;
                m_best_evaluation = resume->best_evaluation;
                m_best_iteration = resume->best_iteration;
            }
            m_jumps = resume->jumps;
            // A state written before the count was kept: its list is all it knows.
            m_jumps_found = std::max(resume->jumps_found, int(resume->jumps.size()));
            m_steps_checked = resume->steps_checked;
        }
    }

    int Run::first_iteration() const { return m_resume ? m_resume->iteration : 0; }

    bool Run::evaluate(const VectorXd& x, OptimizationValues& out)
    {
        const double t0 = now_seconds(), cpu0 = thread_cpu_seconds();
        bool valid = m_problem.evaluate(x, out);
        m_evaluation_seconds += now_seconds() - t0;
        m_evaluation_cpu_seconds += thread_cpu_seconds() - cpu0;
        ++m_evaluations;
        if (m_first_x.size() == 0)
            m_first_x = x;
        if (valid) {
            const Index n = x.size();
            const int mc = m_problem.inequalities(), mh = m_problem.equalities();
            const auto size_error = [](const std::string& what, Index rows, Index cols, Index want_rows,
                                        Index want_cols) {
                return InputError("optimizer.problem",
                    "evaluate() returned " + what + " of size " + std::to_string(rows) + " x " + std::to_string(cols)
                        + ", expected " + std::to_string(want_rows) + " x " + std::to_string(want_cols));
            };
            if (out.gradient.size() != n)
                throw size_error("a gradient", out.gradient.size(), 1, n, 1);
            if (out.inequality.size() != mc)
                throw size_error("inequality values", out.inequality.size(), 1, mc, 1);
            if (out.equality.size() != mh)
                throw size_error("equality values", out.equality.size(), 1, mh, 1);
            if (mc > 0 && (out.inequality_jacobian.rows() != mc || out.inequality_jacobian.cols() != n))
                throw size_error(
                    "an inequality Jacobian", out.inequality_jacobian.rows(), out.inequality_jacobian.cols(), mc, n);
            if (mh > 0 && (out.equality_jacobian.rows() != mh || out.equality_jacobian.cols() != n))
                throw size_error(
                    "an equality Jacobian", out.equality_jacobian.rows(), out.equality_jacobian.cols(), mh, n);
            // A NaN or inf is treated as a failed evaluation: no optimizer here can use it.
            valid = std::isfinite(out.f) && out.gradient.allFinite() && out.inequality.allFinite()
                && out.equality.allFinite() && (mc == 0 || out.inequality_jacobian.allFinite())
                && (mh == 0 || out.equality_jacobian.allFinite());
        }
        if (!valid) {
            ++m_rejected;
            return false;
        }
        if (feasible(x, out) && out.f < m_best_f) {
            m_has_best = true;
            m_best_f = out.f;
            m_best_x = x;
            m_best_values = out;
            m_best_evaluation = m_evaluations;
            m_best_iteration = -1; // until the optimizer accepts it
        }
        return true;
    }

    double Run::max_valid_step(const VectorXd& x, const VectorXd& dx)
    {
        const double t0 = now_seconds(), cpu0 = thread_cpu_seconds();
        const double t = m_problem.max_valid_step(x, dx);
        m_evaluation_seconds += now_seconds() - t0;
        m_evaluation_cpu_seconds += thread_cpu_seconds() - cpu0;
        if (!(t > 0))
            return 0;
        return std::min(t, 1.0);
    }

    double Run::violation(const VectorXd& x, const OptimizationValues& values) const
    {
        double v = 0;
        for (Index i = 0; i < values.inequality.size(); ++i)
            v = std::max(v, values.inequality[i]);
        for (Index i = 0; i < values.equality.size(); ++i)
            v = std::max(v, std::abs(values.equality[i]));
        for (Index i = 0; i < x.size(); ++i)
            v = std::max({ v, m_lower[i] - x[i], x[i] - m_upper[i] });
        return v;
    }

    bool Run::iteration(int iteration, const VectorXd& x, const OptimizationValues& values, double gradient_norm,
        double step_norm, const std::vector<CorrectionPair>* pairs)
    {
        const double previous_f = m_has_accepted ? m_accepted_values.f : std::nan("");
        if (m_has_accepted && x != m_accepted_x)
            check_step(iteration, x, values);
        if (m_has_best && m_best_iteration < 0 && x == m_best_x)
            m_best_iteration = iteration;
        m_has_accepted = true;
        m_accepted_x = x;
        m_accepted_values = values;
        m_step_norm = step_norm;
        IterationInfo info;
        info.iteration = iteration;
        info.x = &x;
        info.values = &values;
        info.gradient_norm = gradient_norm;
        info.step_norm = step_norm;
        info.evaluations = m_evaluations;
        info.rejected = m_rejected;
        info.evaluation_seconds = m_evaluation_seconds;
        const double cpu0 = thread_cpu_seconds();
        const double t0 = now_seconds();
        info.optimizer_seconds = std::max(0.0, t0 - m_start - m_evaluation_seconds - m_callback_seconds);
        info.optimizer_cpu_seconds = m_resumed_optimizer_cpu_seconds
            + std::max(0.0, cpu0 - m_cpu_start - m_evaluation_cpu_seconds - m_callback_cpu_seconds);

        OptimizerCheckpoint& c = m_checkpoint;
        c.algorithm = m_settings.algorithm;
        c.iteration = iteration;
        c.x = x;
        c.values = values;
        c.gradient_norm = gradient_norm;
        c.step_norm = step_norm;
        c.previous_f = previous_f;
        c.initial_gradient_norm = m_initial_gradient_norm;
        c.evaluations = m_evaluations;
        c.rejected = m_rejected;
        c.evaluation_seconds = m_evaluation_seconds;
        c.optimizer_seconds = info.optimizer_seconds;
        c.optimizer_cpu_seconds = info.optimizer_cpu_seconds;
        c.elapsed_seconds = t0 - m_start;
        c.has_best = m_has_best;
        c.best_x = m_has_best ? m_best_x : VectorXd();
        c.best_values = m_has_best ? m_best_values : OptimizationValues();
        c.best_evaluation = m_has_best ? m_best_evaluation : 0;
        c.best_iteration = m_has_best ? m_best_iteration : -1;
        c.jumps = m_jumps;
        c.jumps_found = m_jumps_found;
        c.steps_checked = m_steps_checked;
        if (pairs)
            c.lbfgs_pairs = *pairs;
        else
            c.lbfgs_pairs.clear();
        info.checkpoint = &c;

        const bool go_on = m_problem.iteration(info);
        m_callback_seconds += now_seconds() - t0;
        m_callback_cpu_seconds += thread_cpu_seconds() - cpu0;
        return go_on;
    }

    void Run::check_step(int iteration, const VectorXd& x, const OptimizationValues& values)
    {
        // Only between points of one problem: a remeshed run's first iterate carries no previous f.
        if (!std::isfinite(m_accepted_values.f) || m_accepted_values.gradient.size() != x.size())
            return;
        const VectorXd dx = x - m_accepted_x;
        const double a = m_accepted_values.gradient.dot(dx), b = values.gradient.dot(dx);
        const double change = values.f - m_accepted_values.f;
        const double predicted = 0.5 * (a + b);
        const double first_order = std::abs(a) + std::abs(b);
        ++m_steps_checked;
        const double floor = STEP_JUMP_FLOOR * std::max(std::abs(values.f), std::abs(m_accepted_values.f));
        if (!(std::abs(change - predicted) > STEP_JUMP_FACTOR * first_order + floor))
            return;
        ++m_jumps_found;
        m_jumps.push_back({ iteration, change, predicted, first_order, dx.lpNorm<Eigen::Infinity>() });
        const auto miss = [](const StepJump& j) { return std::abs(j.change - j.predicted); };
        std::stable_sort(
            m_jumps.begin(), m_jumps.end(), [&](const StepJump& p, const StepJump& q) { return miss(p) > miss(q); });
        if (m_jumps.size() > MAX_STEP_JUMPS)
            m_jumps.resize(MAX_STEP_JUMPS);
    }

    bool Run::out_of_time() const { return m_settings.max_seconds > 0 && elapsed() >= m_settings.max_seconds; }

    double Run::elapsed() const { return now_seconds() - m_start; }

    double Run::optimizer_cpu_seconds() const
    {
        return m_resumed_optimizer_cpu_seconds
            + std::max(0.0, thread_cpu_seconds() - m_cpu_start - m_evaluation_cpu_seconds - m_callback_cpu_seconds);
    }

    double Run::remaining_seconds() const
    {
        return m_settings.max_seconds > 0 ? m_settings.max_seconds - elapsed() : INF;
    }

    OptimizerResult Run::finish(StopReason reason, const std::string& message, int iterations)
    {
        OptimizerResult result;
        result.reason = reason;
        result.message = message;
        // The optimizer's own result is its last iterate: the point its stop reason describes.
        // The best point seen (possibly a trial point it rejected, or an earlier iterate on
        // another branch of a non-smooth f) is reported beside it, never in its place.
        if (m_has_accepted) {
            result.x = m_accepted_x;
            result.values = m_accepted_values;
            result.max_violation = violation(result.x, result.values);
        } else {
            result.x = m_first_x;
        }
        result.has_best = m_has_best;
        if (m_has_best) {
            result.best_x = m_best_x;
            result.best_values = m_best_values;
            result.best_max_violation = violation(m_best_x, m_best_values);
            result.best_evaluation = m_best_evaluation;
            result.best_iteration = m_best_iteration;
        }
        result.jumps = m_jumps;
        result.jumps_found = m_jumps_found;
        result.steps_checked = m_steps_checked;
        const bool infeasible_end = m_has_accepted && result.max_violation > m_settings.constraint_tolerance;
        if ((!m_has_best || infeasible_end) && reason != StopReason::INVALID_START) {
            if (reason == StopReason::GRADIENT_TOLERANCE || reason == StopReason::X_TOLERANCE
                || reason == StopReason::F_TOLERANCE)
                result.reason = StopReason::INFEASIBLE;
            if (!m_has_best)
                result.message += "; no point within constraint_tolerance "
                    + format_number(m_settings.constraint_tolerance)
                    + " of the constraints was found (largest violation at x: " + format_number(result.max_violation)
                    + ")";
            else
                result.message += "; the last iterate is " + format_number(result.max_violation)
                    + " outside the constraints (constraint_tolerance " + format_number(m_settings.constraint_tolerance)
                    + "), a feasible point was seen at evaluation " + std::to_string(m_best_evaluation);
        }
        result.iterations = iterations;
        result.evaluations = m_evaluations;
        result.rejected = m_rejected;
        result.evaluation_seconds = m_evaluation_seconds;
        result.optimizer_seconds = std::max(0.0, elapsed() - m_evaluation_seconds - m_callback_seconds);
        result.optimizer_cpu_seconds = optimizer_cpu_seconds();
        return result;
    }

} // namespace optimizer_detail

namespace {

    OptimizerResult run_driver(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0)
    {
        const OptimizerSettings& settings = run.settings();
        const bool lbfgs
            = settings.algorithm == OptimizerAlgorithm::LBFGS || settings.algorithm == OptimizerAlgorithm::LBFGSB;
        // A resumed run whose budget is spent ends here (L-BFGS checks its budgets itself, after
        // the convergence checks, as the uninterrupted run does); the libraries would start anyway.
        if (run.resumed() && !lbfgs) {
            const int done = run.first_iteration();
            if (settings.max_iterations > 0 && done >= settings.max_iterations)
                return run.finish(StopReason::ITERATION_BUDGET,
                    to_string(settings.algorithm) + ": iteration budget of " + std::to_string(settings.max_iterations)
                        + " reached",
                    done);
            if (run.out_of_time())
                return run.finish(StopReason::TIME_BUDGET,
                    to_string(settings.algorithm) + ": wall-time budget of " + format_number(settings.max_seconds)
                        + " s reached",
                    done);
        }
        switch (settings.algorithm) {
        case OptimizerAlgorithm::LBFGS:
        case OptimizerAlgorithm::LBFGSB:
            return minimize_lbfgsb(run, x0, values0);
        case OptimizerAlgorithm::IPOPT:
            return minimize_ipopt(run, x0, values0);
        case OptimizerAlgorithm::MMA:
        case OptimizerAlgorithm::CCSAQ:
        case OptimizerAlgorithm::SLSQP:
            return minimize_nlopt(run, x0, values0);
        }
        throw InputError("optimizer.algorithm", "unknown algorithm");
    }

    /// @brief A checkpoint's sizes against the problem's; its numbers finite.
    /// @throws InputError naming "optimizer.checkpoint"
    void check_checkpoint(const OptimizationProblem& problem, const OptimizerCheckpoint& c)
    {
        const Index n = problem.size();
        const auto fail = [](const std::string& why) { throw InputError("optimizer.checkpoint", why); };
        const auto check_values = [&](const OptimizationValues& v, const std::string& where) {
            if (v.gradient.size() != n || v.inequality.size() != problem.inequalities()
                || v.equality.size() != problem.equalities()
                || (problem.inequalities() > 0
                    && (v.inequality_jacobian.rows() != problem.inequalities() || v.inequality_jacobian.cols() != n))
                || (problem.equalities() > 0
                    && (v.equality_jacobian.rows() != problem.equalities() || v.equality_jacobian.cols() != n)))
                fail("the values " + where + " do not fit the problem (" + std::to_string(n) + " variables, "
                    + std::to_string(problem.inequalities()) + " inequalities, " + std::to_string(problem.equalities())
                    + " equalities)");
            if (!std::isfinite(v.f) || !v.gradient.allFinite() || !v.inequality.allFinite() || !v.equality.allFinite())
                fail("the values " + where + " are not finite");
        };
        if (c.iteration < 0)
            fail("negative iteration " + std::to_string(c.iteration));
        if (c.x.size() != n)
            fail("x has " + std::to_string(c.x.size()) + " entries, the problem has " + std::to_string(n)
                + " variables");
        check_values(c.values, "at x");
        if (c.has_best) {
            if (c.best_x.size() != n)
                fail("the best point has " + std::to_string(c.best_x.size()) + " entries, the problem has "
                    + std::to_string(n) + " variables");
            check_values(c.best_values, "at the best point");
        }
        for (const CorrectionPair& pair : c.lbfgs_pairs)
            if (pair.s.size() != n || pair.y.size() != n || !pair.s.allFinite() || !pair.y.allFinite())
                fail("an L-BFGS correction pair does not have " + std::to_string(n) + " finite entries");
        if (!(c.evaluations >= 0 && c.rejected >= 0 && c.evaluation_seconds >= 0 && c.optimizer_seconds >= 0
                && c.optimizer_cpu_seconds >= 0 && c.elapsed_seconds >= 0 && std::isfinite(c.elapsed_seconds)
                && std::isfinite(c.initial_gradient_norm) && c.initial_gradient_norm >= 0))
            fail("negative or non-finite counts, times or initial gradient norm");
    }

} // namespace

OptimizerResult resume_minimize(
    OptimizationProblem& problem, const OptimizerCheckpoint& checkpoint, const OptimizerSettings& settings)
{
    optimizer_detail::validate(problem, checkpoint.x, settings);
    if (checkpoint.algorithm != settings.algorithm)
        throw InputError("optimizer.algorithm",
            "\"" + to_string(settings.algorithm) + "\" cannot continue a run of \"" + to_string(checkpoint.algorithm)
                + "\" (start a new run from its last design instead)");
    check_checkpoint(problem, checkpoint);
    optimizer_detail::Run run(problem, settings, &checkpoint);
    return run_driver(run, checkpoint.x, checkpoint.values);
}

void check_optimizer_settings(const OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings)
{
    optimizer_detail::validate(problem, x0, settings);
}

OptimizerResult minimize(OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings)
{
    optimizer_detail::validate(problem, x0, settings);
    optimizer_detail::Run run(problem, settings);
    OptimizationValues values0;
    if (!run.evaluate(x0, values0))
        return run.finish(StopReason::INVALID_START,
            "the initial point is invalid: evaluate() returned false or a non-finite value there", 0);
    run.set_initial_gradient_norm(
        optimizer_detail::projected_gradient_norm(x0, values0.gradient, run.lower(), run.upper()));
    return run_driver(run, x0, values0);
}

} // namespace diffipc
