#pragma once
/// @file problem_parameters.hpp
/// The "parameters" list of a problem file (docs/problem_format.md): which simulation
/// values the optimization vector p drives. Entry k is a slice of p; value i of the slice
/// drives a list of canonical entries (forward/simulation/parameters.hpp): a selection of
/// rest-position components (shape), Young's modulus and Poisson's ratio or the Lame
/// parameters mu and lambda (one pair or the other) or density per element or per body, an
/// initial velocity or displacement per body or per vertex, the friction coefficients, or
/// every prescribed displacement of every step.

#include "adjoint/adjoint.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/parameters.hpp"
#include "forward/simulation/simulator.hpp"
#include "shape_opt/parametrization/parameter_map.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace diffipc {

/// Where a design puts the shape's remeshable map (a free-form deformation:
/// ProblemParameters::shape_lattice_input).
struct ShapeLatticeInput {
    size_t entry = 0, map = 0; ///< parameters[entry].maps[map] is the remeshable shape ("ffd")
    VectorXd design; ///< the entry's design values
    VectorXd lattice; ///< the map's input
    std::string mesh_input_key; ///< the map spec's key for it (RemeshableShape::mesh_input_key)
};

/// One entry of the problem's "parameters" list.
struct ParameterSpec {
    enum class Kind {
        SHAPE,
        YOUNGS_MODULUS,
        POISSON_RATIO,
        LAME_MU,
        LAME_LAMBDA,
        DENSITY,
        INITIAL_VELOCITY,
        INITIAL_DISPLACEMENT,
        PRESCRIBED,
        FRICTION
    };
    Kind kind = Kind::SHAPE;
    std::string name; ///< as in the file ("shape", "E", "mu", ...)
    std::string field; ///< JSON path for messages
    /// Canonical indices this parameter's entries drive: entry i of the slice drives
    /// targets[i] (a list of canonical indices in the block).
    std::vector<std::vector<Index>> targets;
    /// One value per element, per vertex or per prescribed dof (the count depends on the mesh).
    bool per_mesh_item = false;
};

class ProblemParameters {
public:
    /// @brief Parses and checks the list.
    /// @param params the problem's "parameters" (a non-empty list)
    /// @param scene, sim the first load case's scene and a simulator of it (selections, prescribed dofs, friction)
    /// @param bases every load case's canonical values (the first gives p's initial values;
    ///        friction and prescribed parameters need the same sizes in every case)
    /// @throws InputError naming the entry
    ProblemParameters(const nlohmann::json& params, const Scene& scene, const Simulator& sim,
        const std::vector<const SimulationParameters*>& bases);

    /// Size of p.
    Index size() const { return m_size; }
    /// p at the first load case's values (the starting point).
    const VectorXd& initial() const { return m_initial; }
    /// A typical magnitude per variable (gradcheck's direction scale).
    const VectorXd& scales() const { return m_scales; }
    /// Names of the entries with their slice sizes.
    std::vector<std::pair<std::string, Index>> layout() const;
    const std::vector<ParameterSpec>& entries() const { return m_entries; }
    /// The elastic moduli are parametrized by mu and lambda (else by E and nu, or not at all).
    bool lame() const { return m_lame; }
    /// The parameter derivatives the adjoint must compute.
    ParameterRequest request() const;

    /// @brief Writes p into the canonical values `sp` (every target of every entry).
    void apply(const VectorXd& p, SimulationParameters& sp) const;
    /// @brief Adds dJ/dp, from the adjoint's canonical gradient `g` at the values `at`, to
    /// `dJ_dp` (size()); dJ/dE and dJ/dnu by the chain rule through the Lame parameters
    /// (plane stress where `plane_stress`, per element, says so: Simulator::plane_stress()).
    void add_gradient(const ParameterGradient& g, const SimulationParameters& at, const std::vector<char>& plane_stress,
        VectorXd& dJ_dp) const;

    /// The design variables x: per entry, the inputs of its "maps" (docs/parametrizations.md;
    /// an entry without maps: its values). Size of x.
    Index design_size() const { return m_design->in_size(); }
    /// x at the start: the entry's "initial", else the maps' inverse of p's initial values,
    /// else 0 where the maps give those values at 0 (a shape control at rest).
    const VectorXd& design_initial() const { return m_design_initial; }
    /// Bounds of x: the entries' "lower" and "upper" (-inf, +inf without).
    const VectorXd& design_lower() const { return m_design_lower; }
    const VectorXd& design_upper() const { return m_design_upper; }
    /// p = P(x).
    VectorXd parameters_of(const VectorXd& x) const { return m_design->apply(x); }
    /// dJ/dx = P'(x)^T dJ/dp.
    VectorXd design_gradient(const VectorXd& x, const VectorXd& dJ_dp) const { return m_design->vjp(x, dJ_dp); }
    /// Names of the entries with their design sizes.
    std::vector<std::pair<std::string, Index>> design_layout() const;
    /// Whether some entry has maps (else x = p).
    bool has_maps() const { return m_has_maps; }
    /// Why a remesh could not keep these design variables ("" if it can): a remesh needs its
    /// shape entry driven by a free-form deformation, whose variables do not depend on the
    /// mesh (shape_opt/remesh.hpp).
    std::string remesh_obstacle() const;
    /// @brief Where x puts the shape entry's free-form deformation: the entry, the map's index
    /// in its chain, the entry's design values and the lattice's input (the maps before it
    /// applied to them).
    /// @throws std::runtime_error if remesh_obstacle() is not empty
    ShapeLatticeInput shape_lattice_input(const VectorXd& x) const;
    /// @brief The body positions (#V by dim) that x moves onto `current` through the shape's
    /// free-form deformation (FreeFormDeformation::pull_back).
    /// @throws std::runtime_error as shape_lattice_input, or where the pull-back fails
    Positions pull_back_shape(const VectorXd& x, const Positions& current) const;

private:
    void parse_maps(const nlohmann::json& params, const Scene& scene);

    std::vector<ParameterSpec> m_entries;
    std::unique_ptr<Concatenation> m_design;
    std::vector<Index> m_design_sizes;
    std::vector<const ParameterChain*> m_chains; ///< per entry, owned by m_design
    VectorXd m_design_initial, m_design_lower, m_design_upper;
    bool m_has_maps = false;
    std::vector<Index> m_offsets;
    Index m_size = 0;
    VectorXd m_initial, m_scales;
    bool m_lame = false;
};

} // namespace diffipc
