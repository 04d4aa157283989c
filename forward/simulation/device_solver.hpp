#pragma once
/// @file device_solver.hpp
/// The GPU path of a time step (scene key "device": "gpu"): the step's Newton solve on the
/// device (cuda/solver/device_newton.hpp), in place of NewtonSolver::solve. Everything else of
/// the step stays the Simulator's (integrator, Dirichlet targets, loads, statuses, records,
/// output), so the GPU path writes the same records and files as the CPU path.
///
/// Data residency: the mesh, the materials, the masses, the Hessian's pattern and every work
/// vector live on the GPU for the whole run; per step the start x, the inertial target, the
/// external force and the prescribed targets go up (4 vectors) and the converged x comes back
/// (the step record, which the HDF5 output and the adjoint read).
///
/// Builds without CUDA compile this file too: constructing a DeviceSolver then throws an
/// InputError naming the scene's "device" field.

#include "forward/potentials/elastic_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/solver/newton.hpp"

#include <memory>
#include <string>
#include <vector>

namespace diffipc {

class DeviceSolver {
public:
    /// @brief Uploads the mesh, materials and masses.
    /// @param elastic      the scene's elastic potential (its mesh, models and Lame parameters)
    /// @param inertia      the lumped masses, or nullptr for a static scene (no inertial term)
    /// @param constrained  #dofs Dirichlet flags
    /// @throws InputError naming "device" when this build has no CUDA or no GPU is present
    DeviceSolver(
        const ElasticPotential& elastic, const InertiaPotential* inertia, const std::vector<char>& constrained);
    ~DeviceSolver();
    DeviceSolver(const DeviceSolver&) = delete;
    DeviceSolver& operator=(const DeviceSolver&) = delete;

    /// @brief One step's solve, with NewtonSolver::solve's meaning of every argument and of the
    /// result (status, iterations, residual, newton_step, line_search_cuts; times: assembly,
    /// solve and line_search). x is changed only when the status is CONVERGED.
    /// @param inertial_target x~ (ignored for a static scene)
    /// @param weight          c h^2 of the non-inertial potentials
    /// @param force           #dofs external force f (N)
    NewtonResult solve(VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force,
        const VectorXd& target, double force_scale, double step_scale, const NewtonSettings& settings);

    /// @brief The adjoint system of a converged step on the device (adjoint/adjoint.cpp):
    /// (M + w H) y = b on the free dofs, H the true elastic Hessian at x; y = 0 on constrained dofs.
    /// @return false if PCG did not converge (a true Hessian that is not positive definite, or the
    ///         iteration cap): the caller then factorizes on the CPU
    bool solve_adjoint(const VectorXd& x, double weight, const VectorXd& b, VectorXd& y, int* iterations = nullptr);

    /// PCG iterations of the last solve() (all its Newton iterations).
    int last_pcg_iterations() const { return m_last_pcg_iterations; }

    /// @brief True when this build has CUDA and a GPU is present; otherwise false, with the
    /// reason in *why (if given).
    static bool available(std::string* why = nullptr);
    /// One line about the GPU (name, compute capability, driver), or why there is none.
    static std::string describe_device();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    int m_last_pcg_iterations = 0;
};

} // namespace diffipc
