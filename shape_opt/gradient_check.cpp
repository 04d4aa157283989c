#include "shape_opt/gradient_check.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace diffipc {

namespace {
    /// Relative to the larger of the two, so that it stays finite (at most 2) when one is 0.
    double relative_error(double a, double b)
    {
        return std::abs(a - b) / std::max({ std::abs(a), std::abs(b), 1e-300 });
    }
} // namespace

const char* verdict_name(DirectionVerdict verdict)
{
    switch (verdict) {
    case DirectionVerdict::PASS:
        return "PASS";
    case DirectionVerdict::PASS_AT_KINK:
        return "PASS (kink)";
    case DirectionVerdict::FAIL:
        return "FAIL";
    case DirectionVerdict::NOT_DIFFERENTIABLE:
        return "NOT DIFFERENTIABLE";
    case DirectionVerdict::INCONCLUSIVE:
        return "INCONCLUSIVE";
    }
    return "?";
}

double richardson_one_sided(const std::vector<double>& quotients)
{
    const size_t n = quotients.size();
    if (n < 3)
        throw std::logic_error("richardson_one_sided: at least three quotients");
    // Level 1 removes the h term (steps halve: 2 D(h/2) - D(h)), level 2 the h^2 term.
    std::vector<double> first(n, 0.0);
    for (size_t i = 1; i < n; ++i)
        first[i] = 2 * quotients[i] - quotients[i - 1];
    double best = 0, best_change = std::numeric_limits<double>::infinity();
    for (size_t i = 2; i < n; ++i) {
        const double second = (4 * first[i] - first[i - 1]) / 3;
        const double change = std::abs(second - first[i]);
        if (change < best_change) {
            best_change = change;
            best = second;
        }
    }
    return best;
}

DirectionCheck check_direction(
    const std::function<double(double)>& j, double j0, double slope, double step, int halvings)
{
    std::map<double, double> known;
    const auto J = [&](double h) {
        const auto it = known.find(h);
        if (it != known.end())
            return it->second;
        const double v = j(h);
        known.emplace(h, v);
        return v;
    };
    DirectionCheck r;
    r.slope = slope;
    r.central = (8 * (J(step) - J(-step)) - (J(2 * step) - J(-2 * step))) / (12 * step);
    r.central_error = relative_error(slope, r.central);
    r.floor = 1e-10 * std::abs(j0);

    double max_change = 0, previous = 0;
    double h = step;
    for (int i = 0; i <= halvings; ++i, h /= 2) {
        const double dj = J(h) - j0;
        const DirectionCheck::TaylorRow row { h, std::abs(dj), std::abs(dj - h * slope) };
        r.taylor.push_back(row);
        max_change = std::max(max_change, row.first);
        if (row.second > r.floor) {
            if (i > 0 && previous > r.floor)
                r.last_rate = std::log2(previous / row.second);
            ++r.resolved;
        }
        previous = row.second;
    }
    if (!(max_change > r.floor)) {
        // j did not move along dp: a zero gradient "matches", but nothing was checked.
        r.verdict = DirectionVerdict::INCONCLUSIVE;
        return r;
    }
    // With fewer than three remainders above the floor there is no rate to read: then the
    // difference must match to near the floor.
    const auto rate_ok = [&](double error) { return r.resolved < 3 ? error < 1e-8 : r.last_rate >= 1.9; };
    if (r.central_error < GRADIENT_CHECK_TOLERANCE && rate_ok(r.central_error)) {
        r.verdict = DirectionVerdict::PASS;
        return r;
    }

    r.one_sided = true;
    const int levels = std::max(halvings, 2);
    for (const double side : { 1.0, -1.0 }) {
        std::vector<double> quotients;
        double s = step;
        for (int i = 0; i <= levels; ++i, s /= 2)
            quotients.push_back((J(side * s) - j0) / (side * s));
        (side > 0 ? r.forward : r.backward) = richardson_one_sided(quotients);
    }
    r.forward_error = relative_error(slope, r.forward);
    r.backward_error = relative_error(slope, r.backward);
    const double worst = std::max(r.forward_error, r.backward_error);
    if (worst < GRADIENT_CHECK_TOLERANCE && rate_ok(worst))
        r.verdict = DirectionVerdict::PASS_AT_KINK;
    else if (relative_error(r.forward, r.backward) > KINK_SLOPE_GAP)
        r.verdict = DirectionVerdict::NOT_DIFFERENTIABLE;
    else
        r.verdict = DirectionVerdict::FAIL;
    return r;
}

} // namespace diffipc
