#pragma once
/// @file combinators.hpp
/// Objectives built from other objectives: weighted sums, powers and soft
/// inequality constraints (penalties). Each owns its terms.

#include "objectives/objective.hpp"

#include <memory>
#include <vector>

namespace diffipc {

/// @brief J = \sum_i w_i J_i.
class WeightedSum : public Objective {
public:
    struct Term {
        double weight;
        std::unique_ptr<Objective> objective;
    };
    /// @throws std::invalid_argument for no terms or a null objective.
    explicit WeightedSum(std::vector<Term> terms);

    std::string name() const override;
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    /// Those of every term.
    std::vector<int> states_read(int steps) const override;
    /// sum_i |w_i| round_off_i.
    double round_off(const Simulator& sim, const Trajectory& trajectory) const override;

    const std::vector<Term>& terms() const { return m_terms; }

private:
    std::vector<Term> m_terms;
};

/// @brief J = G^q with dJ = q G^{q-1} dG.
/// For a non-integer q, G must be >= 0 up to its round-off (a G in [-round_off, 0) counts as 0);
/// otherwise, and for the infinite gradient at G = 0 when q < 1 (or the value there, q < 0),
/// ObjectiveDomainError.
class Power : public Objective {
public:
    Power(std::unique_ptr<Objective> objective, double q);

    std::string name() const override;
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    std::vector<int> states_read(int steps) const override { return m_objective->states_read(steps); }

private:
    /// G, or 0 for a G within its round-off below 0 when q is not an integer.
    double base(const Simulator& sim, const Trajectory& trajectory) const;

    std::unique_ptr<Objective> m_objective;
    double m_q;
};

enum class ConstraintSense {
    UPPER, ///< G <= bound
    LOWER, ///< G >= bound
};

/// @brief Quadratic exterior penalty of an inequality constraint on G:
/// J = w \max(0, G - b)^2 for G <= b (UPPER), J = w \max(0, b - G)^2 for G >= b (LOWER).
/// J is C^1 in G (its gradient 2 w (G - b) dG vanishes continuously at the bound).
class SoftConstraint : public Objective {
public:
    /// @param weight w > 0
    SoftConstraint(std::unique_ptr<Objective> objective, ConstraintSense sense, double bound, double weight);

    std::string name() const override;
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    std::vector<int> states_read(int steps) const override { return m_objective->states_read(steps); }

private:
    /// max(0, G - b) (UPPER) or max(0, b - G) (LOWER).
    double violation(double G) const;

    std::unique_ptr<Objective> m_objective;
    ConstraintSense m_sense;
    double m_bound, m_weight;
};

} // namespace diffipc
