#include "cuda/periodic/device_periodic_map.hpp"

#include "cuda/common/device.hpp"
#include "cuda/linalg/reduction.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    __global__ void expand_kernel(
        PeriodicView m, const double* __restrict__ q, const double* __restrict__ rest, double* __restrict__ x)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= m.num_vertices * m.dim)
            return;
        const double s = expand_entry(m, q, k / m.dim, k % m.dim);
        x[k] = rest ? rest[k] + s : s;
    }

    __global__ void reduce_fluctuation_kernel(PeriodicView m, const double* __restrict__ g, double* __restrict__ gq)
    {
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= m.num_classes * m.dim)
            return;
        gq[k] = reduce_fluctuation(m, g, k / m.dim, k % m.dim);
    }

    __global__ void macro_terms_kernel(
        PeriodicView m, const double* __restrict__ g, int i, int j, double* __restrict__ terms)
    {
        const int v = blockIdx.x * blockDim.x + threadIdx.x;
        if (v < m.num_vertices)
            terms[v] = macro_term(m, g, v, i, j);
    }

} // namespace

DevicePeriodicMap::DevicePeriodicMap(int dim, const std::vector<int>& vertex_class, const std::vector<double>& rest,
    const std::vector<double>& origin, double length)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("DevicePeriodicMap: dim must be 2 or 3, got " + std::to_string(dim));
    const size_t nv = vertex_class.size();
    if (nv == 0)
        throw std::invalid_argument("DevicePeriodicMap: vertex_class is empty");
    if (rest.size() != nv * size_t(dim))
        throw std::invalid_argument("DevicePeriodicMap: rest has " + std::to_string(rest.size())
            + " values, expected #V dim = " + std::to_string(nv * size_t(dim)));
    if (origin.size() != size_t(dim))
        throw std::invalid_argument("DevicePeriodicMap: origin has " + std::to_string(origin.size())
            + " values, expected dim = " + std::to_string(dim));
    if (!(length > 0) || !std::isfinite(length))
        throw std::invalid_argument("DevicePeriodicMap: length must be finite and > 0");
    int classes = 0;
    for (size_t v = 0; v < nv; ++v) {
        if (vertex_class[v] < 0 || vertex_class[v] >= int(nv))
            throw std::invalid_argument("DevicePeriodicMap: vertex_class[" + std::to_string(v)
                + "] = " + std::to_string(vertex_class[v]) + " is not a class in 0 .. #V - 1");
        classes = std::max(classes, vertex_class[v] + 1);
    }
    // Each class's vertices in increasing order (a counting sort).
    std::vector<int> start(size_t(classes) + 1, 0), members(nv);
    for (const int c : vertex_class)
        ++start[size_t(c) + 1];
    for (int c = 0; c < classes; ++c) {
        if (start[size_t(c) + 1] == 0)
            throw std::invalid_argument(
                "DevicePeriodicMap: class " + std::to_string(c) + " has no vertex (classes must be 0 .. C - 1)");
        start[size_t(c) + 1] += start[size_t(c)];
    }
    std::vector<int> next(start.begin(), start.end() - 1);
    for (size_t v = 0; v < nv; ++v)
        members[size_t(next[size_t(vertex_class[v])]++)] = int(v);
    std::vector<double> lever(rest.size());
    for (size_t v = 0; v < nv; ++v)
        for (int j = 0; j < dim; ++j) {
            const double X = rest[v * size_t(dim) + size_t(j)];
            if (!std::isfinite(X) || !std::isfinite(origin[size_t(j)]))
                throw std::invalid_argument(
                    "DevicePeriodicMap: rest position " + std::to_string(v) + " or the origin " + "is not finite");
            lever[v * size_t(dim) + size_t(j)] = (X - origin[size_t(j)]) / length;
        }
    m_class.upload(vertex_class);
    m_start.upload(start);
    m_members.upload(members);
    m_lever.upload(lever);
    m_rest.upload(rest);
    m_terms.resize(nv);
    m_partials.resize(REDUCTION_PARTIALS);
    m_view.dim = dim;
    m_view.num_vertices = int(nv);
    m_view.num_classes = classes;
    m_view.vertex_class = m_class.data();
    m_view.lever = m_lever.data();
    m_view.class_start = m_start.data();
    m_view.class_vertices = m_members.data();
}

void DevicePeriodicMap::expand(const double* d_q, double* d_x, bool with_rest) const
{
    const size_t n = size_t(m_view.num_vertices) * size_t(m_view.dim);
    expand_kernel<<<grid(n), THREADS>>>(m_view, d_q, with_rest ? m_rest.data() : nullptr, d_x);
    check_cuda(cudaGetLastError(), "launch of the periodic expansion");
}

void DevicePeriodicMap::reduce(const double* d_g, double* d_gq)
{
    const int d = m_view.dim;
    reduce_fluctuation_kernel<<<grid(size_t(m_view.num_classes) * size_t(d)), THREADS>>>(m_view, d_g, d_gq);
    check_cuda(cudaGetLastError(), "launch of the periodic class sums");
    for (int i = 0; i < d; ++i)
        for (int j = 0; j < d; ++j) {
            macro_terms_kernel<<<grid(size_t(m_view.num_vertices)), THREADS>>>(m_view, d_g, i, j, m_terms.data());
            check_cuda(cudaGetLastError(), "launch of the periodic macro terms");
            deterministic_sum(m_terms.data(), m_terms.size(), m_partials.data(), d_gq + macro_dof(m_view, i, j));
        }
}

} // namespace diffipc::gpu
