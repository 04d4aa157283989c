#pragma once
/// @file boundary_smoothness.hpp
/// Smoothness of the rest shape's boundary: a regularizer for shape optimization.

#include "objectives/objective.hpp"

#include <vector>

namespace diffipc {

/// @brief J(X) = \sum_{v \in \partial\Omega} |X_v - \frac{1}{|N(v)|} \sum_{w \in N(v)} X_w|^2 (m^2):
/// the squared umbrella (graph Laplacian) vector of every boundary vertex of the bodies, with N(v)
/// the vertices that share a boundary facet with v (its two neighbours along the curve in 2D, its
/// one-ring on the surface in 3D). Obstacles are excluded. Depends on the rest positions only: no
/// state derivative; dJ/dX = 2 L^T r with r_v the umbrella vectors. The neighbourhoods are taken
/// from the mesh given at construction; a simulator with another mesh topology is an error.
class BoundarySmoothness : public Objective {
public:
    /// @param scene the scene whose boundary facets define the neighbourhoods
    /// @param body  only the facets of this body (< 0: all bodies)
    explicit BoundarySmoothness(const Scene& scene, int body = -1);

    std::string name() const override { return "boundary_smoothness"; }
    /// @throws std::invalid_argument if the simulator's mesh has another vertex count.
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    /// None: J depends on the rest shape only.
    std::vector<int> states_read(int) const override { return {}; }

private:
    /// The umbrella vectors r_v (row per listed vertex).
    Positions umbrella(const Mesh& mesh) const;

    Index m_num_vertices = 0;
    std::vector<Index> m_vertices; ///< boundary vertices
    std::vector<std::vector<Index>> m_neighbours; ///< per boundary vertex
};

} // namespace diffipc
