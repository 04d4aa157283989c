#include "objectives/combinators.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

WeightedSum::WeightedSum(std::vector<Term> terms)
    : m_terms(std::move(terms))
{
    if (m_terms.empty())
        throw std::invalid_argument("weighted sum: no terms");
    for (const Term& t : m_terms)
        if (!t.objective)
            throw std::invalid_argument("weighted sum: null objective");
}

std::vector<int> WeightedSum::states_read(int steps) const
{
    std::vector<int> k;
    for (const Term& t : m_terms) {
        const std::vector<int> kt = t.objective->states_read(steps);
        k.insert(k.end(), kt.begin(), kt.end());
    }
    std::sort(k.begin(), k.end());
    k.erase(std::unique(k.begin(), k.end()), k.end());
    return k;
}

std::string WeightedSum::name() const
{
    std::string s;
    for (const Term& t : m_terms)
        s += (s.empty() ? "" : " + ") + std::to_string(t.weight) + " " + t.objective->name();
    return "(" + s + ")";
}

double WeightedSum::value(const Simulator& sim, const Trajectory& trajectory) const
{
    double J = 0;
    for (const Term& t : m_terms)
        J += t.weight * t.objective->value(sim, trajectory);
    return J;
}

double WeightedSum::round_off(const Simulator& sim, const Trajectory& trajectory) const
{
    double total = 0;
    for (const Term& t : m_terms)
        total += std::abs(t.weight) * t.objective->round_off(sim, trajectory);
    return total;
}

void WeightedSum::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    for (const Term& t : m_terms)
        if (t.weight != 0)
            t.objective->add_gradient(sim, trajectory, request, scale * t.weight, seed);
}

Power::Power(std::unique_ptr<Objective> objective, double q)
    : m_objective(std::move(objective))
    , m_q(q)
{
    if (!m_objective)
        throw std::invalid_argument("power: null objective");
    if (!std::isfinite(q))
        throw std::invalid_argument("power: q must be finite");
}

std::string Power::name() const { return "(" + m_objective->name() + ")^" + std::to_string(m_q); }

double Power::base(const Simulator& sim, const Trajectory& trajectory) const
{
    const double G = m_objective->value(sim, trajectory);
    if (G < 0 && m_q != std::round(m_q)) {
        const double round_off = m_objective->round_off(sim, trajectory);
        if (!(G >= -round_off))
            throw ObjectiveDomainError("power " + format_number(m_q) + " of " + m_objective->name() + " = "
                + format_number(G) + ": a non-integer power of a negative value (beyond its round-off of "
                + format_number(round_off) + ")");
        return 0.0; // zero up to round-off
    }
    if (G == 0 && m_q < 0)
        throw ObjectiveDomainError("power " + format_number(m_q) + " of " + m_objective->name() + " = 0 is infinite");
    return G;
}

double Power::value(const Simulator& sim, const Trajectory& trajectory) const
{
    return std::pow(base(sim, trajectory), m_q);
}

void Power::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    const double G = base(sim, trajectory);
    if (m_q == 0)
        return;
    if (G == 0 && m_q < 1)
        throw ObjectiveDomainError("power " + format_number(m_q) + " of " + m_objective->name()
            + " = 0: the gradient of G^q at G = 0 is infinite for q < 1");
    m_objective->add_gradient(sim, trajectory, request, scale * m_q * std::pow(G, m_q - 1), seed);
}

SoftConstraint::SoftConstraint(std::unique_ptr<Objective> objective, ConstraintSense sense, double bound, double weight)
    : m_objective(std::move(objective))
    , m_sense(sense)
    , m_bound(bound)
    , m_weight(weight)
{
    if (!m_objective)
        throw std::invalid_argument("constraint: null objective");
    if (!(weight > 0 && std::isfinite(weight)) || !std::isfinite(bound))
        throw std::invalid_argument("constraint: the weight must be positive and the bound finite");
}

std::string SoftConstraint::name() const
{
    return "penalty(" + m_objective->name() + (m_sense == ConstraintSense::UPPER ? " <= " : " >= ")
        + std::to_string(m_bound) + ")";
}

double SoftConstraint::violation(double G) const
{
    return std::max(0.0, m_sense == ConstraintSense::UPPER ? G - m_bound : m_bound - G);
}

double SoftConstraint::value(const Simulator& sim, const Trajectory& trajectory) const
{
    const double v = violation(m_objective->value(sim, trajectory));
    return m_weight * v * v;
}

void SoftConstraint::add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
    double scale, StateSeed& seed) const
{
    const double v = violation(m_objective->value(sim, trajectory));
    if (v == 0)
        return;
    // d/dG of w (G - b)^2 is 2 w v; of w (b - G)^2 it is -2 w v.
    const double dG = 2 * m_weight * v * (m_sense == ConstraintSense::UPPER ? 1.0 : -1.0);
    m_objective->add_gradient(sim, trajectory, request, scale * dG, seed);
}

} // namespace diffipc
