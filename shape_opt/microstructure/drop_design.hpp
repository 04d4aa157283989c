#pragma once
/// @file drop_design.hpp
/// A cushion's drop test as a design objective (issue 15; docs/microstructures.md, "Drop
/// test"): a pad of nx by ny cells of a family's design p (cell_tiling.hpp) bonded to the ground
/// (its bottom held), a stiff block as wide as the pad falling on it, implicit Euler with
/// contact (a fixed barrier stiffness: the adjoint needs one) and friction between block and
/// pad. The stress on the block's bottom face at step k is
///
///     sigma_k = F_k / W,   F_k = s^T M (v_k - v_{k-1}) / h + M_block g
///
/// (objectives/body_force.hpp: exactly the pad's contact and friction force on the block under
/// implicit Euler), W = nx w h the pad's width, and the objective is its smooth maximum over the
/// run, relative to the plateau's target stress:
///
///     J = (sum_k max(sigma_k, 0)^p)^(1/p) / sigma*.
///
/// dJ/dp: the adjoint's shape gradient over the pad's vertices, summed back onto the cell's
/// (CellTiling::pullback) and pulled back by the cell mesh's velocity; the width stretches the
/// whole scene along x (the pad, its copies' shifts and the block: dX/dw = (X_x / w, 0) for every
/// vertex), lowers the block's density (its mass per depth is fixed: d rho / dw = -rho / w) and
/// widens W (-J / w).

#include "shape_opt/microstructure/cell_objective.hpp"

#include <nlohmann/json.hpp>

namespace diffipc {

class JsonField;

struct DropSettings {
    CellMeshSettings mesh { 0.01, 0.01 / 40 }; ///< the cell's height and mesh size (m)
    int nx = 4, ny = 2; ///< cells along x and y
    /// The pad's material block (docs/scene_format.md).
    nlohmann::json material
        = { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 1000 }, { "plane", "stress" } };
    double block_E = 1e8; ///< the block's Young's modulus (neo-Hookean, nu 0.3, plane stress)
    double mass = 0; ///< the block's mass per metre of depth (kg/m), > 0
    double speed = 0.5; ///< its initial downward speed (m/s)
    double gap = 0; ///< its initial height above the pad (m); 0: height / 20
    double dhat = 0; ///< contact distance (m); 0: height / 1000
    double kappa = 0; ///< fixed barrier stiffness, > 0
    double friction = 0.3; ///< between block and pad (0: none)
    double dt = 1e-4;
    int steps = 200;
    double max_p = 8; ///< the smooth maximum's exponent (>= 1)
    double target_stress = 0; ///< sigma* (Pa), > 0
    nlohmann::json solver = { { "max_iterations", 400 } }; ///< the scene's solver block
};

/// @brief Parses {"height", "size", "cells": [nx, ny], "material", "block": {"E", "mass",
/// "speed", "gap"}, "dhat", "kappa", "friction", "dt", "steps", "max_p", "target_stress", "solver"}
/// ("block.mass", "kappa" and "target_stress" required).
/// @throws InputError naming the field
DropSettings parse_drop_settings(const JsonField& f);

/// One drop.
struct DropEvaluation : DesignValue {
    VectorXd time; ///< t_k, k = 1..T
    VectorXd stress; ///< sigma_k (Pa)
    VectorXd deceleration; ///< the block's upward acceleration (m/s^2), (P_k - P_(k-1)) / (M h)
    double peak = 0; ///< max_k sigma_k
    double width = 0; ///< W (m)
    Index vertices = 0, elements = 0; ///< the scene's
    int newton_iterations = 0;
    double seconds = 0;
};

class DropDesign : public CellObjective {
public:
    /// @throws InputError for settings a drop cannot run with (naming the field)
    DropDesign(CellFamily family, DropSettings settings);

    const CellFamily& family() const override { return m_family; }
    const CellMeshSettings& mesh_settings() const override { return m_settings.mesh; }
    const DropSettings& settings() const { return m_settings; }

    /// @brief The drop on a pad of design p's cell, meshed anew.
    /// @throws InputError for a design outside the bounds or one that cannot be meshed
    DropEvaluation evaluate(const VectorXd& p, bool gradient) const;
    /// @brief The drop on a pad tiled from `cell`, a mesh of p's cell; with `velocity` (dX/dp of
    /// the cell's vertices) its gradient.
    DropEvaluation evaluate_mesh(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const;
    DesignValue value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const override;

    /// The drop's scene for a pad mesh file of cell width w.
    nlohmann::json scene(const std::string& pad_file, double width) const;
    /// @brief Writes design p's pad as `directory`/pad.msh (a new mesh) and the drop as
    /// `directory`/scene.json, for `diffipc simulate` and `diffipc check`; returns the scene's path.
    std::string write_scene(const VectorXd& p, const std::string& directory) const;

private:
    CellFamily m_family;
    DropSettings m_settings;
};

} // namespace diffipc
