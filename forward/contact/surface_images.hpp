#pragma once
/// @file surface_images.hpp
/// Periodic images as the contact potentials see them (forward/periodic/contact_images.hpp): a
/// constant linear map T from the mesh's positions to a contact surface's, x_s = T x. The
/// potentials work on x_s and hand back T^T g_s and T^T H_s T. Without images (T empty) every
/// operation is the identity.

#include "forward/common/types.hpp"

#include <memory>

namespace diffipc {

class SparseAssembler;

class SurfaceImages {
public:
    SurfaceImages();
    /// @param T #S dim by #V dim
    SurfaceImages(SparseMatrixd T, int dim);
    /// Copies T; the copy gets its own scratch assembler.
    SurfaceImages(const SurfaceImages& other);
    SurfaceImages& operator=(const SurfaceImages& other);
    SurfaceImages(SurfaceImages&&) noexcept;
    SurfaceImages& operator=(SurfaceImages&&) noexcept;
    ~SurfaceImages();

    bool empty() const { return m_T.size() == 0; }
    const SparseMatrixd& matrix() const { return m_T; }
    /// x, or T x (in `storage`) with images.
    const VectorXd& surface(const VectorXd& x, VectorXd& storage) const
    {
        if (empty())
            return x;
        storage = m_T * x;
        return storage;
    }
    /// g += T^T g_s.
    void add_back(const VectorXd& surface_g, VectorXd& g) const { g += m_T.transpose() * surface_g; }
    /// The assembler a potential's local matrices go into: with images the surface's (zeroed),
    /// else H itself.
    SparseAssembler& hessian_target(SparseAssembler& H) const;
    /// With images: finalizes the surface's matrix and adds T^T H_s T into H (entries outside
    /// H's element pattern as local matrices: H.finalize() must follow). Nothing without.
    void finish_hessian(SparseAssembler& H) const;

private:
    SparseMatrixd m_T;
    int m_dim = 0;
    mutable std::unique_ptr<SparseAssembler> m_scratch;
};

} // namespace diffipc
