#pragma once
/// @file device_elastic_mesh.hpp
/// The elastic potential Psi(x) = sum_e |e| psi_e(F_e(x)) of a P1 mesh held on the GPU: the
/// device twin of ElasticPotential (forward/potentials/elastic_potential.hpp), with the same
/// element kernels (forward/kernels/element.hpp) and per-element models and Lame parameters. Host API in
/// plain C++ (no CUDA or Eigen types).
///
/// Layouts:
/// - positions (rest_positions, x) and gradients: #V * dim doubles, flattened vertex-major
///   (xyzxyz), in metres and newtons;
/// - elements: #E * (dim+1) vertex indices, flattened element-major (elements[e (dim+1) + a]),
///   as the rows of Mesh::elements;
/// - models: #E laws (forward/kernels/material/material_model.hpp, one enum for both paths);
///   mu, lambda: #E Lame parameters (Pa);
/// - Hessians: a DeviceBsrMatrix (cuda/linalg/bsr_matrix.hpp) with dim by dim blocks, one block
///   row per vertex, on the fixed pattern of the mesh (the diagonal blocks and every vertex pair
///   of an element), both triangles stored.
///
/// Determinism: energies are per-element values summed by a fixed-order tree
/// (cuda/linalg/reduction.hpp); gradients and Hessian blocks are per-element values gathered
/// per vertex (per block) over a precomputed incidence list in increasing element order, as the
/// CPU's VertexScatter does. No atomics: repeated evaluations are bitwise equal.

#include "cuda/common/device_potential.hpp"
#include "cuda/common/kernels.cuh"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/bsr_pattern.hpp"
#include "cuda/linalg/device_array.hpp"
#include "forward/kernels/material/material_model.hpp"

#include <vector>

namespace diffipc::gpu {

class DeviceElasticMesh : public DevicePotential {
public:
    /// @brief Precomputes the rest data (Dm^{-1} as shape gradients, rest volumes), the Hessian's
    /// BSR pattern and the incidence lists, and copies everything to the GPU.
    /// @param dim            2 (plane-strain triangles) or 3 (tetrahedra)
    /// @param rest_positions #V * dim (m)
    /// @param elements       #E * (dim+1) vertex indices
    /// @param models         #E model codes
    /// @param mu, lambda     #E Lame parameters (Pa)
    /// @throws std::invalid_argument for inconsistent sizes, out-of-range indices or model codes,
    ///         and degenerate rest elements (det Dm = 0), naming the element
    void upload(int dim, const std::vector<double>& rest_positions, const std::vector<int>& elements,
        const std::vector<MaterialModel>& models, const std::vector<double>& mu, const std::vector<double>& lambda);
    /// @brief Replaces the per-element Lame parameters (#E each).
    void set_lame_parameters(const std::vector<double>& mu, const std::vector<double>& lambda);

    int dim() const { return m_dim; }
    int num_vertices() const { return m_num_vertices; }
    int num_elements() const { return m_num_elements; }
    int num_dofs() const override { return m_num_vertices * m_dim; }
    /// Rest volume (area in 2D) of each element, as computed at upload (#E, m^dim).
    const std::vector<double>& rest_volumes() const { return m_rest_volumes_host; }

    /// @name Device-resident evaluation: d_x and d_g are num_dofs() doubles in GPU memory.
    /// @{
    /// @brief Psi(x) (J); +inf if a neo-Hookean element is inverted. Copies one double back.
    double energy_device(const double* d_x) const override;
    /// @brief d_g += weight * dPsi/dx (N). Asynchronous.
    void add_gradient_device(const double* d_x, double weight, double* d_g) const override;
    /// @brief H += weight * d^2Psi/dx^2, each element's dP/dF made positive semi-definite first if
    /// `project` (the CPU's per-element projection). Asynchronous.
    /// @param H a matrix from make_hessian_matrix() (this mesh's pattern)
    void add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const override;
    /// @}

    /// @brief A zero matrix on this mesh's Hessian pattern, to assemble into.
    DeviceBsrMatrix make_hessian_matrix() const override;
    /// The pattern and incidence lists (host copy).
    const ElementBsrPattern& pattern() const { return m_pattern; }

    // Host conveniences energy(x), gradient(x), hessian_bsr(x): DevicePotential.

private:
    const char* potential_name() const override { return "DeviceElasticMesh"; }

    int m_dim = 0, m_num_vertices = 0, m_num_elements = 0;
    std::vector<double> m_rest_volumes_host;
    ElementBsrPattern m_pattern;
    // Per-element data, structure of arrays: value k of element e at k * #E + e.
    DeviceArray<int> m_elements; // (dim+1) * #E
    DeviceArray<double> m_shape_gradients; // (dim+1) dim * #E, G(a, j) at k = a dim + j
    DeviceArray<double> m_volumes, m_mu, m_lambda; // #E
    DeviceArray<int> m_models; // #E
    // Incidence lists for the deterministic gathers.
    DeviceArray<int> m_vertex_offsets, m_vertex_codes, m_slot_offsets, m_slot_codes;
    // Scratch: per-element energies, gradients (L * #E) and Hessians (L^2 * #E), reduction partials.
    mutable DeviceArray<double> m_element_energy, m_element_gradient, m_element_hessian, m_partials, m_scalar;
};

} // namespace diffipc::gpu
