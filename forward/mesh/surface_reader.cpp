#include "forward/common/error.hpp"
#include "forward/mesh/gmsh_reader.hpp"
#include "forward/mesh/mesh.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <new>
#include <sstream>
#include <vector>

namespace diffipc {

Mesh annulus_mesh(const VectorXd& center, double inner_radius, double outer_radius, int segments, int layers)
{
    Mesh mesh;
    mesh.dim = 2;
    const int rings = layers + 1;
    mesh.rest_positions.resize(Index(rings) * segments, 2);
    for (int r = 0; r < rings; ++r)
        for (int s = 0; s < segments; ++s) {
            const double radius = inner_radius + (outer_radius - inner_radius) * r / layers;
            const double angle = 2 * M_PI * s / segments;
            mesh.rest_positions.row(Index(r) * segments + s) << center[0] + radius * std::cos(angle),
                center[1] + radius * std::sin(angle);
        }
    mesh.elements.resize(Index(2) * layers * segments, 3);
    Index e = 0;
    for (int r = 0; r < layers; ++r)
        for (int s = 0; s < segments; ++s) {
            const int a = r * segments + s, b = r * segments + (s + 1) % segments;
            const int c = a + segments, d = b + segments;
            // Counter-clockwise: (a, d, b) turns left from the outward diagonal to the tangent.
            mesh.elements.row(e++) << a, d, b;
            mesh.elements.row(e++) << a, c, d;
        }
    mesh.vertex_body = VectorXi::Zero(mesh.num_vertices());
    mesh.element_body = VectorXi::Zero(mesh.num_elements());
    compute_boundary(mesh);
    return mesh;
}

namespace {

    Mesh read_obj(const std::string& path, int dim)
    {
        std::ifstream in(path);
        if (!in)
            throw InputError(path, "cannot open surface mesh file");
        std::vector<Eigen::Vector3d> vertices;
        std::vector<std::vector<int>> facets;
        std::string line;
        int line_number = 0;
        auto fail
            = [&](const std::string& message) { throw InputError(path + ":" + std::to_string(line_number), message); };
        while (std::getline(in, line)) {
            ++line_number;
            std::istringstream ls(line);
            std::string tag;
            if (!(ls >> tag) || tag[0] == '#')
                continue;
            if (tag == "v") {
                Eigen::Vector3d v = Eigen::Vector3d::Zero();
                if (!(ls >> v[0] >> v[1]))
                    fail("expected vertex coordinates");
                if (!(ls >> v[2]))
                    v[2] = 0;
                if (!v.allFinite())
                    fail("non-finite vertex coordinate");
                vertices.push_back(v);
            } else if ((tag == "f" && dim == 3) || (tag == "l" && dim == 2)) {
                std::vector<int> ids;
                std::string token;
                while (ls >> token) {
                    // "7", "7/1", "7//3": the vertex index is before the first slash; negative counts from the end.
                    const std::string head = token.substr(0, token.find('/'));
                    char* end = nullptr;
                    const long id = std::strtol(head.c_str(), &end, 10);
                    if (end == head.c_str() || *end != '\0' || id == 0)
                        fail("bad vertex reference '" + token + "'");
                    const long index = id > 0 ? id - 1 : long(vertices.size()) + id;
                    if (index < 0 || index >= long(vertices.size()))
                        fail("vertex reference " + head + " out of range");
                    ids.push_back(int(index));
                }
                if (dim == 3) {
                    if (ids.size() < 3)
                        fail("a face needs at least 3 vertices");
                    for (size_t k = 1; k + 1 < ids.size(); ++k)
                        facets.push_back({ ids[0], ids[k], ids[k + 1] });
                } else {
                    if (ids.size() < 2)
                        fail("a line needs at least 2 vertices");
                    for (size_t k = 0; k + 1 < ids.size(); ++k)
                        facets.push_back({ ids[k], ids[k + 1] });
                }
            }
        }
        line_number = 0;
        if (facets.empty())
            fail(dim == 3 ? "no faces (\"f\" records)" : "no polylines (\"l\" records)");
        Mesh mesh;
        mesh.dim = dim;
        mesh.rest_positions.resize(Index(vertices.size()), dim);
        for (size_t v = 0; v < vertices.size(); ++v)
            mesh.rest_positions.row(Index(v)) = vertices[v].head(dim).transpose();
        mesh.boundary_facets.resize(Index(facets.size()), dim);
        for (size_t f = 0; f < facets.size(); ++f)
            for (int a = 0; a < dim; ++a)
                mesh.boundary_facets(Index(f), a) = facets[f][size_t(a)];
        return mesh;
    }

    /// Vertices on no facet take no part in contact (it sees vertices, edges and faces of the
    /// facets): they are dropped, and the facets renumbered. Kept, a file of 2 million vertices
    /// with one face was carried as 6 million prescribed dofs, in every state, frame and record.
    void drop_unreferenced_vertices(Mesh& mesh)
    {
        const Index n = mesh.rest_positions.rows();
        std::vector<int> new_index(size_t(n), -1);
        for (Index f = 0; f < mesh.boundary_facets.rows(); ++f)
            for (Index a = 0; a < mesh.boundary_facets.cols(); ++a)
                new_index[size_t(mesh.boundary_facets(f, a))] = 0;
        int kept = 0;
        for (int& i : new_index)
            if (i == 0)
                i = kept++;
        if (kept == n)
            return;
        Positions x(kept, mesh.rest_positions.cols());
        for (Index v = 0; v < n; ++v)
            if (new_index[size_t(v)] >= 0)
                x.row(new_index[size_t(v)]) = mesh.rest_positions.row(v);
        mesh.rest_positions = std::move(x);
        for (Index f = 0; f < mesh.boundary_facets.rows(); ++f)
            for (Index a = 0; a < mesh.boundary_facets.cols(); ++a)
                mesh.boundary_facets(f, a) = new_index[size_t(mesh.boundary_facets(f, a))];
    }

} // namespace

Mesh read_surface_mesh(const std::string& path, int dim)
{
    const std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
    Mesh mesh;
    try {
        if (ext == ".obj") {
            mesh = read_obj(path, dim);
        } else if (ext == ".msh") {
            mesh = read_gmsh_facets(path, dim);
        } else {
            throw InputError(path, "unsupported surface mesh format (expected .obj or .msh)");
        }
    } catch (const std::bad_alloc&) {
        throw InputError(path, "too large to read in the memory this process may use");
    }
    drop_unreferenced_vertices(mesh);
    mesh.elements.resize(0, dim + 1);
    mesh.element_body.resize(0);
    mesh.vertex_body = VectorXi::Zero(mesh.num_vertices());
    mesh.facet_body = VectorXi::Zero(mesh.boundary_facets.rows());
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        // Zero length (2D) or zero area (3D), repeated indices included.
        Eigen::Vector3d c[3] = { Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero() };
        for (int a = 0; a < dim; ++a)
            c[a].head(dim) = mesh.rest_positions.row(mesh.boundary_facets(f, a)).transpose();
        const double size = dim == 2 ? (c[1] - c[0]).norm() : (c[1] - c[0]).cross(c[2] - c[0]).norm();
        if (!(size > 0))
            throw InputError(
                path, "facet " + std::to_string(f) + " is degenerate (zero " + (dim == 2 ? "length" : "area") + ")");
    }
    return mesh;
}

} // namespace diffipc

namespace diffipc {

Mesh torus_mesh(double major_radius, double half_width, int cells_across, int segments)
{
    VectorXd lower(3), upper(3);
    lower << major_radius - half_width, -half_width, 0;
    upper << major_radius + half_width, half_width, 2 * M_PI;
    VectorXi cells(3);
    cells << cells_across, cells_across, segments;
    Mesh mesh = box_mesh(3, lower, upper, cells);
    // box_mesh numbers vertices (k * vy + j) * vx + i with k along theta: the
    // layer k = segments is the last block and coincides with k = 0.
    const Index layer = Index(cells_across + 1) * (cells_across + 1);
    const Index kept = layer * segments;
    for (Index e = 0; e < mesh.num_elements(); ++e)
        for (int a = 0; a < 4; ++a)
            if (mesh.elements(e, a) >= kept)
                mesh.elements(e, a) -= int(kept);
    Positions x(kept, 3);
    for (Index v = 0; v < kept; ++v) {
        const double rho = mesh.rest_positions(v, 0), z = mesh.rest_positions(v, 1), theta = mesh.rest_positions(v, 2);
        x.row(v) << rho * std::cos(theta), rho * std::sin(theta), z;
    }
    mesh.rest_positions = std::move(x);
    for (Index e = 0; e < mesh.num_elements(); ++e)
        if (signed_volume(mesh.rest_positions, mesh.elements, e) < 0)
            std::swap(mesh.elements(e, 1), mesh.elements(e, 2));
    mesh.vertex_body = VectorXi::Zero(kept);
    mesh.element_body = VectorXi::Zero(mesh.num_elements());
    compute_boundary(mesh);
    return mesh;
}

} // namespace diffipc
