#pragma once
/// @file distance.hpp
/// Umbrella header: squared distances between points, lines, planes and the
/// primitives built from them, each with its gradient and Hessian
/// (`*_distance`, `*_distance_gradient`, `*_distance_hessian`), the
/// closest-feature classification, and the edge-edge mollifier.
/// All functions take 3D points; 2D callers set z = 0. Derivatives are
/// vertex-major in argument order, xyz per vertex.

#include "forward/contact/distance/distance_type.hpp"
#include "forward/contact/distance/edge_edge.hpp"
#include "forward/contact/distance/edge_edge_mollifier.hpp"
#include "forward/contact/distance/line_line.hpp"
#include "forward/contact/distance/point_edge.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_plane.hpp"
#include "forward/contact/distance/point_point.hpp"
#include "forward/contact/distance/point_triangle.hpp"
