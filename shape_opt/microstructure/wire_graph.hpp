#pragma once
/// @file wire_graph.hpp
/// The wire graph of a microstructure cell (issue 15): nodes in the cell [-1, 1]^2 and straight
/// edges between them, read from a Wavefront OBJ file (`v x y [z]` records, z ignored, and `l`
/// polylines whose consecutive indices are edges), the format of published topology collections.

#include "forward/common/types.hpp"

#include <string>

namespace diffipc {

struct WireGraph {
    MatrixXd nodes; ///< #N by 2, in [-1, 1]^2
    MatrixXi edges; ///< #M by 2 node indices (0-based), distinct endpoints
};

/// @brief Reads a wire graph from OBJ text.
/// @param name the file name errors are prefixed with
/// @throws InputError naming the file and line: an unreadable record, an index out of range, a
///         node outside [-1, 1]^2, an edge from a node to itself, or no edge at all.
WireGraph parse_wire_graph(const std::string& text, const std::string& name);
/// @brief parse_wire_graph of the file at `path` (InputError naming it if it cannot be read).
WireGraph read_wire_graph(const std::string& path);

} // namespace diffipc
