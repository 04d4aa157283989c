// The element BSR pattern and its incidence lists (cuda/linalg/bsr_pattern.hpp), on the CPU: the
// pattern holds the CPU assembler's, and gathering element matrices and gradients through the
// incidence lists (what the GPU kernels do) gives the CPU potential's Hessian and gradient.

#include "cuda/linalg/bsr_pattern.hpp"
#include "forward/kernels/element.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

using namespace diffipc;

namespace {

template <int dim> void check_gathers(const std::vector<int>& cells)
{
    constexpr int n = dim + 1, L = dim * n;
    const test::ElasticBox box = test::make_elastic_box(dim, cells, -1, 0.1, 0.05, 11);
    const Index ne = box.mesh.num_elements();
    const gpu::ElementBsrPattern p = gpu::element_bsr_pattern(int(box.mesh.num_vertices()), n, box.elements_flat());

    // Element matrices and gradients from the GPU's element functions, run here.
    std::vector<double> Ke(size_t(ne) * L * L), ge(size_t(ne) * L);
    for (Index e = 0; e < ne; ++e) {
        double rest[n * dim], xe[n * dim];
        for (int a = 0; a < n; ++a)
            for (int i = 0; i < dim; ++i) {
                rest[a * dim + i] = box.mesh.rest_positions(box.mesh.elements(e, a), i);
                xe[a * dim + i] = box.x[box.mesh.elements(e, a) * dim + i];
            }
        const MaterialModel model = box.models[size_t(e)];
        kernels::element_hessian_from_rest<dim>(
            model, rest, xe, box.mu[e], box.lambda[e], true, Ke.data() + size_t(e) * L * L);
        kernels::element_gradient_from_rest<dim>(model, rest, xe, box.mu[e], box.lambda[e], ge.data() + size_t(e) * L);
    }

    // Gather per slot and per vertex through the incidence lists.
    gpu::HostBsrMatrix H;
    H.block_size = dim;
    H.num_block_rows = p.num_vertices;
    H.row_offsets = p.row_offsets;
    H.col_indices = p.col_indices;
    H.values.assign(size_t(p.num_slots()) * dim * dim, 0.0);
    for (int s = 0; s < p.num_slots(); ++s)
        for (int c = p.slot_offsets[size_t(s)]; c < p.slot_offsets[size_t(s) + 1]; ++c) {
            const int code = p.slot_codes[size_t(c)], e = code / (n * n), a = (code / n) % n, b = code % n;
            if (c > p.slot_offsets[size_t(s)])
                EXPECT_GT(code, p.slot_codes[size_t(c) - 1]) << "slot contributions in element order";
            EXPECT_EQ(p.element_slots[size_t(code)], s);
            for (int i = 0; i < dim; ++i)
                for (int k = 0; k < dim; ++k)
                    H.values[size_t(s * dim * dim + i * dim + k)]
                        += Ke[size_t(e) * L * L + size_t((a * dim + i) * L + b * dim + k)];
        }
    VectorXd g = VectorXd::Zero(box.mesh.num_dofs());
    for (int v = 0; v < p.num_vertices; ++v)
        for (int c = p.vertex_offsets[size_t(v)]; c < p.vertex_offsets[size_t(v) + 1]; ++c) {
            const int e = p.vertex_codes[size_t(c)] / n, a = p.vertex_codes[size_t(c)] % n;
            EXPECT_EQ(box.mesh.elements(e, a), v);
            for (int i = 0; i < dim; ++i)
                g[v * dim + i] += ge[size_t(e) * L + size_t(a * dim + i)];
        }

    const SparseMatrixd expected = test::cpu_hessian(box, box.x, 1.0, true);
    const SparseMatrixd gathered = test::to_sparse(H);
    EXPECT_LE((gathered - expected).norm(), 1e-12 * expected.norm());
    // Every entry of the CPU pattern is in the BSR pattern (its blocks may hold more zeros).
    for (int col = 0; col < expected.outerSize(); ++col)
        for (SparseMatrixd::InnerIterator it(expected, col); it; ++it) {
            const int r = int(it.row()) / dim, cb = col / dim;
            const auto first = p.col_indices.begin() + p.row_offsets[size_t(r)];
            const auto last = p.col_indices.begin() + p.row_offsets[size_t(r) + 1];
            EXPECT_TRUE(std::binary_search(first, last, cb)) << "block (" << r << ", " << cb << ") missing";
        }
    VectorXd g_cpu = VectorXd::Zero(box.mesh.num_dofs());
    box.potential->add_gradient(box.x, 1.0, g_cpu);
    EXPECT_LE((g - g_cpu).norm(), 1e-12 * g_cpu.norm());
}

TEST(ElementBsrPattern, GathersGiveTheCpuHessianAndGradient2D) { check_gathers<2>({ 5, 4 }); }
TEST(ElementBsrPattern, GathersGiveTheCpuHessianAndGradient3D) { check_gathers<3>({ 3, 3, 2 }); }

TEST(ElementBsrPattern, DiagonalBlocksForEveryVertexAndColumnsSorted)
{
    // Two triangles sharing an edge, and a vertex (4) in no element.
    const gpu::ElementBsrPattern p = gpu::element_bsr_pattern(5, 3, { 0, 1, 2, 1, 3, 2 });
    EXPECT_EQ(p.row_offsets, (std::vector<int> { 0, 3, 7, 11, 14, 15 }));
    EXPECT_EQ(p.col_indices, (std::vector<int> { 0, 1, 2, 0, 1, 2, 3, 0, 1, 2, 3, 1, 2, 3, 4 }));
    EXPECT_EQ(p.vertex_offsets, (std::vector<int> { 0, 1, 3, 5, 6, 6 }));
    EXPECT_EQ(p.vertex_codes, (std::vector<int> { 0, 1, 3, 2, 5, 4 }));
    EXPECT_EQ(p.slot_offsets.back(), 18);
    EXPECT_THROW(gpu::element_bsr_pattern(3, 3, { 0, 1, 3 }), std::invalid_argument);
    EXPECT_THROW(gpu::element_bsr_pattern(3, 3, { 0, 1 }), std::invalid_argument);
}

} // namespace
