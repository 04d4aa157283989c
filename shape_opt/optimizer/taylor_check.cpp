#include "shape_opt/optimizer/taylor_check.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace diffipc {

TaylorCheck final_taylor_check(OptimizationProblem& problem, const VectorXd& x, const OptimizationValues& values,
    const VectorXd& lower, const VectorXd& upper, const TaylorCheckSettings& settings)
{
    if (!(settings.step > 0) || !std::isfinite(settings.step))
        throw InputError("optimizer.final_taylor_check.step", format_number(settings.step) + " must be a number > 0");
    if (settings.halvings < 1)
        throw InputError("optimizer.final_taylor_check.halvings",
            std::to_string(settings.halvings) + " must be at least 1 (a rate needs two steps)");
    const Index n = x.size();
    TaylorCheck check;
    std::mt19937 rng(settings.seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    check.direction.resize(n);
    for (Index i = 0; i < n; ++i) {
        const double lo = lower.size() ? lower[i] : -INFINITY, hi = upper.size() ? upper[i] : INFINITY;
        const double scale = std::isfinite(lo) && std::isfinite(hi) ? hi - lo : std::max(std::abs(x[i]), 1.0);
        double d = u(rng) * scale;
        // Every point of the test inside the box: a design outside it may not be valid.
        const auto inside
            = [&](double di) { return x[i] + settings.step * di >= lo && x[i] + settings.step * di <= hi; };
        if (!inside(d))
            d = inside(-d) ? -d : 0.0;
        check.direction[i] = d;
    }
    const double f0 = values.f;
    check.slope = values.gradient.dot(check.direction);
    check.floor = TAYLOR_FLOOR * std::max(std::abs(f0), 1e-300);
    const double resolved = 100 * check.floor;
    double h = settings.step;
    for (int k = 0; k <= settings.halvings; ++k, h /= 2) {
        OptimizationValues v;
        const bool ok = problem.evaluate(x + h * check.direction, v) && std::isfinite(v.f);
        ++check.evaluations;
        check.steps.push_back(h);
        if (!ok) {
            ++check.rejected;
            check.changes.push_back(NAN);
            check.remainders.push_back(NAN);
        } else {
            check.changes.push_back(std::abs(v.f - f0));
            check.remainders.push_back(std::abs(v.f - f0 - h * check.slope));
        }
        if (k > 0) {
            const double before = check.remainders[size_t(k) - 1], now = check.remainders[size_t(k)];
            check.rates.push_back(before > resolved && now > resolved ? std::log2(before / now) : NAN);
        }
    }

    // The verdict from the rates at the smallest steps that resolve one, as a user reads the table.
    double largest_change = 0, last_rate = NAN, fastest = -INFINITY;
    int valid = 0;
    for (size_t k = 0; k < check.steps.size(); ++k)
        if (std::isfinite(check.changes[k])) {
            ++valid;
            largest_change = std::max(largest_change, check.changes[k]);
        }
    for (double r : check.rates)
        if (std::isfinite(r)) {
            last_rate = r;
            fastest = std::max(fastest, r);
        }
    const bool any_remainder_resolved = std::any_of(
        check.remainders.begin(), check.remainders.end(), [&](double r) { return std::isfinite(r) && r > resolved; });
    if (valid < 2) {
        check.verdict = "inconclusive";
        check.reason = std::to_string(check.rejected) + " of " + std::to_string(check.evaluations)
            + " points were rejected (invalid designs): lower final_taylor_check.step";
    } else if (!(largest_change > check.floor)) {
        check.verdict = "inconclusive";
        check.reason = "f does not change along the direction above the round-off floor " + format_number(check.floor);
    } else if (!any_remainder_resolved) {
        check.verdict = "smooth";
        check.reason = "the first-order model is exact to within 100 x the round-off floor at every step";
    } else if (fastest > TAYLOR_CROSSING_RATE) {
        check.verdict = "non_smooth";
        check.reason = "the remainder falls by 2^" + format_number(fastest)
            + " in one halving: the larger step crosses a jump or kink of f";
    } else if (!std::isfinite(last_rate)) {
        check.verdict = "inconclusive";
        check.reason = "no two consecutive remainders above 100 x the round-off floor (" + format_number(check.floor)
            + "): raise final_taylor_check.step";
    } else if (last_rate >= TAYLOR_SMOOTH_RATE) {
        check.verdict = "smooth";
        check.reason = "the remainder falls like h^" + format_number(last_rate) + " (2 where f is smooth)";
    } else if (last_rate <= TAYLOR_NONSMOOTH_RATE) {
        check.verdict = "non_smooth";
        check.reason = "the remainder falls like h^" + format_number(last_rate)
            + " (2 where f is smooth, 1 at a kink, 0 across a jump): the gradient does not describe f here";
    } else {
        check.verdict = "inconclusive";
        check.reason = "the remainder falls like h^" + format_number(last_rate) + ", between a kink's 1 and 2";
    }
    return check;
}

} // namespace diffipc
