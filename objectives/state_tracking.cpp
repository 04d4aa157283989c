#include "objectives/state_tracking.hpp"

#include <algorithm>
#include <stdexcept>

namespace diffipc {

StateTracking::StateTracking(std::unique_ptr<StateFunctional> functional, std::vector<int> steps,
    std::vector<double> targets, double weight, TrackingSide side)
    : m_functional(std::move(functional))
    , m_steps(std::move(steps))
    , m_targets(std::move(targets))
    , m_weight(weight)
    , m_side(side)
{
    if (!m_functional)
        throw std::invalid_argument("StateTracking: no functional");
    if (m_steps.size() != m_targets.size())
        throw std::invalid_argument(m_functional->name() + ": expected one target per listed step");
    if (!(m_weight > 0))
        throw std::invalid_argument(m_functional->name() + ": the weight must be positive");
}

double StateTracking::residual(double f, double y) const
{
    const double r = f - y;
    switch (m_side) {
    case TrackingSide::ABOVE:
        return std::max(r, 0.0);
    case TrackingSide::BELOW:
        return std::min(r, 0.0);
    case TrackingSide::BOTH:
        break;
    }
    return r;
}

double StateTracking::value(const Simulator& sim, const Trajectory& trajectory) const
{
    double J = 0;
    for (size_t i = 0; i < m_steps.size(); ++i) {
        const int k = m_steps[i];
        const double r = residual(
            m_functional->value(
                sim, { k, state_time(trajectory, k), state_positions(trajectory, k), state_velocities(trajectory, k) }),
            m_targets[i]);
        J += 0.5 * m_weight * r * r;
    }
    return J;
}

void StateTracking::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    for (size_t i = 0; i < m_steps.size(); ++i) {
        const int k = m_steps[i];
        const StateRef state { k, state_time(trajectory, k), state_positions(trajectory, k),
            state_velocities(trajectory, k) };
        const double r = residual(m_functional->value(sim, state), m_targets[i]);
        m_functional->add_gradient(sim, state, request, scale * m_weight * r, seed.positions.at(size_t(k)),
            seed.velocities.at(size_t(k)), seed.explicit_partials);
    }
}

} // namespace diffipc
