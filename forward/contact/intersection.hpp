#pragma once
/// @file intersection.hpp
/// Exact intersection and inversion tests (GMP rationals behind a floating-point
/// filter), independent of the distance, broad-phase and CCD code: the solver
/// uses them to reject invalid initial states and the tests use them to check
/// every committed step.

#include "forward/contact/collision_mesh.hpp"

#include <string>

namespace diffipc {

struct Mesh;

/// @brief Sign of det[b - a, c - a, d - a] (+1, 0, -1), exact.
int orient3d_exact(const double* a, const double* b, const double* c, const double* d);
/// @brief Sign of det[b - a, c - a], exact (2D points).
int orient2d_exact(const double* a, const double* b, const double* c);

/// @brief Do the closed segments (p, q) and triangle (a, b, c) share a point? Exact.
bool segment_triangle_intersect(const double* p, const double* q, const double* a, const double* b, const double* c);
/// @brief Do the closed 2D segments (a, b) and (c, d) share a point? Exact.
bool segments_intersect_2d(const double* a, const double* b, const double* c, const double* d);

/// @brief Finds a pair of surface primitives that intersect at positions X:
/// 3D: an edge and a face, 2D: two edges, not sharing a vertex. Pairs of two
/// kinematic groups are skipped; with `all_pairs` self-contact flags are
/// ignored (every body is checked against itself too).
/// @param X #V by dim positions
/// @return "" if none, else a description of the first intersecting pair
std::string find_intersection(const CollisionMesh& mesh, const Positions& X, bool all_pairs);

/// @brief Finds a contact group lying inside another one's closed surface (a body
/// inside a body or inside a closed obstacle), which has no crossing surfaces and
/// so escapes find_intersection. Meant for states that find_intersection passed:
/// then one vertex per group decides. Uses the generalized winding number
/// (solid angles in 3D, angles in 2D; |w| > 1/2 is inside), in floating point.
/// Groups whose surface is not closed (an open obstacle sheet) enclose nothing.
/// @return "" if none, else a description naming the two groups
std::string find_containment(const CollisionMesh& mesh, const Positions& X);

/// @brief Number of elements whose orientation at X is not positive, exact.
Index count_inverted_elements(const Mesh& mesh, const Positions& X);

} // namespace diffipc
