#pragma once
/// @file time_aggregation.hpp
/// Objectives over a run from a per-state functional f_k (state_functional.hpp),
/// for states k = 0..T with times t_k.

#include "objectives/objective.hpp"
#include "objectives/state_functional.hpp"

#include <memory>

namespace diffipc {

enum class TimeMode {
    FINAL, ///< J = f_T (f_0 for a run without steps)
    SUM, ///< J = \sum_{k=1}^{T} f_k (k = 0 too with include_initial)
    TRAPEZOID, ///< J = \sum_{k=1}^{T} (t_k - t_{k-1}) (f_{k-1} + f_k) / 2, the trapezoid rule for \int_{t_0}^{t_T} f dt
    MAX_P, ///< J = (\sum_{k=1}^{T} f_k^p)^{1/p} (k = 0 too with include_initial), needs f_k >= 0
};

/// @brief Parses "final" | "sum" | "trapezoid" | "max_p"; throws InputError naming `field` otherwise.
TimeMode parse_time_mode(const std::string& name, const std::string& field);
std::string to_string(TimeMode mode);

/// Aggregation in time of a per-state functional.
///
/// MAX_P is a smooth upper bound of max_k f_k: max_k f_k <= J <= n^{1/p} max_k f_k
/// over the n aggregated states, so it tends to the maximum as p grows (and is
/// evaluated as f_max (\sum_k (f_k / f_max)^p)^{1/p} so that a large p does not
/// overflow). Its gradient dJ/df_k = (f_k / J)^{p-1}; at J = 0 (every f_k = 0)
/// J is not differentiable and the gradient returned is zero.
class TimeAggregation : public Objective {
public:
    /// @param functional the per-state functional f
    /// @param p          exponent of MAX_P, >= 1 (ignored by the other modes)
    /// @param include_initial whether SUM and MAX_P include the initial state k = 0
    TimeAggregation(
        std::unique_ptr<StateFunctional> functional, TimeMode mode, double p = 8, bool include_initial = false);

    std::string name() const override;
    /// @throws ObjectiveDomainError for MAX_P when some aggregated f_k is negative beyond its round-off.
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    /// The weighted sum of the states' round-offs (max_p: the largest).
    double round_off(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    /// {T} for FINAL, every state otherwise.
    std::vector<int> states_read(int steps) const override;

    const StateFunctional& functional() const { return *m_functional; }
    TimeMode mode() const { return m_mode; }

private:
    /// The aggregated states k and the weight of each in a linear mode (SUM, FINAL, TRAPEZOID).
    void states(const Trajectory& trajectory, std::vector<int>& k, std::vector<double>& weight) const;
    /// For MAX_P: J and the values f_k of the aggregated states.
    double max_p(
        const Simulator& sim, const Trajectory& trajectory, const std::vector<int>& k, std::vector<double>& f) const;

    std::unique_ptr<StateFunctional> m_functional;
    TimeMode m_mode;
    double m_p;
    bool m_include_initial;
};

} // namespace diffipc
