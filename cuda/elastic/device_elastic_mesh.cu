#include "cuda/elastic/device_elastic_mesh.hpp"

#include "cuda/common/device.hpp"
#include "cuda/common/kernels.cuh"
#include "cuda/linalg/reduction.hpp"
#include "forward/kernels/element.hpp"

#include <cuda_runtime.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 128;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// The per-element inputs of the kernels (structure of arrays, value k of element e at k ne + e).
    struct ElementArrays {
        int ne;
        const int* elements;
        const double* G;
        const double* volume;
        const double* mu;
        const double* lambda;
        const int* model;
    };

    template <int dim>
    __device__ void load_element(const ElementArrays& m, int e, const double* x, double* G, double* xe)
    {
        for (int k = 0; k < (dim + 1) * dim; ++k)
            G[k] = m.G[size_t(k) * m.ne + e];
        for (int a = 0; a <= dim; ++a) {
            const int v = m.elements[size_t(a) * m.ne + e];
            for (int i = 0; i < dim; ++i)
                xe[a * dim + i] = x[size_t(v) * dim + i];
        }
    }

    template <int dim> __global__ void element_energies(ElementArrays m, const double* __restrict__ x, double* out)
    {
        const int e = blockIdx.x * blockDim.x + threadIdx.x;
        if (e >= m.ne)
            return;
        double G[(dim + 1) * dim], xe[(dim + 1) * dim];
        load_element<dim>(m, e, x, G, xe);
        out[e] = element_energy<dim>(MaterialModel(m.model[e]), G, m.volume[e], xe, m.mu[e], m.lambda[e]);
    }

    template <int dim>
    __global__ void element_gradients(ElementArrays m, const double* __restrict__ x, double weight, double* out)
    {
        constexpr int L = dim * (dim + 1);
        const int e = blockIdx.x * blockDim.x + threadIdx.x;
        if (e >= m.ne)
            return;
        double G[L], xe[L], g[L];
        load_element<dim>(m, e, x, G, xe);
        element_gradient<dim>(MaterialModel(m.model[e]), G, weight * m.volume[e], xe, m.mu[e], m.lambda[e], g);
        for (int k = 0; k < L; ++k)
            out[size_t(k) * m.ne + e] = g[k];
    }

    template <int dim>
    __global__ void element_hessians(
        ElementArrays m, const double* __restrict__ x, double weight, bool project, double* out)
    {
        constexpr int L = dim * (dim + 1);
        const int e = blockIdx.x * blockDim.x + threadIdx.x;
        if (e >= m.ne)
            return;
        double G[L], xe[L], H[L * L];
        load_element<dim>(m, e, x, G, xe);
        element_hessian<dim>(MaterialModel(m.model[e]), G, weight * m.volume[e], xe, m.mu[e], m.lambda[e], project, H);
        for (int k = 0; k < L * L; ++k)
            out[size_t(k) * m.ne + e] = H[k];
    }

    /// g[v dim + i] += the vertex's element gradients, in increasing element order.
    template <int dim>
    __global__ void gather_gradient(int nv, int ne, const int* __restrict__ offsets, const int* __restrict__ codes,
        const double* __restrict__ local, double* __restrict__ g)
    {
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= nv * dim)
            return;
        const int v = t / dim, i = t % dim;
        double acc = g[t];
        for (int c = offsets[v]; c < offsets[v + 1]; ++c) {
            const int e = codes[c] / (dim + 1), a = codes[c] % (dim + 1);
            acc += local[size_t(a * dim + i) * ne + e];
        }
        g[t] = acc;
    }

    /// Block slot s, entry (i, k): += the slot's element blocks, in increasing element order.
    template <int dim>
    __global__ void gather_hessian(int slots, int ne, const int* __restrict__ offsets, const int* __restrict__ codes,
        const double* __restrict__ local, double* __restrict__ values)
    {
        constexpr int n = dim + 1, L = dim * (dim + 1);
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= slots * dim * dim)
            return;
        const int s = t / (dim * dim), i = (t / dim) % dim, k = t % dim;
        double acc = values[t];
        for (int c = offsets[s]; c < offsets[s + 1]; ++c) {
            const int code = codes[c];
            const int e = code / (n * n), a = (code / n) % n, b = code % n;
            acc += local[size_t((a * dim + i) * L + b * dim + k) * ne + e];
        }
        values[t] = acc;
    }

    /// Element-major host array (#E by `width`) to structure of arrays (width by #E).
    template <typename T> std::vector<T> transpose(const std::vector<T>& in, size_t ne, size_t width)
    {
        std::vector<T> out(in.size());
        for (size_t e = 0; e < ne; ++e)
            for (size_t k = 0; k < width; ++k)
                out[k * ne + e] = in[e * width + k];
        return out;
    }

    template <int dim>
    void rest_data(const std::vector<double>& rest_positions, const std::vector<int>& elements, size_t ne,
        std::vector<double>& G, std::vector<double>& volumes)
    {
        constexpr int n = dim + 1;
        G.resize(ne * size_t(n * dim));
        volumes.resize(ne);
        for (size_t e = 0; e < ne; ++e) {
            double rest[n * dim];
            for (int a = 0; a < n; ++a)
                for (int i = 0; i < dim; ++i)
                    rest[a * dim + i] = rest_positions[size_t(elements[e * n + size_t(a)]) * dim + size_t(i)];
            const double det = element_rest_data<dim>(rest, G.data() + e * size_t(n * dim), volumes[e]);
            if (!(std::abs(det) > 0) || !std::isfinite(det))
                throw std::invalid_argument(
                    "DeviceElasticMesh: degenerate rest element " + std::to_string(e) + " (det Dm = 0)");
        }
    }

} // namespace

void DeviceElasticMesh::upload(int dim, const std::vector<double>& rest_positions, const std::vector<int>& elements,
    const std::vector<MaterialModel>& models, const std::vector<double>& mu, const std::vector<double>& lambda)
{
    if (dim != 2 && dim != 3)
        throw std::invalid_argument("DeviceElasticMesh: dim must be 2 or 3, not " + std::to_string(dim));
    const int n = dim + 1;
    if (rest_positions.size() % size_t(dim) != 0 || elements.size() % size_t(n) != 0)
        throw std::invalid_argument("DeviceElasticMesh: rest_positions must hold #V * dim and elements #E * (dim+1)");
    const size_t nv = rest_positions.size() / size_t(dim), ne = elements.size() / size_t(n);
    if (models.size() != ne || mu.size() != ne || lambda.size() != ne)
        throw std::invalid_argument(
            "DeviceElasticMesh: models, mu and lambda need one value per element (" + std::to_string(ne) + ")");
    std::vector<int> codes(ne);
    for (size_t e = 0; e < ne; ++e) {
        codes[e] = int(models[e]);
        if (codes[e] < 0 || codes[e] >= MATERIAL_MODEL_COUNT)
            throw std::invalid_argument("DeviceElasticMesh: element " + std::to_string(e) + " has model code "
                + std::to_string(codes[e]) + " (expected 0.." + std::to_string(MATERIAL_MODEL_COUNT - 1) + ")");
    }

    m_pattern = element_bsr_pattern(int(nv), n, elements); // checks the indices
    std::vector<double> G;
    if (dim == 2)
        rest_data<2>(rest_positions, elements, ne, G, m_rest_volumes_host);
    else
        rest_data<3>(rest_positions, elements, ne, G, m_rest_volumes_host);

    m_dim = dim;
    m_num_vertices = int(nv);
    m_num_elements = int(ne);
    m_elements.upload(transpose(elements, ne, size_t(n)));
    m_shape_gradients.upload(transpose(G, ne, size_t(n * dim)));
    m_volumes.upload(m_rest_volumes_host);
    m_models.upload(codes);
    set_lame_parameters(mu, lambda);
    m_vertex_offsets.upload(m_pattern.vertex_offsets);
    m_vertex_codes.upload(m_pattern.vertex_codes);
    m_slot_offsets.upload(m_pattern.slot_offsets);
    m_slot_codes.upload(m_pattern.slot_codes);
    m_element_energy.resize(ne);
    m_partials.resize(REDUCTION_PARTIALS);
    m_scalar.resize(1);
    // The element Hessian buffer (L^2 doubles per element) is allocated on first use.
    m_element_gradient.resize(0);
    m_element_hessian.resize(0);
}

void DeviceElasticMesh::set_lame_parameters(const std::vector<double>& mu, const std::vector<double>& lambda)
{
    if (mu.size() != size_t(m_num_elements) || lambda.size() != size_t(m_num_elements))
        throw std::invalid_argument("DeviceElasticMesh: expected one Lame parameter per element");
    m_mu.upload(mu);
    m_lambda.upload(lambda);
}

DeviceBsrMatrix DeviceElasticMesh::make_hessian_matrix() const
{
    DeviceBsrMatrix H;
    H.set_pattern(m_dim, m_pattern.row_offsets, m_pattern.col_indices);
    return H;
}

double DeviceElasticMesh::energy_device(const double* d_x) const
{
    if (m_num_elements == 0)
        return 0.0;
    const ElementArrays m { m_num_elements, m_elements.data(), m_shape_gradients.data(), m_volumes.data(), m_mu.data(),
        m_lambda.data(), m_models.data() };
    if (m_dim == 2)
        element_energies<2><<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, m_element_energy.data());
    else
        element_energies<3><<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, m_element_energy.data());
    check_launch("launch of the element energies");
    deterministic_sum(m_element_energy.data(), size_t(m_num_elements), m_partials.data(), m_scalar.data());
    double total = 0;
    detail::copy_device_to_host(&total, m_scalar.data(), sizeof(double));
    return total;
}

void DeviceElasticMesh::add_gradient_device(const double* d_x, double weight, double* d_g) const
{
    if (m_num_elements == 0)
        return;
    const int L = m_dim * (m_dim + 1);
    m_element_gradient.resize(size_t(L) * size_t(m_num_elements));
    const ElementArrays m { m_num_elements, m_elements.data(), m_shape_gradients.data(), m_volumes.data(), m_mu.data(),
        m_lambda.data(), m_models.data() };
    const size_t dofs = size_t(num_dofs());
    if (m_dim == 2) {
        element_gradients<2><<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, weight, m_element_gradient.data());
        check_launch("launch of the element gradients");
        gather_gradient<2><<<grid(dofs), THREADS>>>(m_num_vertices, m_num_elements, m_vertex_offsets.data(),
            m_vertex_codes.data(), m_element_gradient.data(), d_g);
    } else {
        element_gradients<3><<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, weight, m_element_gradient.data());
        check_launch("launch of the element gradients");
        gather_gradient<3><<<grid(dofs), THREADS>>>(m_num_vertices, m_num_elements, m_vertex_offsets.data(),
            m_vertex_codes.data(), m_element_gradient.data(), d_g);
    }
    check_launch("launch of the gradient gather");
}

void DeviceElasticMesh::add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const
{
    if (H.block_size() != m_dim || H.num_block_rows() != m_num_vertices || H.num_blocks() != m_pattern.num_slots())
        throw std::invalid_argument("DeviceElasticMesh::add_hessian_device: the matrix does not have this mesh's "
                                    "pattern (make it with make_hessian_matrix())");
    if (m_num_elements == 0)
        return;
    const int L = m_dim * (m_dim + 1);
    m_element_hessian.resize(size_t(L) * size_t(L) * size_t(m_num_elements));
    const ElementArrays m { m_num_elements, m_elements.data(), m_shape_gradients.data(), m_volumes.data(), m_mu.data(),
        m_lambda.data(), m_models.data() };
    const size_t entries = size_t(m_pattern.num_slots()) * size_t(m_dim * m_dim);
    if (m_dim == 2) {
        element_hessians<2>
            <<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, weight, project, m_element_hessian.data());
        check_launch("launch of the element Hessians");
        gather_hessian<2><<<grid(entries), THREADS>>>(m_pattern.num_slots(), m_num_elements, m_slot_offsets.data(),
            m_slot_codes.data(), m_element_hessian.data(), H.device_values());
    } else {
        element_hessians<3>
            <<<grid(size_t(m_num_elements)), THREADS>>>(m, d_x, weight, project, m_element_hessian.data());
        check_launch("launch of the element Hessians");
        gather_hessian<3><<<grid(entries), THREADS>>>(m_pattern.num_slots(), m_num_elements, m_slot_offsets.data(),
            m_slot_codes.data(), m_element_hessian.data(), H.device_values());
    }
    check_launch("launch of the Hessian gather");
}

} // namespace diffipc::gpu
