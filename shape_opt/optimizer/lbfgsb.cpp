#include "shape_opt/optimizer/lbfgsb.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace diffipc {

namespace {

    constexpr double ARMIJO = 1e-4; ///< sufficient-decrease constant c1
    constexpr double CURVATURE_EPS = 1e-10; ///< a pair is kept when s.y > eps |s| |y|
    constexpr double VALID_FRACTION = 0.99; ///< of max_valid_step taken
    constexpr double ACTIVE_WIDTH = 1e-6; ///< relative distance to a bound that counts as "at" it
    constexpr int MAX_TRIALS = 40; ///< trial steps of one line search without progress

    /// @brief The search direction: -H g on the free variables by the two-loop recursion over
    /// the pairs restricted to them, -gamma g on the active ones that can still move, 0 on those
    /// held by a bound.
    /// @param free    n: 1 for a free variable, 0 for an active one
    /// @param held    n: 1 where the variable sits on the bound its gradient pushes it through
    VectorXd search_direction(
        const std::vector<CorrectionPair>& pairs, const VectorXd& gradient, const VectorXd& free, const VectorXd& held)
    {
        const size_t m = pairs.size();
        std::vector<VectorXd> s(m), y(m);
        std::vector<double> rho(m, 0.0), alpha(m, 0.0);
        double gamma = 1;
        bool scaled = false;
        VectorXd q = free.cwiseProduct(gradient);
        for (size_t i = m; i-- > 0;) {
            s[i] = free.cwiseProduct(pairs[i].s);
            y[i] = free.cwiseProduct(pairs[i].y);
            const double sy = s[i].dot(y[i]);
            if (!(sy > CURVATURE_EPS * s[i].norm() * y[i].norm()))
                continue; // no positive curvature on the free variables: this pair would break H > 0
            rho[i] = 1 / sy;
            if (!scaled) {
                // Nocedal & Wright eq. (7.20): H_0 = gamma I from the newest pair.
                gamma = sy / y[i].squaredNorm();
                scaled = true;
            }
            alpha[i] = rho[i] * s[i].dot(q);
            q -= alpha[i] * y[i];
        }
        q *= gamma;
        for (size_t i = 0; i < m; ++i) {
            if (rho[i] == 0)
                continue;
            const double beta = rho[i] * y[i].dot(q);
            q += (alpha[i] - beta) * s[i];
        }
        VectorXd d = -q;
        for (Index i = 0; i < d.size(); ++i)
            if (free[i] == 0)
                d[i] = held[i] != 0 ? 0.0 : -gamma * gradient[i];
        return d;
    }

} // namespace

OptimizerResult minimize_lbfgsb(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0)
{
    using optimizer_detail::projected_gradient_norm;
    const OptimizerSettings& settings = run.settings();
    const VectorXd& lower = run.lower();
    const VectorXd& upper = run.upper();
    const Index n = x0.size();
    const auto project = [&](const VectorXd& y) -> VectorXd { return y.cwiseMax(lower).cwiseMin(upper); };
    const std::string name = to_string(settings.algorithm);

    VectorXd x = x0;
    OptimizationValues values = values0;
    double gradient_norm = projected_gradient_norm(x, values.gradient, lower, upper);
    const double gradient_norm0 = run.initial_gradient_norm();
    const OptimizerCheckpoint* resumed = run.resumed();
    int k = run.first_iteration();
    std::vector<CorrectionPair> pairs; // oldest first
    if (resumed) {
        pairs = resumed->lbfgs_pairs;
        if (int(pairs.size()) > settings.lbfgs_memory) // a smaller memory than the first run's
            pairs.erase(pairs.begin(), pairs.end() - settings.lbfgs_memory);
    }

    if (!resumed && !run.iteration(0, x, values, gradient_norm, 0, &pairs))
        return run.finish(StopReason::USER_STOP, name + ": stopped by the iteration callback at the initial point", 0);
    const auto gradient_converged = [&]() -> std::string {
        if (gradient_norm == 0 || gradient_norm <= settings.gradient_tolerance)
            return name + ": projected gradient inf-norm " + format_number(gradient_norm) + " <= gradient_tolerance "
                + format_number(settings.gradient_tolerance);
        if (gradient_norm <= settings.relative_gradient_tolerance * gradient_norm0)
            return name + ": projected gradient inf-norm " + format_number(gradient_norm)
                + " <= relative_gradient_tolerance " + format_number(settings.relative_gradient_tolerance)
                + " x initial " + format_number(gradient_norm0);
        return "";
    };
    // The checks after an iteration's callback; f_previous is NaN at iteration 0 (no f check).
    const auto converged = [&](double step_norm, double f_previous) -> std::pair<StopReason, std::string> {
        if (std::string message = gradient_converged(); !message.empty())
            return { StopReason::GRADIENT_TOLERANCE, message };
        if (k > 0 && settings.x_tolerance > 0 && step_norm <= settings.x_tolerance)
            return { StopReason::X_TOLERANCE,
                name + ": step inf-norm " + format_number(step_norm) + " <= x_tolerance "
                    + format_number(settings.x_tolerance) };
        if (k > 0 && settings.f_tolerance > 0
            && optimizer_detail::relative_change(f_previous, values.f) <= settings.f_tolerance)
            return { StopReason::F_TOLERANCE,
                name + ": relative change of f "
                    + format_number(optimizer_detail::relative_change(f_previous, values.f)) + " <= f_tolerance "
                    + format_number(settings.f_tolerance) };
        return { StopReason::USER_STOP, "" };
    };
    // A resumed run repeats the checks that followed its last iteration (a run stopped by its
    // callback there did not make them).
    if (const auto [reason, message]
        = resumed ? converged(resumed->step_norm, resumed->previous_f) : converged(0, std::nan(""));
        !message.empty())
        return run.finish(reason, message, k);

    VectorXd free(n), held(n), trial_x, dx;
    OptimizationValues trial;
    while (true) {
        if (settings.max_iterations > 0 && k >= settings.max_iterations)
            return run.finish(StopReason::ITERATION_BUDGET,
                name + ": iteration budget of " + std::to_string(settings.max_iterations) + " reached", k);
        if (run.out_of_time())
            return run.finish(StopReason::TIME_BUDGET,
                name + ": wall-time budget of " + format_number(settings.max_seconds) + " s reached", k);

        // Active set (Bertsekas' epsilon-active set, epsilon <= the projected step's size so that
        // it shrinks to "at the bound" near a solution).
        const double w = (x - project(x - values.gradient)).lpNorm<Eigen::Infinity>();
        for (Index i = 0; i < n; ++i) {
            const double g = values.gradient[i];
            const double width_lo = std::min(w, ACTIVE_WIDTH * std::max(1.0, std::abs(lower[i])));
            const double width_hi = std::min(w, ACTIVE_WIDTH * std::max(1.0, std::abs(upper[i])));
            const bool at_lower = g > 0 && x[i] - lower[i] <= width_lo;
            const bool at_upper = g < 0 && upper[i] - x[i] <= width_hi;
            free[i] = at_lower || at_upper ? 0.0 : 1.0;
            held[i] = (g > 0 && x[i] <= lower[i]) || (g < 0 && x[i] >= upper[i]) ? 1.0 : 0.0;
        }

        bool accepted = false;
        std::string stall;
        for (int attempt = 0; attempt < 2 && !accepted; ++attempt) {
            if (attempt == 1) {
                if (pairs.empty())
                    break; // steepest descent was tried already
                pairs.clear();
            }
            VectorXd d = search_direction(pairs, values.gradient, free, held);
            if (!(values.gradient.dot(d) < 0)) {
                pairs.clear(); // the model lost positive definiteness on the free set (round-off)
                d = search_direction(pairs, values.gradient, free, held);
            }
            const double d_norm = d.lpNorm<Eigen::Infinity>();
            if (!(d_norm > 0) || !std::isfinite(d_norm)) {
                stall = "no descent direction";
                break;
            }
            // Without curvature information the first trial moves 1 in the inf-norm (as
            // L-BFGS-B's first step of unit length): a gradient of 3e-5 in log-modulus units
            // otherwise gives steps of 3e-5 whose curvature is below the gradient's noise, and
            // the run creeps along the gradient without ever forming a pair.
            double t = pairs.empty() ? 1.0 / d_norm : 1.0;
            for (int trials = 0; trials < MAX_TRIALS; ++trials) {
                if (run.out_of_time())
                    return run.finish(StopReason::TIME_BUDGET,
                        name + ": wall-time budget of " + format_number(settings.max_seconds) + " s reached", k);
                trial_x = project(x + t * d);
                dx = trial_x - x;
                if (!dx.allFinite()) {
                    t *= 0.5;
                    continue;
                }
                const double slope = values.gradient.dot(dx);
                if (dx.lpNorm<Eigen::Infinity>() == 0 || !(slope < 0)) {
                    stall = "the projected step is " + std::string(slope < 0 ? "zero" : "no descent step");
                    break;
                }
                const double tau = run.max_valid_step(x, dx);
                if (tau < 1) {
                    t *= tau > 0 ? VALID_FRACTION * tau : 0.5;
                    stall = "max_valid_step() cut the step to " + format_number(tau);
                    continue;
                }
                if (!run.evaluate(trial_x, trial)) {
                    t *= 0.5;
                    stall = "evaluate() failed at the trial points";
                    continue;
                }
                if (trial.f <= values.f + ARMIJO * slope) {
                    accepted = true;
                    break;
                }
                // Safeguarded minimizer of the quadratic through f, the slope and f(x_t) (halving at most).
                const double curvature = trial.f - values.f - slope;
                const double s = curvature > 0 ? -slope / (2 * curvature) : 0.5;
                t *= std::clamp(s, 0.1, 0.5);
                stall = "no sufficient decrease (f = " + format_number(trial.f) + " at the last trial, "
                    + format_number(values.f) + " at x)";
            }
        }
        if (!accepted)
            return run.finish(StopReason::LINE_SEARCH_STALLED,
                name + ": line search stalled after " + std::to_string(MAX_TRIALS) + " trial steps without progress ("
                    + stall + ")",
                k);

        VectorXd y = trial.gradient - values.gradient;
        if (dx.dot(y) > CURVATURE_EPS * dx.norm() * y.norm()) {
            pairs.push_back({ dx, std::move(y) });
            if (int(pairs.size()) > settings.lbfgs_memory)
                pairs.erase(pairs.begin());
        }
        const double f_previous = values.f;
        x = trial_x;
        std::swap(values, trial);
        ++k;
        gradient_norm = projected_gradient_norm(x, values.gradient, lower, upper);
        const double step_norm = dx.lpNorm<Eigen::Infinity>();

        if (!run.iteration(k, x, values, gradient_norm, step_norm, &pairs))
            return run.finish(StopReason::USER_STOP,
                name + ": stopped by the iteration callback at iteration " + std::to_string(k), k);
        if (const auto [reason, message] = converged(step_norm, f_previous); !message.empty())
            return run.finish(reason, message, k);
    }
}

} // namespace diffipc
