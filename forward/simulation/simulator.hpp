#pragma once
/// @file simulator.hpp
/// Runs a scene: builds the FE space and the potentials it needs, then takes
/// transactional time steps (only a converged Newton solve commits).

#include "forward/contact/contact_potential.hpp"
#include "forward/fem/fe_space.hpp"
#include "forward/periodic/periodic_cell.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/device_solver.hpp"
#include "forward/simulation/parameters.hpp"
#include "forward/simulation/step_record.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/problem.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "forward/time/integrator.hpp"

#include <functional>
#include <memory>

namespace diffipc {

class NewtonSolver;
struct NewtonResult;

class Simulator {
public:
    explicit Simulator(Scene scene);
    /// @brief A simulation of `scene` with some of its values replaced
    /// (forward/simulation/parameters.hpp).
    /// @throws InputError naming the parameter for wrong sizes, non-finite or
    /// out-of-range values, or rest positions that degenerate or invert an element.
    Simulator(Scene scene, const SimulationParameters& parameters);
    ~Simulator();
    Simulator(const Simulator&) = delete;
    Simulator& operator=(const Simulator&) = delete;

    const Scene& scene() const { return m_scene; }
    const Mesh& mesh() const { return m_scene.mesh; }
    const FESpace& space() const { return *m_space; }
    const Problem& problem() const { return m_problem; }
    const ElasticPotential& elastic() const { return *m_elastic; }
    const InertiaPotential& inertia() const { return *m_inertia; }
    /// The GPU path's solver (scene "device": "gpu"), or nullptr on the CPU path.
    DeviceSolver* device_solver() const { return m_device.get(); }
    /// The barrier potential, or nullptr when the scene has no contact.
    const ContactPotential* contact() const { return m_contact.get(); }
    /// The friction potential, or nullptr when no coefficient is positive.
    const FrictionPotential* friction() const { return m_friction.get(); }
    double bbox_diagonal() const { return m_bbox_diagonal; }

    /// @brief Attempts the next time step. On CONVERGED the step is committed
    /// and recorded; otherwise the state is unchanged and the status returned
    /// (the attempt's diagnostics are in last_attempt()).
    StepStatus step();
    /// @brief Runs the remaining steps, stopping at the first failure.
    /// @param progress called after every committed step
    const Trajectory& run(const std::function<void(const StepRecord&)>& progress = {});

    /// @brief Why the current committed state cannot start a step, or "" when it can: for
    /// contact, intersecting or nested surfaces, or a pair at or below the minimum distance;
    /// an inverted or degenerate element. `validate` runs it on the initial state.
    std::string state_problem() const;

    const Trajectory& trajectory() const { return m_trajectory; }
    const StepRecord& last_attempt() const { return m_last_attempt; }
    int steps_done() const { return m_trajectory.committed(); }
    double time() const;

    /// Current committed positions, velocities (flattened #V*dim).
    const VectorXd& positions() const { return m_integrator->positions(); }
    const VectorXd& velocities() const { return m_integrator->velocities(); }

    /// Force scale (N) of the residual: mean E times mean element volume^((d-1)/d).
    double force_scale() const { return m_force_scale; }
    /// Nodal external forces (gravity + tractions) at time t, flattened.
    VectorXd external_forces(double t) const;
    /// Dirichlet flags per dof.
    const std::vector<char>& constrained() const { return m_constrained; }
    /// Per dof: the scene.dirichlet entry that prescribes it (the last one whose region holds the
    /// vertex, as in the scene file), dirichlet.size() + o for a vertex of obstacle o, -1 if free.
    const std::vector<int>& prescribing_condition() const { return m_prescribing_condition; }
    /// #E: is element e's material in plane stress (2D "plane": "stress"; else plane strain or 3D)?
    const std::vector<char>& plane_stress() const { return m_plane_stress; }

    /// @name Contact and friction forces at the committed state (for output)
    /// Nodal forces in newtons, flattened #V*dim: the barrier and friction terms enter the
    /// incremental potential with the same weight as the elastic energy, so their negative
    /// gradients are forces (docs/math.md). Obstacle vertices receive the reactions.
    /// @{
    /// -dB/dx at positions() with the current barrier stiffness; zero on vertices in no
    /// contact, all zero without contact.
    VectorXd contact_forces() const;
    /// -dD/dx at positions() with the lagged normal forces, tangents and start positions that
    /// the last committed step's final Newton solve used (the forces that step balanced).
    /// All zero without friction, before the first step, after a failed step, and after
    /// resume(), restore_state() or step_problem() until the last step is taken again.
    VectorXd friction_forces() const;
    /// @}

    /// @brief Replaces the initial state (before the first step): positions and
    /// velocities of all #V*dim dofs; prescribed dofs (Dirichlet, obstacles) keep
    /// their own values. Newmark's a0 is not recomputed (it stays the scene's).
    /// @throws InputError("initial_state", ...) for wrong sizes, non-finite values or after a step.
    void set_initial_state(const VectorXd& positions, const VectorXd& velocities);

    /// @brief Per-element Young's modulus and Poisson's ratio (#E each);
    /// only before the first step.
    void set_element_materials(const VectorXd& youngs_modulus, const VectorXd& poisson_ratio);

    /// @name For the adjoint: the scene's canonical parameters and the problem of a committed step.
    /// @{
    /// Prescribed dofs (Dirichlet, then obstacle vertices), the order of SimulationParameters::prescribed.
    std::vector<Index> prescribed_dofs() const;
    /// The canonical parameter values of this simulation, every field filled
    /// (rest positions, mu, lambda, E, nu, density, friction per group, u0, v0,
    /// prescribed displacements for the scene's T steps, kappa).
    SimulationParameters parameters() const;
    /// @brief Sets the problem (inertial target, weights, external forces, barrier
    /// stiffness, lagged friction data) to that of committed step k (1-based) and returns it.
    const Problem& step_problem(int k);
    /// The integrator's linear maps of step k (1-based).
    StepScheme step_scheme(int k) const { return m_integrator->scheme(k); }
    /// @brief Sets the problem to that of sub-step j (1-based, up to substep_times.size()) of
    /// committed dynamic step k, solved in sub-steps (StepRecord::substep_times): inertial target
    /// from the state sub-step j started at, weights of its increment, loads at its end time,
    /// the step's barrier stiffness. Without friction (the adjoint refuses sub-stepped steps with it).
    const Problem& substep_problem(int k, int j);
    /// The integrator's linear maps of sub-step j of step k (as substep_problem()).
    StepScheme substep_scheme(int k, int j) const;
    /// @brief Adds d(direction^T f_ext(t))/dX (#V*dim) and d/drho (#E) to the
    /// non-null outputs: gravity through the lumped masses, tractions through facet areas.
    void external_force_derivatives(
        double t, const VectorXd& direction, VectorXd* d_rest_positions, VectorXd* d_density) const;
    /// The periodic cell's solver and map (scene "periodic"), or null.
    const PeriodicCell* periodic() const { return m_periodic.get(); }
    /// A periodic cell's homogenized first Piola stress at x (d^2 values, row-major):
    /// (1/|Y|) d(Psi + kappa B)/dG, the elastic energy's and the barrier's across the boundary.
    VectorXd macro_stress(const VectorXd& x) const;
    /// False for a static (quasi-static) scene.
    bool dynamic() const { return m_integrator->dynamic(); }
    /// Number of contact groups (bodies, then obstacles).
    int num_groups() const { return int(m_scene.bodies.size() + m_scene.obstacles.size()); }
    /// @}

    /// @name Checkpointing (adjoint/checkpointing.hpp): records thinned after the
    /// forward run are refilled by re-running their steps from a held one.
    /// The forward is deterministic, so a recomputed step repeats the first one.
    /// @{
    /// Committed states a step reads (the integrator's history): 2 for BDF2, 1 otherwise.
    /// restore_state(k) and step_problem(k + 1) need the records k - history() + 1 .. k.
    int history() const { return m_integrator->history(); }
    /// The committed step the integrator stands at: steps_done() unless restore_state() moved it back.
    int current_step() const { return m_integrator->steps(); }
    /// @brief Frees the state of committed step k's record (StepRecord::release_state()).
    void release_state(int k);
    /// @brief Drops the records of every committed step (a streamed run that wrote them):
    /// memory then does not grow with the number of steps. The trajectory keeps its
    /// totals (Trajectory::totals) and count; the adjoint, step_problem() and
    /// restore_state() need the records and refuse a simulator that forgot them.
    void forget_records();
    /// @brief Continues a run whose committed steps are in `stored` (trajectory.h5 read back:
    /// `simulate --restart`): puts the integrator at stored's last step, with the history
    /// BDF2 and Newmark need, and the barrier stiffness that step ended with. The records
    /// are not kept (as after forget_records()); the totals and counts are stored's.
    /// @throws InputError("restart", ...) before the first step only, and if stored does not
    ///         start from this scene's initial state or its states have the wrong size
    void resume(const Trajectory& stored, bool stored_contact);
    /// @brief Puts the integrator (and the barrier stiffness) back at committed step k
    /// (0: the initial state); the next step() recomputes step k + 1.
    /// @throws std::logic_error if a record that this needs does not hold its state.
    void restore_state(int k);
    /// @brief Re-runs steps current_step() + 1 .. last, refilling their records' states;
    /// the records' diagnostics, last_attempt() and the trajectory's totals stay those of the first run.
    /// @throws std::runtime_error if a recomputed step does not converge (it did the first time).
    void recompute_steps(int last);
    /// @}

private:
    /// @name The constructor's steps, in the order it takes them
    /// @{
    /// Rest positions given as a parameter replace the scene's (each element checked against its
    /// `reference`, the scene's own rest shape).
    void apply_rest_positions(const Positions& reference);
    /// Each element's law and parameters (checked), the force and length scales, the elastic, inertia
    /// and external-force potentials, the integrator and the problem's first terms.
    void setup_potentials();
    /// Dirichlet dofs: those in each condition's region (tested at the `reference` rest positions
    /// within `tol`); later conditions override earlier ones on the same dof.
    void setup_dirichlet(const Positions& reference, double tol);
    /// Obstacle vertices are prescribed dofs that follow the obstacle's motion.
    void setup_obstacle_motion(const Positions& reference);
    /// Neumann conditions: the boundary facets whose vertices all lie in the region.
    void setup_neumann(const Positions& reference, double tol);
    void setup_gravity();
    /// The integrator's and the trajectory's initial state, after checking the per-step parameters.
    void setup_initial_state();
    /// Rest positions (plus an initial displacement given as a parameter), Dirichlet values at t = 0.
    VectorXd initial_positions() const;
    /// The per-step parameters (prescribed values, sub-steps, macro gradients) against the scene.
    void check_step_parameters() const;
    /// Body velocities (or the parameter's), the prescribed rate on Dirichlet dofs.
    VectorXd initial_velocities(const VectorXd& x0) const;
    /// Newmark's a0 = M^-1 (f_ext(0) - grad Psi(x0)) on free dofs, 0 on Dirichlet dofs; else 0.
    VectorXd initial_accelerations(const VectorXd& x0) const;
    /// The GPU path's solver (scene "device": "gpu").
    void setup_device();
    /// @}

    /// @name step()'s steps, in the order it takes them
    /// @{
    struct StepContext; ///< what one step() hands from one of its steps to the next (simulator.cpp)
    /// The step's index, time, weights and inertial target.
    StepContext begin_step();
    /// External forces and prescribed targets at the step's end; false (NON_FINITE, refused) where a
    /// boundary expression is not finite there.
    bool set_step_loads(StepContext& s);
    /// The scene's Newton settings, with the longest step a contact scene's solve may take.
    NewtonSettings step_settings(const VectorXd& inertial_target) const;
    /// The first step checks the initial state as validate does; false (refused) where it is invalid.
    bool check_run_start(StepContext& s);
    /// A step that cannot start: its status recorded (and, unless recomputed, the run's failure).
    void refuse_step(StepContext& s, StepStatus status, const std::string& message);
    /// Contact at the step's start: kappa (adaptive rule, or the device's step), friction lagged.
    void begin_contact_step(const StepContext& s);
    /// The sub-steps step `index` takes as given (its own when recomputed), or null.
    const std::vector<double>* substep_plan(int index, bool recompute) const;
    /// The step's solve: given sub-steps, a periodic cell's, the device's or the CPU's Newton.
    NewtonResult solve_step(StepContext& s, const NewtonSolver& newton);
    /// Friction lagging after a converged solve r: re-lagged at the solution and solved again, up
    /// to friction.iterations solves (docs/math.md "Friction").
    void iterate_friction_lagging(StepContext& s, const NewtonSolver& newton, NewtonResult& r);
    /// Automatic step control after the full solve `first` failed: dynamic or load sub-steps.
    NewtonResult solve_step_in_substeps(StepContext& s, const NewtonSolver& newton, const NewtonResult& first);
    /// The solve's diagnostics and contact timings in the record and the run's totals.
    void record_solve(StepContext& s, const NewtonResult& result);
    /// A converged step's state: the record's positions, velocities, contacts; the integrator commits.
    void commit_step(StepContext& s);
    /// A failed step's message in the trajectory (with a hint where the fixed kappa is too soft).
    void record_failure(const StepContext& s, const NewtonResult& result);
    /// A recomputed step refills the state of its kept record.
    void refill_record(StepContext& s, StepStatus status);
    /// A new step's record: the last attempt, and the trajectory's if it converged.
    void store_record(StepContext& s, StepStatus status);
    /// @}

    /// Committed step k's record; std::logic_error naming `caller` if it was forgotten.
    StepRecord& record_of(int k, const char* caller);

    void dirichlet_targets(double t, VectorXd& x) const;
    /// Prescribed positions at step k (1-based): the override's g_k if given, else the expressions at t_k.
    void prescribed_targets(int k, VectorXd& x) const;
    /// @brief Prescribed positions at a time t in step k's interval ((k-1) dt, k dt]: the
    /// expressions at t, or, with an override, its g_k interpolated linearly from the committed g_{k-1}.
    void prescribed_targets_at(int k, double t, VectorXd& x) const;
    /// @brief Automatic load stepping (load_stepping.cpp): step k's static solve again in
    /// sub-steps of its load increment after its full solve failed. On success x is the
    /// equilibrium at t_k and the result CONVERGED; otherwise the last sub-step's status, with
    /// `why` saying how far it got. Fills the record's substeps, cuts and min_increment.
    /// In a GPU run the sub-steps are solved on the device (solve_current).
    NewtonResult solve_in_substeps(int k, const NewtonSolver& newton, double step_scale, double kappa_before,
        VectorXd& x, StepRecord& record, std::string& why);
    /// @brief Displacement control past a limit point (load_stepping.cpp): from the equilibrium x at
    /// time t of step k, follows the equilibria along the load increment f(t_k) - f(t) by
    /// prescribing the displacement along it (the load is the constraint's multiplier) until the
    /// bodies carry that increment, then solves at t_k. On success x is the equilibrium at t_k.
    /// `failed` is the sub-step failure that led here: returned (with `why`) when the step changes no load.
    /// In a GPU run its solves run on the device where limit_point_on_device() says so.
    NewtonResult pass_limit_point(int k, const NewtonSolver& newton, double step_scale, double t, VectorXd& x,
        const NewtonResult& failed, StepRecord& record, NewtonResult& total, std::string& why);
    static constexpr int MAX_CONTROL_STEPS = 2000;
    /// @brief Proximal relaxation (load_stepping.cpp): from x, a sequence of static solves at t_k
    /// of step k, each with a mass-weighted proximal term c/2 |y - x_j|_M^2 centred at the last
    /// one (an inertia-like regularization that keeps each solve well posed), c shrinking after
    /// easy solves, then a plain solve at t_k: on success x is the equilibrium at t_k.
    NewtonResult relax_to_equilibrium(int k, const NewtonSolver& newton, double step_scale, VectorXd& x,
        StepRecord& record, NewtonResult& total, std::string& why);
    /// Whether a GPU run passes limit points on the device (displacement control: DeviceSolver::solve
    /// with a LoadControl; relaxation: DeviceSolver::solve_proximal): with lumped masses outside a
    /// periodic cell; otherwise (and in a CPU run) on the CPU's Newton.
    bool limit_point_on_device() const;
    static constexpr int MAX_RELAXATION_STEPS = 2000;
    /// @brief Automatic step control in dynamic scenes (dynamic_substepping.cpp): dynamic step k
    /// taken in sub-steps of its time increment, each a step of the integrator with its own
    /// increment from the last sub-step's state; the sub-steps given in `plan` (their end times),
    /// or chosen by time.adaptive's policy when plan is null. On success x is the state at t_k,
    /// and the record holds its velocities, accelerations, sub-step times and intermediate states.
    /// In a GPU run the sub-steps are solved on the device (solve_current).
    NewtonResult solve_dynamic_substeps(int k, const NewtonSolver& newton, const std::vector<double>* plan,
        double kappa_before, VectorXd& x, StepRecord& record, std::string& why);
    /// The message of sub-stepping (`what`) in step k that got to time t in `substeps` sub-steps and
    /// failed to ts with `status`, its increment then below time.adaptive.min_increment.
    std::string substeps_exhausted(const char* what, int substeps, double t, int k, double ts, StepStatus status) const;
    /// Weight w of the elastic, external, contact and friction potentials.
    void set_potential_weights(double w);
    /// @brief The problem of a sub-step of integrator `sub` (initialized at the sub-step's start)
    /// ending at time t: weights, inertial target, external forces. Returns the weight.
    double setup_substep(const TimeIntegrator& sub, double t);
    /// Empty if SimulationParameters::substeps fits this scene; otherwise why not.
    std::string check_substep_plan(const std::vector<std::vector<double>>& plan) const;
    /// @brief With friction, each solve of load stepping slides from its own start: friction's
    /// start positions set to `from` with increment h, its data lagged there. A sub-stepped step's
    /// state is then its last solve's (friction from that solve's start), which the adjoint refuses.
    void restart_friction(const VectorXd& from, double h);
    /// @brief With friction, a converged load-stepping solve r at y is re-lagged at y and solved
    /// again, up to friction.iterations solves in all, as step() does with a step's solve (the
    /// sliding then feels the normal forces of its end, not of its start). A failed re-solve is
    /// returned as the solve's failure (y keeps the last solution, the friction its data).
    /// w: the weight of the solve's non-inertial potentials.
    /// on_device: the re-solves on the GPU path's device (solve_current), as the solve r was.
    NewtonResult relag_friction(const NewtonSolver& newton, double w, double step_scale, const VectorXd& target,
        VectorXd& y, NewtonResult r, NewtonResult& total, bool on_device = false);
    /// @brief A solve of the current step problem from y toward `target` (weight w of the
    /// non-inertial potentials; in a dynamic scene the inertia's current target): on the device in a
    /// GPU run when on_device, else by `newton` (on the device with its settings). Load stepping's and
    /// dynamic sub-stepping's sub-steps run on the device, and so do load stepping's displacement
    /// control and proximal relaxation past a limit point (limit_point_on_device).
    /// control: displacement control (NewtonSolver::solve's).
    NewtonResult solve_current(const NewtonSolver& newton, VectorXd& y, const VectorXd& target, double w,
        double step_scale, bool on_device, LoadControl* control = nullptr);
    /// The inertia potential's current target in a dynamic scene (the step's or the sub-step's, as
    /// set last), empty in a static one: what a device solve of the current problem is given.
    const VectorXd& current_inertial_target() const;
    /// @brief The barrier stiffness the next solve starts from: the device's in a GPU run (which
    /// carries it between the step's solves), else (and during a CPU fallback) the CPU contact's; 0
    /// without contact.
    double solve_kappa() const;
    /// @brief Sets the barrier stiffness on the CPU contact and, in a GPU run, on the device: what a
    /// failed solve of a sub-stepped step restores (the adaptive rule's state is left as it is).
    void restore_kappa(double kappa);
    void setup_contact();
    void setup_friction();
    /// max |free-dof gradient| / (w f_s) at x, w the weight of the non-inertial potentials
    /// (default: the integrator's).
    /// Lags friction at x (FrictionPotential::lag); on the GPU path from the device's active set and
    /// kappa, and uploads the lagged data to the device (during a CPU fallback: on the CPU).
    void lag_friction_at(const VectorXd& x);
    /// @brief In a GPU run where limit_point_on_device() is false, load stepping's displacement control
    /// and relaxation run on the CPU's Newton: the CPU contact takes the device's kappa (with the adaptive kappa also
    /// the rule, and whether it was applied in this step) for them, and friction is lagged on the CPU meanwhile;
    /// hand_contact_to_device() gives the kappa they ended with back. No-ops without a device.
    void hand_contact_to_cpu();
    void hand_contact_to_device();
    double force_residual(const VectorXd& x, double w) const;
    double force_residual(const VectorXd& x) const { return force_residual(x, m_integrator->potential_weight()); }
    /// Adaptive kappa at the start of a step (docs/math.md "Barrier stiffness").
    void update_kappa_for_step(const VectorXd& x);
    /// IPC's balancing stiffness -(grad B . grad E) / (w |grad B|^2), clamped.
    double balancing_kappa(const VectorXd& x) const;
    /// Empty if the state is valid for contact; otherwise why not.
    std::string check_contact_state(const VectorXd& x) const;

    Scene m_scene;
    std::unique_ptr<FESpace> m_space;
    std::unique_ptr<ElasticPotential> m_elastic;
    std::unique_ptr<InertiaPotential> m_inertia;
    std::unique_ptr<ExternalForcePotential> m_external;
    std::unique_ptr<ContactPotential> m_contact;
    std::unique_ptr<FrictionPotential> m_friction;
    double m_kappa_min = 0;
    double m_kappa_initial = 0; ///< the barrier stiffness before the first step (restore_state(0))
    Problem m_problem;
    SparseAssembler m_assembler;
    std::unique_ptr<LinearSolver> m_linear;
    std::unique_ptr<TimeIntegrator> m_integrator;
    /// The GPU path's solver (scene "device": "gpu"), else null.
    std::unique_ptr<DeviceSolver> m_device;
    bool m_fallback_on_cpu = false; ///< between hand_contact_to_cpu() and hand_contact_to_device()

    struct DirichletDof {
        Index dof;
        const Expression* expression;
        Eigen::Vector3d rest; ///< X of the vertex (the parameter's, if overridden)
        Eigen::Vector3d reference; ///< the scene's own rest position: the expression's argument
    };
    SimulationParameters m_overrides;
    std::vector<DirichletDof> m_dirichlet;
    std::vector<char> m_constrained;
    std::vector<int> m_prescribing_condition;
    std::vector<char> m_plane_stress; ///< per element
    struct LoadedFacet {
        Index facet;
        int spec;
        double area;
        Eigen::Vector3d centroid; ///< at the scene's own rest positions (the traction's argument)
    };
    std::vector<LoadedFacet> m_loaded_facets;
    VectorXd m_gravity_forces;
    double m_force_scale = 1;
    double m_bbox_diagonal = 1;

    Trajectory m_trajectory;
    StepRecord m_last_attempt;
    std::unique_ptr<PeriodicCell> m_periodic;
    VectorXd m_macro; ///< the periodic cell's G at the integrator's committed step
    /// With contact across a periodic cell's boundary: each image surface vertex's source class (the
    /// GPU path's surface map, DeviceSolver::set_periodic).
    std::vector<int> m_image_classes;
    /// m_friction holds the start positions of committed step steps_done() (friction_forces())
    bool m_friction_at_last_step = false;
};

} // namespace diffipc
