#pragma once
/// @file cell_family.hpp
/// A parametric family of microstructure cells (issue 15; docs/microstructures.md): a wire graph,
/// a symmetry, and the design variables that move it:
///
///   - node offsets, one variable per orbit of nodes under the symmetry and free axis (`node[i].x`,
///     `node[i].y`, i the orbit's first node, 0-based): the other nodes of the orbit move by the
///     mirrored offset, a node on a mirror line or on the cell's boundary (x = +-1, y = +-1) only
///     along it, so the graph keeps its symmetry and its periodic connections;
///   - edge thicknesses, one per orbit of edges (`thickness[e]`);
///   - the blending radius (`blend`) of the smooth union (cell_sdf.hpp);
///   - the cell's width scale (`width`): the cell is `width` times as wide (along x) as it is tall.
///
/// Offsets, thicknesses and the blend are in the graph's coordinates ([-1, 1]^2 is the cell). The
/// map from design variables to CellParameters is affine. Each variable has bounds; a design
/// outside them is an input error naming the variable.

#include "shape_opt/microstructure/cell_sdf.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace diffipc {

class JsonField;

/// The mirror symmetries a graph may keep: none, x -> -x, y -> -y, or both.
enum class CellSymmetry { NONE, REFLECTION_X, REFLECTION_Y, REFLECTION_XY };

/// "none", "reflection_x", "reflection_y", "reflection_xy"
std::string to_string(CellSymmetry symmetry);

class CellFamily {
public:
    /// Per group of variables: the initial value and bounds (offsets start at 0).
    struct Range {
        double initial = 0, lower = 0, upper = 0;
    };
    struct Settings {
        CellSymmetry symmetry = CellSymmetry::NONE;
        double offset_bound = 0.2; ///< offsets within [-b, b] (and nodes within the cell)
        Range thickness { 0.15, 0.08, 0.3 };
        Range blend { 0.03, 0.01, 0.1 };
        Range width { 1, 0.7, 1.5 };
    };

    /// @throws InputError naming `field` if the graph does not have the symmetry (naming the
    ///         node or edge without a mirror image) or a range is empty or out of its domain
    CellFamily(WireGraph graph, const Settings& settings, const std::string& field);

    const WireGraph& graph() const { return m_graph; }
    CellSymmetry symmetry() const { return m_settings.symmetry; }
    Index size() const { return Index(m_names.size()); }
    const std::vector<std::string>& names() const { return m_names; }
    const VectorXd& lower() const { return m_lower; }
    const VectorXd& upper() const { return m_upper; }
    const VectorXd& initial() const { return m_initial; }
    /// The index of the width variable (the last one).
    Index width_index() const { return size() - 1; }

    /// @brief Throws InputError naming `field`[name] for a value that is not finite or outside
    /// its bounds (1e-12 relative slack), or a vector of the wrong size.
    void check(const VectorXd& p, const std::string& field) const;
    /// The cell's parameters at design p (checked).
    CellParameters cell_parameters(const VectorXd& p) const;
    /// d CellParameters::flatten() / dp: constant, (2 #N + #M + 1) by size() (the width column is zero).
    const MatrixXd& jacobian() const { return m_jacobian; }

private:
    WireGraph m_graph;
    Settings m_settings;
    std::vector<std::string> m_names;
    VectorXd m_lower, m_upper, m_initial;
    MatrixXd m_jacobian;
};

/// @brief A family file: {"graph": OBJ path (relative to `base_directory`), "symmetry": name,
/// "offset": {"bound": b}, "thickness" | "blend" | "width": {"initial": v, "bounds": [lo, hi]}};
/// every key but "graph" optional (CellFamily::Settings' defaults).
/// @throws InputError naming the field (or the OBJ file and line)
CellFamily parse_cell_family(const JsonField& f, const std::string& base_directory);
/// @brief parse_cell_family of the JSON file at `path` (graph paths relative to its folder).
CellFamily read_cell_family(const std::string& path);

} // namespace diffipc
