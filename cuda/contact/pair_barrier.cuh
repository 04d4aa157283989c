#pragma once
/// @file pair_barrier.cuh
/// The projected Hessian of one contact pair on the host and the device: the pair's energy and true
/// Hessian from forward/kernels/contact_pair.hpp (the code ContactPotential runs), projected to
/// positive semi-definite by cyclic Jacobi (forward/kernels/project_psd.hpp; the CPU uses Eigen's
/// eigensolver for the same projection, twice as fast there: bench/psd_projection.cpp) and scaled.

#include "cuda/common/kernels.cuh"
#include "forward/kernels/contact_pair.hpp"
#include "forward/kernels/project_psd.hpp"

namespace diffipc::gpu {

/// @brief The pair's Hessian as ContactPotential::add_hessian assembles it: pair_energy's
/// Hessian, projected to positive semi-definite if `project` (the CPU's project_psd: unchanged if
/// it has a Cholesky factorization, else V max(D, 0) V^T, here by cyclic Jacobi,
/// forward/kernels/project_psd.hpp), then times `scale` (kappa times the potential weight).
/// NaN (not projected) for an intersecting pair of the barrier.
/// @param hess out: n by n row-major (n = #vertices * dim)
/// @return the pair's energy without kappa (+inf if an intersecting barrier pair)
DIFFIPC_HD inline double pair_energy_hessian(ContactKind kind, int dim, const vec3* points, const vec3& normal,
    double eps_x, const PairModel& model, bool project, double scale, double* hess)
{
    const double e = pair_energy(kind, dim, points, normal, eps_x, -1, model, nullptr, hess);
    const int n = contact_num_vertices(kind) * dim;
    if (project && is_finite(e)) {
        switch (n) {
        case 4:
            project_psd<4>(hess);
            break;
        case 6:
            project_psd<6>(hess);
            break;
        case 9:
            project_psd<9>(hess);
            break;
        case 12:
            project_psd<12>(hess);
            break;
        default:
            break;
        }
    }
    for (int k = 0; k < n * n; ++k)
        hess[k] *= scale;
    return e;
}

/// @brief pair_energy_hessian with the barrier model.
DIFFIPC_HD inline double pair_barrier_hessian(ContactKind kind, int dim, const vec3* points, const vec3& normal,
    double eps_x, double dmin2, double shat, bool project, double scale, double* hess)
{
    PairModel model;
    model.dmin2 = dmin2;
    model.shat = shat;
    return pair_energy_hessian(kind, dim, points, normal, eps_x, model, project, scale, hess);
}

} // namespace diffipc::gpu
