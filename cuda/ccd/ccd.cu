#include "cuda/ccd/ccd.cuh"

#include "cuda/common/device.hpp"
#include "forward/common/error.hpp" // header-only, standard library only: the CPU CCD's InputError

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

        /// A device allocation freed on scope exit.
        template <typename T> class ScopedDeviceBuffer {
        public:
            explicit ScopedDeviceBuffer(std::size_t n, const char* what)
            {
                check_cuda(cudaMalloc(reinterpret_cast<void**>(&m_data), n * sizeof(T)), what);
            }
            ~ScopedDeviceBuffer() { cudaFree(m_data); }
            ScopedDeviceBuffer(const ScopedDeviceBuffer&) = delete;
            ScopedDeviceBuffer& operator=(const ScopedDeviceBuffer&) = delete;
            T* get() const { return m_data; }

        private:
            T* m_data = nullptr;
        };

        /// A CUDA event destroyed on scope exit.
        class ScopedEvent {
        public:
            ScopedEvent() { check_cuda(cudaEventCreate(&m_event), "cudaEventCreate"); }
            ~ScopedEvent() { cudaEventDestroy(m_event); }
            ScopedEvent(const ScopedEvent&) = delete;
            ScopedEvent& operator=(const ScopedEvent&) = delete;
            cudaEvent_t get() const { return m_event; }

        private:
            cudaEvent_t m_event = nullptr;
        };

        float elapsed_ms(const ScopedEvent& from, const ScopedEvent& to)
        {
            float ms = 0;
            check_cuda(cudaEventElapsedTime(&ms, from.get(), to.get()), "cudaEventElapsedTime");
            return ms;
        }

    } // namespace

    void check_ccd_settings(const CCDSettings& s)
    {
        // The CPU's check_settings (forward/contact/ccd/ccd.cpp), same fields and messages.
        if (!(s.min_distance >= 0) || !is_finite(s.min_distance))
            throw InputError("ccd.min_distance", "must be finite and >= 0, got " + format_number(s.min_distance));
        if (!(s.conservative_rescaling > 0 && s.conservative_rescaling < 1))
            throw InputError("ccd.conservative_rescaling",
                "must be in (0, 1) (0.9 is usual), got " + format_number(s.conservative_rescaling));
        if (!(s.t_max >= 0) || !is_finite(s.t_max))
            throw InputError("ccd.t_max", "must be finite and >= 0, got " + format_number(s.t_max));
        if (!(s.refine_tolerance > 0) || !is_finite(s.refine_tolerance))
            throw InputError(
                "ccd.refine_tolerance", "must be finite and > 0, got " + format_number(s.refine_tolerance));
        if (s.max_iterations < 1)
            throw InputError("ccd.max_iterations", "must be >= 1, got " + std::to_string(s.max_iterations));
    }

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
        ScopedDeviceBuffer<double> d_vertices(n_doubles, "cudaMalloc of the CCD queries");
        ScopedDeviceBuffer<CCDResult> d_results(n_queries, "cudaMalloc of the CCD results");
        ScopedEvent start, launched, finished, copied;

        check_cuda(cudaEventRecord(start.get()), "cudaEventRecord");
        check_cuda(cudaMemcpy(d_vertices.get(), vertices, n_doubles * sizeof(double), cudaMemcpyHostToDevice),
            "cudaMemcpy of the CCD queries to the device");
        check_cuda(cudaEventRecord(launched.get()), "cudaEventRecord");
        const unsigned blocks = unsigned((n_queries + THREADS_PER_BLOCK - 1) / THREADS_PER_BLOCK);
        switch (kind) {
        case CCDKind::POINT_TRIANGLE:
            ccd_kernel<CCDKind::POINT_TRIANGLE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.get(), n_queries, settings, d_results.get());
            break;
        case CCDKind::EDGE_EDGE:
            ccd_kernel<CCDKind::EDGE_EDGE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.get(), n_queries, settings, d_results.get());
            break;
        case CCDKind::POINT_EDGE:
            ccd_kernel<CCDKind::POINT_EDGE>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.get(), n_queries, settings, d_results.get());
            break;
        case CCDKind::POINT_POINT:
            ccd_kernel<CCDKind::POINT_POINT>
                <<<blocks, THREADS_PER_BLOCK>>>(d_vertices.get(), n_queries, settings, d_results.get());
            break;
        }
        check_cuda(cudaGetLastError(), "the CCD kernel's launch");
        check_cuda(cudaEventRecord(finished.get()), "cudaEventRecord");
        check_cuda(cudaMemcpy(results.data(), d_results.get(), n_queries * sizeof(CCDResult), cudaMemcpyDeviceToHost),
            "the CCD kernel, or cudaMemcpy of its results to the host");
        check_cuda(cudaEventRecord(copied.get()), "cudaEventRecord");
        check_cuda(cudaEventSynchronize(copied.get()), "cudaEventSynchronize");
        if (timing) {
            timing->kernel_ms = elapsed_ms(launched, finished);
            timing->total_ms = elapsed_ms(start, copied);
        }
        return results;
    }

} // namespace gpu
} // namespace diffipc
