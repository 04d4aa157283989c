#include "objectives/time_aggregation.hpp"

#include "forward/common/error.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

TimeMode parse_time_mode(const std::string& name, const std::string& field)
{
    if (name == "final")
        return TimeMode::FINAL;
    if (name == "sum")
        return TimeMode::SUM;
    if (name == "trapezoid")
        return TimeMode::TRAPEZOID;
    if (name == "max_p")
        return TimeMode::MAX_P;
    throw InputError(field, "unknown time aggregation \"" + name + "\" (expected final, sum, trapezoid or max_p)");
}

std::string to_string(TimeMode mode)
{
    switch (mode) {
    case TimeMode::FINAL:
        return "final";
    case TimeMode::SUM:
        return "sum";
    case TimeMode::TRAPEZOID:
        return "trapezoid";
    case TimeMode::MAX_P:
        return "max_p";
    }
    return "?";
}

TimeAggregation::TimeAggregation(
    std::unique_ptr<StateFunctional> functional, TimeMode mode, double p, bool include_initial)
    : m_functional(std::move(functional))
    , m_mode(mode)
    , m_p(p)
    , m_include_initial(include_initial)
{
    if (!m_functional)
        throw std::invalid_argument("TimeAggregation needs a functional");
    if (mode == TimeMode::MAX_P && !(p >= 1 && std::isfinite(p)))
        throw std::invalid_argument("TimeAggregation: max_p needs a finite p >= 1");
}

std::string TimeAggregation::name() const
{
    const std::string mode = m_mode == TimeMode::MAX_P ? "max_p(" + std::to_string(m_p) + ")" : to_string(m_mode);
    return mode + "(" + m_functional->name() + ")";
}

std::vector<int> TimeAggregation::states_read(int steps) const
{
    return m_mode == TimeMode::FINAL ? std::vector<int> { steps } : Objective::states_read(steps);
}

void TimeAggregation::states(const Trajectory& trajectory, std::vector<int>& k, std::vector<double>& weight) const
{
    const int T = num_steps(trajectory);
    k.clear();
    weight.clear();
    switch (m_mode) {
    case TimeMode::FINAL:
        k.push_back(T);
        weight.push_back(1.0);
        break;
    case TimeMode::SUM:
    case TimeMode::MAX_P:
        for (int i = m_include_initial ? 0 : 1; i <= T; ++i) {
            k.push_back(i);
            weight.push_back(1.0);
        }
        break;
    case TimeMode::TRAPEZOID:
        if (T == 0)
            break;
        for (int i = 0; i <= T; ++i) {
            const double before = i > 0 ? state_time(trajectory, i) - state_time(trajectory, i - 1) : 0.0;
            const double after = i < T ? state_time(trajectory, i + 1) - state_time(trajectory, i) : 0.0;
            k.push_back(i);
            weight.push_back(0.5 * (before + after));
        }
        break;
    }
}

namespace {
    StateRef state_ref(const Trajectory& trajectory, int k)
    {
        return { k, state_time(trajectory, k), state_positions(trajectory, k), state_velocities(trajectory, k) };
    }
} // namespace

double TimeAggregation::max_p(
    const Simulator& sim, const Trajectory& trajectory, const std::vector<int>& k, std::vector<double>& f) const
{
    f.resize(k.size());
    double f_max = 0;
    for (size_t i = 0; i < k.size(); ++i) {
        const StateRef state = state_ref(trajectory, k[i]);
        f[i] = m_functional->value(sim, state);
        if (f[i] < 0) {
            // Zero up to round-off counts as zero; below, the value is truly negative.
            const double round_off = m_functional->round_off(sim, state);
            if (!(f[i] >= -round_off))
                throw ObjectiveDomainError("max_p time aggregation needs nonnegative values; " + m_functional->name()
                    + " is " + format_number(f[i]) + " at state " + std::to_string(k[i]) + ", beyond its round-off of "
                    + format_number(round_off));
            f[i] = 0;
        }
        f_max = std::max(f_max, f[i]);
    }
    if (f_max == 0)
        return 0;
    double sum = 0;
    for (double fi : f)
        sum += std::pow(fi / f_max, m_p);
    return f_max * std::pow(sum, 1.0 / m_p);
}

double TimeAggregation::round_off(const Simulator& sim, const Trajectory& trajectory) const
{
    std::vector<int> k;
    std::vector<double> weight;
    states(trajectory, k, weight);
    double total = 0;
    for (size_t i = 0; i < k.size(); ++i) {
        const double r = m_functional->round_off(sim, state_ref(trajectory, k[i]));
        total = m_mode == TimeMode::MAX_P ? std::max(total, r) : total + std::abs(weight[i]) * r;
    }
    return total;
}

double TimeAggregation::value(const Simulator& sim, const Trajectory& trajectory) const
{
    std::vector<int> k;
    std::vector<double> weight;
    states(trajectory, k, weight);
    if (m_mode == TimeMode::MAX_P) {
        std::vector<double> f;
        return max_p(sim, trajectory, k, f);
    }
    double J = 0;
    for (size_t i = 0; i < k.size(); ++i)
        J += weight[i] * m_functional->value(sim, state_ref(trajectory, k[i]));
    return J;
}

void TimeAggregation::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    std::vector<int> k;
    std::vector<double> weight;
    states(trajectory, k, weight);
    if (m_mode == TimeMode::MAX_P) {
        std::vector<double> f;
        const double J = max_p(sim, trajectory, k, f);
        if (J == 0)
            return;
        for (size_t i = 0; i < k.size(); ++i)
            weight[i] = std::pow(f[i] / J, m_p - 1);
    }
    for (size_t i = 0; i < k.size(); ++i) {
        if (weight[i] == 0)
            continue;
        const size_t s = size_t(k[i]);
        m_functional->add_gradient(sim, state_ref(trajectory, k[i]), request, scale * weight[i], seed.positions.at(s),
            seed.velocities.at(s), seed.explicit_partials);
    }
}

} // namespace diffipc
