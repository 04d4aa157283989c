#pragma once
/// @file check_ccd_settings.hpp
/// The host's check of CCD settings, for the CPU path (forward/contact/ccd/ccd.cpp) and the GPU's
/// batched CCD (cuda/ccd/ccd.cu) alike. Header-only and standard C++ only (forward/common/error.hpp
/// is too), so that the CUDA library uses it without linking diffipc_forward.

#include "forward/common/error.hpp"
#include "forward/kernels/ccd/ccd.hpp"

#include <cmath>
#include <string>

namespace diffipc {

/// @brief Throws InputError naming the field on min_distance < 0, conservative_rescaling outside
/// (0, 1), t_max < 0, max_iterations < 1, refine_tolerance <= 0 or non-finite values.
inline void check_ccd_settings(const kernels::CCDSettings& s)
{
    if (!(s.min_distance >= 0) || !std::isfinite(s.min_distance))
        throw InputError("ccd.min_distance", "must be finite and >= 0, got " + format_number(s.min_distance));
    if (!(s.conservative_rescaling > 0 && s.conservative_rescaling < 1))
        throw InputError("ccd.conservative_rescaling",
            "must be in (0, 1) (0.9 is usual), got " + format_number(s.conservative_rescaling));
    if (!(s.t_max >= 0) || !std::isfinite(s.t_max))
        throw InputError("ccd.t_max", "must be finite and >= 0, got " + format_number(s.t_max));
    if (!(s.refine_tolerance > 0) || !std::isfinite(s.refine_tolerance))
        throw InputError("ccd.refine_tolerance", "must be finite and > 0, got " + format_number(s.refine_tolerance));
    if (s.max_iterations < 1)
        throw InputError("ccd.max_iterations", "must be >= 1, got " + std::to_string(s.max_iterations));
}

} // namespace diffipc
