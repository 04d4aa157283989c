#pragma once
/// @file penalty.hpp
/// The penalty contact baseline (scene `contact.model: "penalty"`, docs/math.md "Penalty
/// contact"): a quadratic penalty on the penetration into a layer of thickness dhat around each
/// surface, P(d) = 1/2 (dhat - d)^2 for d < dhat and 0 beyond, times the penalty stiffness k (N/m):
/// a linear spring of stiffness k per contact pair inside the layer, force k (dhat - d).
/// Unlike the barrier it is finite at d = 0 and lets surfaces pass through each other.

namespace diffipc {

/// P and its first two derivatives with respect to the squared distance s = d^2
/// (the form the contact distances provide): P' = -(dhat - d) / (2 d), P'' = dhat / (4 d^3).
struct PenaltyValue {
    double value = 0, first = 0, second = 0;
};

/// @brief P(sqrt(s)) and its s-derivatives; all 0 for s >= dhat^2. A distance below
/// 1e-9 dhat is taken as 1e-9 dhat (surfaces that touch exactly: the force's direction is
/// undefined there, its size is k dhat).
PenaltyValue penalty_of_squared_distance(double s, double dhat);

/// @brief |dP/dd| = dhat - d for d < dhat, else 0: the normal force of one pair per unit stiffness.
double penalty_force(double d, double dhat);

} // namespace diffipc
