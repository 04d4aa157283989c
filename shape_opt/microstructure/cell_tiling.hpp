#pragma once
/// @file cell_tiling.hpp
/// A pad tiled from a periodic cell (issue 15; docs/microstructures.md, "Drop test"): nx by ny
/// copies of a cell mesh, copy (i, j) shifted by ((i + 1/2) w h, (j + 1/2) h) so that the pad
/// fills [0, nx w h] x [0, ny h], the vertices where copies meet welded into one. Which copies'
/// vertices weld is found once, from the cell's periodic structure (a vertex on the right side
/// and the left side's vertex at the same height; top and bottom alike), so that a moved cell
/// mesh tiles into a pad of the same connectivity.

#include "forward/mesh/mesh.hpp"

#include <vector>

namespace diffipc {

class CellTiling {
public:
    /// @param cell a periodic mesh of a cell in its box [-w h/2, w h/2] x [-h/2, h/2] (width w, height h)
    /// @throws InputError naming "cell mesh" if a side's vertex has no partner on the opposite side
    CellTiling(const Mesh& cell, double width, double height, int nx, int ny);

    /// The pad: one body, its elements the copies' in the order (i, j) (j fastest).
    const Mesh& mesh() const { return m_mesh; }
    int nx() const { return m_nx; }
    int ny() const { return m_ny; }
    /// Per pad vertex: the cell vertex it comes from (the first copy's that holds it).
    const std::vector<Index>& source() const { return m_source; }

    /// @brief The pad's rest positions for the cell's rest positions `cell` (#V_cell by 2, a mesh
    /// of the same connectivity, for example moved to another design) at width w:
    /// X_v = cell(source(v)) + ((i_v + 1/2) w h, (j_v + 1/2) h).
    Positions positions(const Positions& cell, double width) const;
    /// @brief dJ/d(cell's rest positions) (#V_cell*2) from dJ/d(pad's rest positions) (#V_pad*2,
    /// vertex-major): the transpose of `positions` at fixed width.
    VectorXd pullback(const VectorXd& dJ_dpad) const;

private:
    int m_nx, m_ny;
    double m_height;
    Index m_cell_vertices;
    Mesh m_mesh;
    std::vector<Index> m_source;
    std::vector<Eigen::Vector2i> m_copy; ///< per pad vertex: (i, j) of its copy
};

} // namespace diffipc
