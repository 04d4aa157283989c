#pragma once
// Helpers shared by the tests of cuda/elastic and cuda/linalg: a box mesh with random per-element
// materials and a random deformation, its CPU ElasticPotential, and BSR matrices as Eigen ones.

#include "cuda/common/device.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "forward/fem/fe_space.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <Eigen/SparseCore>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

/// Skips a test that needs a GPU, saying why.
#define DIFFIPC_SKIP_WITHOUT_GPU()                                                                                     \
    if (!diffipc::gpu::cuda_device_available())                                                                        \
    GTEST_SKIP() << diffipc::gpu::cuda_device_description() << " (this test runs on the GPU)"

namespace diffipc::test {

/// A box mesh with per-element models, Lame parameters and a deformed state x, with the CPU
/// potential on it and the flattened arrays DeviceElasticMesh::upload takes.
struct ElasticBox {
    Mesh mesh;
    std::unique_ptr<FESpace> space;
    std::unique_ptr<ElasticPotential> potential;
    std::vector<MaterialModel> models;
    VectorXd mu, lambda, x;

    std::vector<double> rest_flat() const
    {
        return std::vector<double>(mesh.rest_positions.data(), mesh.rest_positions.data() + mesh.rest_positions.size());
    }
    std::vector<int> elements_flat() const
    {
        return std::vector<int>(mesh.elements.data(), mesh.elements.data() + mesh.elements.size());
    }
    std::vector<double> mu_vector() const { return std::vector<double>(mu.data(), mu.data() + mu.size()); }
    std::vector<double> lambda_vector() const
    {
        return std::vector<double>(lambda.data(), lambda.data() + lambda.size());
    }
    std::vector<double> x_vector() const { return std::vector<double>(x.data(), x.data() + x.size()); }
};

/// @param model       a model for every element, or -1 for a random one per element
/// @param amplitude   random displacement per coordinate, in units of the cell size
/// @param stretch     x <- (1 + stretch) x along the first axis before the noise
inline ElasticBox make_elastic_box(int dim, const std::vector<int>& cells, int model, double amplitude, double stretch,
    unsigned seed, bool random_parameters = true)
{
    ElasticBox box;
    VectorXd lower = VectorXd::Zero(dim), upper(dim);
    VectorXi c(dim);
    for (int i = 0; i < dim; ++i) {
        upper[i] = 0.1 * cells[size_t(i)];
        c[i] = cells[size_t(i)];
    }
    box.mesh = box_mesh(dim, lower, upper, c);
    box.space = std::make_unique<FESpace>(box.mesh);
    const Index ne = box.mesh.num_elements();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    box.mu.resize(ne);
    box.lambda.resize(ne);
    for (Index e = 0; e < ne; ++e) {
        box.models.push_back(model >= 0 ? MaterialModel(model) : MaterialModel(int(4 * u(rng)) % 4));
        box.mu[e] = random_parameters ? 1e4 * (1 + 4 * u(rng)) : 4e4;
        box.lambda[e] = random_parameters ? 1e4 * (1 + 9 * u(rng)) : 6e4;
    }
    box.potential = std::make_unique<ElasticPotential>(*box.space, box.models, box.mu, box.lambda);
    box.x = flatten(box.mesh.rest_positions);
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        for (int i = 0; i < dim; ++i)
            box.x[v * dim + i] = (i == 0 ? 1 + stretch : 1.0) * box.x[v * dim + i] + 0.1 * amplitude * (2 * u(rng) - 1);
    return box;
}

/// The full symmetric CPU Hessian (weight * d2Psi/dx2, projected or not) of the box at x.
inline SparseMatrixd cpu_hessian(const ElasticBox& box, const VectorXd& x, double weight, bool project)
{
    SparseAssembler H;
    H.build(box.mesh.dim, box.mesh.num_vertices(), box.mesh.elements);
    H.set_zero();
    box.potential->add_hessian(x, weight, project, H);
    return H.matrix().selfadjointView<Eigen::Lower>();
}

/// A host BSR matrix as an Eigen sparse matrix (every stored entry, zeros included).
inline SparseMatrixd to_sparse(const gpu::HostBsrMatrix& A)
{
    std::vector<Eigen::Triplet<double>> t;
    const int b = A.block_size;
    for (int r = 0; r < A.num_block_rows; ++r)
        for (int k = A.row_offsets[size_t(r)]; k < A.row_offsets[size_t(r) + 1]; ++k)
            for (int i = 0; i < b; ++i)
                for (int j = 0; j < b; ++j)
                    t.emplace_back(
                        r * b + i, A.col_indices[size_t(k)] * b + j, A.values[size_t(k * b * b + i * b + j)]);
    SparseMatrixd S(A.size(), A.size());
    S.setFromTriplets(t.begin(), t.end());
    return S;
}

} // namespace diffipc::test
