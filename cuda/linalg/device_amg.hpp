#pragma once
/// @file device_amg.hpp
/// Smoothed-aggregation algebraic multigrid on the device, as a preconditioner for DevicePCG: one
/// symmetric V-cycle per application. The hierarchy's patterns and product lists come from
/// plan_amg() (amg_hierarchy.hpp), built once on the host; setup() recomputes every value on the
/// device from a matrix on the plan's fine pattern (once per linear system):
///
/// - A_0 = the matrix with its fixed dofs' rows and columns replaced by identity ones (as DevicePCG
///   eliminates them);
/// - per level: D^-1, the inverted diagonal blocks; rho, an estimate of the spectral radius of D^-1 A
///   by power iteration; the smoothed prolongator P = (I - 4/(3 rho) D^-1 A) T; the Galerkin coarse
///   matrix A_{l+1} = P^T (A P), block by block from the plan's lists;
/// - at the coarsest level, the dense inverse by Gauss-Jordan elimination (principal pivots: the
///   matrix is symmetric positive definite; a pivot that is not positive makes setup() fail).
///
/// The V-cycle smooths with damped block-Jacobi, x += s D^-1 (b - A x), s = 1/(1.1 rho_est), the same
/// number of sweeps before and after the coarse correction, so the preconditioner is symmetric; it is
/// positive definite while s rho(D^-1 A) < 2, i.e. while the power iteration's rho_est (usually a little
/// below rho; not a bound) exceeds rho / 2.2. DeviceNewton falls back to block-Jacobi if a multigrid
/// solve fails. Every value is a fixed-order sum (no atomics): two setups
/// and applications on the same data give bitwise equal results.

#include "cuda/linalg/amg_hierarchy.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/device_preconditioner.hpp"

#include <memory>
#include <vector>

namespace diffipc::gpu {

struct AmgSettings {
    /// Block-Jacobi sweeps before and after each coarse correction (>= 1).
    int smoothing_sweeps = 1;
    /// Power iterations for each level's rho(D^-1 A) (>= 1).
    int power_iterations = 10;
};

class DeviceAmg : public DevicePreconditioner {
public:
    /// @brief Uploads the plan's patterns, lists and tentative prolongators (the plan is not kept).
    /// @throws std::invalid_argument on settings out of range or a coarsest level above 4000 dofs
    explicit DeviceAmg(const AmgPlan& plan, const AmgSettings& settings = {});
    ~DeviceAmg() override;
    DeviceAmg(const DeviceAmg&) = delete;
    DeviceAmg& operator=(const DeviceAmg&) = delete;

    /// @brief Computes the hierarchy's values from A (on the plan's fine pattern and block size).
    /// Synchronizes once (to read the coarsest factorization's status).
    /// @return false if the coarsest matrix is not numerically positive definite (then apply() must not
    ///         be used until a later setup() succeeds)
    /// @throws std::invalid_argument if A's pattern is not the plan's
    bool setup(const DeviceBsrMatrix& A);

    int size() const override;
    void apply(const double* d_r, double* d_z) const override;

    /// Levels with a coarser one below (the coarsest, solved densely, not counted).
    int num_levels() const;
    /// Dofs of level l, for l in [0, num_levels()] (num_levels() is the coarsest).
    int level_size(int l) const;
    /// Values of level l's matrix A_l (l in [0, num_levels()]; masked, the plan's pattern) and of its
    /// smoothed prolongator P_l (l < num_levels()), as of the last setup(); for tests.
    std::vector<double> matrix_values(int l) const;
    std::vector<double> prolongator_values(int l) const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc::gpu
