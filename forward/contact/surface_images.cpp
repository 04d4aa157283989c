#include "forward/contact/surface_images.hpp"

#include "forward/solver/sparse_assembler.hpp"

namespace diffipc {

SurfaceImages::SurfaceImages() = default;
SurfaceImages::~SurfaceImages() = default;

SurfaceImages::SurfaceImages(SparseMatrixd T, int dim)
    : m_T(std::move(T))
    , m_dim(dim)
{
    if (!empty()) {
        m_scratch = std::make_unique<SparseAssembler>();
        m_scratch->build(dim, m_T.rows() / dim, MatrixXi(0, dim + 1));
    }
}

SurfaceImages::SurfaceImages(const SurfaceImages& other)
    : SurfaceImages(other.m_T, other.m_dim)
{
}

SurfaceImages::SurfaceImages(SurfaceImages&&) noexcept = default;
SurfaceImages& SurfaceImages::operator=(SurfaceImages&&) noexcept = default;

SurfaceImages& SurfaceImages::operator=(const SurfaceImages& other)
{
    if (this != &other) {
        SurfaceImages copy(other);
        *this = std::move(copy);
    }
    return *this;
}

SparseAssembler& SurfaceImages::hessian_target(SparseAssembler& H) const
{
    if (empty())
        return H;
    m_scratch->set_zero();
    return *m_scratch;
}

void SurfaceImages::finish_hessian(SparseAssembler& H) const
{
    if (empty())
        return;
    m_scratch->finalize();
    const SparseMatrixd full = m_scratch->matrix().selfadjointView<Eigen::Lower>();
    // Exact zeros (an empty surface matrix) would only grow H's pattern.
    const SparseMatrixd reduced = SparseMatrixd(m_T.transpose() * full * m_T).pruned();
    H.add_matrix(reduced.triangularView<Eigen::Lower>());
}

} // namespace diffipc
