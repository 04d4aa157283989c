#pragma once
/// @file potential.hpp
/// A potential is one scalar energy term of the incremental potential, a
/// function of the deformed positions x (flattened vertex-major, #V*dim).
/// The Problem sums only the potentials a scene needs. Later issues add
/// contact, friction and parameter derivatives behind the same interface.

#include "forward/common/types.hpp"

#include <cmath>
#include <string>

namespace diffipc {

class SparseAssembler;

class Potential {
public:
    virtual ~Potential() = default;
    virtual std::string name() const = 0;

    /// @brief Energy at x (J); +inf where undefined (an inverted element).
    virtual double value(const VectorXd& x) const = 0;
    /// @brief Size of the terms that value(x) sums and cancels (J): its round-off
    /// is about machine epsilon times this. Default |value(x)|.
    virtual double value_scale(const VectorXd& x) const { return std::abs(value(x)); }
    /// @brief Adds weight * dE/dx to g (length #V*dim).
    virtual void add_gradient(const VectorXd& x, double weight, VectorXd& g) const = 0;
    /// @brief Adds weight * d2E/dx2 into the assembler's pattern; with
    /// `project_to_psd` each local contribution is made positive semi-definite
    /// first (the Newton search matrix), without it the true Hessian is added.
    virtual void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const = 0;
    /// @brief Shape derivative of the gradient along a direction: adds
    /// weight * d/dX [direction^T dE/dx (x; X)] at fixed x to d_rest_positions
    /// (#V*dim), X the rest positions. The default adds nothing: a potential
    /// whose gradient depends on X must override it (the adjoint relies on it).
    virtual void add_shape_derivative(
        const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const
    {
        (void)x;
        (void)direction;
        (void)weight;
        (void)d_rest_positions;
    }
    /// @brief Largest t in (0, 1] such that x + s p stays valid for this term
    /// for all s in [0, t] (1 if this term has no restriction).
    virtual double max_step(const VectorXd& x, const VectorXd& p) const
    {
        (void)x;
        (void)p;
        return 1.0;
    }
    /// True if the last max_step() could not certify any positive step (CCD budget).
    virtual bool step_unresolved() const { return false; }
    /// True while the term is identically zero (e.g. external forces that are all zero):
    /// the Problem then skips it, as it skips a zero weight.
    virtual bool vanishes() const { return false; }
    /// @brief Called after each accepted Newton iteration at the new iterate;
    /// returns true if the potential changed its own parameters (the energy
    /// at x must then be re-evaluated), e.g. an adaptive barrier stiffness.
    virtual bool end_iteration(const VectorXd& x)
    {
        (void)x;
        return false;
    }
};

} // namespace diffipc
