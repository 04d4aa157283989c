#include "cuda/ccd/ccd.cuh"

#include "cuda/common/device.hpp"
#include "cuda/common/device_event.hpp"
#include "cuda/linalg/device_array.hpp"
#include "forward/common/error.hpp" // header-only, standard library only
#include "forward/contact/ccd/check_ccd_settings.hpp" // header-only too

#include <cuda_runtime.h>

#include <string>

namespace diffipc {
namespace gpu {

    namespace {

        constexpr int THREADS_PER_BLOCK = 128;

        /// One thread per query; the kind is a template parameter so that each kernel keeps only its own
        /// primitive's code (and registers).
        template <CCDKind KIND>
        __global__ void ccd_kernel(
            const double* vertices, std::size_t n_queries, CCDSettings settings, CCDResult* results)
        {
            const std::size_t q = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
            if (q >= n_queries)
                return;
            const std::size_t stride = 6 * std::size_t(ccd_vertex_count(KIND));
            results[q] = ccd_query(KIND, vertices + q * stride, settings);
        }

    } // namespace

    std::vector<CCDResult> ccd_batch(CCDKind kind, const double* vertices, std::size_t n_queries,
        const CCDSettings& settings, CCDBatchTiming* timing)
    {
        check_ccd_settings(settings);
        if (!(kind == CCDKind::POINT_TRIANGLE || kind == CCDKind::EDGE_EDGE || kind == CCDKind::POINT_EDGE
                || kind == CCDKind::POINT_POINT))
            throw InputError("ccd kind", "not a CCD kind: " + std::to_string(int(kind)));
        std::vector<CCDResult> results(n_queries);
        if (n_queries == 0)
            return results;
        require_cuda_device("the GPU CCD (gpu::ccd_batch)");

        const std::size_t n_doubles = n_queries * 6 * std::size_t(ccd_vertex_count(kind));
        DeviceArray<double> d_vertices;
        DeviceArray<CCDResult> d_results;
        d_results.resize(n_queries);
        DeviceEvent start, launched, finished, copied;

        start.record();
        d_vertices.upload(vertices, n_doubles);
        launched.record();
        const unsigned blocks = unsigned((n_queries + THREADS_PER_BLOCK - 1) / THREADS_PER_BLOCK);
        switch (kind) {
        case CCDKind::POINT_TRIANGLE:
            ccd_kernel<CCDKind::POINT_TRIANGLE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.data(), n_queries, settings, d_results.data());
            break;
        case CCDKind::EDGE_EDGE:
            ccd_kernel<CCDKind::EDGE_EDGE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.data(), n_queries, settings, d_results.data());
            break;
        case CCDKind::POINT_EDGE:
            ccd_kernel<CCDKind::POINT_EDGE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.data(), n_queries, settings, d_results.data());
            break;
        case CCDKind::POINT_POINT:
            ccd_kernel<CCDKind::POINT_POINT>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.data(), n_queries, settings, d_results.data());
            break;
        }
        check_cuda(cudaGetLastError(), "the CCD kernel's launch");
        finished.record();
        check_cuda(cudaMemcpy(results.data(), d_results.data(), n_queries * sizeof(CCDResult), cudaMemcpyDeviceToHost),
            "the CCD kernel, or cudaMemcpy of its results to the host");
        copied.record();
        copied.synchronize("cudaEventSynchronize");
        if (timing) {
            timing->kernel_ms = finished.ms_since(launched);
            timing->total_ms = copied.ms_since(start);
        }
        return results;
    }

} // namespace gpu
} // namespace diffipc
