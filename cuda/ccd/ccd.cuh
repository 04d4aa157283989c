#pragma once
/// @file ccd.cuh
/// Conservative continuous collision detection on the GPU, batched: many queries of one kind in one
/// kernel, one thread per query, each running the CCD that the CPU path runs
/// (forward/kernels/ccd/ccd.hpp: its contract, its algorithm and why the GPU's results are the
/// CPU's bit for bit when the device code is compiled without fused multiply-adds, as
/// cuda/ccd/ccd.cu is).
///
/// Names are in diffipc::gpu rather than diffipc::cuda so that libcu++'s ::cuda namespace is not
/// shadowed inside diffipc.

#include "cuda/common/kernels.cuh"
#include "forward/kernels/ccd/ccd.hpp"

#include <cstddef>
#include <vector>

namespace diffipc {
namespace gpu {

    /// Device timing of one batch, from CUDA events (milliseconds).
    struct CCDBatchTiming {
        float kernel_ms = 0; ///< the kernel alone
        float total_ms = 0; ///< copy in, kernel, copy out (allocation excluded)
    };

    /// @brief Run many CCD queries of one kind on the GPU, one thread per query: copy the queries to the device,
    /// launch, copy the results back.
    /// @param kind       the primitive pair of every query
    /// @param vertices   n_queries * 2 * ccd_vertex_count(kind) * 3 doubles: query q starts at
    ///                   vertices + q * 6 * ccd_vertex_count(kind) and holds its vertices at t = 0 in the kind's
    ///                   order, then the same vertices at t = 1, xyz each (m). For point-triangle and edge-edge
    ///                   that is 8 positions (24 doubles) per query, the row order of the CCD sample queries; for
    ///                   point-edge 6, for point-point 4.
    /// @param n_queries  number of queries (0 is fine: no device call)
    /// @param settings   checked first (check_ccd_settings)
    /// @param timing     if non-null, the device times of this batch
    /// @return           one result per query, in order; bitwise the CPU CCD's (see the file comment)
    /// @throws InputError on invalid settings; std::runtime_error starting "no CUDA device: " when there is no
    ///         usable GPU, or naming the failed CUDA call
    std::vector<CCDResult> ccd_batch(CCDKind kind, const double* vertices, std::size_t n_queries,
        const CCDSettings& settings, CCDBatchTiming* timing = nullptr);

} // namespace gpu
} // namespace diffipc
