#pragma once
// Central-difference checks of a Potential (value -> gradient -> true Hessian)
// along random directions; shared by the contact and friction potential tests.

#include "test_utils.hpp"

#include "forward/potentials/potential.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>

namespace diffipc::test {

struct PotentialFD {
    double gradient = 0; ///< max |fd - g.p| / (|g| |p|)
    double hessian = 0; ///< max |fd(g) - H p| / max(|H p|, hessian_scale |p|)
    double min_eigenvalue = 0; ///< smallest eigenvalue of H / max(|H|, hessian_scale)
    double gradient_norm = 0;
};

/// @param mesh, dim       for the sparse pattern of the assembled Hessian
/// @param h               difference step (m)
/// @param hessian_scale   natural size of the Hessian: where the true Hessian is
///                        (nearly) zero, errors are measured against it
/// @param eigenvalues     false: skip min_eigenvalue (a dense eigensolve, too slow for thousands of dofs)
inline PotentialFD potential_fd(const Potential& P, const Mesh& mesh, int dim, const Eigen::VectorXd& x, double h,
    double hessian_scale = 0, bool eigenvalues = true)
{
    const Eigen::Index n = x.size();
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    P.add_gradient(x, 1.0, g);
    SparseAssembler H;
    H.build(dim, mesh.num_vertices(), mesh.elements);
    H.set_zero();
    P.add_hessian(x, 1.0, false, H);
    H.finalize();
    const SparseMatrixd Hs = H.matrix().selfadjointView<Eigen::Lower>();
    PotentialFD e;
    e.gradient_norm = g.norm();
    for (unsigned seed = 1; seed <= 4; ++seed) {
        const Eigen::VectorXd dir = random_vector(n, seed);
        const double fd = (P.value(x + h * dir) - P.value(x - h * dir)) / (2 * h);
        e.gradient = std::max(e.gradient, std::abs(fd - g.dot(dir)) / std::max(g.norm() * dir.norm(), 1e-300));
        Eigen::VectorXd gp = Eigen::VectorXd::Zero(n), gm = Eigen::VectorXd::Zero(n);
        P.add_gradient(x + h * dir, 1.0, gp);
        P.add_gradient(x - h * dir, 1.0, gm);
        const Eigen::VectorXd Hp = Hs * dir;
        e.hessian = std::max(
            e.hessian, ((gp - gm) / (2 * h) - Hp).norm() / std::max({ Hp.norm(), hessian_scale * dir.norm(), 1e-300 }));
    }
    if (eigenvalues) {
        const Eigen::MatrixXd Hd = Eigen::MatrixXd(Hs);
        e.min_eigenvalue = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Hd).eigenvalues().minCoeff()
            / std::max({ Hd.norm(), hessian_scale, 1e-300 });
    }
    return e;
}

} // namespace diffipc::test
