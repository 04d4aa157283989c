#pragma once
/// @file design_problem.hpp
/// A problem file as an optimization problem (issue 12): the design variables x of its
/// parameter entries (docs/parametrizations.md), f(x) = J(P(x)), and its constraints
/// g_i(P(x)) compared with their bounds, with gradients by the adjoint and the maps' VJPs.
///
/// Constraints reach the optimizer scaled by their bound: c = (g - b) / |b| for g <= b,
/// (b - g) / |b| for g >= b, and h = (g - b) / |b| for g == b (|b| replaced by 1 for b = 0),
/// so that the optimizer's constraint tolerance is relative (1e-6: a millionth of the bound).
///
/// The objective reaches the optimizer divided by |J| at the first design evaluated (the start,
/// for every driver), so that tolerances and the first steps do not depend on J's units (a
/// stress p-norm of 2e5 Pa, a marker misfit of 1e-2 m^2); objective_scale() gives the factor.
///
/// A design that cannot be evaluated is a rejected point, not the end of the run: an
/// invalid rest mesh (inverted elements, an intersecting boundary: shape_opt/rest_validity.hpp),
/// a failed forward step, a value outside a map's domain. Shape steps are bounded by
/// RestValidity::max_step along the rest positions' motion.

#include "forward/common/timer.hpp"
#include "shape_opt/optimizer/optimizer.hpp"
#include "shape_opt/reduced_functional.hpp"
#include "shape_opt/rest_validity.hpp"

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace diffipc {

class DesignProblem : public OptimizationProblem {
public:
    explicit DesignProblem(const ReducedFunctional& functional);
    ~DesignProblem() override;

    /// The reduced functional now evaluated: the one given, or after a remesh the one on the
    /// new mesh (same design variables, bounds and constraints).
    const ReducedFunctional& functional() const { return *m_functional; }
    /// Where remeshed rest meshes go (default: a folder under the system's temporary directory).
    void set_remesh_directory(const std::string& directory) { m_remesh_directory = directory; }
    /// Every remesh so far, and why the last attempt failed ("" if none did).
    const std::vector<RemeshRecord>& remeshes() const { return m_remeshes; }
    const std::string& remesh_failure() const { return m_remesh_failure; }
    /// Called after each remesh (the CLI prints it).
    std::function<void(const RemeshRecord&)> on_remesh;

    Index size() const override { return m_functional->design_size(); }
    int inequalities() const override { return int(m_inequality.size()); }
    int equalities() const override { return int(m_equality.size()); }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override;
    double max_valid_step(const VectorXd& x, const VectorXd& dx) override;
    bool iteration(const IterationInfo& info) override;

    /// Called at every accepted iterate (after the optimizer's own bookkeeping); return false
    /// to stop. The values are those of the iterate; the last evaluation's times are in
    /// last_evaluation().
    std::function<bool(const IterationInfo&)> on_iteration;

    /// The constraint functionals' indices in the problem's "constraints", per kind.
    const std::vector<size_t>& inequality_constraints() const { return m_inequality; }
    const std::vector<size_t>& equality_constraints() const { return m_equality; }
    /// g_i(p) of every constraint at the last successful evaluation (unscaled, in the file's order).
    const VectorXd& last_constraint_values() const { return m_last_constraints; }
    /// The last successful evaluation (value, times; gradients in p's layout).
    const Evaluation& last_evaluation() const { return m_last; }
    /// Why the last rejected point was rejected ("" if none was).
    const std::string& last_rejection() const { return m_last_rejection; }
    int rejections() const { return m_rejections; }
    /// J = objective_scale() * f (1 until the first successful evaluation).
    double objective_scale() const { return m_objective_scale > 0 ? m_objective_scale : 1.0; }
    /// Stop at the first accepted iterate with J <= target and the constraints holding
    /// (OptimizerSettings::objective_target); whether that happened.
    void set_objective_target(double target) { m_objective_target = target; }
    bool target_reached() const { return m_target_reached; }
    /// Fixes the scale (a resumed run keeps its first run's |J(x0)|).
    void set_objective_scale(double scale) { m_objective_scale = scale; }

    /// After a remesh iteration() stops the optimizer (its stored values belong to the old
    /// mesh); minimize_design() continues the run from this checkpoint with the values on the
    /// new mesh.
    bool restart_pending() const { return m_restart != nullptr; }
    std::unique_ptr<OptimizerCheckpoint> take_restart() { return std::move(m_restart); }
    /// Wall time (s) inside evaluate() and max_valid_step() spent in the parameter maps (p = P(x)
    /// and the vector-Jacobian products) and in the validity checks of rest meshes.
    struct Times {
        double parametrization = 0, validity = 0;
    };
    const Times& times() const { return m_times; }
    /// Wall time since the last iteration() began (s).
    double seconds_since_iteration() const { return m_restart_clock.seconds(); }

    /// @brief Remeshes at the accepted design x if the problem's "remesh" settings ask for it
    /// (worst quality below the threshold, remeshes left); iteration() calls it after
    /// on_iteration. Returns whether it remeshed; a failed remesh is recorded in
    /// remesh_failure() and the run goes on with the old mesh.
    /// `seconds`: gmsh's time limit (no remesh at <= 0).
    bool remesh_if_needed(const VectorXd& x, int iteration, bool force = false, double seconds = 600);
    /// A resumed run goes on with the remeshes, attempts, trigger and failed attempts' time of
    /// the run it continues (the CLI keeps them in DIR/remeshes.json).
    void restore_remeshes(
        const std::vector<RemeshRecord>& records, int attempts, double trigger, double failed_seconds);
    int remesh_attempts() const { return m_remesh_attempts; }
    double remesh_trigger() const { return m_remesh_trigger; }
    double failed_remesh_seconds() const { return m_failed_remesh_seconds; }
    /// Wall time of every remesh attempt so far, used or not (s).
    double remesh_seconds() const;
    /// Called after every remesh attempt, used or not (the CLI saves the remesh state).
    std::function<void()> on_remesh_attempt;
    /// Called by minimize_design() with the checkpoint it continues from after a remesh (the
    /// values on the new mesh; the CLI saves it as the run's state).
    std::function<void(const OptimizerCheckpoint&)> on_restart;
    /// Settings minimize_design() passes on: the run's time budget (remeshing gets what is
    /// left of it) and the constraint tolerance (objective_target's feasibility).
    void set_time_budget(double seconds) { m_time_budget = seconds; }
    void set_constraint_tolerance(double tolerance) { m_constraint_tolerance = tolerance; }

private:
    bool reject(const std::string& why);
    /// p = P(x) of the functional now evaluated, kept for the last x.
    VectorXd parameters(const VectorXd& x);
    bool constraints_hold(const OptimizationValues& values) const;
    void build_validity();

    const ReducedFunctional* m_functional;
    std::unique_ptr<ReducedFunctional> m_remeshed; ///< the functional on the newest mesh
    std::string m_remesh_directory;
    std::vector<RemeshRecord> m_remeshes;
    std::string m_remesh_failure;
    double m_remesh_size = 0;
    double m_remesh_trigger = 0; ///< remesh below this worst quality (remesh.hpp)
    int m_remesh_attempts = 0;
    double m_failed_remesh_seconds = 0;
    double m_time_budget = 0;
    double m_constraint_tolerance = 1e-6;
    std::unique_ptr<OptimizerCheckpoint> m_restart;
    Timer m_restart_clock;
    Times m_times;
    VectorXd m_parameters_x, m_parameters_p;
    double m_objective_target = -std::numeric_limits<double>::infinity();
    bool m_target_reached = false;
    std::unique_ptr<RestValidity> m_validity; ///< with a shape entry
    std::vector<size_t> m_inequality, m_equality;
    VectorXd m_scale; ///< per constraint: |bound|, or 1
    Evaluation m_last;
    VectorXd m_last_constraints;
    std::string m_last_rejection;
    int m_rejections = 0;
    double m_objective_scale = 0;
};

/// @brief minimize() (or resume_minimize() from `resume`) of a design problem, continued
/// across remeshes: after each, the run goes on from the remesh's iterate with J, the
/// constraints and the gradients evaluated on the new mesh (one evaluation, counted), its
/// iteration numbers, counts, budgets and (L-BFGS-B) correction pairs kept; the best point
/// so far becomes the remesh's iterate (values on the old mesh do not compare with the new).
OptimizerResult minimize_design(DesignProblem& problem, const VectorXd& x0, const OptimizerSettings& settings,
    const OptimizerCheckpoint* resume = nullptr);

} // namespace diffipc
