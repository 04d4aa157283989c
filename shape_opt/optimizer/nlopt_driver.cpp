#include "shape_opt/optimizer/nlopt_driver.hpp"

#include "forward/common/error.hpp"

#include <nlopt.hpp>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <limits>
#include <vector>

namespace diffipc {

namespace {

    constexpr double INF = std::numeric_limits<double>::infinity();
    constexpr double INVALID_MARGIN = 1e3; ///< how far above the valid values an invalid point's are
    constexpr int MAX_REPEATS = 20; ///< objective calls at one point after the first before we stop
    constexpr int MAX_WITHOUT_PROGRESS = 200; ///< evaluations without a new best point before we stop

    nlopt::algorithm nlopt_algorithm(OptimizerAlgorithm a)
    {
        switch (a) {
        case OptimizerAlgorithm::MMA:
            return nlopt::LD_MMA;
        case OptimizerAlgorithm::CCSAQ:
            return nlopt::LD_CCSAQ;
        case OptimizerAlgorithm::SLSQP:
            return nlopt::LD_SLSQP;
        default:
            throw InputError("optimizer.algorithm", "\"" + to_string(a) + "\" is not an NLopt algorithm");
        }
    }

    bool parse_number(const std::string& text, double& value)
    {
        if (text.empty())
            return false;
        char* end = nullptr;
        errno = 0;
        value = std::strtod(text.c_str(), &end);
        return end == text.c_str() + text.size() && errno == 0 && !std::isnan(value);
    }

    bool parse_count(const std::string& text, int& value)
    {
        if (text.empty())
            return false;
        char* end = nullptr;
        errno = 0;
        const long v = std::strtol(text.c_str(), &end, 10);
        if (end != text.c_str() + text.size() || errno != 0 || v < 0 || v > INT_MAX)
            return false;
        value = int(v);
        return true;
    }

    /// @brief Applies settings.options to `opt` (nullptr: only checks them).
    /// @throws InputError naming "optimizer.options.<name>"
    void apply_options(const OptimizerSettings& settings, nlopt::opt* opt)
    {
        const bool ccsa
            = settings.algorithm == OptimizerAlgorithm::MMA || settings.algorithm == OptimizerAlgorithm::CCSAQ;
        for (const auto& [name, value] : settings.options) {
            const std::string field = "optimizer.options." + name;
            const auto number = [&, &value = value](double lowest) {
                double v = 0;
                if (!parse_number(value, v) || v < lowest)
                    throw InputError(field,
                        "\"" + value + "\" is not a number" + (lowest > -INF ? " >= " + format_number(lowest) : ""));
                return v;
            };
            const auto count = [&, &value = value]() {
                int v = 0;
                if (!parse_count(value, v))
                    throw InputError(field, "\"" + value + "\" is not an integer >= 0");
                return v;
            };
            if (name == "maxeval") {
                const int v = count();
                if (opt)
                    opt->set_maxeval(v);
            } else if (name == "xtol_rel") {
                const double v = number(0);
                if (opt)
                    opt->set_xtol_rel(v);
            } else if (name == "ftol_abs") {
                const double v = number(0);
                if (opt)
                    opt->set_ftol_abs(v);
            } else if (name == "stopval") {
                const double v = number(-INF);
                if (opt)
                    opt->set_stopval(v);
            } else if (ccsa && (name == "inner_maxeval" || name == "dual_maxeval" || name == "verbosity")) {
                const int v = count();
                if (opt)
                    opt->set_param(name.c_str(), v);
            } else if (ccsa && (name == "dual_ftol_rel" || name == "dual_ftol_abs")) {
                const double v = number(0);
                if (opt)
                    opt->set_param(name.c_str(), v);
            } else if (ccsa && name == "dual_algorithm") {
                int v = int(nlopt_algorithm_from_string(value.c_str()));
                if (v < 0 && (!parse_count(value, v) || v >= NLOPT_NUM_ALGORITHMS))
                    throw InputError(field, "\"" + value + "\" is not an NLopt algorithm (a name such as \"LD_MMA\")");
                if (opt)
                    opt->set_param(name.c_str(), v);
            } else {
                throw InputError(field,
                    "not an option of " + to_string(settings.algorithm)
                        + " (NLopt options here: maxeval, xtol_rel, ftol_abs, stopval"
                        + (ccsa ? ", inner_maxeval, dual_algorithm, dual_ftol_rel, dual_ftol_abs, dual_maxeval, "
                                  "verbosity"
                                : "")
                        + ")");
            }
        }
    }

    /// What NLopt's callbacks share: the one evaluation per point, the best point, the stop.
    class NloptContext {
    public:
        NloptContext(optimizer_detail::Run& run, nlopt::opt& opt, const VectorXd& x0, const OptimizationValues& values0)
            : m_run(run)
            , m_opt(opt)
            , m_settings(run.settings())
            , m_constrained(run.problem().inequalities() > 0 || run.problem().equalities() > 0)
            , m_x(x0)
            , m_valid(true)
            , m_values(values0)
            , m_last_valid(values0)
            , m_f_max(values0.f)
            , m_f_min(values0.f)
            , m_previous_x(x0)
        {
            m_iterations = run.first_iteration();
            m_gradient_norm0 = run.initial_gradient_norm();
            const double violation = run.violation(x0, values0);
            if (violation <= m_settings.constraint_tolerance) {
                m_has_feasible = true;
                m_best_f = values0.f;
            } else
                m_best_violation = violation;
        }

        double objective(unsigned n, const double* x, double* grad)
        {
            try {
                // With its tolerances at 0, CCSA can keep asking for one point for ever (its
                // step vanished, or rho overflowed after repeated invalid points).
                const bool same = m_called && Eigen::Map<const VectorXd>(x, n) == m_x;
                m_repeats = same ? m_repeats + 1 : 0;
                m_called = true;
                if (m_repeats >= MAX_REPEATS)
                    stop(m_valid ? StopReason::X_TOLERANCE : StopReason::LINE_SEARCH_STALLED,
                        std::string("NLopt asked for the same ") + (m_valid ? "" : "invalid ") + "point "
                            + std::to_string(MAX_REPEATS + 1) + " times in a row: no progress");
                const OptimizationValues& v = values_at(n, x);
                if (grad)
                    Eigen::Map<VectorXd>(grad, n) = v.gradient;
                return m_valid ? v.f : m_f_max + INVALID_MARGIN * (std::abs(m_f_max) + std::abs(m_f_min) + 1);
            } catch (...) {
                fail();
                if (grad)
                    Eigen::Map<VectorXd>(grad, n).setZero();
                return 0;
            }
        }

        /// c (equality: false) or h (true) and their Jacobian rows, grad[i n + j] = d c_i / d x_j.
        void constraints(bool equality, unsigned m, double* result, unsigned n, const double* x, double* grad)
        {
            try {
                const OptimizationValues& v = values_at(n, x);
                const VectorXd& c = equality ? v.equality : v.inequality;
                const MatrixXd& jacobian = equality ? v.equality_jacobian : v.inequality_jacobian;
                // Inequalities reach NLopt looser by a tenth of the tolerance: a start on an
                // active constraint up to round-off (c = 1e-14) is then strictly feasible for
                // CCSA's subproblems, which otherwise shrink their steps to nothing there; the
                // result stays within the tolerance (c <= 0.1 tol).
                const double margin = equality ? 0.0 : 0.1 * m_settings.constraint_tolerance;
                for (unsigned i = 0; i < m; ++i)
                    result[i] = m_valid ? c[i] - margin : std::max(c[i], 0.0) + INVALID_MARGIN * (std::abs(c[i]) + 1);
                if (grad)
                    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(grad, m, n)
                        = jacobian;
            } catch (...) {
                fail();
                std::fill(result, result + m, 0.0);
                if (grad)
                    std::fill(grad, grad + size_t(m) * n, 0.0);
            }
        }

        /// Iterations as defined in nlopt_driver.hpp.
        int iterations() const { return m_iterations; }
        bool stopped() const { return m_stopped; }
        StopReason stop_reason() const { return m_stop_reason; }
        const std::string& stop_message() const { return m_stop_message; }
        std::exception_ptr exception() const { return m_exception; }

    private:
        /// @brief The values at x (one evaluation per point); at an invalid point the last valid
        /// ones, with m_valid false.
        const OptimizationValues& values_at(unsigned n, const double* x)
        {
            const Eigen::Map<const VectorXd> xv(x, n);
            if (xv == m_x)
                return m_valid ? m_values : m_last_valid;
            m_x = xv;
            m_valid = false; // until evaluate() returns (it may throw)
            if (m_exception || m_stopped) // NLopt is stopping: no more evaluations
                return m_last_valid;
            m_valid = m_run.evaluate(m_x, m_values);
            if (++m_since_improvement > MAX_WITHOUT_PROGRESS)
                stop(StopReason::LINE_SEARCH_STALLED,
                    "no improvement in " + std::to_string(MAX_WITHOUT_PROGRESS) + " evaluations");
            if (m_run.out_of_time())
                stop(StopReason::TIME_BUDGET,
                    "wall-time budget of " + format_number(m_settings.max_seconds) + " s reached");
            if (!m_valid)
                return m_last_valid;
            m_last_valid = m_values;
            m_f_max = std::max(m_f_max, m_values.f);
            m_f_min = std::min(m_f_min, m_values.f);
            if (!m_stopped)
                check_improvement();
            return m_values;
        }

        /// A new best point is an iteration: the callback and the stopping rules.
        void check_improvement()
        {
            const double violation = m_run.violation(m_x, m_values);
            const bool feasible = violation <= m_settings.constraint_tolerance;
            bool improved = false;
            if (feasible && (!m_has_feasible || m_values.f < m_best_f)) {
                m_has_feasible = true;
                m_best_f = m_values.f;
                improved = true;
            } else if (!feasible && !m_has_feasible && violation < m_best_violation) {
                m_best_violation = violation;
                improved = true;
            }
            if (!improved)
                return;
            m_since_improvement = 0;
            ++m_iterations;
            const double step_norm = (m_x - m_previous_x).lpNorm<Eigen::Infinity>();
            m_previous_x = m_x;
            const double gradient_norm
                = optimizer_detail::projected_gradient_norm(m_x, m_values.gradient, m_run.lower(), m_run.upper());
            if (!m_run.iteration(m_iterations, m_x, m_values, gradient_norm, step_norm))
                return stop(StopReason::USER_STOP,
                    "stopped by the iteration callback at iteration " + std::to_string(m_iterations));
            if (m_settings.max_iterations > 0 && m_iterations >= m_settings.max_iterations)
                return stop(StopReason::ITERATION_BUDGET,
                    "iteration budget of " + std::to_string(m_settings.max_iterations)
                        + " reached (iterations: evaluations that improved the best point)");
            if (!m_constrained) {
                if (gradient_norm == 0 || gradient_norm <= m_settings.gradient_tolerance)
                    return stop(StopReason::GRADIENT_TOLERANCE,
                        "projected gradient inf-norm " + format_number(gradient_norm) + " <= gradient_tolerance "
                            + format_number(m_settings.gradient_tolerance));
                if (gradient_norm <= m_settings.relative_gradient_tolerance * m_gradient_norm0)
                    return stop(StopReason::GRADIENT_TOLERANCE,
                        "projected gradient inf-norm " + format_number(gradient_norm)
                            + " <= relative_gradient_tolerance " + format_number(m_settings.relative_gradient_tolerance)
                            + " x initial " + format_number(m_gradient_norm0));
            }
        }

        void stop(StopReason reason, const std::string& message)
        {
            if (m_stopped)
                return;
            m_stopped = true;
            m_stop_reason = reason;
            m_stop_message = message;
            m_opt.force_stop();
        }

        void fail()
        {
            if (!m_exception)
                m_exception = std::current_exception();
            m_opt.force_stop();
        }

        optimizer_detail::Run& m_run;
        nlopt::opt& m_opt;
        const OptimizerSettings& m_settings;
        bool m_constrained;
        VectorXd m_x; ///< the last point asked for
        bool m_valid; ///< evaluate() succeeded there
        OptimizationValues m_values, m_last_valid;
        double m_f_max, m_f_min; ///< of the valid f seen
        bool m_has_feasible = false;
        double m_best_f = INF, m_best_violation = INF;
        int m_iterations = 0;
        VectorXd m_previous_x; ///< of the last iteration
        double m_gradient_norm0 = 0;
        bool m_called = false;
        int m_repeats = 0; ///< objective calls in a row at m_x, after the first
        int m_since_improvement = 0; ///< evaluations since the last iteration
        bool m_stopped = false;
        StopReason m_stop_reason = StopReason::USER_STOP;
        std::string m_stop_message;
        std::exception_ptr m_exception;
    };

    double objective(unsigned n, const double* x, double* grad, void* data)
    {
        return static_cast<NloptContext*>(data)->objective(n, x, grad);
    }

    void inequalities(unsigned m, double* result, unsigned n, const double* x, double* grad, void* data)
    {
        static_cast<NloptContext*>(data)->constraints(false, m, result, n, x, grad);
    }

    void equalities(unsigned m, double* result, unsigned n, const double* x, double* grad, void* data)
    {
        static_cast<NloptContext*>(data)->constraints(true, m, result, n, x, grad);
    }

    /// The StopReason of a result NLopt ended with by itself.
    StopReason stop_reason(nlopt::result result)
    {
        switch (result) {
        case nlopt::SUCCESS:
            return StopReason::GRADIENT_TOLERANCE;
        case nlopt::STOPVAL_REACHED:
        case nlopt::FTOL_REACHED:
            return StopReason::F_TOLERANCE;
        case nlopt::XTOL_REACHED:
            return StopReason::X_TOLERANCE;
        case nlopt::MAXEVAL_REACHED:
            return StopReason::ITERATION_BUDGET;
        case nlopt::MAXTIME_REACHED:
            return StopReason::TIME_BUDGET;
        case nlopt::ROUNDOFF_LIMITED:
            return StopReason::LINE_SEARCH_STALLED;
        case nlopt::FORCED_STOP:
            return StopReason::USER_STOP;
        default:
            return StopReason::FAILED;
        }
    }

} // namespace

void check_nlopt_options(const OptimizerSettings& settings) { apply_options(settings, nullptr); }

OptimizerResult minimize_nlopt(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0)
{
    const OptimizerSettings& settings = run.settings();
    const std::string name = to_string(settings.algorithm);
    const unsigned n = unsigned(x0.size());
    const int mc = run.problem().inequalities(), mh = run.problem().equalities();

    nlopt::opt opt(nlopt_algorithm(settings.algorithm), n);
    NloptContext context(run, opt, x0, values0);
    if (!run.resumed()
        && !run.iteration(0, x0, values0,
            optimizer_detail::projected_gradient_norm(x0, values0.gradient, run.lower(), run.upper()), 0))
        return run.finish(StopReason::USER_STOP, name + ": stopped by the iteration callback at the initial point", 0);

    opt.set_lower_bounds(std::vector<double>(run.lower().data(), run.lower().data() + n));
    opt.set_upper_bounds(std::vector<double>(run.upper().data(), run.upper().data() + n));
    opt.set_min_objective(objective, &context);
    if (mc > 0)
        opt.add_inequality_mconstraint(
            inequalities, &context, std::vector<double>(size_t(mc), settings.constraint_tolerance));
    if (mh > 0)
        opt.add_equality_mconstraint(
            equalities, &context, std::vector<double>(size_t(mh), settings.constraint_tolerance));
    if (settings.f_tolerance > 0)
        opt.set_ftol_rel(settings.f_tolerance);
    if (settings.x_tolerance > 0)
        opt.set_xtol_abs(settings.x_tolerance);
    if (settings.max_seconds > 0)
        opt.set_maxtime(std::max(run.remaining_seconds(), 1e-3)); // a resumed run: the budget's rest
    apply_options(settings, &opt);

    std::vector<double> x(x0.data(), x0.data() + n);
    double f = 0;
    std::string error;
    try {
        opt.optimize(x, f);
    } catch (const nlopt::forced_stop&) {
    } catch (const nlopt::roundoff_limited&) {
    } catch (const std::bad_alloc&) {
        throw;
    } catch (const std::exception& e) { // NLOPT_FAILURE, NLOPT_INVALID_ARGS
        error = e.what();
    }
    if (context.exception())
        std::rethrow_exception(context.exception());
    const nlopt::result result = opt.last_optimize_result();
    const std::string status = nlopt_result_to_string(nlopt_result(result));
    if (context.stopped())
        return run.finish(context.stop_reason(), name + ": " + context.stop_message() + " (NLOPT_" + status + ")",
            context.iterations());
    std::string message = name + ": NLOPT_" + status;
    if (!error.empty())
        message += " (" + error + ")";
    else if (result == nlopt::MAXEVAL_REACHED)
        message += " (" + std::to_string(opt.get_maxeval()) + " evaluations)";
    return run.finish(stop_reason(result), message, context.iterations());
}

} // namespace diffipc
