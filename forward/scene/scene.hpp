#pragma once
/// @file scene.hpp
/// A validated scene: what a JSON scene file describes (see docs/scene_format.md).
/// load_scene() checks every field and throws InputError naming the first bad one.

#include "forward/common/types.hpp"
#include "forward/materials/material.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/scene/expression.hpp"

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <vector>

namespace diffipc {

enum class IntegratorType { STATIC, IMPLICIT_EULER, BDF2, NEWMARK };
enum class MassType { LUMPED, CONSISTENT };
enum class LinearSolverType { CHOLMOD, LDLT };

std::string to_string(IntegratorType type);

struct MaterialSpec {
    MaterialModel model = MaterialModel::NEO_HOOKEAN;
    double youngs_modulus = 1e6; ///< E (Pa)
    double poisson_ratio = 0.3; ///< nu, in (-1, 0.5)
    double density = 1000; ///< rho (kg/m^3)
};

struct BoxRegion {
    VectorXd lower, upper; ///< inclusive corners, world coordinates (after translation)
    bool contains(const Eigen::Ref<const VectorXd>& p, double tolerance) const;
};

struct BodySpec {
    std::string name;
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

struct TimeSpec {
    IntegratorType integrator = IntegratorType::IMPLICIT_EULER;
    double dt = 0.01;
    int steps = 1;
};

struct SolverSpec {
    double residual_tolerance = 1e-8; ///< on the force residual relative to the force scale (docs/math.md)
    double step_tolerance = 0; ///< on the Newton step (m/s dynamic, relative static); 0 disables it
    int max_iterations = 100;
    LinearSolverType linear_solver = LinearSolverType::CHOLMOD;
    int line_search_max_halvings = 40;
    double armijo = 1e-4;
};

struct OutputSpec {
    std::string directory = "output";
    int vtu_every = 0; ///< write a VTU file every n steps (0: none)
    bool hdf5 = true;
};

struct Scene {
    int dim = 3;
    std::vector<BodySpec> bodies;
    Mesh mesh; ///< all bodies, with per-body indices; rest positions include translations
    VectorXd gravity;
    std::vector<DirichletSpec> dirichlet;
    std::vector<NeumannSpec> neumann;
    TimeSpec time;
    MassType mass = MassType::LUMPED;
    SolverSpec solver;
    OutputSpec output;
    std::string source; ///< file name, or "<dict>"
};

/// @brief Reads and validates a scene file; relative mesh paths are resolved
/// against the scene file's directory.
/// @throws InputError naming the file or field.
Scene load_scene(const std::string& path);

/// @brief Validates a scene given as JSON text or a parsed document.
/// @param base_directory where relative mesh paths are resolved
Scene parse_scene(const nlohmann::json& document, const std::string& base_directory, const std::string& source);
Scene parse_scene_text(const std::string& text, const std::string& base_directory, const std::string& source);

} // namespace diffipc
