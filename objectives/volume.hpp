#pragma once
/// @file volume.hpp
/// Deformed volume (area in 2D) of the bodies in one state.

#include "objectives/state_functional.hpp"

#include <vector>

namespace diffipc {

/// @brief f(x) = \sum_e vol_e(x) (m^3, m^2 in 2D) with vol_e = \det(D_s) / d! = |e| \det F_e the
/// signed current volume of element e.
///
/// df/dx_a = |e| cof(F_e) G_a. The current volume is a function of x alone (|e| \det F =
/// \det D_s / d!), so there is no explicit parameter partial; no velocity dependence.
///
/// With `rest`: the rest volume f(X) = \sum_e |e| = \sum_e \det(D_m) / d!, the material a shape
/// uses (a volume constraint of shape optimization). df/dX_a = |e| G_a (the same formula at
/// F = I), an explicit partial in the rest positions; no state dependence.
class Volume : public StateFunctional {
public:
    /// @param elements the elements summed over (a body); empty: all
    /// @param rest the rest volume instead of the current one
    explicit Volume(std::vector<Index> elements = {}, bool rest = false)
        : m_elements(std::move(elements))
        , m_rest(rest)
    {
    }
    std::string name() const override { return m_rest ? "rest volume" : "volume"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

private:
    std::vector<Index> m_elements;
    bool m_rest = false;
};

} // namespace diffipc
