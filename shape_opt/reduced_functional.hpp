#pragma once
/// @file reduced_functional.hpp
/// A problem file (docs/problem_format.md): scenes (load cases) with an objective
/// each, and the parameters to differentiate, as one reduced functional
/// p -> J(p) = sum_c w_c J_c(u_c(p), p) with its adjoint gradient dJ/dp.
///
/// The optimization vector p concatenates the listed parameters in order; each
/// maps linearly onto canonical simulation parameters (forward/simulation/parameters.hpp):
/// a selection of rest-position components (shape), Young's modulus and Poisson's
/// ratio or the Lame parameters mu and lambda (one pair or the other) or density
/// per element or per body, an initial velocity or displacement per body or per
/// vertex, the friction coefficients, or every prescribed displacement of every step.
///
/// With the file's "checkpointing" the gradient is computed by checkpointed_gradient()
/// (adjoint/checkpointing.hpp) through StreamedObjectiveAdapter (objectives/streamed.hpp):
/// the same J and dJ/dp to round-off, with the step records bounded by the schedule.

#include "adjoint/adjoint.hpp"
#include "adjoint/checkpointing.hpp"
#include "objectives/objective.hpp"
#include "shape_opt/remesh.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace diffipc {

class CaseDistribution;
class JsonField;
class ProblemParameters;
struct ShapeLatticeInput;

/// What the checkpointed adjoint of one load case held and recomputed.
struct LoadCaseCheckpoint {
    CheckpointStatistics records; ///< the step records (peak held, the schedule's bound, recomputed steps, times)
    int objective_stored_states = 0; ///< states whose x_k, v_k the objective's adapter copied (T + 1 at most)
    size_t objective_stored_bytes = 0; ///< their bytes
};

/// One entry of the problem's "constraints": a functional of one load case with a bound,
/// g(p) <= upper, g(p) >= lower or g(p) == equals (docs/problem_format.md).
struct ConstraintSpec {
    enum class Kind { UPPER, LOWER, EQUALS };
    std::string name; ///< the file's "name", else "constraint i"
    std::string field; ///< "constraints[i]"
    Kind kind = Kind::UPPER;
    double bound = 0;
    size_t load_case = 0;
    nlohmann::json objective; ///< the functional g, an objective (docs/objectives.md)
};

/// Results of one evaluation.
struct Evaluation {
    double value = 0;
    VectorXd gradient; ///< empty unless requested
    /// s, summed over load cases; with checkpointing the adjoint time includes the recomputed steps
    double forward_time = 0, adjoint_time = 0;
    /// One per load case when the problem has checkpointing and the gradient was computed; else empty.
    std::vector<LoadCaseCheckpoint> checkpoints;
    /// With the gradient: the parameter blocks the adjoint computed (adjoint/sensitivity.hpp
    /// computed_blocks(), union over load cases and functionals, sorted): only those the
    /// parametrization reads, nothing else.
    std::vector<std::string> adjoint_blocks;
    /// With constraints: g_i(p) for every constraint (not compared with its bound), and with
    /// the gradient dg_i/dp as row i; else empty.
    VectorXd constraint_values;
    MatrixXd constraint_gradients;
};

class ReducedFunctional {
public:
    /// @brief Loads and validates a problem file; relative scene paths are relative to the file.
    /// `device`: "cpu" or "gpu" runs every load case's simulations there, replacing the scenes'
    /// "device" (select_device's checks; errors name "device"); empty: the scenes' own.
    /// @throws InputError naming the field or file.
    static ReducedFunctional load(const std::string& path, const std::string& device = "");
    /// @brief From a parsed document; `base_directory` resolves scene paths; `device` as load()'s.
    ReducedFunctional(const nlohmann::json& document, const std::string& base_directory, const std::string& source,
        const std::string& device = "");
    ~ReducedFunctional();
    ReducedFunctional(ReducedFunctional&&) noexcept;

    /// Number of optimization variables.
    Index size() const;
    /// The parameter values of the scenes as given (the starting point).
    const VectorXd& initial() const;
    /// Names of the parameters, one per "parameters" entry, with their slice sizes.
    std::vector<std::pair<std::string, Index>> layout() const;

    /// @brief J(p) and, if `gradient`, dJ/dp by the adjoint; with `constraints`, also every
    /// constraint's functional and its gradient, from the same forward run of its load case
    /// (one adjoint sweep per functional; with checkpointing, one checkpointed run each).
    /// @throws InputError for a p of the wrong size or with non-finite entries;
    ///         AdjointError (no gradient) if a forward step fails.
    Evaluation evaluate(const VectorXd& p, bool gradient, bool constraints = false) const;

    /// @brief Load case c's share of evaluate(p, ...): its weighted objective and gradient, the rows
    /// of the constraints on it (the other rows zero), its blocks, times and checkpoint record.
    /// evaluate() is the sum of the shares in case order (add_share), whatever evaluated them: a
    /// distributed run that evaluates the cases apart and adds their shares in that order gets the
    /// same bits. The checks on p are evaluate()'s (check_parameters); those on the sum are not made.
    /// @throws AdjointError (no gradient) if a forward step of the case fails; InputError from its
    ///         functionals.
    Evaluation evaluate_case(size_t c, const VectorXd& p, bool gradient, bool constraints = false) const;
    /// @brief total += share, one load case's (evaluate_case) after those before it: sums of values,
    /// gradients, constraint rows and times; the union of the adjoint blocks (sorted); its checkpoint
    /// record appended. An empty total (default-constructed) takes the share's shape.
    static void add_share(Evaluation& total, const Evaluation& share);
    /// @throws InputError naming "parameters" for a p of the wrong size or with non-finite entries.
    void check_parameters(const VectorXd& p) const;
    /// @brief evaluate()'s checks on the sum of the shares: a finite J and constraint values, and
    /// with `gradient` finite derivatives.
    /// @throws ObjectiveDomainError for a J or constraint value that is not finite; AdjointError for a
    ///         derivative that is not
    void check_sum(const Evaluation& total, bool gradient, bool constraints) const;

    /// @brief From now on evaluate() runs through `distribution` (shape_opt/case_distribution.hpp:
    /// the load cases over processes, the same bits); null: here, case after case.
    void set_distribution(std::shared_ptr<CaseDistribution> distribution) { m_distribution = std::move(distribution); }
    const std::shared_ptr<CaseDistribution>& distribution() const { return m_distribution; }
    /// A number no other ReducedFunctional of this process has (a distribution's name for the problem).
    uint64_t id() const { return m_id; }
    /// What the problem was loaded from (its path, or a description), as errors name it.
    const std::string& source() const { return m_source; }

    /// The design variables x (docs/parametrizations.md): per parameter entry, the inputs of
    /// its "maps"; p = P(x). Without maps x = p.
    Index design_size() const;
    const VectorXd& design_initial() const;
    std::vector<std::pair<std::string, Index>> design_layout() const;
    /// Bounds of x from the entries' "lower" and "upper" (infinite without).
    const VectorXd& design_lower() const;
    const VectorXd& design_upper() const;
    /// The file's "optimizer" object (null without), read by the optimization run.
    const nlohmann::json& optimizer_spec() const { return m_optimizer; }
    /// The file's "remesh" settings (RemeshSettings(), never remesh, without; shape_opt/remesh.hpp).
    const RemeshSettings& remesh_settings() const { return m_remesh; }
    /// Why a remesh could not keep the design variables ("" if it can).
    std::string remesh_obstacle() const;
    /// Where x puts the shape's free-form deformation (ProblemParameters::shape_lattice_input).
    ShapeLatticeInput shape_lattice_input(const VectorXd& x) const;
    /// The positions that x moves onto `current` through the shape's free-form deformation
    /// (ProblemParameters::pull_back_shape).
    Positions pull_back_shape(const VectorXd& x, const Positions& current) const;
    /// The document as loaded and the folder its relative paths start from (for the problem
    /// file an optimization writes with its optimum).
    const nlohmann::json& document() const { return m_document; }
    const std::string& base_directory() const { return m_base_directory; }
    /// p = P(x).
    VectorXd parameters_of(const VectorXd& x) const;
    /// dJ/dx = P'(x)^T dJ/dp (and so for any row vector in p's layout).
    VectorXd design_gradient(const VectorXd& x, const VectorXd& dJ_dp) const;

    /// Whether p moves rest positions (a "shape" entry), and the rest positions it gives
    /// (#V * dim of the bodies, vertex-major; the first load case's mesh, which every case shares).
    bool has_shape() const;
    VectorXd rest_positions_of(const VectorXd& p) const;
    /// The first load case's simulation parameters with p applied (rest positions, E and nu
    /// or mu and lambda, densities, ...).
    SimulationParameters simulation_parameters_of(const VectorXd& p) const;
    /// The first load case's scene (the mesh every case shares), and load case c's.
    const Scene& scene() const;
    const Scene& scene(size_t c) const;
    /// The device the scenes were moved to at load ("" if they keep their own): a remeshed problem
    /// is loaded with it too.
    const std::string& device_override() const { return m_device; }
    size_t load_cases() const;

    /// The problem's "constraints" (empty without).
    const std::vector<ConstraintSpec>& constraints() const { return m_constraints; }

    /// Settings of `diffipc gradcheck` from the file's optional "gradcheck" object.
    struct CheckSettings {
        int directions = 2;
        unsigned seed = 1;
        double step = 1e-2; ///< first Taylor step (relative to the direction)
        int halvings = 4;
    };
    const CheckSettings& check_settings() const { return m_check; }
    /// Direction scale per variable (a typical magnitude: lengths for positions, the value for moduli).
    const VectorXd& scales() const;
    /// The file's "checkpointing" (mode NONE without it: the full-memory adjoint).
    const CheckpointSettings& checkpointing() const { return m_checkpointing; }

private:
    void parse_constraints(const JsonField& list);

    struct LoadCase;
    std::vector<std::unique_ptr<LoadCase>> m_cases;
    std::unique_ptr<ProblemParameters> m_parameters;
    CheckSettings m_check;
    CheckpointSettings m_checkpointing;
    std::vector<ConstraintSpec> m_constraints;
    RemeshSettings m_remesh;
    nlohmann::json m_optimizer, m_document;
    std::string m_base_directory;
    std::string m_device;
    std::string m_source;
    uint64_t m_id = 0;
    std::shared_ptr<CaseDistribution> m_distribution;
};

} // namespace diffipc
