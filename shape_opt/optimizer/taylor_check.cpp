#include "shape_opt/optimizer/taylor_check.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace diffipc {

namespace {

    /// Where a rate of R(h) - 4 R(h/2) points: 1 smooth, -1 a kink or jump, 0 between.
    int rate_class(double rate) { return rate >= TAYLOR_SMOOTH_RATE ? 1 : (rate <= TAYLOR_NONSMOOTH_RATE ? -1 : 0); }

    /// @brief The verdict from the signed remainders (TaylorCheck's fields other than verdict
    /// and reason).
    /// @return true where the rate at the smallest steps is out of line with the one before it:
    ///         a further halving can tell which of the two holds
    bool judge(TaylorCheck& check, double largest_change, int valid)
    {
        const double resolved = 100 * check.floor;
        const std::vector<double>& R = check.remainders;
        const size_t m = R.size();
        const auto is_resolved = [&](size_t k) { return std::isfinite(R[k]) && std::abs(R[k]) > resolved; };
        // R(h) - 4 R(h/2) for steps k, k + 1 (NaN where either point was rejected).
        const auto settle = [&](size_t k) { return R[k] - 4 * R[k + 1]; };

        if (check.stopped) {
            check.verdict = "inconclusive";
            check.reason = "stopped by a signal after " + std::to_string(check.evaluations) + " evaluations";
            return false;
        }
        if (valid < 3) {
            check.verdict = "inconclusive";
            check.reason = std::to_string(check.rejected) + " of " + std::to_string(check.evaluations)
                + " points were rejected (invalid designs): lower final_taylor_check.step";
            return false;
        }
        if (!(largest_change > check.floor)) {
            check.verdict = "inconclusive";
            check.reason = "f does not change along the direction above the round-off floor";
            return false;
        }
        // A larger step that crossed a jump or kink: its R(h) - 4 R(h/2) far above the next one's
        // (floored at the resolution: below it, R/h^2 has settled), wherever the smaller steps are.
        for (size_t k = 0; k + 2 < m; ++k) {
            const double a = settle(k), b = settle(k + 1);
            if (std::isfinite(a) && std::isfinite(b) && std::abs(a) > resolved
                && std::log2(std::abs(a) / std::max(std::abs(b), resolved)) > TAYLOR_CROSSING_RATE) {
                check.verdict = "non_smooth";
                check.reason = "R/h^2 changes from h = " + format_number(check.steps[k]) + " to h/2 by 2^"
                    + format_number(std::log2(std::abs(a) / std::max(std::abs(b), resolved)) - 2)
                    + " times more than from h/2 to h/4 (2 where f is smooth): the larger step crosses a jump or "
                      "kink of f";
                return false;
            }
        }
        // The smallest three consecutive steps with resolved remainders: two resolved rates.
        size_t window = m;
        for (size_t k = 0; k + 2 < m; ++k)
            if (is_resolved(k) && is_resolved(k + 1) && is_resolved(k + 2))
                window = k;
        if (window == m) {
            const bool any = std::any_of(R.begin(), R.end(), [&](double r) { return std::abs(r) > resolved; });
            check.verdict = "inconclusive";
            check.reason = any
                ? "fewer than three consecutive remainders above 100 x the round-off floor: raise "
                  "final_taylor_check.step"
                : "the first-order model is exact to within 100 x the round-off floor at every step: raise "
                  "final_taylor_check.step";
            return false;
        }
        const double a = settle(window), b = settle(window + 1);
        if (!(std::abs(b) > resolved)) {
            check.verdict = "smooth";
            check.reason = "R/h^2 settles (R(h) - 4 R(h/2) within 100 x the round-off floor at the smallest steps)";
            return false;
        }
        const double rate = std::log2(std::abs(a) / std::abs(b));
        const std::string falls = "R(h) - 4 R(h/2) falls like h^" + format_number(rate)
            + " at the smallest steps (3 where f is smooth, 1 at a kink, 0 across a jump)";
        // The rate one step larger, where resolved: a rate that disagrees with it is not yet the
        // asymptotic one (a smooth f whose h^3 and h^4 terms cancel at one step reads as a kink).
        const double before
            = window > 0 && is_resolved(window - 1) ? std::log2(std::abs(settle(window - 1)) / std::abs(a)) : NAN;
        const bool out_of_line = std::isfinite(before) && std::abs(settle(window - 1)) > resolved
            && std::abs(a) > resolved && rate_class(before) != rate_class(rate);
        if (out_of_line) {
            check.verdict = "inconclusive";
            check.reason = falls + ", out of line with h^" + format_number(before)
                + " one step larger: raise final_taylor_check.halvings";
        } else if (rate >= TAYLOR_SMOOTH_RATE) {
            check.verdict = "smooth";
            check.reason = falls + ": R/h^2 settles";
        } else if (rate <= TAYLOR_NONSMOOTH_RATE) {
            check.verdict = "non_smooth";
            check.reason = falls + ": the gradient does not describe f here";
        } else {
            check.verdict = "inconclusive";
            check.reason = falls + ": between a kink and smooth";
        }
        return out_of_line;
    }

} // namespace

TaylorCheck final_taylor_check(OptimizationProblem& problem, const VectorXd& x, const OptimizationValues& values,
    const VectorXd& lower, const VectorXd& upper, const VectorXd& scales, const TaylorCheckSettings& settings,
    const std::function<bool()>& stop)
{
    if (!(settings.step > 0) || !std::isfinite(settings.step))
        throw InputError("optimizer.final_taylor_check.step", format_number(settings.step) + " must be a number > 0");
    if (settings.halvings < 2)
        throw InputError("optimizer.final_taylor_check.halvings",
            std::to_string(settings.halvings) + " must be at least 2 (a verdict needs three steps)");
    const Index n = x.size();
    if (scales.size() != n || !(scales.array() >= 0).all() || !scales.allFinite())
        throw std::invalid_argument("final_taylor_check: " + std::to_string(n) + " scales >= 0 expected");
    TaylorCheck check;
    std::mt19937 rng(settings.seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    check.direction.resize(n);
    for (Index i = 0; i < n; ++i) {
        const double lo = lower.size() ? lower[i] : -INFINITY, hi = upper.size() ? upper[i] : INFINITY;
        double d = u(rng) * scales[i];
        // Every point of the test inside the box: a design outside it may not be valid.
        const auto inside
            = [&](double di) { return x[i] + settings.step * di >= lo && x[i] + settings.step * di <= hi; };
        if (!inside(d))
            d = inside(-d) ? -d : 0.0;
        check.direction[i] = d;
    }
    double h = settings.step;
    // Inside the valid designs too (a rest mesh that does not invert), as the optimizers' steps.
    const double valid_step = problem.max_valid_step(x, h * check.direction);
    if (!(valid_step >= 1))
        h *= valid_step > 0 ? TAYLOR_VALID_FRACTION * valid_step : 0.0; // NaN: no valid step
    const double f0 = values.f;
    check.slope = values.gradient.dot(check.direction);
    check.floor = TAYLOR_FLOOR * std::max(std::abs(f0), 1e-300);
    const double resolved = 100 * check.floor;
    double largest_change = 0;
    int valid = 0;
    const auto evaluate_at = [&](double step) {
        const size_t k = check.steps.size();
        OptimizationValues v;
        const bool ok = step > 0 && problem.evaluate(x + step * check.direction, v) && std::isfinite(v.f);
        ++check.evaluations;
        check.steps.push_back(step);
        if (!ok) {
            ++check.rejected;
            check.changes.push_back(NAN);
            check.remainders.push_back(NAN);
        } else {
            ++valid;
            check.changes.push_back(std::abs(v.f - f0));
            check.remainders.push_back(v.f - f0 - step * check.slope);
            largest_change = std::max(largest_change, check.changes.back());
        }
        const std::vector<double>& R = check.remainders;
        if (k > 0) {
            const double before = std::abs(R[k - 1]), now = std::abs(R[k]);
            check.rates.push_back(before > resolved && now > resolved ? std::log2(before / now) : NAN);
        }
        if (k > 1) {
            const double a = std::abs(R[k - 2] - 4 * R[k - 1]), b = std::abs(R[k - 1] - 4 * R[k]);
            check.settle_rates.push_back(a > resolved && b > resolved ? std::log2(a / b) : NAN);
        }
    };
    for (int k = 0; k <= settings.halvings; ++k, h /= 2) {
        if (stop && stop()) {
            check.stopped = true;
            break;
        }
        evaluate_at(h);
    }
    // A rate out of line with the one before: halve further before a verdict.
    for (int extra = 0; judge(check, largest_change, valid) && extra < TAYLOR_EXTRA_HALVINGS; ++extra, h /= 2) {
        if (stop && stop()) {
            check.stopped = true;
            judge(check, largest_change, valid);
            break;
        }
        evaluate_at(h);
    }
    return check;
}

} // namespace diffipc
