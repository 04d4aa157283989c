#pragma once
/// @file scene.hpp
/// A validated scene: what a JSON scene file describes (see docs/scene_format.md).
/// load_scene() checks every field and throws InputError naming the first bad one.

#include "forward/common/types.hpp"
#include "forward/io/vtu_encoding.hpp"
#include "forward/materials/material.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/periodic/pairing.hpp"
#include "forward/scene/expression.hpp"

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <vector>

namespace diffipc {

enum class IntegratorType { STATIC, IMPLICIT_EULER, BDF2, NEWMARK };
enum class MassType { LUMPED, CONSISTENT };
/// Where the Newton solves run: "device": "cpu" (default) or "gpu" (forward/simulation/device_solver.hpp).
enum class DeviceType { CPU, GPU };
enum class LinearSolverType { CHOLMOD, LDLT };

std::string to_string(IntegratorType type);

struct MaterialSpec {
    MaterialModel model = MaterialModel::NEO_HOOKEAN;
    double youngs_modulus = 1e6; ///< E (Pa)
    double poisson_ratio = 0.3; ///< nu, in (-1, 0.5)
    double density = 1000; ///< rho (kg/m^3)
    /// 2D only: "plane": "stress" (a thin sheet) instead of plane strain (the default).
    bool plane_stress = false;
};

struct BoxRegion {
    VectorXd lower, upper; ///< inclusive corners, world coordinates (after translation)
    bool contains(const Eigen::Ref<const VectorXd>& p, double tolerance) const;
};

struct BodySpec {
    std::string name;
    bool self_contact = true; ///< may this body touch itself (when contact is enabled)?
    double friction_coefficient = -1; ///< mu of this body; < 0: the global one
    std::string mesh_source; ///< "box" or the resolved file path
    MaterialSpec material;
    VectorXd initial_velocity; ///< dim (m/s)
    VectorXd translation; ///< dim (m)
};

struct DirichletSpec {
    int body = 0;
    BoxRegion region;
    /// per component: displacement expression of (t, x, y, z), or none for a free component
    std::vector<std::optional<Expression>> displacement;
    std::string field; ///< JSON path, for messages
};

struct NeumannSpec {
    int body = 0;
    BoxRegion region;
    std::vector<Expression> traction; ///< per component, Pa, expression of (t, x, y, z)
    std::string field;
};

/// Automatic load stepping ("time": {"adaptive": ...}, docs/scene_format.md): a static step whose
/// solve fails is retried in sub-steps of its load increment, cut on failure and grown after
/// easy sub-steps; the step's state is the equilibrium at its own time, as without sub-steps.
struct AdaptiveSpec {
    bool enabled = false;
    double min_increment = 0; ///< smallest sub-step (s of load time); 0: dt / 1024
    double cut = 0.5; ///< factor of the increment after a failed sub-step, in (0, 1)
    double growth = 1.5; ///< factor after an easy sub-step, >= 1
    int iteration_target = 10; ///< a sub-step that converged in at most this many Newton iterations is easy
    /// Past a limit point of the load (sub-steps cut below min_increment), follow the equilibria by
    /// displacement control along the load increment (load_stepping.cpp).
    bool displacement_control = true;
    /// Then (or for loads of prescribed displacements only), relax to the equilibrium at t_k by
    /// proximal (pseudo-transient) solves (load_stepping.cpp).
    bool relaxation = true;
};

struct TimeSpec {
    IntegratorType integrator = IntegratorType::IMPLICIT_EULER;
    double dt = 0.01;
    int steps = 1;
    AdaptiveSpec adaptive;
};

struct SolverSpec {
    double residual_tolerance = 1e-8; ///< on the force residual relative to the force scale (docs/math.md)
    double step_tolerance = 0; ///< on the Newton step (m/s dynamic, relative static); 0 disables it
    int max_iterations = 100;
    LinearSolverType linear_solver = LinearSolverType::CHOLMOD;
    int line_search_max_halvings = 40;
    double armijo = 1e-4;
    bool adaptive_projection = true; ///< "hessian_projection": "adaptive" (default) or "always"
    /// "gpu_adjoint_preconditioner": "multigrid" (true) or "block_jacobi" (false, the default): what
    /// preconditions a GPU run's adjoint solves (cuda/linalg/device_amg.hpp)
    bool gpu_adjoint_multigrid = false;
    bool step_extension = true; ///< "step_extension": lengthen almost linearly descending full steps (NewtonSettings)
    /// "threads": thread count for this run (forward/common/threads.hpp); 0 (absent): the
    /// cores the process may use. The CLI's --threads and DIFFIPC_THREADS take precedence.
    int threads = 0;
};

/// Contact (docs/scene_format.md "contact"). Distances in meters.
struct ContactSpec {
    bool enabled = false;
    double dhat = 0; ///< activation distance (m); 0 until parsed: the default is 1e-3 times the bbox diagonal
    bool adaptive_kappa = true; ///< IPC's adaptive barrier stiffness
    double kappa = 0; ///< fixed barrier stiffness, when not adaptive
    bool self_contact = true; ///< default for bodies without their own "self_contact"
    double min_distance = 0; ///< minimum separation dmin (m)
    int ccd_max_iterations = 1000000; ///< per query budget of the additive CCD
    double ccd_rescaling = 0.9; ///< conservative rescaling s of the additive CCD
    /// `"model": "penalty"`: the baseline most finite element codes use instead of IPC's barrier,
    /// a quadratic penalty on the penetration into a layer of thickness dhat, without CCD
    /// (docs/math.md "Penalty contact"). kappa then holds penalty_stiffness (N/m).
    bool penalty = false;
};

/// Friction (docs/scene_format.md "friction"); needs contact.
struct FrictionSpec {
    double coefficient = 0; ///< global mu; bodies and obstacles may override it
    double eps_v = 1e-3; ///< m/s, slip speed below which friction is smoothed
    int iterations = 1; ///< lagging iterations (Newton solves) per step
    bool strict = false; ///< FRICTION_EXHAUSTED if lagging has not converged after `iterations`
};

enum class ObstacleType { PLANE, MESH };

/// A kinematic obstacle: its vertices are appended to the mesh after the bodies'
/// and move as prescribed (Dirichlet) dofs; it has no elements and no mass.
struct ObstacleSpec {
    std::string name;
    ObstacleType type = ObstacleType::PLANE;
    VectorXd normal; ///< plane: unit normal (dim), pointing to the side bodies may occupy
    std::string file; ///< mesh: resolved path
    /// per component: displacement expression of (t, x, y, z) (rest coordinates); zero if not given
    std::vector<Expression> motion;
    Index first_vertex = 0; ///< index of its first vertex in Scene::mesh
    Index num_vertices = 0; ///< 1 for a plane (its point)
    double friction_coefficient = -1; ///< mu of this obstacle; < 0: the global one
    std::string field;
};

struct OutputSpec {
    std::string directory = "output";
    int vtu_every = 0; ///< write a VTU file every n steps (0: none)
    /// Seconds (wall time) between flushes of trajectory.h5, summary.json and the .pvd during a run.
    double flush_interval = 1.0;
    bool hdf5 = true;
    /// "vtu_encoding": "binary" (appended raw, the default) or "ascii".
    VtuEncoding vtu_encoding = VtuEncoding::BINARY;
};

/// A periodic cell (docs/scene_format.md, "periodic"; forward/periodic/).
struct PeriodicSpec {
    bool enabled = false;
    PeriodicBox box;
    double tolerance = 0; ///< m: a vertex this close to a face is on it
    /// The macroscopic displacement gradient G, d x d row-major: an expression of t where the
    /// component is prescribed, none where it is free (solved for: zero average stress).
    std::vector<std::optional<Expression>> gradient;
    PeriodicPairing pairing; ///< of the bodies' vertices
};

struct Scene {
    int dim = 3;
    std::vector<BodySpec> bodies;
    /// All bodies, then all obstacles (vertex_body / facet_body = #bodies + obstacle index);
    /// rest positions include translations.
    Mesh mesh;
    Index body_vertices = 0; ///< vertices [0, body_vertices) belong to bodies
    VectorXd gravity;
    std::vector<DirichletSpec> dirichlet;
    std::vector<NeumannSpec> neumann;
    TimeSpec time;
    MassType mass = MassType::LUMPED;
    DeviceType device = DeviceType::CPU;
    SolverSpec solver;
    ContactSpec contact;
    FrictionSpec friction;
    std::vector<ObstacleSpec> obstacles;
    OutputSpec output;
    PeriodicSpec periodic;
    std::string source; ///< file name, or "<dict>"
};

/// @brief Sets where the scene's Newton solves run: "cpu" or "gpu" (the scene key "device",
/// or the CLI's --device). The GPU path has elasticity, inertia, gravity, tractions and
/// Dirichlet conditions; a scene with anything else (contact, obstacles, periodic cells, the
/// consistent mass, adaptive time stepping) is refused.
/// @throws InputError naming `field` for another name or a scene the GPU path cannot run
void select_device(Scene& scene, const std::string& name, const std::string& field);

/// Memory this process may use (bytes): the machine's physical memory, or less under a limit
/// on its address space (ulimit -v). The scene's memory estimates compare with it.
double usable_memory_bytes();

/// @brief Reads and validates a scene file; relative mesh paths are resolved
/// against the scene file's directory.
/// @throws InputError naming the file or field.
Scene load_scene(const std::string& path);
/// @brief load_scene() of a file already read and parsed (`document`, from `path`): a pipe
/// such as /dev/stdin cannot be read twice.
Scene load_scene(const nlohmann::json& document, const std::string& path);

/// @brief Validates a scene given as JSON text or a parsed document.
/// @param base_directory where relative mesh paths are resolved
Scene parse_scene(const nlohmann::json& document, const std::string& base_directory, const std::string& source);
Scene parse_scene_text(const std::string& text, const std::string& base_directory, const std::string& source);

} // namespace diffipc
