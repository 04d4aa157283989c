#include "cuda/broad_phase/step_bound.hpp"
#include "cuda/common/device_event.hpp"

#include "cuda/ccd/ccd.cuh"
#include "cuda/common/device.hpp"
#include "forward/common/error.hpp" // header-only, standard library only: InputError, format_number
#include "forward/contact/ccd/check_ccd_settings.hpp" // header-only too

#include <cuda_runtime.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;
    constexpr int MAX_BLOCKS = 256;

    unsigned blocks_for(std::size_t n) { return unsigned((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// Vertex v of row-major positions, z = 0 in 2D (the CPU's vertex_point).
    __device__ inline vec3 vertex_point(const double* x, int v, int dim)
    {
        const double* p = x + std::size_t(v) * dim;
        return dim == 3 ? vec3(p[0], p[1], p[2]) : vec3(p[0], p[1], 0);
    }

    __global__ void add_kernel(const double* x, const double* p, std::size_t n, double* x1)
    {
        const std::size_t i = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (i < n)
            x1[i] = x[i] + p[i];
    }

    /// max|x|, max|p| and whether any entry is not finite: stage 1 per block into partials[3 b .. 3 b + 2],
    /// stage 2 in one block. Maxima are exact, so the order does not matter.
    __global__ void max_abs_kernel(const double* x, const double* p, std::size_t n, double* partials)
    {
        __shared__ double s[3][THREADS];
        double mx = 0, mp = 0, bad = 0;
        for (std::size_t i = std::size_t(blockIdx.x) * THREADS + threadIdx.x; i < n;
             i += std::size_t(gridDim.x) * THREADS) {
            const double a = x[i], b = p[i];
            if (!is_finite(a) || !is_finite(b))
                bad = 1;
            else {
                mx = max_of(mx, fabs(a));
                mp = max_of(mp, fabs(b));
            }
        }
        s[0][threadIdx.x] = mx;
        s[1][threadIdx.x] = mp;
        s[2][threadIdx.x] = bad;
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (int(threadIdx.x) < h)
                for (int q = 0; q < 3; ++q)
                    s[q][threadIdx.x] = max_of(s[q][threadIdx.x], s[q][threadIdx.x + h]);
        }
        if (threadIdx.x == 0)
            for (int q = 0; q < 3; ++q)
                partials[3 * blockIdx.x + q] = s[q][0];
    }

    __global__ void max_abs_final_kernel(const double* partials, int blocks, double* result)
    {
        __shared__ double s[3][THREADS];
        for (int q = 0; q < 3; ++q)
            s[q][threadIdx.x] = int(threadIdx.x) < blocks ? partials[3 * threadIdx.x + q] : 0.0;
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (int(threadIdx.x) < h)
                for (int q = 0; q < 3; ++q)
                    s[q][threadIdx.x] = max_of(s[q][threadIdx.x], s[q][threadIdx.x + h]);
        }
        if (threadIdx.x == 0)
            for (int q = 0; q < 3; ++q)
                result[q] = s[q][0];
    }

    /// The reduction's state: the bits of the smallest toi (non-negative doubles order like their bit patterns)
    /// and whether a colliding pair exhausted its budget.
    struct Outcome {
        unsigned long long toi_bits;
        unsigned long long exhausted;
    };

    __device__ inline void accept(const CCDResult& r, Outcome* outcome)
    {
        if (!r.collision)
            return;
        double toi = r.toi;
        if (toi != toi) // std::min(o.toi, NaN) keeps o.toi (never happens: the CCD returns toi in [0, t_max])
            return;
        if (!(toi > 0))
            toi = 0; // -0 and (impossible) negative times: alpha 0, unresolved, as on the CPU
        atomicMin(&outcome->toi_bits, static_cast<unsigned long long>(__double_as_longlong(toi)));
        if (r.budget_exhausted)
            atomicOr(&outcome->exhausted, 1ull);
    }

    enum ContactKind : int { VERTEX_EDGE = 0, VERTEX_FACE = 1, EDGE_EDGE = 2 };

    /// One thread per candidate pair of one kind (the kind a template parameter, so each kernel keeps only its own
    /// CCD's code and registers).
    template <int KIND>
    __global__ void ccd_kernel(const int* pairs, std::size_t count, const int* edges, const int* faces, int dim,
        const double* x0, const double* x1, CCDSettings settings, Outcome* outcome)
    {
        const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= count)
            return;
        const int first = pairs[2 * k], second = pairs[2 * k + 1];
        CCDResult r;
        if (KIND == VERTEX_EDGE) {
            const int a = edges[2 * second], b = edges[2 * second + 1];
            r = point_edge_ccd(vertex_point(x0, first, dim), vertex_point(x0, a, dim), vertex_point(x0, b, dim),
                vertex_point(x1, first, dim), vertex_point(x1, a, dim), vertex_point(x1, b, dim), settings);
        } else if (KIND == VERTEX_FACE) {
            const int a = faces[3 * second], b = faces[3 * second + 1], c = faces[3 * second + 2];
            r = point_triangle_ccd(vertex_point(x0, first, dim), vertex_point(x0, a, dim), vertex_point(x0, b, dim),
                vertex_point(x0, c, dim), vertex_point(x1, first, dim), vertex_point(x1, a, dim),
                vertex_point(x1, b, dim), vertex_point(x1, c, dim), settings);
        } else {
            const int a0 = edges[2 * first], a1 = edges[2 * first + 1];
            const int b0 = edges[2 * second], b1 = edges[2 * second + 1];
            r = edge_edge_ccd(vertex_point(x0, a0, dim), vertex_point(x0, a1, dim), vertex_point(x0, b0, dim),
                vertex_point(x0, b1, dim), vertex_point(x1, a0, dim), vertex_point(x1, a1, dim),
                vertex_point(x1, b0, dim), vertex_point(x1, b1, dim), settings);
        }
        accept(r, outcome);
    }

    /// One thread per (plane q, plane vertex i): k = q * num_plane_vertices + i, as the CPU enumerates them.
    __global__ void plane_ccd_kernel(const PlaneObstacle* planes, const int* plane_vertices, int num_plane_vertices,
        std::size_t count, int dim, const double* x0, const double* x1, CCDSettings settings, Outcome* outcome)
    {
        const std::size_t k = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= count)
            return;
        const PlaneObstacle plane = planes[k / std::size_t(num_plane_vertices)];
        const int v = plane_vertices[k % std::size_t(num_plane_vertices)];
        const vec3 normal(plane.normal[0], plane.normal[1], plane.normal[2]);
        accept(point_plane_ccd(vertex_point(x0, v, dim), vertex_point(x1, v, dim), vertex_point(x0, plane.vertex, dim),
                   vertex_point(x1, plane.vertex, dim), normal, settings),
            outcome);
    }

    template <int KIND>
    void launch_ccd(const int* pairs, std::size_t count, const int* edges, const int* faces, int dim, const double* x0,
        const double* x1, const CCDSettings& settings, Outcome* outcome)
    {
        if (count == 0)
            return;
        // 128 threads per block as cuda/ccd/ccd.cu: the CCD's loops diverge, and smaller blocks retire sooner.
        ccd_kernel<KIND>
            <<<unsigned((count + 127) / 128), 128>>>(pairs, count, edges, faces, dim, x0, x1, settings, outcome);
        check_launch("the step bound's CCD kernel");
    }

    CCDSettings ccd_settings(const StepBoundSettings& s)
    {
        CCDSettings c;
        c.min_distance = s.min_distance;
        c.conservative_rescaling = s.ccd_rescaling;
        c.max_iterations = s.ccd_max_iterations;
        c.t_max = 1;
        c.refine = false;
        return c;
    }

    void check_settings(const StepBoundSettings& s)
    {
        if (!(s.dhat >= 0) || !is_finite(s.dhat))
            throw InputError("contact.dhat", "must be finite and >= 0, got " + format_number(s.dhat));
        check_ccd_settings(ccd_settings(s));
    }

} // namespace

struct DeviceStepBound::Impl {
    explicit Impl(const CollisionMeshData& mesh)
        : broad_phase(mesh)
    {
    }

    DeviceBroadPhase broad_phase;
    StepBoundSettings settings;
    int dim = 3;
    std::size_t num_dofs = 0;
    DeviceArray<PlaneObstacle> planes;
    std::size_t num_planes = 0;
    DeviceArray<int> plane_vertices;
    int num_plane_vertices = 0;

    DeviceArray<double> x1, partials, max_abs, host_x, host_p;
    DeviceArray<Outcome> outcome;
    DeviceCandidates candidates;

    DeviceEvent start, broad_phase_done, finished;
};

DeviceStepBound::DeviceStepBound(
    const CollisionMeshData& mesh, const std::vector<PlaneObstacle>& planes, const StepBoundSettings& settings)
{
    check_settings(settings);
    for (const PlaneObstacle& plane : planes) {
        if (plane.vertex < 0 || plane.vertex >= mesh.num_vertices)
            throw std::invalid_argument("step bound: a plane's vertex " + std::to_string(plane.vertex)
                + " is out of range [0, #V = " + std::to_string(mesh.num_vertices) + ")");
        const double n2
            = plane.normal[0] * plane.normal[0] + plane.normal[1] * plane.normal[1] + plane.normal[2] * plane.normal[2];
        if (!is_finite(plane.normal[0]) || !is_finite(plane.normal[1]) || !is_finite(plane.normal[2]) || !(n2 > 0))
            throw InputError("normal", "the plane normal must be finite and nonzero");
    }
    // Checks the mesh first (DeviceBroadPhase's constructor), so that the loop below indexes valid data.
    m_impl = std::make_unique<Impl>(mesh);
    Impl& m = *m_impl;
    m.settings = settings;
    m.dim = mesh.dim;
    m.num_dofs = std::size_t(mesh.num_vertices) * std::size_t(mesh.dim);
    // The CPU's m_plane_vertices: collision vertices of non-kinematic groups, in the mesh's order.
    std::vector<int> plane_vertices;
    for (int v : mesh.vertices) {
        const int g = mesh.vertex_group[std::size_t(v)];
        if (g >= 0 && !mesh.group_kinematic[std::size_t(g)])
            plane_vertices.push_back(v);
    }
    m.num_planes = planes.size();
    m.num_plane_vertices = int(plane_vertices.size());
    if (!planes.empty())
        m.planes.upload(planes);
    if (!plane_vertices.empty())
        m.plane_vertices.upload(plane_vertices);
    m.x1.resize(m.num_dofs);
    m.partials.resize(3 * MAX_BLOCKS);
    m.max_abs.resize(3);
    m.outcome.resize(1);
}

DeviceStepBound::~DeviceStepBound() = default;

StepBoundResult DeviceStepBound::max_step(const double* d_x, const double* d_p)
{
    require_cuda_device("the GPU step bound (gpu::DeviceStepBound)");
    Impl& m = *m_impl;
    const std::size_t n = m.num_dofs;
    StepBoundResult result;

    m.start.record();
    if (n > 0) {
        add_kernel<<<blocks_for(n), THREADS>>>(d_x, d_p, n, m.x1.data());
        check_launch("the step bound's x + p kernel");
    }
    const int blocks = int(std::max<std::size_t>(1, std::min<std::size_t>(blocks_for(n), MAX_BLOCKS)));
    max_abs_kernel<<<blocks, THREADS>>>(d_x, d_p, n, m.partials.data());
    check_launch("the step bound's max-norm kernel");
    max_abs_final_kernel<<<1, THREADS>>>(m.partials.data(), blocks, m.max_abs.data());
    check_launch("the step bound's max-norm kernel");
    double max_abs[3];
    check_cuda(cudaMemcpy(max_abs, m.max_abs.data(), sizeof max_abs, cudaMemcpyDeviceToHost),
        "the step bound's max-norm, or cudaMemcpy of it to the host");
    // The CPU: tolerance = 1e-12 (|x|_inf + |p|_inf), inflation dmin + dhat + 4 tolerance. A non-finite entry
    // makes the CPU's inflation non-finite (or its positions), which its broad phase refuses: so does ours.
    const double tolerance = max_abs[2] != 0 ? NAN : 1e-12 * (max_abs[0] + max_abs[1]);
    result.inflation = m.settings.min_distance + m.settings.dhat + 4 * tolerance;
    m.candidates = m.broad_phase.find(d_x, m.x1.data(), result.inflation);
    m.broad_phase_done.record();

    Outcome initial;
    const double one = 1.0;
    std::memcpy(&initial.toi_bits, &one, sizeof one);
    initial.exhausted = 0;
    check_cuda(cudaMemcpy(m.outcome.data(), &initial, sizeof initial, cudaMemcpyHostToDevice),
        "cudaMemcpy of the step bound's start value");
    const CCDSettings settings = ccd_settings(m.settings);
    const DeviceBroadPhase::MeshPointers mesh = m.broad_phase.mesh_pointers();
    const DeviceCandidates& c = m.candidates;
    launch_ccd<VERTEX_EDGE>(
        c.vertex_edge, c.num_vertex_edge, mesh.edges, mesh.faces, m.dim, d_x, m.x1.data(), settings, m.outcome.data());
    launch_ccd<VERTEX_FACE>(
        c.vertex_face, c.num_vertex_face, mesh.edges, mesh.faces, m.dim, d_x, m.x1.data(), settings, m.outcome.data());
    launch_ccd<EDGE_EDGE>(
        c.edge_edge, c.num_edge_edge, mesh.edges, mesh.faces, m.dim, d_x, m.x1.data(), settings, m.outcome.data());
    const std::size_t num_plane_pairs = m.num_planes * std::size_t(m.num_plane_vertices);
    if (num_plane_pairs > 0) {
        plane_ccd_kernel<<<blocks_for(num_plane_pairs), THREADS>>>(m.planes.data(), m.plane_vertices.data(),
            m.num_plane_vertices, num_plane_pairs, m.dim, d_x, m.x1.data(), settings, m.outcome.data());
        check_launch("the step bound's plane CCD kernel");
    }
    Outcome outcome;
    check_cuda(cudaMemcpy(&outcome, m.outcome.data(), sizeof outcome, cudaMemcpyDeviceToHost),
        "the step bound's CCD kernels, or cudaMemcpy of their result to the host");
    m.finished.record();
    m.finished.synchronize("the step bound's CCD kernels");

    std::memcpy(&result.alpha, &outcome.toi_bits, sizeof result.alpha);
    result.budget_exhausted = outcome.exhausted != 0;
    result.unresolved = !(result.alpha > 0);
    result.num_vertex_edge = c.num_vertex_edge;
    result.num_vertex_face = c.num_vertex_face;
    result.num_edge_edge = c.num_edge_edge;
    result.num_plane = num_plane_pairs;
    result.broad_phase_ms = m.broad_phase_done.ms_since(m.start);
    result.ccd_ms = m.finished.ms_since(m.broad_phase_done);
    result.total_ms = m.finished.ms_since(m.start);
    return result;
}

StepBoundResult DeviceStepBound::max_step(const std::vector<double>& x, const std::vector<double>& p)
{
    Impl& m = *m_impl;
    for (const std::vector<double>* v : { &x, &p })
        if (v->size() != m.num_dofs)
            throw std::invalid_argument("step bound: a vector has " + std::to_string(v->size())
                + " entries, expected #V * dim = " + std::to_string(m.num_dofs));
    require_cuda_device("the GPU step bound (gpu::DeviceStepBound)");
    m.host_x.upload(x);
    m.host_p.upload(p);
    return max_step(m.host_x.data(), m.host_p.data());
}

const DeviceCandidates& DeviceStepBound::segment_candidates() const { return m_impl->candidates; }
const double* DeviceStepBound::segment_end() const { return m_impl->x1.data(); }
const StepBoundSettings& DeviceStepBound::settings() const { return m_impl->settings; }

void DeviceStepBound::set_settings(const StepBoundSettings& settings)
{
    check_settings(settings);
    m_impl->settings = settings;
}

DeviceBroadPhase& DeviceStepBound::broad_phase() { return m_impl->broad_phase; }

} // namespace diffipc::gpu
