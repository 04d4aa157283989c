#include "forward/solver/newton.hpp"

#include "forward/common/timer.hpp"

#include <cmath>
#include <limits>

namespace diffipc {

namespace {
    constexpr double ROUNDOFF_STEP = 128 * std::numeric_limits<double>::epsilon();
    constexpr double ENERGY_RESOLUTION = 1e-10;
    /// A full step whose energy decrease is above this fraction of the linear prediction -g^T p
    /// (0.5 when the search matrix is the exact curvature along p) is extended.
    constexpr double EXTENSION_RATIO = 0.9;
    constexpr int MAX_EXTENSIONS = 12; ///< doublings: steps up to 4096 p
} // namespace

double NewtonSolver::extend(const VectorXd& x, const VectorXd& p, double slope, double length, double energy,
    double& new_energy, VectorXd& trial, VectorXd& longer, NewtonResult& result) const
{
    // The full step took nearly the whole decrease the gradient predicts: along p the energy is
    // far less curved than the search matrix says (a projected Hessian where the true one is
    // indefinite or nearly singular: a structure at a bifurcation creeping along its buckling
    // mode, one short step per iteration). Doubling the step while the energy keeps falling
    // (Armijo against the start) and CCD and the inversion bound admit the longer step walks
    // that mode in a few trials instead of hundreds of iterations.
    double alpha = 1.0;
    for (int k = 0; k < MAX_EXTENSIONS; ++k) {
        const double a = 2 * alpha;
        if (m_settings.max_displacement > 0 && a * length > m_settings.max_displacement)
            break;
        longer = a * p;
        if (m_problem.max_step(x, longer) < 1.0)
            break;
        longer += x;
        const double e = m_problem.energy(longer);
        if (!(e < new_energy) || e > energy + m_settings.armijo * a * slope)
            break;
        alpha = a;
        new_energy = e;
        trial.swap(longer);
    }
    result.extended_steps += alpha > 1.0;
    return alpha;
}

NewtonResult NewtonSolver::solve(VectorXd& x, const VectorXd& target, const std::vector<char>& constrained,
    double force_scale, double step_scale, LoadControl* control) const
{
    NewtonResult result;
    const Index n = x.size();
    // Work vectors allocated once per solve, reused by every iteration and trial.
    VectorXd g(n), p(n), rhs(n), pD(n), trial(n), g_trial(n), longer(n);
    const double a_norm2 = control ? control->direction.squaredNorm() : 0.0;
    // max |free-dof gradient|, less the load the constraint carries under load control
    const auto free_residual = [&](const VectorXd& gradient) {
        const double carried = control ? control->direction.dot(gradient) / a_norm2 : 0.0;
        double largest = 0;
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                largest = std::max(
                    largest, std::abs(control ? gradient[i] - carried * control->direction[i] : gradient[i]));
        return largest;
    };
    bool full_step_taken = false;
    int true_hessian_pause = 0;

    double energy;
    {
        Timer t;
        energy = m_problem.energy(x);
        t.add_to(result.times.line_search);
    }
    if (!std::isfinite(energy)) {
        result.status = StepStatus::INVALID_INITIAL_STATE;
        return result;
    }
    // Round-off of energy differences scales with the terms, not with their
    // (possibly cancelling) sum.
    const double magnitude = m_problem.energy_magnitude(x);

    for (int it = 0;; ++it) {
        {
            Timer t;
            m_problem.gradient(x, g);
            t.add_to(result.times.assembly);
        }
        if (!g.allFinite()) {
            result.status = StepStatus::NON_FINITE;
            return result;
        }
        // Under load control the multiplier's share lambda a of the gradient is the load the
        // constraint carries, not a residual.
        double gap = 0;
        if (control) {
            control->multiplier = control->direction.dot(g) / a_norm2;
            gap = control->level - control->direction.dot(x);
        }
        double dmax = 0;
        for (Index i = 0; i < n; ++i) {
            if (constrained[size_t(i)]) {
                pD[i] = target[i] - x[i];
                dmax = std::max(dmax, std::abs(pD[i]));
            } else {
                pD[i] = 0;
            }
        }
        const double gmax = free_residual(g);
        const bool lifting = dmax > 0 || (control && std::abs(gap) > control->tolerance);
        result.residual = gmax / force_scale;
        if (!std::isfinite(result.residual)) {
            // A force scale that underflowed or overflowed: no residual can be judged.
            result.status = StepStatus::NON_FINITE;
            return result;
        }
        if (!lifting && result.residual <= m_settings.residual_tolerance
            && (m_settings.step_tolerance <= 0 || it == 0 || result.newton_step <= m_settings.step_tolerance)) {
            result.status = StepStatus::CONVERGED;
            return result;
        }
        if (it >= m_settings.max_iterations) {
            result.status = StepStatus::NEWTON_EXHAUSTED;
            return result;
        }

        // Projected Newton converges linearly where elements are strongly
        // compressed; once a full step has been accepted, try the true Hessian
        // and keep it if Cholesky proves it positive definite.
        const bool try_true = m_settings.adaptive_projection && full_step_taken && !lifting && m_linear.cholesky_first()
            && true_hessian_pause == 0;
        if (true_hessian_pause > 0)
            --true_hessian_pause;
        bool factorized = false;
        bool indefinite = false; // the true Hessian, factorized by LDL^T (load control only)
        for (int attempt = try_true ? 0 : 1; attempt < 2 && !factorized; ++attempt) {
            const bool project = attempt == 1;
            {
                Timer t;
                m_problem.hessian(x, project, m_assembler);
                rhs = -g;
                if (lifting) {
                    // Free rows see the coupling to the prescribed motion: -(g_F + H_FD p_D).
                    const VectorXd coupling = m_assembler.matrix().selfadjointView<Eigen::Lower>() * pD;
                    rhs -= coupling;
                }
                for (Index i = 0; i < n; ++i)
                    if (constrained[size_t(i)])
                        rhs[i] = pD[i];
                m_assembler.apply_constraints(constrained);
                t.add_to(result.times.assembly);
            }
            Timer t;
            const double analysis_before = m_linear.analysis_time();
            const int analyses_before = m_linear.analyses();
            // Under load control the true Hessian may be indefinite on a path past a limit point
            // while the constrained problem is convex on the constraint surface: LDL^T is tried,
            // and the step is kept if it descends (below).
            const bool ok = m_linear.factorize(m_assembler.matrix(), /*allow_fallback=*/project || control);
            t.add_to(result.times.factorization);
            result.times.analysis += m_linear.analysis_time() - analysis_before;
            result.times.analyses += m_linear.analyses() - analyses_before;
            if (!project) {
                // An indefinite true Hessian costs a second assembly and factorization:
                // after a failure, skip the attempt for the next two iterations.
                factorized = ok;
                indefinite = ok && m_linear.used_fallback();
                result.true_hessian_steps += ok;
                if (!ok)
                    true_hessian_pause = 2;
                continue;
            }
            result.linear_fallbacks += m_linear.used_fallback();
            if (!ok) {
                result.status = StepStatus::LINEAR_BREAKDOWN;
                return result;
            }
            factorized = true;
        }
        {
            Timer t;
            p = m_linear.solve(rhs);
            t.add_to(result.times.solve);
        }
        if (control) {
            // The constrained (KKT) step: p - beta H^-1 a, with beta such that a^T p = gap.
            Timer t;
            const VectorXd y = m_linear.solve(control->direction);
            t.add_to(result.times.solve);
            const double ay = control->direction.dot(y);
            if (!(std::abs(ay) > 0) || !std::isfinite(ay)) {
                if (indefinite) {
                    true_hessian_pause = 2;
                    --it; // the same iteration with the projected Hessian
                    continue;
                }
                result.status = StepStatus::LINEAR_BREAKDOWN;
                return result;
            }
            p -= ((control->direction.dot(p) - gap) / ay) * y;
        }
        if (!p.allFinite()) {
            result.status = StepStatus::LINEAR_BREAKDOWN;
            return result;
        }
        if (!lifting && p.lpNorm<Eigen::Infinity>() <= ROUNDOFF_STEP * x.lpNorm<Eigen::Infinity>()) {
            // The remaining correction is within a few hundred ulps of the largest
            // position, below what the energy resolves. It is still taken while it
            // halves the residual (the positions near the origin resolve it, and the
            // adjoint needs the residual as small as it gets); once it does not, the
            // residual is at its round-off floor (a tiny dt makes M (x - x~) / h^2
            // dominate it) and further iterations cannot improve x.
            // Like any step it must be certified by CCD (a gap of a few ulps could be crossed).
            trial = x + p;
            bool improves = m_problem.max_step(x, p) >= 1.0;
            const double trial_energy = improves ? m_problem.energy(trial) : INFINITY;
            improves = improves && std::isfinite(trial_energy);
            double trial_max = 0;
            if (improves) {
                m_problem.gradient(trial, g_trial);
                trial_max = free_residual(g_trial);
                improves = g_trial.allFinite() && trial_max < 0.5 * gmax;
            }
            if (!improves) {
                result.status = StepStatus::CONVERGED;
                result.roundoff_limited = true;
                return result;
            }
            x = trial;
            energy = trial_energy;
            result.newton_step = p.lpNorm<Eigen::Infinity>() / step_scale;
            if (m_problem.end_iteration(x))
                energy = m_problem.energy(x);
            result.iterations = it + 1;
            if (result.iterations >= m_settings.max_iterations
                && trial_max / force_scale > m_settings.residual_tolerance) {
                // Out of iterations inside the round-off regime: converged as far as it gets
                // (the state before this step was already accepted as such).
                result.residual = trial_max / force_scale;
                result.status = StepStatus::CONVERGED;
                result.roundoff_limited = true;
                return result;
            }
            continue;
        }
        double slope = g.dot(p);
        if (indefinite && !(slope < 0)) {
            // The constrained problem is not convex here either: the projected Hessian's step instead.
            true_hessian_pause = 2;
            --it;
            continue;
        }
        if (!lifting && !(slope < 0)) {
            // An indefinite LDL^T can return an ascent direction: use the negative gradient
            // instead, scaled to the rejected step's length (g is a force: unscaled, the
            // swept CCD boxes of a contact scene could cover the whole scene).
            const double length = p.lpNorm<Eigen::Infinity>();
            double gfree = 0;
            for (Index i = 0; i < n; ++i)
                if (!constrained[size_t(i)])
                    gfree = std::max(gfree, std::abs(g[i]));
            const double scale = gfree > 0 && length > 0 ? length / gfree : 1.0;
            for (Index i = 0; i < n; ++i)
                p[i] = constrained[size_t(i)] ? 0.0 : -scale * g[i];
            if (control) // stay on the constraint surface
                p -= (control->direction.dot(p) / a_norm2) * control->direction;
            slope = g.dot(p);
            ++result.gradient_steps;
        }

        Timer ls;
        double alpha;
        double length = 0; // of the free dofs' step: lifting moves prescribed dofs as far as it must
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                length = std::max(length, std::abs(p[i]));
        if (m_settings.max_displacement > 0 && length > m_settings.max_displacement) {
            const double cap = m_settings.max_displacement / length;
            trial = cap * p; // the line search starts at the capped step
            alpha = cap * std::min(1.0, m_problem.max_step(x, trial));
        } else
            alpha = std::min(1.0, m_problem.max_step(x, p));
        if (!(alpha > 0) && m_problem.step_unresolved()) {
            ls.add_to(result.times.line_search);
            result.status = StepStatus::CCD_UNRESOLVED;
            return result;
        }
        bool accepted = false;
        double new_energy = energy;
        // Differences below this are round-off in the energy sum.
        constexpr double EPS = std::numeric_limits<double>::epsilon();
        const double roundoff = std::max(1e-13 * std::abs(energy), 16 * EPS * magnitude);
        // Near the solution the predicted decrease can drop below what the energy
        // sum resolves; there a full step is judged by the free-dof gradient instead.
        const bool unresolvable = !lifting
            && std::abs(alpha * slope) < std::max(ENERGY_RESOLUTION * std::abs(energy), 1e3 * EPS * magnitude);
        for (int h = 0; h <= m_settings.line_search_max_halvings && alpha > 0; ++h, alpha *= 0.5) {
            trial = x + alpha * p;
            new_energy = m_problem.energy(trial);
            if (!std::isfinite(new_energy))
                continue;
            if (lifting || new_energy <= energy + m_settings.armijo * alpha * slope + roundoff) {
                accepted = true;
                result.line_search_cuts += h;
                break;
            }
            if (unresolvable && h == 0) {
                m_problem.gradient(trial, g_trial);
                const double trial_max = free_residual(g_trial);
                if (g_trial.allFinite() && trial_max < 0.5 * gmax) {
                    accepted = true;
                    result.line_search_cuts += h;
                    result.roundoff_limited = true;
                    break;
                }
            }
        }
        if (m_settings.step_extension && accepted && alpha == 1.0 && !lifting && !control && !result.roundoff_limited
            && energy - new_energy > EXTENSION_RATIO * -slope)
            alpha = extend(x, p, slope, length, energy, new_energy, trial, longer, result);
        ls.add_to(result.times.line_search);
        if (!accepted) {
            result.status = StepStatus::LINE_SEARCH_EXHAUSTED;
            return result;
        }
        full_step_taken = alpha >= 1.0;
        result.newton_step = alpha * p.lpNorm<Eigen::Infinity>() / step_scale;
        x = trial;
        if (lifting && alpha >= 1.0) {
            // x_D + (target - x_D) need not round to target: snap so lifting ends exactly,
            // unless the snapped state is invalid (then the rounding stays for one more iteration).
            for (Index i = 0; i < n; ++i)
                if (constrained[size_t(i)])
                    x[i] = target[i];
            energy = m_problem.energy(x);
            if (!std::isfinite(energy)) {
                x = trial;
                energy = new_energy;
            }
        } else {
            energy = new_energy;
        }
        if (m_problem.end_iteration(x))
            energy = m_problem.energy(x);
        result.iterations = it + 1;
    }
}

} // namespace diffipc
