#pragma once
/// @file rest_validity.hpp
/// Valid designs (issue 12, docs/parametrizations.md "Valid designs"): a rest mesh is valid
/// when no element is inverted or degenerate and no two boundary primitives of the bodies
/// intersect (both tested exactly, forward/contact/intersection.hpp). A design step moves the
/// rest positions along a line X + t dX; its valid length is bounded by the first loss of
/// positive element volume along it (the forward solver's volume polynomial bound) and by
/// conservative CCD of the rest boundary along it (every body against itself and the others),
/// so that a valid mesh stays valid along the whole step, not only at its end.

#include "forward/contact/collision_mesh.hpp"
#include "forward/mesh/mesh.hpp"

#include <string>

namespace diffipc {

class RestValidity {
public:
    /// @param bodies the bodies' mesh (no obstacles): elements and boundary facets
    explicit RestValidity(Mesh bodies);
    /// @brief "" if the rest positions X are valid, else what is wrong (exact tests).
    /// @param X #V * dim rest positions, vertex-major
    std::string problem(const VectorXd& X) const;
    /// @brief Largest t in (0, 1] such that X + s dX is valid for every s in [0, t] (1: the
    /// whole step), with a margin: no element keeps less than `keep` of its volume, and CCD's
    /// conservative rescaling leaves 10% of each boundary gap. 0 if none is certified.
    double max_step(const VectorXd& X, const VectorXd& dX, double keep = 0.1) const;

private:
    Mesh m_mesh;
    CollisionMesh m_collision;
};

} // namespace diffipc
