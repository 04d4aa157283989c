#pragma once
/// @file state_tracking.hpp
/// A per-state functional compared with targets at listed states: a measured reaction force, a
/// cell's stress against a plateau, a macro gradient held at zero.

#include "objectives/objective.hpp"
#include "objectives/state_functional.hpp"

#include <memory>
#include <vector>

namespace diffipc {

/// Which deviations from a target count: both signs, or only one (a bound: ABOVE penalizes f > y,
/// an upper bound; BELOW penalizes f < y, a lower bound).
enum class TrackingSide { BOTH, ABOVE, BELOW };

/// @brief J = \tfrac{w}{2} \sum_{s} r_s^2 over the listed states k_s with targets y_s, r_s = f(x_{k_s}) - y_s
/// (one-sided: r_s = max(f - y, 0) for ABOVE, min(f - y, 0) for BELOW; J stays C^1).
/// Gradient: w r_s df_k.
class StateTracking : public Objective {
public:
    /// @param steps   the states k compared (0 = initial state, 1..T the steps)
    /// @param targets one target per listed state (f's unit)
    /// @param weight  w > 0 (1 / sigma^2 for a quantity measured with standard deviation sigma)
    /// @throws std::invalid_argument for inconsistent sizes, a null functional or w <= 0
    StateTracking(std::unique_ptr<StateFunctional> functional, std::vector<int> steps, std::vector<double> targets,
        double weight, TrackingSide side = TrackingSide::BOTH);

    std::string name() const override { return m_functional->name() + "_tracking"; }
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    std::vector<int> states_read(int) const override { return m_steps; }

private:
    std::unique_ptr<StateFunctional> m_functional;
    std::vector<int> m_steps;
    std::vector<double> m_targets;
    double m_weight;
    TrackingSide m_side;
    /// The residual that counts: f - y, clipped to the penalized side.
    double residual(double f, double y) const;
};

} // namespace diffipc
