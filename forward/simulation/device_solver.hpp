#pragma once
/// @file device_solver.hpp
/// The GPU path of a time step (scene key "device": "gpu"): the step's Newton solve on the
/// device (cuda/solver/device_newton.hpp), in place of NewtonSolver::solve. Everything else of
/// the step stays the Simulator's (integrator, Dirichlet targets, loads, statuses, records,
/// output), so the GPU path writes the same records and files as the CPU path.
///
/// Contact (the barrier model without periodic images): the CPU's ContactPotential
/// gives the collision mesh, planes and settings, and stays the source of kappa between steps;
/// the device has its own twin (cuda/contact/device_contact.hpp). The adaptive stiffness runs as
/// on the CPU (Simulator::update_kappa_for_step at the step's start, ContactPotential::end_iteration
/// after each iterate: IPC's balancing rule once contact appears, then doubling), with the
/// balancing products and the smallest gap computed on the device.
///
/// Friction: the Simulator lags it on the host (FrictionPotential::lag from this solver's active set,
/// contacts()) and hands each lagged set to set_friction(), which uploads it for the next solves
/// (cuda/contact/device_friction.hpp); the lagging iterations' residual comes from residual().
///
/// Data residency: the mesh, the materials, the masses, the Hessian's pattern and every work
/// vector live on the GPU for the whole run; per step the start x, the inertial target, the
/// external force and the prescribed targets go up (4 vectors) and the converged x comes back
/// (the step record, which the HDF5 output and the adjoint read).
///
/// Builds without CUDA compile this file too: constructing a DeviceSolver then throws an
/// InputError naming the scene's "device" field. Nothing here depends on whether the build has
/// CUDA (device_conversion.hpp holds what does), so that turning DIFFIPC_CUDA on or off
/// recompiles forward's files, not every file of the other libraries that includes the scene.

#include "forward/contact/contact_potential.hpp"
#include "forward/contact/friction/friction_potential.hpp"
#include "forward/periodic/periodic_cell.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/solver/newton.hpp"

#include <memory>
#include <string>
#include <utility>
#include <vector>


namespace diffipc {

namespace gpu {
    struct DeviceNewtonResult;
}


class DeviceSolver {
public:
    /// @brief Uploads the mesh, materials and masses.
    /// @param elastic      the scene's elastic potential (its mesh, models and Lame parameters)
    /// @param inertia      the lumped masses, or nullptr for a static scene (no inertial term)
    /// @param constrained  #dofs Dirichlet flags
    /// @param contact      the scene's contact potential (with periodic images: set_periodic() gives
    ///                     the device its image surface's map), or nullptr
    /// @throws InputError naming "device" when this build has no CUDA or no GPU is present
    DeviceSolver(const ElasticPotential& elastic, const InertiaPotential* inertia, const std::vector<char>& constrained,
        const ContactPotential* contact = nullptr);
    ~DeviceSolver();
    DeviceSolver(const DeviceSolver&) = delete;
    DeviceSolver& operator=(const DeviceSolver&) = delete;

    /// @brief One step's solve, with NewtonSolver::solve's meaning of every argument and of the
    /// result (status, iterations, residual, newton_step, line_search_cuts; times: assembly,
    /// solve and line_search). x is changed only when the status is CONVERGED.
    /// @param inertial_target x~ (ignored for a static scene)
    /// @param weight          c h^2 of the non-inertial potentials
    /// @param force           #dofs external force f (N)
    /// @param control         if given: displacement control on the device (NewtonSolver::solve's `control`:
    ///                        the bordered step by projected PCG, cuda/solver/device_newton.hpp); its
    ///                        multiplier is set. Counted by control_solves().
    NewtonResult solve(VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force,
        const VectorXd& target, double force_scale, double step_scale, const NewtonSettings& settings,
        LoadControl* control = nullptr);
    /// Displacement-control solves on the device so far (solve() with a control).
    long control_solves() const { return m_control_solves; }

    /// @brief A proximal solve of load stepping's relaxation (Simulator::relax_to_equilibrium) in a static
    /// scene: solve()'s problem plus (proximal_weight / 2) |x - center|_M^2 with the lumped masses M
    /// (per vertex), as the CPU's Problem with the inertia potential weighted proximal_weight. The device
    /// is static again afterwards. Counted by proximal_solves().
    /// @throws std::logic_error for a dynamic scene's solver (its inertia is the integrator's)
    NewtonResult solve_proximal(VectorXd& x, const VectorXd& center, double proximal_weight,
        const VectorXd& lumped_masses, double weight, const VectorXd& force, const VectorXd& target, double force_scale,
        double step_scale, const NewtonSettings& settings);
    /// Proximal solves on the device so far (solve_proximal).
    long proximal_solves() const { return m_proximal_solves; }

    /// @brief Makes the device solve a periodic cell's steps (a DevicePeriodicMap of the cell's classes,
    /// q's constrained entries; cuda/solver/device_newton.hpp, set_periodic): then solve_periodic()
    /// solves, not solve(). With contact, the contact runs on the image surface (cuda/README.md,
    /// "Periodic cells on the device").
    /// @param image_classes with contact across the cell's boundary: the class of each image surface
    ///        vertex's source (ContactImages::source), the surface's own periodic map (empty: no contact)
    void set_periodic(const PeriodicCell& cell, const std::vector<int>& image_classes = {});
    /// @brief PeriodicCell::solve's Newton solve on the device: q and target as PeriodicCell::step_unknowns
    /// gives them, the other arguments and the result as solve()'s. q is changed only when CONVERGED.
    NewtonResult solve_periodic(VectorXd& q, const VectorXd& target, const VectorXd& inertial_target, double weight,
        const VectorXd& force, double force_scale, double step_scale, const NewtonSettings& settings);

    /// The adaptive stiffness' parameters (Simulator::update_kappa_for_step's).
    struct AdaptiveKappa {
        bool enabled = false;
        double kappa_min = 0; ///< the rule's floor (barrier_stiffness_min)
        double kappa_max = 0; ///< 100 kappa_min
        double bbox_diagonal = 1; ///< m
    };
    /// @brief The contact's state at the start of a step (call before solve() in a contact scene):
    /// kappa from the CPU contact (the value carried between steps); with the adaptive stiffness,
    /// kappa = max(kappa, the balancing rule) if contacts are active at x, and the rule's state reset.
    /// @param x, inertial_target, weight, force  the step's start and its terms (as solve()'s)
    /// @param q a periodic cell's unknowns at x (its contact balances in q); nullptr otherwise
    void begin_step(double kappa, const AdaptiveKappa& adaptive, const VectorXd& x, const VectorXd& inertial_target,
        double weight, const VectorXd& force, const VectorXd* q = nullptr);
    /// The device contact's kappa (after a solve: the value it ended with).
    double kappa() const;
    /// @brief Sets the device contact's kappa, leaving the adaptive rule's state of the step as it is:
    /// what a failed solve of a sub-stepped step restores (as ContactPotential::set_kappa on the CPU).
    void set_kappa(double kappa);
    /// With the adaptive kappa: whether this step's balancing rule was applied (at its start, or when
    /// contact appeared); what the CPU contact takes over for load stepping's CPU fallbacks.
    bool adaptive_rule_applied() const;
    /// @brief The active contacts at x (the CPU's ContactPotential::contacts(x): the same pairs in the
    /// same order, with their distance types and squared distances classified on the host).
    ContactSet contacts(const VectorXd& x) const;
    /// @brief Uploads friction's lagged data for the next solves: its lagged pairs (with their
    /// weights, tangents and mu lambda), its start-of-step positions and eps = eps_v h; empty pairs:
    /// no friction work.
    void set_friction(const FrictionPotential& friction);
    /// @brief max |g_free| at x of the step's E (inertia, elastic, external, barrier with the device's
    /// kappa and active set at x, the uploaded friction): Simulator::force_residual times w times the
    /// force scale. NaN if not finite.
    double residual(const VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force);
    /// @brief ContactPotential::min_distance(x, radius) on the device.
    double min_distance(const VectorXd& x, double radius) const;
    /// Wall times of the device contact work since the last begin_step().
    ContactTimes contact_times() const;
    /// The device contact's work over the whole run (s and counts): active-set rebuilds (part of
    /// contact_times().barrier) and energy evaluations, the largest active set.
    struct ContactProfile {
        double active_sets = 0, energies = 0;
        long active_set_count = 0, energy_count = 0;
        int max_active = 0;
        /// contacts() that were not the last one's x (device active set, host copy and classification), and
        /// set_friction() (conversion, the pairs' preparation on the host, upload): s and counts.
        double contact_sets = 0, friction_uploads = 0;
        long contact_set_count = 0, friction_upload_count = 0;
    };
    ContactProfile contact_profile() const { return m_profile; }

    /// @brief The adjoint's preconditioner on the device: the smoothed-aggregation multigrid or block-Jacobi
    /// (the default; DeviceNewton::solve_true_hessian). The Simulator sets it from the scene's
    /// solver.gpu_adjoint_preconditioner.
    void set_adjoint_multigrid(bool on);

    /// @brief The adjoint system of a converged step on the device (adjoint/adjoint.cpp):
    /// (M + w H) y = b on the free dofs, H the true Hessian at x (elastic, and the barrier's of the
    /// active set at x with stiffness `kappa` in a contact scene, and the friction's of the data last
    /// given to set_friction()); y = 0 on constrained dofs.
    /// @return false if PCG did not converge (a true Hessian that is not positive definite, or the
    ///         iteration cap): the caller then factorizes on the CPU
    /// @param coupling if given: #dofs, H y without the constraints (on the constrained dofs: their
    ///                 couplings to the free ones times y, what the adjoint subtracts there)
    bool solve_adjoint(const VectorXd& x, double weight, const VectorXd& b, VectorXd& y, int* iterations = nullptr,
        double kappa = 0, VectorXd* coupling = nullptr);

    /// PCG iterations of the last solve() (all its Newton iterations).
    int last_pcg_iterations() const { return m_last_pcg_iterations; }
    /// PCG iterations of every solve() so far.
    long total_pcg_iterations() const { return m_total_pcg_iterations; }

    /// @brief True when this build has CUDA and a GPU is present; otherwise false, with the
    /// reason in *why (if given).
    static bool available(std::string* why = nullptr);
    /// One line about the GPU (name, compute capability, driver), or why there is none.
    static std::string describe_device();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    const ContactPotential* m_cpu_contact = nullptr;
    int m_last_pcg_iterations = 0;
    long m_total_pcg_iterations = 0;
    /// After a solve: its PCG iterations, and the contact's times since the last solve into the profile.
    void account(const gpu::DeviceNewtonResult& r);
    long m_proximal_solves = 0;
    long m_control_solves = 0;
    mutable ContactProfile m_profile;
};

} // namespace diffipc
