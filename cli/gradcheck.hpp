#pragma once
#include <memory>
#include <string>

namespace diffipc {

class CaseDistribution;

/// @brief `diffipc gradcheck PROBLEM.json`: adjoint gradient against central differences
/// in random directions, with a Taylor table per direction; where the central difference
/// disagrees, one-sided differences on both sides (shape_opt/gradient_check.hpp), so that a
/// kink of J'' (an exterior penalty at its bound) is reported as such and not as a failure.
/// @return 0 if every direction passes (at a kink or not), 4 if one fails, is inconclusive or
/// crosses a kink of J itself (bad input throws InputError, a failed forward step or gradient
/// throws AdjointError). DIFFIPC_GRADCHECK_PERTURB=r multiplies the adjoint's dJ.dp by 1 + r.
/// `device`: "cpu" or "gpu" replaces the scenes' "device" ("": theirs). `distribution`: under
/// mpirun, the load cases over the ranks (null: this process alone).
int gradcheck(const std::string& problem_path, int directions, const std::string& device = "",
    std::shared_ptr<CaseDistribution> distribution = nullptr);

} // namespace diffipc
