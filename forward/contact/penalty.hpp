#pragma once
/// @file penalty.hpp
/// The penalty contact baseline (scene `contact.model: "penalty"`, docs/math.md "Penalty
/// contact"): a quadratic penalty on the penetration into a layer of thickness dhat around each
/// surface, P(d) = 1/2 (dhat - d)^2 for d < dhat and 0 beyond, times the penalty stiffness k (N/m):
/// a linear spring of stiffness k per contact pair inside the layer, force k (dhat - d).
/// Unlike the barrier it is finite at d = 0 and lets surfaces pass through each other.

#include "forward/kernels/contact_pair.hpp"

namespace diffipc {

/// P and its first two derivatives with respect to the squared distance s = d^2 (the form the
/// contact distances provide): P' = -(dhat - d) / (2 d), P'' = dhat / (4 d^3). The functions are
/// the shared kernels' (forward/kernels/contact_pair.hpp), which both paths evaluate.
using PenaltyValue = kernels::EnergyTerms<>;
using kernels::penalty_force;
using kernels::penalty_of_squared_distance;

} // namespace diffipc
