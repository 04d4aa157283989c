#pragma once
/// @file wire_graph.hpp
/// The wire graph of a microstructure cell (issue 15): nodes in the cell [-1, 1]^2 and straight
/// edges between them. Read from a Wavefront OBJ file (`v x y [z]` records, z ignored, and `l`
/// polylines whose consecutive indices are edges), or from a `.wire` file as published pattern
/// libraries write them (PyMesh's wire networks: `v x y [z [w]]`, `l i j`, 1-based; nodes in the
/// unit cell [0, 1]^2, mapped to [-1, 1]^2 as y = 2 x - 1).

#include "forward/common/types.hpp"

#include <string>

namespace diffipc {

struct WireGraph {
    MatrixXd nodes; ///< #N by 2, in [-1, 1]^2
    MatrixXi edges; ///< #M by 2 node indices (0-based), distinct endpoints
    std::string file; ///< the file it was read from (errors about the cell name it), "" if none
};

/// How a wire graph's text is written.
enum class WireGraphFormat {
    OBJ, ///< nodes in the cell [-1, 1]^2, z ignored
    WIRE, ///< nodes in [0, 1]^2 (a 2D pattern: z absent or the same for every node), rescaled
};

/// @brief The format of a graph file by its extension: ".wire" is WIRE, anything else OBJ.
WireGraphFormat wire_graph_format(const std::string& path);

/// @brief Reads a wire graph from OBJ or .wire text.
/// @param name the file name errors are prefixed with (and WireGraph::file)
/// @throws InputError naming the file and line: an unreadable record, an index out of range, a
///         node outside [-1, 1]^2 (OBJ) or [0, 1]^2 (WIRE, the message saying how either is
///         read), a 3D pattern (WIRE nodes whose z differ), an edge from a node to itself, or no
///         edge at all.
WireGraph parse_wire_graph(
    const std::string& text, const std::string& name, WireGraphFormat format = WireGraphFormat::OBJ);
/// @brief parse_wire_graph of the file at `path` in its extension's format (InputError naming it
/// if it cannot be read).
WireGraph read_wire_graph(const std::string& path);

} // namespace diffipc
