#pragma once
/// @file stress_norm.hpp
/// Stress p-norm of one state, the usual surrogate of the maximum stress in
/// stress-constrained shape and material optimization.

#include "objectives/state_functional.hpp"

#include <vector>

namespace diffipc {

enum class StressMeasure {
    CAUCHY, ///< \sigma = P F^T / \det F (Pa), true stress in the deformed configuration
    FIRST_PIOLA, ///< P = d\psi/dF (Pa), force per unit rest area
};

enum class StressNormType {
    FROBENIUS, ///< s = \sqrt{S : S}
    /// s = \sqrt{\tfrac32 S : S - \tfrac12 (\operatorname{tr} S)^2}: in 3D the von Mises stress
    /// \sqrt{\tfrac32 \operatorname{dev} S : \operatorname{dev} S}. In 2D (plane strain) the same
    /// formula applied to the in-plane 2 by 2 stress, i.e. the 3D von Mises stress of the
    /// embedding with S_{zz} = 0, s^2 = S_{xx}^2 - S_{xx} S_{yy} + S_{yy}^2 + 3 S_{xy}^2 for a
    /// symmetric S. The plane-strain out-of-plane stress S_{zz} (material dependent) is not
    /// included, so in 2D this is the in-plane von Mises measure, not that of the full 3D state.
    /// For the non-symmetric first Piola stress the same formula is used
    /// (S : S counts S_{xy} and S_{yx} separately); it is nonnegative for every S.
    VON_MISES,
};

struct StressNormOptions {
    double p = 8; ///< exponent, >= 1 (the gradient needs p > 1 wherever an element's stress vanishes)
    StressNormType norm = StressNormType::VON_MISES;
    StressMeasure stress = StressMeasure::CAUCHY;
    /// Divide by the total rest volume V of the elements (a volume-weighted mean):
    /// J = (\sum_e |e| s_e^p / V)^{1/p}, which is <= max_e s_e for every p.
    bool normalized = false;
    std::vector<Index> elements; ///< the elements summed over (a body); empty: all
};

/// @brief f(x) = (\sum_e |e| s_e(F_e)^p)^{1/p} (Pa m^{dim/p}) with s_e the chosen norm of the
/// chosen stress of element e with its own material law and Lame parameters, |e| its rest
/// volume (area in 2D).
///
/// Maximum stress: (\sum_e |e| s_e^p)^{1/p} -> \max_e s_e as p -> \infty (bounded by
/// V^{1/p} \max_e s_e from above and (|e^*|)^{1/p} \max_e s_e from below), so a large p
/// (8..32) with `normalized` gives a smooth approximation of the maximum stress from below.
/// It is evaluated as s_max (\sum_e |e| (s_e / s_max)^p)^{1/p} so that large p does not overflow.
///
/// Derivatives: df/ds_e = |e| (s_e / f)^{p-1} (divided by V when normalized); at f = 0 (no stress
/// anywhere) f is not differentiable and the gradient is zero. Explicit partials: rest
/// positions through F = D_s D_m^{-1} and |e| (element_kinematics.hpp), Lame parameters through
/// P(F; \mu, \lambda) = \mu P(F; 1, 0) + \lambda P(F; 0, 1), which holds for all four material laws.
/// No velocity or density dependence.
class StressNorm : public StateFunctional {
public:
    /// @throws std::invalid_argument for p < 1 or an element index out of range (checked at evaluation).
    explicit StressNorm(StressNormOptions options);
    std::string name() const override { return "stress_norm"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

    const StressNormOptions& options() const { return m_options; }

private:
    StressNormOptions m_options;
};

} // namespace diffipc
