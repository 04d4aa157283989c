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

    /// What an iteration's step tells the loop: go on, redo this iteration (with the projected
    /// Hessian), or stop with result.status set.
    enum class Flow { NEXT, RETRY, STOP };
} // namespace

/// One call of NewtonSolver::solve: its arguments, its work vectors (allocated once, reused by
/// every iteration and trial) and what one iteration hands to the next, named as in the algorithm
/// (docs/math.md "Newton"). Each member function after run() is one step of an iteration, in the
/// order run() calls them.
struct NewtonSolver::Run {
    Run(const NewtonSolver& solver, VectorXd& x, const VectorXd& target, const std::vector<char>& constrained,
        double force_scale, double step_scale, LoadControl* control)
        : problem(solver.m_problem)
        , assembler(solver.m_assembler)
        , linear(solver.m_linear)
        , settings(solver.m_settings)
        , x(x)
        , target(target)
        , constrained(constrained)
        , force_scale(force_scale)
        , step_scale(step_scale)
        , control(control)
        , n(x.size())
        , g(n)
        , p(n)
        , rhs(n)
        , pD(n)
        , trial(n)
        , g_trial(n)
        , longer(n)
        , a_norm2(control ? control->direction.squaredNorm() : 0.0)
    {
    }

    NewtonResult run()
    {
        if (!start())
            return result;
        for (int it = 0;; ++it) {
            if (measure(it) == Flow::STOP || factorize() == Flow::STOP)
                return result;
            Flow flow = solve_direction();
            if (flow == Flow::STOP)
                return result;
            if (flow == Flow::RETRY) {
                --it;
                continue;
            }
            if (!lifting && p.lpNorm<Eigen::Infinity>() <= ROUNDOFF_STEP * x.lpNorm<Eigen::Infinity>()) {
                if (roundoff_step(it) == Flow::STOP)
                    return result;
                continue;
            }
            flow = ensure_descent();
            if (flow == Flow::RETRY) {
                --it;
                continue;
            }
            if (line_search() == Flow::STOP)
                return result;
            commit(it);
        }
    }

    Flow stop(StepStatus status)
    {
        result.status = status;
        return Flow::STOP;
    }

    /// max |free-dof gradient|, less the load the constraint carries under load control
    double free_residual(const VectorXd& gradient) const
    {
        const double carried = control ? control->direction.dot(gradient) / a_norm2 : 0.0;
        double largest = 0;
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                largest = std::max(
                    largest, std::abs(control ? gradient[i] - carried * control->direction[i] : gradient[i]));
        return largest;
    }

    /// The starting energy; false (INVALID_INITIAL_STATE) where it is not finite.
    bool start()
    {
        {
            Timer t;
            energy = problem.energy(x);
            t.add_to(result.times.line_search);
        }
        if (!std::isfinite(energy)) {
            stop(StepStatus::INVALID_INITIAL_STATE);
            return false;
        }
        // Round-off of energy differences scales with the terms, not with their
        // (possibly cancelling) sum.
        magnitude = problem.energy_magnitude(x);
        return true;
    }

    /// The gradient, the prescribed dofs' remaining motion and the residual at x; stops where the
    /// iterate converged, is out of iterations or is not finite.
    Flow measure(int it)
    {
        {
            Timer t;
            problem.gradient(x, g);
            t.add_to(result.times.assembly);
        }
        if (!g.allFinite())
            return stop(StepStatus::NON_FINITE);
        // Under load control the multiplier's share lambda a of the gradient is the load the
        // constraint carries, not a residual.
        control_gap = 0;
        if (control) {
            control->multiplier = control->direction.dot(g) / a_norm2;
            control_gap = control->level - control->direction.dot(x);
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
        gmax = free_residual(g);
        lifting = dmax > 0 || (control && std::abs(control_gap) > control->tolerance);
        result.residual = gmax / force_scale;
        if (!std::isfinite(result.residual)) {
            // A force scale that underflowed or overflowed: no residual can be judged.
            return stop(StepStatus::NON_FINITE);
        }
        if (!lifting && result.residual <= settings.residual_tolerance
            && (settings.step_tolerance <= 0 || it == 0 || result.newton_step <= settings.step_tolerance))
            return stop(StepStatus::CONVERGED);
        if (it >= settings.max_iterations)
            return stop(StepStatus::NEWTON_EXHAUSTED);
        return Flow::NEXT;
    }

    /// The search matrix (true or projected Hessian, constraints applied) and the right-hand side.
    void assemble(bool project)
    {
        Timer t;
        problem.hessian(x, project, assembler);
        rhs = -g;
        if (lifting) {
            // Free rows see the coupling to the prescribed motion: -(g_F + H_FD p_D).
            const VectorXd coupling = assembler.matrix().selfadjointView<Eigen::Lower>() * pD;
            rhs -= coupling;
        }
        for (Index i = 0; i < n; ++i)
            if (constrained[size_t(i)])
                rhs[i] = pD[i];
        assembler.apply_constraints(constrained);
        t.add_to(result.times.assembly);
    }

    /// Assembles and factorizes the search matrix: the true Hessian where it is worth trying and
    /// Cholesky proves it positive definite, the projected one otherwise (LINEAR_BREAKDOWN where
    /// even that fails).
    Flow factorize()
    {
        // Projected Newton converges linearly where elements are strongly
        // compressed; once a full step has been accepted, try the true Hessian
        // and keep it if Cholesky proves it positive definite.
        const bool try_true = settings.adaptive_projection && full_step_taken && !lifting && linear.cholesky_first()
            && true_hessian_pause == 0;
        if (true_hessian_pause > 0)
            --true_hessian_pause;
        bool factorized = false;
        indefinite = false;
        for (int attempt = try_true ? 0 : 1; attempt < 2 && !factorized; ++attempt) {
            const bool project = attempt == 1;
            assemble(project);
            Timer t;
            const double analysis_before = linear.analysis_time();
            const int analyses_before = linear.analyses();
            // Under load control the true Hessian may be indefinite on a path past a limit point
            // while the constrained problem is convex on the constraint surface: LDL^T is tried,
            // and the step is kept if it descends (ensure_descent).
            const bool ok = linear.factorize(assembler.matrix(), /*allow_fallback=*/project || control);
            t.add_to(result.times.factorization);
            result.times.analysis += linear.analysis_time() - analysis_before;
            result.times.analyses += linear.analyses() - analyses_before;
            if (!project) {
                // An indefinite true Hessian costs a second assembly and factorization:
                // after a failure, skip the attempt for the next two iterations.
                factorized = ok;
                indefinite = ok && linear.used_fallback();
                result.true_hessian_steps += ok;
                if (!ok)
                    true_hessian_pause = 2;
                continue;
            }
            result.linear_fallbacks += linear.used_fallback();
            if (!ok)
                return stop(StepStatus::LINEAR_BREAKDOWN);
            factorized = true;
        }
        return Flow::NEXT;
    }

    /// The Newton direction p, on the constraint surface under load control; RETRY where an
    /// indefinite true Hessian leaves the constrained step undefined.
    Flow solve_direction()
    {
        {
            Timer t;
            p = linear.solve(rhs);
            t.add_to(result.times.solve);
        }
        if (control) {
            // The constrained (KKT) step: p - beta H^-1 a, with beta such that a^T p = gap.
            Timer t;
            const VectorXd y = linear.solve(control->direction);
            t.add_to(result.times.solve);
            const double ay = control->direction.dot(y);
            if (!(std::abs(ay) > 0) || !std::isfinite(ay)) {
                if (indefinite) {
                    true_hessian_pause = 2;
                    return Flow::RETRY;
                }
                return stop(StepStatus::LINEAR_BREAKDOWN);
            }
            p -= ((control->direction.dot(p) - control_gap) / ay) * y;
        }
        if (!p.allFinite())
            return stop(StepStatus::LINEAR_BREAKDOWN);
        return Flow::NEXT;
    }

    /// A correction within a few hundred ulps of the largest position, below what the energy
    /// resolves: taken while it halves the residual, else the solve has converged as far as it can.
    Flow roundoff_step(int it)
    {
        // The positions near the origin resolve such a step, and the adjoint needs the residual
        // as small as it gets; once it does not halve the residual, the residual is at its
        // round-off floor (a tiny dt makes M (x - x~) / h^2 dominate it) and further iterations
        // cannot improve x. Like any step it must be certified by CCD (a gap of a few ulps could
        // be crossed).
        trial = x + p;
        bool improves = problem.max_step(x, p) >= 1.0;
        const double trial_energy = improves ? problem.energy(trial) : INFINITY;
        improves = improves && std::isfinite(trial_energy);
        double trial_max = 0;
        if (improves) {
            problem.gradient(trial, g_trial);
            trial_max = free_residual(g_trial);
            improves = g_trial.allFinite() && trial_max < 0.5 * gmax;
        }
        if (!improves) {
            result.roundoff_limited = true;
            return stop(StepStatus::CONVERGED);
        }
        x = trial;
        energy = trial_energy;
        result.newton_step = p.lpNorm<Eigen::Infinity>() / step_scale;
        if (problem.end_iteration(x))
            energy = problem.energy(x);
        result.iterations = it + 1;
        if (result.iterations >= settings.max_iterations && trial_max / force_scale > settings.residual_tolerance) {
            // Out of iterations inside the round-off regime: converged as far as it gets
            // (the state before this step was already accepted as such).
            result.residual = trial_max / force_scale;
            result.roundoff_limited = true;
            return stop(StepStatus::CONVERGED);
        }
        return Flow::NEXT;
    }

    /// The slope g^T p, made negative: RETRY where an indefinite true Hessian gave no descent
    /// under load control, the negative gradient where an indefinite LDL^T gave an ascent direction.
    Flow ensure_descent()
    {
        slope = g.dot(p);
        if (indefinite && !(slope < 0)) {
            // The constrained problem is not convex here either: the projected Hessian's step instead.
            true_hessian_pause = 2;
            return Flow::RETRY;
        }
        if (!lifting && !(slope < 0)) {
            // Use the negative gradient, scaled to the rejected step's length (g is a force:
            // unscaled, the swept CCD boxes of a contact scene could cover the whole scene).
            const double step_length = p.lpNorm<Eigen::Infinity>();
            double gfree = 0;
            for (Index i = 0; i < n; ++i)
                if (!constrained[size_t(i)])
                    gfree = std::max(gfree, std::abs(g[i]));
            const double scale = gfree > 0 && step_length > 0 ? step_length / gfree : 1.0;
            for (Index i = 0; i < n; ++i)
                p[i] = constrained[size_t(i)] ? 0.0 : -scale * g[i];
            if (control) // stay on the constraint surface
                p -= (control->direction.dot(p) / a_norm2) * control->direction;
            slope = g.dot(p);
            ++result.gradient_steps;
        }
        return Flow::NEXT;
    }

    /// The first step length to try: 1, shortened to max_displacement and to what CCD and the
    /// inversion bound admit.
    double bounded_step()
    {
        length = 0; // of the free dofs' step: lifting moves prescribed dofs as far as it must
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                length = std::max(length, std::abs(p[i]));
        if (settings.max_displacement > 0 && length > settings.max_displacement) {
            const double cap = settings.max_displacement / length;
            trial = cap * p; // the line search starts at the capped step
            return cap * std::min(1.0, problem.max_step(x, trial));
        }
        return std::min(1.0, problem.max_step(x, p));
    }

    /// Backtracking (Armijo) from the bounded step, then the step extension; leaves the accepted
    /// step in trial, new_energy and alpha.
    Flow line_search()
    {
        Timer ls;
        alpha = bounded_step();
        if (!(alpha > 0) && problem.step_unresolved()) {
            ls.add_to(result.times.line_search);
            return stop(StepStatus::CCD_UNRESOLVED);
        }
        bool accepted = false;
        new_energy = energy;
        // Differences below this are round-off in the energy sum.
        constexpr double EPS = std::numeric_limits<double>::epsilon();
        const double roundoff = std::max(1e-13 * std::abs(energy), 16 * EPS * magnitude);
        // Near the solution the predicted decrease can drop below what the energy
        // sum resolves; there a full step is judged by the free-dof gradient instead.
        const bool unresolvable = !lifting
            && std::abs(alpha * slope) < std::max(ENERGY_RESOLUTION * std::abs(energy), 1e3 * EPS * magnitude);
        for (int h = 0; h <= settings.line_search_max_halvings && alpha > 0; ++h, alpha *= 0.5) {
            trial = x + alpha * p;
            new_energy = problem.energy(trial);
            if (!std::isfinite(new_energy))
                continue;
            if (lifting || new_energy <= energy + settings.armijo * alpha * slope + roundoff) {
                accepted = true;
                result.line_search_cuts += h;
                break;
            }
            if (unresolvable && h == 0) {
                problem.gradient(trial, g_trial);
                const double trial_max = free_residual(g_trial);
                if (g_trial.allFinite() && trial_max < 0.5 * gmax) {
                    accepted = true;
                    result.line_search_cuts += h;
                    result.roundoff_limited = true;
                    break;
                }
            }
        }
        if (settings.step_extension && accepted && alpha == 1.0 && !lifting && !control && !result.roundoff_limited
            && energy - new_energy > EXTENSION_RATIO * -slope)
            alpha = extend();
        ls.add_to(result.times.line_search);
        if (!accepted)
            return stop(StepStatus::LINE_SEARCH_EXHAUSTED);
        return Flow::NEXT;
    }

    /// After an accepted full step x + p that decreased the energy by more than EXTENSION_RATIO of
    /// -slope: tries 2p, 4p, ... while each lowers the energy further, satisfies Armijo and is
    /// admitted by max_step (and max_displacement). Returns the step length taken (1 if none was
    /// better); trial and new_energy are then that step's.
    double extend()
    {
        // The full step took nearly the whole decrease the gradient predicts: along p the energy is
        // far less curved than the search matrix says (a projected Hessian where the true one is
        // indefinite or nearly singular: a structure at a bifurcation creeping along its buckling
        // mode, one short step per iteration). Doubling the step while the energy keeps falling
        // (Armijo against the start) and CCD and the inversion bound admit the longer step walks
        // that mode in a few trials instead of hundreds of iterations.
        double taken = 1.0;
        for (int k = 0; k < MAX_EXTENSIONS; ++k) {
            const double a = 2 * taken;
            if (settings.max_displacement > 0 && a * length > settings.max_displacement)
                break;
            longer = a * p;
            if (problem.max_step(x, longer) < 1.0)
                break;
            longer += x;
            const double e = problem.energy(longer);
            if (!(e < new_energy) || e > energy + settings.armijo * a * slope)
                break;
            taken = a;
            new_energy = e;
            trial.swap(longer);
        }
        result.extended_steps += taken > 1.0;
        return taken;
    }

    /// Moves x to the accepted trial (snapping the prescribed dofs onto their targets once lifting
    /// took a full step) and ends the iteration.
    void commit(int it)
    {
        full_step_taken = alpha >= 1.0;
        result.newton_step = alpha * p.lpNorm<Eigen::Infinity>() / step_scale;
        x = trial;
        if (lifting && alpha >= 1.0) {
            // x_D + (target - x_D) need not round to target: snap so lifting ends exactly,
            // unless the snapped state is invalid (then the rounding stays for one more iteration).
            for (Index i = 0; i < n; ++i)
                if (constrained[size_t(i)])
                    x[i] = target[i];
            energy = problem.energy(x);
            if (!std::isfinite(energy)) {
                x = trial;
                energy = new_energy;
            }
        } else {
            energy = new_energy;
        }
        if (problem.end_iteration(x))
            energy = problem.energy(x);
        result.iterations = it + 1;
    }

    const Problem& problem;
    SparseAssembler& assembler;
    LinearSolver& linear;
    const NewtonSettings& settings;

    // The solve's arguments (NewtonSolver::solve).
    VectorXd& x;
    const VectorXd& target;
    const std::vector<char>& constrained;
    const double force_scale;
    const double step_scale;
    LoadControl* const control;

    const Index n;
    VectorXd g, p, rhs, pD, trial, g_trial, longer;
    const double a_norm2; ///< |a|^2 of the load control's direction
    NewtonResult result;

    // Carried across iterations.
    double energy = 0; ///< at x
    double magnitude = 0; ///< the energy's terms' size at the start (its round-off scale)
    bool full_step_taken = false;
    int true_hessian_pause = 0; ///< iterations left before the true Hessian is tried again

    // Set by one step of an iteration, read by the later ones.
    double gmax = 0; ///< free_residual(g)
    bool lifting = false; ///< prescribed dofs (or the load control's level) not reached yet
    double control_gap = 0; ///< level - a^T x under load control
    bool indefinite = false; ///< the true Hessian, factorized by LDL^T (load control only)
    double slope = 0; ///< g^T p
    double length = 0; ///< max |p| over the free dofs
    double alpha = 0; ///< the accepted step length
    double new_energy = 0; ///< at trial
};

NewtonResult NewtonSolver::solve(VectorXd& x, const VectorXd& target, const std::vector<char>& constrained,
    double force_scale, double step_scale, LoadControl* control) const
{
    return Run(*this, x, target, constrained, force_scale, step_scale, control).run();
}

} // namespace diffipc
