#pragma once
/// @file marker_file.hpp
/// Markers from measured data (issue 13, docs/objectives.md "markers from a file"): a text file
/// of marker positions, attached to the mesh in its rest configuration.
///
/// One marker per row, numbers separated by blanks or commas, '#' starts a comment:
///   static:    X Y [Z]  x y [z]      rest and measured (deformed) position, metres
///   transient: X Y [Z]  t  x y [z]   rest position, time (s), measured position at t
/// Every row of a file has the same form. In a transient file a marker is a rest position:
/// its rows at the different times repeat it exactly; every marker has a row at every time;
/// each time is a step of the scene (t = k dt within 1e-6 dt).
///
/// Attaching: the nearest body vertex if it lies within `vertex_tolerance` of the marker
/// (default 1e-6 of the bodies' bounding-box diagonal), else the element that contains it,
/// as barycentric weights (on a shared face or edge, the first element found). A marker
/// outside the bodies' bounding box (enlarged by 5%) is refused with a hint at units (a file
/// in millimetres); one inside the box but outside every element, with its distance.

#include "forward/common/types.hpp"
#include "forward/mesh/mesh.hpp"
#include "objectives/markers.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// The markers of a file, attached, and their measured positions.
struct MarkerData {
    std::vector<MarkerPoint> markers; ///< M
    Positions rest; ///< M by dim, as in the file
    std::vector<int> steps; ///< the states measured (transient: from the times; static: empty)
    std::vector<Positions> targets; ///< one M by dim block per measured state
    int at_vertices = 0; ///< markers attached to a vertex (the others: inside an element)
};

/// @brief Reads `path` and attaches its markers to the body elements of `mesh` (rest positions
/// `rest`, the bodies' vertices first: vertices at or beyond `body_vertices` are not used).
/// @param dt the scene's time step (transient files), steps its number of steps
/// @param vertex_tolerance <= 0: 1e-6 of the bodies' bounding-box diagonal
/// @throws InputError naming the file and line (malformed or non-finite rows, a marker
///         outside the mesh, times off the steps, a marker missing at a time)
MarkerData read_marker_file(const std::string& path, const Mesh& mesh, const Positions& rest, Index body_vertices,
    double dt, int steps, double vertex_tolerance);

} // namespace diffipc
