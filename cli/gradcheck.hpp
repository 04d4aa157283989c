#pragma once
#include <string>

namespace diffipc {

/// @brief `diffipc gradcheck PROBLEM.json`: adjoint gradient against central differences
/// in random directions, with a Taylor table per direction.
/// @return 0 if every direction passes, 4 if one does not (bad input throws InputError,
/// a failed forward step or gradient throws AdjointError).
/// `device`: "cpu" or "gpu" replaces the scenes' "device" ("": theirs).
int gradcheck(const std::string& problem_path, int directions, const std::string& device = "");

} // namespace diffipc
