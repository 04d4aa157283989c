#pragma once
/// @file tiling.hpp
/// The tiling of a deformed periodic cell: copies of the cell's mesh shifted by (I + G) L s for
/// the lattice vectors s in {-n .. n} along the periodic axes, the copies' shared vertices welded
/// (a vertex is identified by its class and its lattice position), so that the tiled mesh's
/// boundary is the boundary of the union. Checks that must hold for the infinite tiling (no
/// intersection across the cell's boundary) run on it, independently of the contact code.

#include "forward/common/types.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/periodic/pairing.hpp"

#include <array>
#include <vector>

namespace diffipc {

struct Tiling {
    Mesh mesh; ///< rest positions: the tiled rest positions; boundary facets of the union
    Positions positions; ///< the tiled deformed positions
};

/// The lattice shifts s in {-n .. n}^(periodic axes) (0 along the others), the zero shift among them.
std::vector<std::array<int, 3>> lattice_shifts(const PeriodicBox& box, int dim, int copies);

/// @param mesh   the cell (rest positions, elements); @param pairing its vertex classes
/// @param x      #V d deformed positions of the cell; @param G d^2 values (row-major)
/// @param copies n: 1 gives 3 x 3 (x 3) copies
Tiling tile_cell(const Mesh& mesh, const PeriodicBox& box, const PeriodicPairing& pairing, const VectorXd& x,
    const VectorXd& G, int copies = 1);

} // namespace diffipc
