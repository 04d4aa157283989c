#pragma once
/// @file device_newton.hpp
/// One time step's Newton solve on the GPU: the device twin of NewtonSolver
/// (forward/solver/newton.hpp) for scenes of elastic bodies with inertia, external forces,
/// Dirichlet conditions, (set_contact()) IPC barrier contact and (set_friction()) lagged friction. The mesh, its
/// material data, the Hessian's pattern and every work vector stay on the device; per solve, the
/// start x, the inertial target, the force and the prescribed targets are copied up and the
/// converged x copied back (the step record).
///
/// Incremental potential (docs/math.md), the CPU's:
///   E(x) = 1/2 (x - xt)^T M (x - xt) + w [Psi(x) + B(x) - f^T x]
/// with M the lumped mass (diagonal, per dof), xt the inertial target, w = c h^2 the potential
/// weight (1 for static solves, which have no M), Psi the elastic energy (DeviceElasticMesh),
/// B the contact barrier kappa sum_k m_k b_k (DeviceContact; 0 without contact) and, with friction,
/// + w D(x), the lagged friction of the solve (DeviceFriction; its pairs fixed during the solve).
///
/// Contact (as the CPU's ContactPotential inside NewtonSolver): the active set is rebuilt at each
/// iterate (DeviceContact::update_active) for the gradient and the search matrix, whose contact
/// part (per-pair PSD projection) is added to the elastic one by a SumOperator; every step is
/// bounded by the CCD step bound as well as by the inversion bound (a bound that is not > 0 with
/// unresolved CCD is CCD_UNRESOLVED); trial energies on the step's segment reuse its swept
/// candidates. After each accepted iterate the end-of-iteration hook (set_end_iteration: the
/// adaptive stiffness, which the caller owns) may change kappa; the energy is then re-evaluated.
///
/// Algorithm (as NewtonSolver::solve; contact above, load control and the step extension below):
///  - residual max |g_free| / force_scale; converged when <= residual_tolerance and no lifting
///    remains;
///  - lifting: constrained dofs move toward `target` by steps p_D = target - x_D, free rows of the
///    Newton system see -(g_F + H_FD p_D); a lifting step is bounded (inversion) but not
///    Armijo-tested; a full lifting step snaps the constrained dofs to target exactly;
///  - the search matrix M + w H_Psi with each element's dP/dF projected to PSD, solved by
///    block-Jacobi PCG (device_pcg.hpp) to an inexact-Newton forcing tolerance;
///  - step bound: the largest alpha <= 1 at which no element has lost more than
///    1 - inversion_keep of its volume (the CPU's inversion_free_step, same polynomial roots),
///    then Armijo backtracking by halving, with the CPU's round-off allowance;
///  - round-off regime: a step below 128 eps |x|_inf is taken only while it halves the residual.
/// Statuses mirror StepStatus (forward/solver/status.hpp); a failed solve leaves the host x as
/// it was given (the caller's committed state is untouched).
///
/// Load control (solve()'s `control`, the CPU's LoadControl: displacement control past a limit point,
/// docs/math.md "Load stepping past limit points"): minimizes E on the hyperplane a^T x = level. The
/// residual is that of g - lambda a with lambda = a^T g / a^T a (the load the constraint carries); the
/// step is p = p0 + d with p0 = (level - a^T x) a / a^T a and d the projected PCG solve
/// (device_pcg.hpp, set_constraint) of the search matrix on a^T d = 0, with right-hand side
/// -(g + H (pD + p0)): the CPU's bordered step, a^T p = level - a^T x. While |level - a^T x| exceeds the
/// control's tolerance the step lifts (bounded, not Armijo-tested), like a prescribed motion. The true
/// Hessian (adaptive_projection) needs to be positive definite only on the hyperplane, where the CPU
/// factorizes an indefinite one by LDL^T; no step extension under load control, as on the CPU.
///
/// Differences from the CPU solver: adaptive_projection keeps the true Hessian when PCG meets no
/// negative curvature and its step descends (the CPU: when Cholesky succeeds); no step_tolerance; the
/// Newton system is
/// solved inexactly by PCG (forcing above) instead of by Cholesky. A PCG run that stops at its
/// iteration cap, or on a breakdown after at least one iteration, still gives a descent direction
/// and is used; a breakdown before any iteration (the search matrix is not positive definite on
/// the free dofs) is LINEAR_BREAKDOWN. As on the CPU, a direction that does not descend falls
/// back to the negative gradient scaled to the rejected step's length.
///
/// Round-off allowance of the line search (as NewtonSolver): max(1e-13 |E|, 16 eps magnitude)
/// with magnitude the CPU Problem's energy_magnitude at the start x:
///   |1/2 (x - xt)^T M (x - xt)| + w (|Psi(x)| + material_scale) + w |B(x)| + w |f^T (x - x_ref)|,
/// where material_scale = sum over neo-Hookean and stable neo-Hookean elements of |e| mu_e dim
/// (ElasticPotential::value_scale's term; set_material_scale(), 0 until set) and x_ref the force
/// reference (set_force_reference(), 0 until set; the CPU's ExternalForcePotential measures the
/// work from the rest positions, so set it to them to reproduce the CPU's energy values).
///
/// Determinism: every sum is a fixed-order tree (as cuda/linalg/reduction.hpp), maxima and minima
/// are order-independent, the gradient and Hessian gathers and the PCG are deterministic: two
/// solves of the same input give the same bits.
///
/// Layouts: all vectors #dofs = #V * dim doubles, flattened vertex-major (xyzxyz), SI units.

#include "cuda/contact/device_contact.hpp"
#include "cuda/contact/device_friction.hpp"
#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "cuda/periodic/device_periodic_map.hpp"

#include <functional>
#include <vector>

namespace diffipc::gpu {

/// The StepStatus values a device solve can end with: the same names and numbers as
/// forward/solver/status.hpp's StepStatus (stable: they are written to HDF5), so that
/// StepStatus(int(s)) converts.
enum class DeviceStepStatus {
    CONVERGED = 0,
    INVALID_INITIAL_STATE = 1,
    CCD_UNRESOLVED = 2,
    LINEAR_BREAKDOWN = 3,
    LINE_SEARCH_EXHAUSTED = 4,
    NEWTON_EXHAUSTED = 5,
    NON_FINITE = 7
};

struct DeviceNewtonSettings {
    double residual_tolerance = 1e-8; ///< on max |g_free| / force_scale
    int max_iterations = 100;
    int line_search_max_halvings = 40;
    double armijo = 1e-4;
    /// Fraction of its volume an element must keep along a step (the CPU's 0.1).
    double inversion_keep = 0.1;
    /// Inexact Newton: PCG's relative tolerance is min(forcing_max, sqrt(|g_free|_2 / |g_free,0|_2))
    /// (Eisenstat-Walker's choice), never looser than forcing_max and never tighter than forcing_min.
    /// |g_free,0|_2 is the largest free-gradient norm of the solve so far: the start's, unless lifting
    /// raised the gradient (a prescribed motion that starts from equilibrium), so that the linear
    /// solves tighten as the residual falls from its peak rather than from the start's.
    double forcing_max = 0.5;
    double forcing_min = 1e-12;
    /// The relative tolerance's cap while prescribed unknowns are lifted (1: forcing_max alone). Where the
    /// lifted step can pass only with the free unknowns' accurate response in the same iteration (a
    /// periodic cell's G pressing its posts on the next cell's, a boundary lifted against a proximal
    /// term), DeviceSolver sets it tight (forward/simulation/device_solver.cpp, device_settings).
    double lifting_forcing_max = 1.0;
    /// Near convergence (a residual r within `terminal_window` times the tolerance), the relative
    /// tolerance is at most terminal_factor * residual_tolerance / r: the last step then lands about
    /// terminal_factor times the tolerance below it, as the CPU's exact (Cholesky) last step does,
    /// instead of just under it. The converged state then depends smoothly on the problem's data,
    /// which finite differences of an objective need (docs/performance.md: without it 405's gradient
    /// check failed on the GPU). terminal_factor 0: off.
    double terminal_factor = 1e-2;
    double terminal_window = 100;
    int pcg_max_iterations = 20000;
    /// The longest step (m) of a free dof one iteration may take (NewtonSettings::max_displacement;
    /// 0: no cap). The line search starts from the capped step.
    double max_displacement = 0;
    /// NewtonSettings::adaptive_projection: after a full step, try the true Hessian (kept if PCG meets
    /// no negative curvature and its step descends; else the projected one, and the true one is
    /// skipped for two iterations).
    bool adaptive_projection = true;
    /// NewtonSettings::step_extension: a full step along which the energy fell by more than 0.9 of the
    /// linear prediction is tried at 2, 4, ... 4096 times its length while the energy keeps falling (Armijo
    /// against the start) and the step bound admits it (docs/math.md, "Step extension").
    bool step_extension = true;
};

/// A linear constraint a^T x = level on the free dofs for load control (solve(); the CPU's LoadControl,
/// forward/solver/newton.hpp).
struct DeviceLoadControl {
    std::vector<double> direction; ///< a (#dofs, zero on the constrained dofs, finite, not all zero)
    double level = 0; ///< a^T x at the solution
    double tolerance = 0; ///< |a^T x - level| below which the constraint holds (>= 0)
    double multiplier = 0; ///< out: lambda = a^T g / a^T a at the last iterate
};

/// The adaptive stiffness' balancing products at a state (Simulator::balancing_kappa): with gE the
/// gradient of E without the barrier and gB the barrier's gradient without kappa, both zero on the
/// constrained dofs: gB . gE and gB . gB; and the number of active contact pairs there.
struct ContactBalance {
    double gb_ge = 0, gb_gb = 0;
    int active = 0;
};

struct DeviceNewtonResult {
    DeviceStepStatus status = DeviceStepStatus::NEWTON_EXHAUSTED;
    int iterations = 0; ///< Newton steps taken
    double residual = 0; ///< max |free-dof gradient| / force_scale at the last iterate
    double newton_step = 0; ///< max |last step| / step_scale
    int line_search_cuts = 0; ///< halvings of accepted steps after the inversion bound
    int pcg_iterations = 0; ///< summed over the Newton iterations
    int pcg_capped = 0; ///< PCG solves that stopped at pcg_max_iterations (their iterate was used)
    int gradient_steps = 0; ///< iterations that fell back to the negative gradient
    int extended_steps = 0; ///< accepted steps lengthened by the step extension
    bool roundoff_limited = false;
    /// Wall time (s) per phase, measured with device synchronization at phase ends.
    double assembly_time = 0, solve_time = 0, line_search_time = 0;
    int kappa_updates = 0; ///< end-of-iteration hooks that changed kappa
    int true_hessian_steps = 0; ///< iterations that used the true Hessian (adaptive_projection)
};

class DeviceNewton {
public:
    /// @param mesh         an uploaded DeviceElasticMesh (must outlive the solver)
    /// @param lumped_mass  #dofs masses (kg, the vertex's lumped mass repeated per component; 0 for
    ///                     the massless vertices of obstacles and plane points, which are constrained);
    ///                     empty: static, no inertial term
    /// @throws std::invalid_argument on a size mismatch or a negative or non-finite mass
    DeviceNewton(const DeviceElasticMesh& mesh, const std::vector<double>& lumped_mass);
    ~DeviceNewton();
    DeviceNewton(const DeviceNewton&) = delete;
    DeviceNewton& operator=(const DeviceNewton&) = delete;

    /// @brief Replaces the lumped masses (#dofs values, finite and >= 0; empty: the solver becomes static)
    /// between solves. Load stepping's proximal relaxation of a static scene solves with the masses
    /// scaled by its proximal weight and the last iterate as inertial target, then makes the solver
    /// static again.
    /// @throws std::invalid_argument on a size mismatch or a negative or non-finite mass;
    ///         std::logic_error with a consistent mass (set_consistent_mass) or a periodic cell
    void set_lumped_mass(const std::vector<double>& lumped_mass);

    /// @brief The consistent mass matrix M in place of the lumped masses (a dynamic solver only):
    /// scalar entries (row, col, value) of the #dofs square matrix, summed where repeated; every
    /// entry must couple two vertices of one element (the Hessian's block pattern). The inertial
    /// energy, gradient and Hessian (search and adjoint matrices) then use M; the lumped masses
    /// given at construction only say that the solver is dynamic.
    /// @throws std::invalid_argument for a static solver, an index out of range, an entry outside the
    ///         pattern or a non-finite value
    void set_consistent_mass(
        const std::vector<int>& rows, const std::vector<int>& cols, const std::vector<double>& values);

    /// @brief Sets the constrained (Dirichlet) dofs: #dofs flags, nonzero = constrained (none until set).
    /// @throws std::invalid_argument on a size mismatch
    void set_constrained(const std::vector<char>& constrained);

    /// @brief The point from which the external work f^T (x - x_ref) is measured (#dofs, m; empty: 0).
    /// It shifts E by a constant, so only the line search's round-off allowance sees it; the CPU's
    /// ExternalForcePotential uses the rest positions.
    /// @throws std::invalid_argument on a size mismatch
    void set_force_reference(const std::vector<double>& reference);

    /// @brief Sets material_scale (file comment) from the mesh's elements: sum over the elements
    /// whose model is neo-Hookean or stable neo-Hookean of rest volume * mu * dim (J).
    /// @param models #E model codes, @param mu #E Lame parameters (Pa), as given to the mesh's upload
    /// @throws std::invalid_argument on a size mismatch
    void set_material_scale(const std::vector<MaterialModel>& models, const std::vector<double>& mu);
    /// material_scale (J), 0 until set.
    double material_scale() const;

    /// @brief Minimizes E over the free dofs after lifting the constrained dofs to `target`.
    /// @param x                in: start (feasible: no inverted element); out: last iterate if
    ///                         CONVERGED, unchanged otherwise
    /// @param inertial_target  xt, #dofs (ignored, and may be empty, when static)
    /// @param weight           w = c h^2 (> 0)
    /// @param force            f (N), #dofs
    /// @param target           #dofs, the constrained dofs' values at the end of the step
    /// @param force_scale      residual = max |g_free| / force_scale (> 0)
    /// @param step_scale       newton_step = max |alpha p| / step_scale (> 0)
    /// @param control          if given: minimize on its hyperplane (file comment, "Load control"); its
    ///                         multiplier is set at every iterate
    /// @throws std::invalid_argument on a size mismatch, a weight or scale that is not positive and
    ///         finite, invalid settings or an invalid control (checked before any GPU work)
    DeviceNewtonResult solve(std::vector<double>& x, const std::vector<double>& inertial_target, double weight,
        const std::vector<double>& force, const std::vector<double>& target, double force_scale, double step_scale,
        const DeviceNewtonSettings& settings, DeviceLoadControl* control = nullptr);

    /// @brief Makes this the solver of a periodic cell (cuda/periodic/device_periodic_map.hpp; the CPU's
    /// PeriodicCell): its unknowns are the cell's q = [w, L G], positions x = X + P q. The gradient and the
    /// Newton matrix enter as P^T g and P^T A P (ReducedOperator), the residual, the fixed mask and the
    /// lifting are q's, and the line search, the inversion bound and the energies work on X + P q, as the
    /// CPU's PeriodicPotential does. Then only solve_periodic() solves. Its contact (on the image surface)
    /// is set after this by set_periodic_contact(); std::logic_error if set_contact() set one before.
    /// @param map the cell's map over the mesh's vertices (must outlive the solver)
    /// @param fixed_q map->num_reduced() flags: q's constrained entries (the pinned class, G's prescribed ones)
    /// @throws std::invalid_argument on a size or dimension mismatch
    void set_periodic(DevicePeriodicMap* map, const std::vector<char>& fixed_q);

    /// @brief Contact across a periodic cell's boundary (after set_periodic()): the contact runs on its
    /// image surface, whose positions y = X_s + P_s q are `surface`'s map (rest positions T X, each image
    /// in its source's class; cuda/README.md, "Periodic cells on the device"). Its gradient enters as
    /// P_s^T g_c, its Hessian as P_s^T C P_s, its CCD along P_s p; the adaptive stiffness balances in q.
    /// Both must outlive their use. No friction with it (std::logic_error).
    /// @throws std::logic_error without set_periodic(); std::invalid_argument if the contact's dofs or the
    ///         surface map's classes or dimension do not fit
    void set_periodic_contact(DeviceContact* contact, DevicePeriodicMap* surface);
    /// @brief balance_at() of a periodic cell with contact at its unknowns q (builds the active set there).
    ContactBalance balance_at_periodic(const std::vector<double>& q, const std::vector<double>& inertial_target,
        double weight, const std::vector<double>& force);

    /// @brief PeriodicCell::solve's Newton solve on the device (set_periodic() first): minimizes E(X + P q)
    /// over q's free entries after lifting its constrained ones to target_q.
    /// @param q        in: start; out: last iterate if CONVERGED, unchanged otherwise (num_reduced())
    /// @param target_q num_reduced(), the constrained entries' values at the end of the step
    /// @param inertial_target, weight, force, force_scale, step_scale, settings as solve()'s (positions)
    /// @throws std::logic_error without set_periodic(); std::invalid_argument as solve()
    DeviceNewtonResult solve_periodic(std::vector<double>& q, const std::vector<double>& target_q,
        const std::vector<double>& inertial_target, double weight, const std::vector<double>& force, double force_scale,
        double step_scale, const DeviceNewtonSettings& settings);

    /// @brief Solves the adjoint system of a converged step on the device: (M + w (H_Psi(x) + H_B(x))) y
    /// = b on the free dofs, H_Psi the true (unprojected) elastic Hessian at x, H_B the contact barrier's
    /// true Hessian of the active set at x (with the contact's current kappa; none without contact), M
    /// the lumped mass of a dynamic solver (none for a static one); y = 0 on the constrained dofs.
    /// PCG from y = 0, preconditioned by block-Jacobi or, after set_adjoint_multigrid(true), by the
    /// smoothed-aggregation multigrid (cuda/linalg/device_amg.hpp) of M + w H_Psi (planned at the first
    /// solve after set_constrained(), with the rigid-body modes at that solve's x; block-Jacobi if it
    /// cannot be built, or if its solve does not converge within 1,000 iterations: then the iterations of
    /// both count).
    /// @param x       #dofs, the converged state
    /// @param weight  w of the step (> 0)
    /// @param b       #dofs right-hand side (its constrained entries are ignored)
    /// @param y       out: #dofs solution (valid when converged)
    /// @return the PCG's result: a breakdown means the true Hessian is not positive definite on the
    ///         free dofs, and the caller must solve otherwise (the CPU's LDL^T)
    /// With friction (set_friction()), w H_D of its current pairs is in the matrix too (the step's lagged data:
    /// the caller sets them first).
    /// @param product if given: #dofs, (M + w (H_Psi + H_B [+ H_D])) y without the constraints (the full
    ///                matrix times y; on the constrained dofs, their couplings to the free ones times y)
    PcgResult solve_true_hessian(const std::vector<double>& x, double weight, const std::vector<double>& b,
        std::vector<double>& y, double relative_tolerance, int max_iterations, std::vector<double>* product = nullptr);

    /// @brief Whether solve_true_hessian() preconditions with the multigrid or block-Jacobi (default).
    /// @param plan_threads threads for the multigrid plan's patterns (0: the hardware's, at most 16)
    /// @param max_coarsest_dofs the plan's coarsest level's largest size (AmgPlanSettings; 0: its default);
    ///        a new value discards the plan
    /// @throws std::invalid_argument if plan_threads or max_coarsest_dofs < 0
    void set_adjoint_multigrid(bool on, int plan_threads = 0, int max_coarsest_dofs = 0);
    bool adjoint_multigrid() const;
    /// The multigrid plan's levels above its coarsest (DeviceAmg::num_levels; 0: a dense solve of the
    /// whole system), -1 while there is no plan (none built yet, or it could not be built).
    int adjoint_multigrid_levels() const;

    /// @brief Adds the contact barrier (nullptr: none). The contact object must outlive its use; its
    /// kappa is read at every evaluation.
    /// @throws std::invalid_argument if its dofs differ from the mesh's
    void set_contact(DeviceContact* contact);
    DeviceContact* contact() const { return m_contact; }

    /// @brief Adds lagged friction (nullptr: none): w D(x) in E, its gradient, and its Hessian (PSD) in
    /// the search and the adjoint matrices, as a third addend of the SumOperator. The caller sets its
    /// pairs and step start (the lagging) before each solve; it must outlive its use. Not part of the
    /// adaptive stiffness' balance (the CPU leaves friction out of it too).
    /// @throws std::invalid_argument if its dofs differ from the mesh's; std::logic_error without contact
    void set_friction(DeviceFriction* friction);
    DeviceFriction* friction() const { return m_friction; }

    /// @brief max |g_free| of E's gradient at a host state (the CPU's Simulator::force_residual times
    /// the force scale), with the contact's active set built there and the current friction pairs.
    /// @param x, inertial_target, weight, force as solve()'s
    /// @return NaN if the gradient is not finite
    double residual_at(const std::vector<double>& x, const std::vector<double>& inertial_target, double weight,
        const std::vector<double>& force);

    /// @brief The end-of-iteration hook (ContactPotential::end_iteration's role; empty: none): called
    /// after each accepted iterate, with the active set already built at it (DeviceContact's
    /// num_active(), min_active_gap_squared()); current_balance() may be called from it. Returns true
    /// if it changed kappa.
    void set_end_iteration(std::function<bool()> hook) { m_end_iteration = std::move(hook); }

    /// @brief The balancing products at the solve's current iterate (only from the hook).
    ContactBalance current_balance();
    /// @brief The balancing products at a host state, before a solve (the step's start: the CPU's
    /// update_kappa_for_step); builds the active set there.
    /// @param x, inertial_target, force as solve()'s; @param weight w
    ContactBalance balance_at(const std::vector<double>& x, const std::vector<double>& inertial_target, double weight,
        const std::vector<double>& force);

    const DeviceElasticMesh& mesh() const { return m_mesh; }

private:
    /// The Newton loop of solve() and solve_periodic(), from the state they uploaded.
    DeviceNewtonResult iterate(const std::vector<double>& inertial_target, double weight,
        const std::vector<double>& force, double force_scale, double step_scale, const DeviceNewtonSettings& settings);

    struct Impl;
    const DeviceElasticMesh& m_mesh;
    Impl* m_impl;
    DeviceContact* m_contact = nullptr;
    DeviceFriction* m_friction = nullptr;
    std::function<bool()> m_end_iteration;
};

} // namespace diffipc::gpu
