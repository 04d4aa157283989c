#include "cli/gradcheck.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/gradient_check.hpp"
#include "shape_opt/reduced_functional.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

namespace diffipc {

int gradcheck(const std::string& problem_path, int directions, const std::string& device,
    std::shared_ptr<CaseDistribution> distribution)
{
    ReducedFunctional rf = ReducedFunctional::load(problem_path, device);
    rf.set_distribution(distribution);
    const auto& settings = rf.check_settings();
    const int count = directions > 0 ? directions : settings.directions;
    // At the design's start: the entries' "initial" design values through their maps (so a
    // problem written by diffipc optimize is checked at its optimum), else the scene's values.
    const VectorXd p0 = rf.parameters_of(rf.design_initial());
    std::printf("%s: %ld parameters (", problem_path.c_str(), long(rf.size()));
    bool first = true;
    for (const auto& [name, size] : rf.layout()) {
        std::printf("%s%s x %ld", first ? "" : ", ", name.c_str(), long(size));
        first = false;
    }
    std::printf(")\n");
    const Evaluation e0 = rf.evaluate(p0, true);
    std::printf("J = %.12e   forward %.3f s, adjoint %.3f s (%.1f%% of the forward)\n", e0.value, e0.forward_time,
        e0.adjoint_time, 100 * e0.adjoint_time / e0.forward_time);
    for (size_t c = 0; c < e0.checkpoints.size(); ++c) {
        const CheckpointStatistics& r = e0.checkpoints[c].records;
        if (e0.checkpoints.size() > 1)
            std::printf("  load case %zu: ", c);
        std::printf("checkpointing: stride %d, peak %d of %d step records held (bound %d, %.1f KiB), %d steps "
                    "recomputed, cost %.2f x the forward; the objective holds %d of %d states (%.1f KiB)\n",
            r.stride, r.peak_stored_states, r.steps, r.bound_stored_states, r.peak_stored_bytes / 1024.0,
            r.recomputed_steps, r.cost_ratio, e0.checkpoints[c].objective_stored_states, r.steps + 1,
            e0.checkpoints[c].objective_stored_bytes / 1024.0);
    }

    // A self-test of the check (docs/problem_format.md): the adjoint's g.dp times (1 + r), so that
    // one can see which error the check catches on a given problem.
    double perturbation = 0;
    if (const char* text = std::getenv("DIFFIPC_GRADCHECK_PERTURB")) {
        char* end = nullptr;
        perturbation = std::strtod(text, &end);
        if (end == text || *end != '\0' || !std::isfinite(perturbation))
            throw InputError("DIFFIPC_GRADCHECK_PERTURB", "expected a number, got '" + std::string(text) + "'");
        std::printf("DIFFIPC_GRADCHECK_PERTURB: the adjoint's dJ.dp is multiplied by 1 + %g\n", perturbation);
    }

    std::mt19937 rng(settings.seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int failed = 0, kinks = 0, inconclusive = 0, not_differentiable = 0;
    for (int k = 0; k < count; ++k) {
        VectorXd dp(rf.size());
        for (Index i = 0; i < dp.size(); ++i)
            dp[i] = u(rng) * rf.scales()[i];
        const double exact = (1 + perturbation) * e0.gradient.dot(dp);
        const auto J = [&](double h) { return rf.evaluate(p0 + h * dp, false).value; };
        const DirectionCheck c = check_direction(J, e0.value, exact, settings.step, settings.halvings);
        std::printf("\ndirection %d: dJ.dp adjoint %.10e, central difference %.10e, relative error %.2e\n", k + 1,
            exact, c.central, c.central_error);
        std::printf("  %-10s %-14s %-6s %-14s %-6s\n", "h", "|J(h)-J(0)|", "rate", "|J(h)-J(0)-h g.dp|", "rate");
        // A rate only where both differences are nonzero (no "nan" or "inf" in the table).
        const auto rate = [](double previous, double now) {
            char text[16] = "-";
            if (previous > 0 && now > 0)
                std::snprintf(text, sizeof text, "%.2f", std::log2(previous / now));
            return std::string(text);
        };
        for (size_t i = 0; i < c.taylor.size(); ++i) {
            const auto& row = c.taylor[i];
            std::printf("  %-10.3e %-14.6e %-6s %-14.6e %-6s\n", row.h, row.first,
                i == 0 ? "" : rate(c.taylor[i - 1].first, row.first).c_str(), row.second,
                i == 0 ? "" : rate(c.taylor[i - 1].second, row.second).c_str());
        }
        if (c.one_sided)
            std::printf("  one-sided differences (Richardson-extrapolated over h, h/2, ...): forward %.10e "
                        "(relative error %.2e), backward %.10e (relative error %.2e)\n",
                c.forward, c.forward_error, c.backward, c.backward_error);
        switch (c.verdict) {
        case DirectionVerdict::PASS:
            std::printf(
                "  PASS (relative error < 1e-5 and second-order rate >= 1.9 above the solver floor %.1e)\n", c.floor);
            break;
        case DirectionVerdict::PASS_AT_KINK:
            ++kinks;
            std::printf("  PASS at a kink: J'' jumps at p along this direction (an exterior penalty at its bound, "
                        "a contact or constraint switching on), so the central difference, which straddles it, is "
                        "off by O(h); both one-sided differences agree with the adjoint (relative error < 1e-5) and "
                        "the second-order rate is >= 1.9 above the solver floor %.1e\n",
                c.floor);
            break;
        case DirectionVerdict::NOT_DIFFERENTIABLE:
            ++not_differentiable;
            std::printf("  NOT DIFFERENTIABLE: J has a kink at p along this direction (its one-sided slopes differ "
                        "by more than %.0e relative), so J has no gradient there to check; check at another p\n",
                KINK_SLOPE_GAP);
            break;
        case DirectionVerdict::INCONCLUSIVE:
            ++inconclusive;
            std::printf("  INCONCLUSIVE: J does not change along this direction above the solver floor %.1e; "
                        "choose parameters that the objective depends on\n",
                c.floor);
            break;
        case DirectionVerdict::FAIL:
            ++failed;
            std::printf("  FAIL (needs: relative error < 1e-5, of the central difference or of both one-sided "
                        "ones, and second-order rate >= 1.9 above the solver floor %.1e)\n",
                c.floor);
            break;
        }
    }
    if (failed)
        std::printf("\ngradcheck FAILED (%d of %d directions)\n", failed, count);
    else if (not_differentiable)
        std::printf("\ngradcheck CANNOT CHECK: J is not differentiable at p along %d of %d directions\n",
            not_differentiable, count);
    else if (inconclusive)
        std::printf("\ngradcheck INCONCLUSIVE (no direction changed J: nothing was checked there)\n");
    else if (kinks)
        std::printf("\ngradcheck passed (%d of %d directions at a kink of J'', checked by one-sided differences)\n",
            kinks, count);
    else
        std::printf("\ngradcheck passed\n");
    return failed + not_differentiable + inconclusive == 0 ? 0 : 4;
}

} // namespace diffipc
