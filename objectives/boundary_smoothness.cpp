#include "objectives/boundary_smoothness.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <stdexcept>

namespace diffipc {

BoundarySmoothness::BoundarySmoothness(const Scene& scene, int body)
    : m_num_vertices(scene.mesh.num_vertices())
{
    const Mesh& mesh = scene.mesh;
    const int num_bodies = int(scene.bodies.size());
    std::map<Index, std::set<Index>> neighbours;
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        const int b = mesh.facet_body[f];
        if (b >= num_bodies || (body >= 0 && b != body))
            continue;
        for (int i = 0; i < mesh.dim; ++i)
            for (int j = 0; j < mesh.dim; ++j)
                if (i != j)
                    neighbours[mesh.boundary_facets(f, i)].insert(mesh.boundary_facets(f, j));
    }
    if (neighbours.empty())
        throw std::invalid_argument("boundary_smoothness: no boundary facet of body " + std::to_string(body));
    for (const auto& [v, n] : neighbours) {
        m_vertices.push_back(v);
        m_neighbours.emplace_back(n.begin(), n.end());
    }
}

Positions BoundarySmoothness::umbrella(const Mesh& mesh) const
{
    if (mesh.num_vertices() != m_num_vertices)
        throw std::invalid_argument("boundary_smoothness: the mesh has " + std::to_string(mesh.num_vertices())
            + " vertices, the objective was built for " + std::to_string(m_num_vertices));
    Positions r(Index(m_vertices.size()), mesh.dim);
    for (size_t i = 0; i < m_vertices.size(); ++i) {
        r.row(Index(i)) = mesh.rest_positions.row(m_vertices[i]);
        for (const Index w : m_neighbours[i])
            r.row(Index(i)) -= mesh.rest_positions.row(w) / double(m_neighbours[i].size());
    }
    return r;
}

double BoundarySmoothness::value(const Simulator& sim, const Trajectory&) const
{
    return umbrella(sim.mesh()).squaredNorm();
}

void BoundarySmoothness::add_gradient(
    const Simulator& sim, const Trajectory&, const ParameterRequest& request, double scale, StateSeed& seed) const
{
    if (!request.rest_positions)
        return;
    const Mesh& mesh = sim.mesh();
    const int d = mesh.dim;
    const Positions r = umbrella(mesh);
    VectorXd& dX = gradient_block(seed.explicit_partials.rest_positions, mesh.num_dofs());
    for (size_t i = 0; i < m_vertices.size(); ++i) {
        dX.segment(m_vertices[i] * d, d) += 2 * scale * r.row(Index(i)).transpose();
        for (const Index w : m_neighbours[i])
            dX.segment(w * d, d) -= 2 * scale / double(m_neighbours[i].size()) * r.row(Index(i)).transpose();
    }
}

} // namespace diffipc
