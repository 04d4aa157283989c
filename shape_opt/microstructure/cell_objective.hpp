#pragma once
/// @file cell_objective.hpp
/// What the cell optimization (cell_optimization.hpp) minimizes: a function J(p) of a cell
/// family's design p, evaluated on a mesh of the cell, with its gradient from the mesh's
/// velocity dX/dp (cell_shape_map.hpp). Two kinds: the quasi-static plateau of the cell's
/// compression (cell_design.hpp) and the peak stress on a block dropped on a pad tiled from the
/// cell (drop_design.hpp).

#include "shape_opt/microstructure/cell_family.hpp"
#include "shape_opt/microstructure/cell_mesher.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace diffipc {

/// J at one design.
struct DesignValue {
    bool ok = false; ///< the simulation converged (else `message` says why; J and the gradient are not set)
    std::string message;
    double J = 0;
    VectorXd gradient; ///< dJ/dp (when asked)
};

class CellObjective {
public:
    virtual ~CellObjective() = default;
    virtual const CellFamily& family() const = 0;
    /// How the cell is meshed (its height and target edge length).
    virtual const CellMeshSettings& mesh_settings() const = 0;
    /// @brief J at design p on `cell`, a mesh of p's cell (a new one, or one moved to p); with
    /// `velocity` (d cell.rest_positions / dp, #V*2 by the family's size) its gradient.
    virtual DesignValue value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const = 0;
};

/// A new mesh of a design and, when asked, its velocity dX/dp (CellShapeMap).
struct DesignMesh {
    Mesh mesh;
    MatrixXd velocity; ///< empty unless asked
    const MatrixXd* velocity_or_null() const { return velocity.size() ? &velocity : nullptr; }
};

/// @brief Meshes design p anew (mesh_design), with its velocity if `velocity`.
/// @throws InputError for a design outside the bounds or one that cannot be meshed
DesignMesh mesh_with_velocity(const CellObjective& objective, const VectorXd& p, bool velocity);

/// @brief J and its gradient at design p on a new mesh of it.
/// @throws InputError as mesh_with_velocity
DesignValue evaluate_new_mesh(const CellObjective& objective, const VectorXd& p);

/// @brief Writes `mesh` as `directory`/`mesh_name` and `scene` (which reads that file by its
/// name) as `directory`/scene.json; returns the scene file's path.
/// @throws InputError naming a file that cannot be written
std::string write_mesh_and_scene(
    const std::string& directory, const std::string& mesh_name, const Mesh& mesh, const nlohmann::json& scene);

} // namespace diffipc
