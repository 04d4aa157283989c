#pragma once
/// @file cell_design.hpp
/// A cushion cell's design objective (issue 15; docs/microstructures.md): the cell of a family's
/// design p, meshed, compressed quasi-statically along y as a periodic cell (G_yy = -strain t
/// prescribed over static steps, G_xx and G_xy free (or G_xy = 0: "shear": "fixed"), G_yx = 0 to
/// remove the rigid rotation), with
/// contact across its boundary and between its own beams, judged at sample steps k_i by
///
///     J = sum_i (sigma_i / sigma* - 1)^2 + w_s sum_i G_xy(k_i)^2 + w_l sum_i G_xx(k_i)^2,
///
/// sigma_i = -P_yy(k_i) the compressive homogenized stress (objectives/macro_stress.hpp), sigma*
/// the plateau's target; and its gradient dJ/dp: the adjoint's shape gradient dJ/dX pulled back
/// by the mesh's velocity (cell_shape_map.hpp), plus, for the width, the cell volume's own
/// derivative (the homogenized stress divides by the box's volume |Y| = width height^2).

#include "forward/simulation/step_record.hpp"
#include "shape_opt/microstructure/cell_objective.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace diffipc {

class JsonField;

struct CellDesignSettings {
    CellMeshSettings mesh;
    /// The material block of the scene (docs/scene_format.md).
    nlohmann::json material
        = { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 1000 }, { "plane", "stress" } };
    double dhat = 0; ///< contact distance (m); 0: height / 1000
    /// Fixed barrier stiffness; 0: 1e4 E / h^2 (the barrier's energy scales as kappa dhat^4, the
    /// cell's as E h^2; the adaptive rule picks 1.7e10-4.6e10 for the re-entrant cell of h = 1 m,
    /// E = 1 MPa, dhat = h / 1000; 100 times softer stalls Newton where beams touch).
    double kappa = 0;
    double max_strain = 0.4; ///< compressive strain at the last step
    int steps = 16; ///< static load steps
    std::vector<int> samples { 4, 8, 12, 16 }; ///< the steps the objective compares
    /// Steps where the compressive stress may not exceed sigma* (one-sided: (sigma / sigma* - 1)^2
    /// only above it); none by default. Before the plateau a stress above sigma* is a peak.
    std::vector<int> cap_samples;
    double target_stress = 0; ///< sigma* (Pa), > 0
    double shear_weight = 50, lateral_weight = 10;
    bool free_shear = true; ///< G_xy free (else held at 0: the cell cannot sway sideways)
    nlohmann::json solver = { { "max_iterations", 400 } }; ///< the scene's solver block
};

/// @brief Parses {"height", "size", "material", "dhat", "kappa", "max_strain", "steps",
/// "samples", "cap_samples", "target_stress", "shear_weight", "lateral_weight", "shear" ("free" | "fixed"),
/// "solver"}.
/// @throws InputError naming the field
CellDesignSettings parse_cell_design_settings(const JsonField& f);

/// One evaluation of a design.
struct CellEvaluation : DesignValue {
    VectorXd strain, stress; ///< per step 1..T: compressive strain and stress sigma = -P_yy (Pa)
    VectorXd shear, lateral; ///< per step: G_xy, G_xx
    VectorXi contacts; ///< per step: active contact pairs
    Index vertices = 0, elements = 0;
    int newton_iterations = 0;
    double seconds = 0;
};

class CellDesign : public CellObjective {
public:
    CellDesign(CellFamily family, CellDesignSettings settings);

    const CellFamily& family() const override { return m_family; }
    const CellMeshSettings& mesh_settings() const override { return m_settings.mesh; }
    const CellDesignSettings& settings() const { return m_settings; }

    /// @brief J (and dJ/dp) at design p on a new mesh of it.
    /// @throws InputError for a design outside the bounds or one that cannot be meshed
    CellEvaluation evaluate(const VectorXd& p, bool gradient) const;
    /// @brief J at design q on the mesh `reference` of design p moved to q (CellShapeMap::moved),
    /// and with `gradient` the derivative of that function of q (CellShapeMap::moved_jacobian).
    CellEvaluation evaluate_moved(const Mesh& reference, const VectorXd& p, const VectorXd& q, bool gradient) const;
    /// The periodic scene of a cell mesh file at the given width.
    nlohmann::json scene(const std::string& mesh_file, double width) const;
    /// @brief Writes design p's cell as `directory`/cell.msh (a new mesh) and its compression as
    /// `directory`/scene.json (the mesh path relative to it), so that `diffipc simulate SCENE -o
    /// OUT` and `diffipc check OUT` run it; returns the scene file's path.
    std::string write_scene(const VectorXd& p, const std::string& directory) const;

    /// @brief J at design p on `mesh` (a mesh of p: a new one, or one moved to p); with
    /// `velocity` (dX/dp, #V*2 by the family's size) its gradient.
    CellEvaluation evaluate_mesh(const Mesh& mesh, const VectorXd& p, const MatrixXd* velocity) const;
    /// evaluate_mesh's J and gradient.
    DesignValue value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const override;

private:
    CellFamily m_family;
    CellDesignSettings m_settings;
};

} // namespace diffipc
