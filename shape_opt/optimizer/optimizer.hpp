#pragma once
/// @file optimizer.hpp
/// Optimizers behind one interface (issue 12): a smooth problem
///
///   min f(x)  subject to  lower <= x <= upper,  c(x) <= 0,  h(x) = 0,
///
/// with gradients of f, c and h, a validity hook (a design may be invalid: an inverted
/// or self-intersecting rest mesh, a forward solve that fails) and a per-iteration
/// callback. Drivers: a projected L-BFGS with bounds (ours, because it must honour the
/// validity hook), Ipopt (limited-memory Hessian, true constraints) and NLopt's MMA,
/// CCSAQ and SLSQP (vector constraints).
///
/// Invalid points are never reported to an optimizer as NaN (NLopt's CCSA methods stall on
/// it): L-BFGS bounds its line search by max_valid_step() and backtracks past a failed
/// evaluation; Ipopt is told the evaluation failed (its line search cuts the step); NLopt
/// gets a large finite value, so that CCSA's conservative check fails and it retries with a
/// more conservative approximation (SLSQP's line search backtracks).

#include "forward/common/types.hpp"

#include <limits>
#include <map>
#include <string>
#include <vector>

namespace diffipc {

/// f, c, h and their derivatives at one point.
struct OptimizationValues {
    double f = 0;
    VectorXd gradient; ///< n
    VectorXd inequality; ///< m_c values of c (feasible: <= 0)
    MatrixXd inequality_jacobian; ///< m_c by n
    VectorXd equality; ///< m_h values of h (feasible: == 0)
    MatrixXd equality_jacobian; ///< m_h by n
};

struct OptimizerCheckpoint;

/// What the per-iteration callback sees; `x`, `values` and `checkpoint` point into the optimizer
/// and are valid during the call only (copy what you keep).
struct IterationInfo {
    int iteration = 0; ///< 0: the initial point
    const VectorXd* x = nullptr;
    const OptimizationValues* values = nullptr;
    double gradient_norm = 0; ///< inf-norm of the projected gradient (L-BFGS) or of the Lagrangian's (Ipopt)
    double step_norm = 0; ///< inf-norm of the last accepted change of x
    int evaluations = 0; ///< evaluations so far
    int rejected = 0; ///< trial points rejected so far (invalid or failed)
    double evaluation_seconds = 0; ///< wall time inside evaluate() and max_valid_step() so far
    double optimizer_seconds = 0; ///< wall time of the optimizer itself so far
    /// CPU time of the optimizer itself so far: that of the thread that runs it (the library's
    /// work and ours), less its CPU time in evaluate(), max_valid_step() and iteration().
    /// Unlike the wall time it does not grow while the thread waits for a core on a loaded
    /// machine; threads the library may start (a threaded BLAS) are not counted.
    double optimizer_cpu_seconds = 0;
    /// The run's state after this iteration: minimize() continues from it (a resumed run).
    const OptimizerCheckpoint* checkpoint = nullptr;
};

/// The problem an optimizer sees.
class OptimizationProblem {
public:
    virtual ~OptimizationProblem() = default;
    /// Number of variables n.
    virtual Index size() const = 0;
    /// Number of inequality constraints m_c and equality constraints m_h.
    virtual int inequalities() const { return 0; }
    virtual int equalities() const { return 0; }
    /// @brief f, its gradient and the constraints with their Jacobians at x, from one
    /// evaluation (one forward run and its adjoints).
    /// @return false if x is not a valid design or cannot be evaluated (a failed forward
    /// solve): the optimizer rejects the point, `out` is not used
    virtual bool evaluate(const VectorXd& x, OptimizationValues& out) = 0;
    /// @brief Largest t in (0, 1] such that x + s dx is valid for every s in [0, t]; 1 when
    /// the whole step is (the default: every point is valid).
    virtual double max_valid_step(const VectorXd& x, const VectorXd& dx)
    {
        (void)x;
        (void)dx;
        return 1.0;
    }
    /// @brief Called at the initial point and after every accepted iterate.
    /// @return false to stop the run (StopReason::USER_STOP)
    virtual bool iteration(const IterationInfo& info)
    {
        (void)info;
        return true;
    }
};

enum class OptimizerAlgorithm { LBFGS, LBFGSB, IPOPT, MMA, CCSAQ, SLSQP };

/// What an algorithm takes, in the one table of algorithms (optimizer.cpp): minimize()'s checks,
/// their messages, the JSON and Python names and docs/optimization.md's table all follow it.
struct OptimizerAlgorithmInfo {
    OptimizerAlgorithm algorithm;
    const char* name; ///< as problem files and Python name it
    bool bounds; ///< lower <= x <= upper
    bool inequalities; ///< c(x) <= 0
    bool equalities; ///< h(x) = 0
    bool library_options; ///< takes `optimizer.options` (a library's own settings)
    const char* library; ///< "ours", "Ipopt 3.11", "NLopt 2.7"
};
/// Every algorithm, in the order the docs list them.
const std::vector<OptimizerAlgorithmInfo>& registered_optimizer_algorithms();
const OptimizerAlgorithmInfo& optimizer_algorithm_info(OptimizerAlgorithm algorithm);

/// The algorithm's name: "lbfgs", "lbfgsb", "ipopt", "mma", "ccsaq", "slsqp"
std::string to_string(OptimizerAlgorithm algorithm);
/// @throws InputError naming `field` for an unknown name (listing the known ones)
OptimizerAlgorithm parse_optimizer_algorithm(const std::string& name, const std::string& field);

/// The Taylor test diffipc optimize makes where a run ended (final_taylor_check(),
/// shape_opt/optimizer/taylor_check.hpp); minimize() itself does not make it.
struct TaylorCheckSettings {
    bool enabled = true;
    double step = 0.1; ///< the first step, relative to each variable's scale (as diffipc gradcheck's)
    int halvings = 3; ///< steps after the first, each half the one before (at least 2)
    unsigned seed = 1; ///< of the random direction
};

struct OptimizerSettings {
    OptimizerAlgorithm algorithm = OptimizerAlgorithm::LBFGSB;
    /// Bounds per variable (empty: none); -inf / +inf for a free side.
    VectorXd lower, upper;
    /// Stopping rules; a rule with value 0 (or a budget <= 0) is off.
    double gradient_tolerance = 1e-8; ///< projected-gradient inf-norm, absolute
    double relative_gradient_tolerance = 1e-6; ///< ... relative to the initial point's
    double x_tolerance = 0; ///< inf-norm of the change of x in one iteration
    double f_tolerance = 0; ///< |f_k - f_{k-1}| / max(|f_k|, |f_{k-1}|, 1e-300)
    int max_iterations = 100;
    double max_seconds = 0; ///< wall-time budget
    double constraint_tolerance = 1e-6; ///< largest violation accepted as feasible (absolute)
    int lbfgs_memory = 10; ///< correction pairs of the L-BFGS Hessian approximation (L-BFGS, Ipopt; NLopt: unused)
    /// Stop once an accepted iterate's objective, in the problem's own units, is at most this
    /// and the constraints hold (a discrepancy-principle stop for fits to noisy data). Checked
    /// by the problem (DesignProblem), which knows the units; -inf: off.
    double objective_target = -std::numeric_limits<double>::infinity();
    /// Options passed to the library as they are. Ipopt: any of its options, read as the
    /// option's type (number, integer, string) and overriding ours. NLopt: "maxeval",
    /// "xtol_rel", "ftol_abs", "stopval", and for MMA/CCSAQ the parameters "inner_maxeval",
    /// "dual_algorithm", "dual_ftol_rel", "dual_ftol_abs", "dual_maxeval", "verbosity".
    /// L-BFGS: none. Anything else is an InputError naming "optimizer.options.<name>".
    std::map<std::string, std::string> options;
    /// The problem file's "final_taylor_check" (false: off), for the run's caller.
    TaylorCheckSettings final_taylor_check;
};

enum class StopReason {
    GRADIENT_TOLERANCE,
    X_TOLERANCE,
    F_TOLERANCE,
    ITERATION_BUDGET,
    TIME_BUDGET,
    LINE_SEARCH_STALLED,
    USER_STOP,
    OBJECTIVE_TARGET, ///< J reached OptimizerSettings::objective_target (feasible)
    INFEASIBLE, ///< the optimizer stopped without satisfying the constraints
    INVALID_START, ///< the initial point is invalid (evaluate() returned false there; outside the bounds: InputError)
    FAILED ///< the library reported an error (message says which)
};
/// "gradient_tolerance", "x_tolerance", ...
std::string to_string(StopReason reason);

/// @brief An accepted step along which f changed by far more than the gradients at its two ends
/// predict: f is discontinuous between the iterates (a jump), or the step is far outside the
/// range of its first-order model. For a smooth f, f_k - f_{k-1} = (g_{k-1} + g_k).dx / 2 +
/// O(|dx|^3) (the trapezoidal rule); the step is recorded when the miss exceeds
/// STEP_JUMP_FACTOR (|g_{k-1}.dx| + |g_k.dx|) plus the round-off floor STEP_JUMP_FLOOR
/// max(|f_{k-1}|, |f_k|). Where f is smooth and convex or concave along the step, its change
/// lies between g_{k-1}.dx and g_k.dx, so the miss is at most half that sum: the factor 2 leaves
/// room for an inflection within the step.
struct StepJump {
    int iteration = 0; ///< the step from iteration - 1 to iteration
    double change = 0; ///< f_k - f_{k-1}
    double predicted = 0; ///< (g_{k-1} + g_k).dx / 2
    double first_order = 0; ///< |g_{k-1}.dx| + |g_k.dx|
    double step_norm = 0; ///< inf-norm of dx
};
constexpr double STEP_JUMP_FACTOR = 2;
constexpr double STEP_JUMP_FLOOR = 1e-8;
/// At most this many StepJump records are kept (the largest misses).
constexpr size_t MAX_STEP_JUMPS = 20;

struct OptimizerResult {
    /// The optimizer's own result: the last iterate it accepted (the start if it accepted none).
    /// This is the point the stop reason describes; it need not be the best point seen (best_x).
    VectorXd x;
    OptimizationValues values; ///< at x
    StopReason reason = StopReason::FAILED;
    std::string message; ///< the reason in words, with the library's own status where there is one
    int iterations = 0;
    int evaluations = 0;
    int rejected = 0;
    double max_violation = 0; ///< of the constraints and bounds at x (0 without constraints)
    double evaluation_seconds = 0, optimizer_seconds = 0;
    double optimizer_cpu_seconds = 0; ///< as IterationInfo::optimizer_cpu_seconds
    /// The lowest valid f seen within constraint_tolerance of the constraints (any evaluation,
    /// accepted or a trial point): reported beside x, never in its place.
    bool has_best = false;
    VectorXd best_x;
    OptimizationValues best_values; ///< at best_x
    double best_max_violation = 0;
    int best_evaluation = 0; ///< which evaluation found it (1: the start)
    int best_iteration = -1; ///< the iteration whose iterate it is; -1: a point the optimizer did not accept
    /// Accepted steps whose change of f the gradients do not explain (StepJump), largest miss first.
    std::vector<StepJump> jumps;
    int jumps_found = 0; ///< all flagged steps (jumps keeps at most MAX_STEP_JUMPS of them)
    int steps_checked = 0; ///< accepted steps compared with their first-order model
};

/// One L-BFGS correction pair: s = x_{k+1} - x_k, y = g_{k+1} - g_k (n values each).
struct CorrectionPair {
    VectorXd s, y;
};

/// @brief A run's state after a completed iteration, from which minimize() continues it (a
/// resumed run, docs/optimization.md). Every driver continues from x with the values there (no
/// evaluation), the iteration and evaluation counts, the times, the best point and the
/// reference gradient norm of the relative tolerance. L-BFGS(-B) also keeps its correction
/// pairs and repeats the checks that follow an iteration, so that its iterates are the
/// uninterrupted run's; Ipopt and NLopt cannot take their internal state back and start
/// afresh from x (a warm start: their later iterates differ from an uninterrupted run's).
struct OptimizerCheckpoint {
    OptimizerAlgorithm algorithm = OptimizerAlgorithm::LBFGSB;
    int iteration = 0; ///< the iteration whose iterate x is
    VectorXd x; ///< n
    OptimizationValues values; ///< at x
    double gradient_norm = 0; ///< as reported at this iteration
    double step_norm = 0; ///< inf-norm of this iteration's change of x (0 at iteration 0)
    double previous_f = 0; ///< f at the previous iteration (NaN at iteration 0)
    double initial_gradient_norm = 0; ///< projected gradient inf-norm at the run's start
    int evaluations = 0, rejected = 0;
    double evaluation_seconds = 0, optimizer_seconds = 0;
    double optimizer_cpu_seconds = 0; ///< as IterationInfo::optimizer_cpu_seconds
    double elapsed_seconds = 0; ///< wall time of the run so far (what max_seconds counts)
    bool has_best = false; ///< a feasible valid point was seen: the best one
    VectorXd best_x;
    OptimizationValues best_values;
    int best_evaluation = 0; ///< as OptimizerResult::best_evaluation
    int best_iteration = -1; ///< as OptimizerResult::best_iteration
    std::vector<StepJump> jumps; ///< as OptimizerResult::jumps, so far
    int jumps_found = 0; ///< as OptimizerResult::jumps_found, so far
    int steps_checked = 0;
    std::vector<CorrectionPair> lbfgs_pairs; ///< L-BFGS(-B): its memory, oldest first; else empty
};

/// @brief Minimizes `problem` from `x0` with the settings' algorithm.
/// @param x0  n initial values, inside the bounds
/// @throws InputError for settings that do not fit the problem (bound sizes, lower > upper, NaN,
///         x0 outside its bounds, constraints given to L-BFGS, equalities given to MMA/CCSAQ, an
///         option the library rejects); an exception thrown by the problem passes through.
OptimizerResult minimize(OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings);

/// @brief The checks minimize() makes on the settings before its first evaluation, for a caller
/// that refuses bad settings before it writes anything (diffipc optimize).
/// @throws InputError as minimize()
void check_optimizer_settings(
    const OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings);

/// @brief Continues the run that wrote `checkpoint` (IterationInfo::checkpoint) with the same
/// problem: from its x and values, its iteration numbers and counts going on, the budgets
/// (max_iterations, max_seconds) counting the whole run; the result describes the whole run.
/// `settings` may differ from the first run's (a larger budget) but not in the algorithm.
/// @throws InputError as minimize(), naming "optimizer.algorithm" for another algorithm than the
///         checkpoint's and "optimizer.checkpoint" for one that does not fit the problem
OptimizerResult resume_minimize(
    OptimizationProblem& problem, const OptimizerCheckpoint& checkpoint, const OptimizerSettings& settings);

/// Shared by the drivers (lbfgsb.cpp, ipopt_driver.cpp, nlopt_driver.cpp); not for users.
namespace optimizer_detail {

    /// @brief Checks the settings against the problem and x0.
    /// @throws InputError naming the field ("optimizer.lower", "optimizer.x0", ...)
    void validate(const OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& settings);

    /// @brief Inf-norm of the projected gradient: g_i, except 0 where x_i sits on a bound and
    /// -g_i points out of the box (the variable is held by the bound).
    /// @param lower, upper  n bounds (-inf / +inf for a free side)
    double projected_gradient_norm(
        const VectorXd& x, const VectorXd& gradient, const VectorXd& lower, const VectorXd& upper);

    /// |f1 - f0| / max(|f0|, |f1|, 1e-300): the measure of OptimizerSettings::f_tolerance.
    double relative_change(double f0, double f1);

    /// @brief One run of a driver: evaluations through it are timed and counted, every valid one
    /// is a candidate for the result (the best feasible point), and the per-iteration callback
    /// gets the counts and times. Times: evaluation = evaluate() + max_valid_step(); optimizer =
    /// the rest of the wall time, less the time spent in iteration(); optimizer CPU = the same
    /// split of the calling thread's CPU time (CLOCK_THREAD_CPUTIME_ID). The driver runs on the
    /// thread that constructed the Run.
    class Run {
    public:
        /// @param resume  the state a resumed run continues from (nullptr: a new run)
        Run(OptimizationProblem& problem, const OptimizerSettings& settings,
            const OptimizerCheckpoint* resume = nullptr);

        OptimizationProblem& problem() { return m_problem; }
        const OptimizerSettings& settings() const { return m_settings; }
        /// n bounds, +-inf where the settings give none.
        const VectorXd& lower() const { return m_lower; }
        const VectorXd& upper() const { return m_upper; }

        /// @brief problem.evaluate(), timed and counted. A point where it returns false, or a
        /// non-finite f, gradient or constraint value, is rejected (counted; returns false).
        /// @throws InputError naming "optimizer.problem" when the values have the wrong sizes
        bool evaluate(const VectorXd& x, OptimizationValues& out);
        /// problem.max_valid_step(), timed, clamped to [0, 1] (NaN: 0).
        double max_valid_step(const VectorXd& x, const VectorXd& dx);
        /// Largest violation of the constraints (c > 0, h != 0) and of the bounds at x.
        double violation(const VectorXd& x, const OptimizationValues& values) const;
        /// True when x is within constraint_tolerance of the constraints and bounds.
        bool feasible(const VectorXd& x, const OptimizationValues& values) const
        {
            return violation(x, values) <= m_settings.constraint_tolerance;
        }

        /// @brief problem.iteration() with the counts, times and the checkpoint filled in; x
        /// becomes the last accepted point (the result when no feasible point is found).
        /// @param pairs  L-BFGS: its correction pairs after this iteration (for the checkpoint)
        /// @return false when the callback asks to stop
        bool iteration(int iteration, const VectorXd& x, const OptimizationValues& values, double gradient_norm,
            double step_norm, const std::vector<CorrectionPair>* pairs = nullptr);
        /// @brief Compares f's change over the step to x with the first-order model from the
        /// gradients at its two ends (StepJump); called by iteration().
        void check_step(int iteration, const VectorXd& x, const OptimizationValues& values);
        /// True once settings.max_seconds (when > 0) of wall time have passed.
        bool out_of_time() const;
        /// Wall time since the run began (with a resumed run's earlier part), s.
        double elapsed() const;
        /// The optimizer's CPU time so far (IterationInfo::optimizer_cpu_seconds), s.
        double optimizer_cpu_seconds() const;
        /// settings.max_seconds less elapsed() (+inf without a budget).
        double remaining_seconds() const;
        /// The checkpoint a resumed run continues from (nullptr for a new run).
        const OptimizerCheckpoint* resumed() const { return m_resume; }
        /// The iteration number of the first point: 0, or the checkpoint's iteration.
        int first_iteration() const;
        /// Projected gradient inf-norm at the run's start (the relative tolerance's reference).
        double initial_gradient_norm() const { return m_initial_gradient_norm; }
        void set_initial_gradient_norm(double norm) { m_initial_gradient_norm = norm; }
        int evaluations() const { return m_evaluations; }
        int rejected() const { return m_rejected; }
        /// True once a valid point within constraint_tolerance has been evaluated.
        bool has_feasible() const { return m_has_best; }
        /// The best feasible valid f so far (+inf before the first).
        double best_f() const { return m_best_f; }

        /// @brief The result: the last accepted point (else x0), with the best valid feasible
        /// point seen beside it. A tolerance reason (gradient, x, f) at a point outside
        /// constraint_tolerance becomes INFEASIBLE.
        OptimizerResult finish(StopReason reason, const std::string& message, int iterations);

    private:
        OptimizationProblem& m_problem;
        const OptimizerSettings& m_settings;
        const OptimizerCheckpoint* m_resume = nullptr;
        double m_initial_gradient_norm = 0;
        VectorXd m_lower, m_upper;
        double m_start = 0; ///< steady clock at construction, s
        double m_evaluation_seconds = 0, m_callback_seconds = 0;
        double m_cpu_start = 0; ///< the thread's CPU time at construction, s
        double m_evaluation_cpu_seconds = 0, m_callback_cpu_seconds = 0; ///< of this process's part
        double m_resumed_optimizer_cpu_seconds = 0; ///< the checkpoint's (a resumed run's earlier part)
        int m_evaluations = 0, m_rejected = 0;
        bool m_has_best = false, m_has_accepted = false;
        double m_best_f = 0;
        VectorXd m_best_x, m_accepted_x, m_first_x;
        OptimizationValues m_best_values, m_accepted_values;
        double m_step_norm = 0; ///< of the last accepted iterate
        int m_best_evaluation = 0, m_best_iteration = -1;
        std::vector<StepJump> m_jumps;
        int m_jumps_found = 0;
        int m_steps_checked = 0;
        OptimizerCheckpoint m_checkpoint; ///< the one passed to the callback
    };

} // namespace optimizer_detail

} // namespace diffipc
