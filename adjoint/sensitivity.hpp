#pragma once
/// @file sensitivity.hpp
/// The data the adjoint exchanges with objectives and parametrizations.
///
/// Canonical parameters of a simulation (forward/simulation/parameters.hpp):
///   rest positions X (#V*dim, flattened vertex-major; shape), per-element Lame
///   parameters mu, lambda (#E, Pa), per-element density rho (#E, kg/m^3),
///   friction coefficient per contact group (bodies, then obstacles),
///   initial displacement u0 = x_0 - X and initial velocity v_0 (#V*dim),
///   prescribed displacements g_k of the constrained dofs per step k = 1..T
///   (T by #prescribed dofs, in Simulator::prescribed_dofs() order).
/// The state of step k (k = 0 is the initial state) is the positions x_k and
/// velocities v_k, #V*dim each.

#include "forward/common/types.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// Which canonical parameter blocks a gradient call computes (nothing else is).
struct ParameterRequest {
    bool rest_positions = false;
    bool lame = false; ///< mu and lambda per element (E and nu follow by the chain rule)
    bool density = false;
    bool friction = false;
    bool initial_displacement = false;
    bool initial_velocity = false;
    bool prescribed = false;
    bool macro = false; ///< a periodic cell's prescribed macro gradient per step

    bool any() const
    {
        return rest_positions || lame || density || friction || initial_displacement || initial_velocity || prescribed
            || macro;
    }
};

/// dJ/dp for the canonical blocks; a block not requested (or with no
/// contribution) is left empty (size 0), which reads as zero.
struct ParameterGradient {
    VectorXd rest_positions; ///< #V*dim (J/m)
    VectorXd mu, lambda; ///< #E (J/Pa)
    VectorXd density; ///< #E
    VectorXd friction; ///< #groups
    VectorXd initial_displacement; ///< #V*dim
    VectorXd initial_velocity; ///< #V*dim
    MatrixXd prescribed; ///< T by #prescribed dofs
    /// Periodic cells: T by d^2, dJ/dG at each step (zero in G's free components).
    MatrixXd macro;

    /// this += scale * other, growing empty blocks as needed.
    void add(const ParameterGradient& other, double scale = 1.0);
};

/// The names of the blocks a gradient holds (non-empty): "rest_positions", "lame" (mu and
/// lambda), "density", "friction", "initial_displacement", "initial_velocity", "prescribed", "macro".
std::vector<std::string> computed_blocks(const ParameterGradient& g);

/// @brief Adds `scale * v` to `block`, allocating it (zeros) if empty.
void accumulate(VectorXd& block, const VectorXd& v, double scale = 1.0);
void accumulate(MatrixXd& block, const MatrixXd& v, double scale = 1.0);

/// What an objective J hands the adjoint: dJ/dx_k and dJ/dv_k for every state
/// k = 0..T (an empty vector reads as zero), and J's explicit partial
/// derivatives with respect to the parameters at fixed states.
struct StateSeed {
    std::vector<VectorXd> positions; ///< T+1 entries, each empty or #V*dim
    std::vector<VectorXd> velocities; ///< T+1 entries, each empty or #V*dim
    ParameterGradient explicit_partials;

    /// @brief Sizes the per-state lists for T steps (entries stay empty).
    void resize(int steps)
    {
        positions.resize(size_t(steps) + 1);
        velocities.resize(size_t(steps) + 1);
    }
    /// @brief positions[k] += scale * v (allocating the entry if empty).
    void add_position(int k, const VectorXd& v, double scale = 1.0) { accumulate(positions[size_t(k)], v, scale); }
    void add_velocity(int k, const VectorXd& v, double scale = 1.0) { accumulate(velocities[size_t(k)], v, scale); }
};

/// @brief dJ/dE and dJ/dnu from dJ/dmu and dJ/dlambda (per element).
/// @param E, nu #E Young's moduli (Pa) and Poisson's ratios
/// @param plane_stress #E flags (empty: none): lambda = E nu / (1 - nu^2) there
void lame_to_young_poisson(const VectorXd& E, const VectorXd& nu, const VectorXd& dmu, const VectorXd& dlambda,
    VectorXd& dE, VectorXd& dnu, const std::vector<char>& plane_stress = {});

} // namespace diffipc
