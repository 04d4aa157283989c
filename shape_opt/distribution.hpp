#pragma once

/// Splitting a problem's load cases over processes (the groundwork of MPI runs, issue 18): which
/// process evaluates which case, and a case's share of an evaluation (ReducedFunctional::evaluate_case)
/// as bytes, bit for bit, to send it to the process that adds the shares in case order.

#include "shape_opt/reduced_functional.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// @brief Which process evaluates each of `cases` load cases: owner[c] in [0, processes).
/// With costs (one per case, e.g. the seconds its last evaluation took): the longest-processing-time
/// rule, the cases by decreasing cost (equal costs: the lower case first), each to the process with
/// the least cost so far (ties: the lower process); its longest process is within 4/3 of the best
/// possible. Without (empty costs), round robin: case c to process c mod processes. Deterministic:
/// every process computes the same assignment from the same costs.
/// @throws std::invalid_argument if processes < 1, or costs is neither empty nor one per case, or a
///         cost is negative or not finite
std::vector<int> assign_cases(size_t cases, const std::vector<double>& costs, int processes);

/// @brief The evaluation as bytes: every value and time, the gradient, the constraint rows, the
/// adjoint blocks and the checkpoint records, doubles copied bit for bit (processes of one machine
/// type: the same byte order and sizes).
std::string pack_evaluation(const Evaluation& e);
/// @brief pack_evaluation's inverse.
/// @throws std::invalid_argument if the bytes are not a whole packed evaluation (truncated, trailing
///         bytes, a size out of range)
Evaluation unpack_evaluation(const std::string& bytes);

} // namespace diffipc
