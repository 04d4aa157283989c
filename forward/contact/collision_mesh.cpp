#include "forward/contact/collision_mesh.hpp"

#include "forward/mesh/mesh.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

namespace diffipc {

CollisionMesh build_collision_mesh(
    const Mesh& mesh, const std::vector<char>& self_contact, const std::vector<char>& kinematic)
{
    if (self_contact.size() != kinematic.size())
        throw std::invalid_argument("build_collision_mesh: group flag sizes differ");
    CollisionMesh c;
    c.dim = mesh.dim;
    c.num_vertices = mesh.num_vertices();
    c.group_self_contact = self_contact;
    c.group_kinematic = kinematic;
    c.vertex_group.assign(size_t(mesh.num_vertices()), -1);
    const MatrixXi& facets = mesh.boundary_facets;
    std::vector<int> used;
    for (Index f = 0; f < facets.rows(); ++f)
        for (int a = 0; a < facets.cols(); ++a) {
            const int v = facets(f, a);
            c.vertex_group[size_t(v)] = mesh.vertex_body[v];
            used.push_back(v);
        }
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());
    c.vertices = Eigen::Map<const VectorXi>(used.data(), Index(used.size()));
    for (int g : c.vertex_group)
        if (g >= int(self_contact.size()))
            throw std::invalid_argument("build_collision_mesh: a vertex has a group without flags");

    if (mesh.dim == 2) {
        c.edges = facets;
        c.faces.resize(0, 3);
        return c;
    }
    c.faces = facets;
    std::vector<std::array<int, 2>> edges;
    edges.reserve(size_t(facets.rows()) * 3);
    for (Index f = 0; f < facets.rows(); ++f)
        for (int a = 0; a < 3; ++a) {
            const int u = facets(f, a), w = facets(f, (a + 1) % 3);
            edges.push_back({ std::min(u, w), std::max(u, w) });
        }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    c.edges.resize(Index(edges.size()), 2);
    for (size_t e = 0; e < edges.size(); ++e)
        c.edges.row(Index(e)) << edges[e][0], edges[e][1];
    return c;
}

} // namespace diffipc
