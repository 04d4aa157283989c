#pragma once
#include <memory>
#include <string>

namespace diffipc {

class CaseDistribution;

/// @brief `diffipc gradcheck PROBLEM.json`: adjoint gradient against central differences
/// in random directions, with a Taylor table per direction.
/// @return 0 if every direction passes, 4 if one does not (bad input throws InputError,
/// a failed forward step or gradient throws AdjointError).
/// `device`: "cpu" or "gpu" replaces the scenes' "device" ("": theirs). `distribution`: under
/// mpirun, the load cases over the ranks (null: this process alone).
int gradcheck(const std::string& problem_path, int directions, const std::string& device = "",
    std::shared_ptr<CaseDistribution> distribution = nullptr);

} // namespace diffipc
