#include "forward/mesh/mesh.hpp"

#include "forward/common/error.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace diffipc {

Mesh box_mesh(int dim, const VectorXd& lower, const VectorXd& upper, const VectorXi& cells)
{
    Mesh mesh;
    mesh.dim = dim;
    const int nx = cells[0], ny = cells[1], nz = dim == 3 ? cells[2] : 0;
    const int vx = nx + 1, vy = ny + 1, vz = dim == 3 ? nz + 1 : 1;
    mesh.rest_positions.resize(Index(vx) * vy * vz, dim);
    auto vid = [&](int i, int j, int k) { return (k * vy + j) * vx + i; };
    for (int k = 0; k < vz; ++k)
        for (int j = 0; j < vy; ++j)
            for (int i = 0; i < vx; ++i) {
                const int v = vid(i, j, k);
                const std::array<int, 3> ijk { i, j, k };
                for (int a = 0; a < dim; ++a)
                    mesh.rest_positions(v, a) = lower[a] + (upper[a] - lower[a]) * double(ijk[a]) / cells[a];
            }

    std::vector<std::array<int, 4>> elements;
    if (dim == 2) {
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const int v00 = vid(i, j, 0), v10 = vid(i + 1, j, 0), v01 = vid(i, j + 1, 0),
                          v11 = vid(i + 1, j + 1, 0);
                elements.push_back({ v00, v10, v11, -1 });
                elements.push_back({ v00, v11, v01, -1 });
            }
    } else {
        // Kuhn subdivision: one tet per permutation of the axes, walking from
        // corner 000 to 111 one unit step per axis.
        const std::array<std::array<int, 3>, 6> perms { { { 0, 1, 2 }, { 0, 2, 1 }, { 1, 0, 2 }, { 1, 2, 0 },
            { 2, 0, 1 }, { 2, 1, 0 } } };
        for (int k = 0; k < nz; ++k)
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i)
                    for (const auto& p : perms) {
                        std::array<int, 3> c { 0, 0, 0 };
                        std::array<int, 4> tet;
                        tet[0] = vid(i, j, k);
                        for (int s = 0; s < 3; ++s) {
                            c[p[s]] = 1;
                            tet[s + 1] = vid(i + c[0], j + c[1], k + c[2]);
                        }
                        elements.push_back(tet);
                    }
    }
    mesh.elements.resize(Index(elements.size()), dim + 1);
    for (size_t e = 0; e < elements.size(); ++e)
        for (int a = 0; a <= dim; ++a)
            mesh.elements(Index(e), a) = elements[e][a];
    // Orient every element positively (odd permutations come out negative).
    for (Index e = 0; e < mesh.num_elements(); ++e)
        if (signed_volume(mesh.rest_positions, mesh.elements, e) < 0)
            std::swap(mesh.elements(e, 1), mesh.elements(e, 2));
    mesh.vertex_body = VectorXi::Zero(mesh.num_vertices());
    mesh.element_body = VectorXi::Zero(mesh.num_elements());
    compute_boundary(mesh);
    return mesh;
}

double signed_volume(const Positions& x, const MatrixXi& elements, Index e)
{
    const int dim = int(x.cols());
    if (dim == 2) {
        const Eigen::Vector2d a = x.row(elements(e, 0)), b = x.row(elements(e, 1)), c = x.row(elements(e, 2));
        const Eigen::Vector2d u = b - a, v = c - a;
        return 0.5 * (u[0] * v[1] - u[1] * v[0]);
    }
    const Eigen::Vector3d a = x.row(elements(e, 0)), b = x.row(elements(e, 1)), c = x.row(elements(e, 2)),
                          d = x.row(elements(e, 3));
    return (b - a).cross(c - a).dot(d - a) / 6.0;
}

void compute_boundary(Mesh& mesh)
{
    const int dim = mesh.dim;
    // Facets of a positively oriented simplex, listed with outward orientation.
    static const int tri_facets[3][2] = { { 0, 1 }, { 1, 2 }, { 2, 0 } };
    static const int tet_facets[4][3] = { { 0, 2, 1 }, { 0, 1, 3 }, { 0, 3, 2 }, { 1, 2, 3 } };
    std::map<std::array<int, 3>, std::pair<std::array<int, 3>, int>> open; // sorted key -> (oriented, count)
    std::vector<std::array<int, 3>> order;
    for (Index e = 0; e < mesh.num_elements(); ++e) {
        for (int f = 0; f < dim + 1; ++f) {
            std::array<int, 3> oriented { -1, -1, -1 };
            for (int a = 0; a < dim; ++a)
                oriented[a] = mesh.elements(e, dim == 2 ? tri_facets[f][a] : tet_facets[f][a]);
            std::array<int, 3> key = oriented;
            std::sort(key.begin(), key.begin() + dim);
            auto it = open.find(key);
            if (it == open.end()) {
                open.emplace(key, std::make_pair(oriented, 1));
                order.push_back(key);
            } else {
                ++it->second.second;
            }
        }
    }
    std::vector<std::array<int, 3>> facets;
    for (const auto& key : order) {
        const auto& entry = open.at(key);
        if (entry.second == 1)
            facets.push_back(entry.first);
    }
    mesh.boundary_facets.resize(Index(facets.size()), dim);
    mesh.facet_body.resize(Index(facets.size()));
    for (size_t f = 0; f < facets.size(); ++f) {
        for (int a = 0; a < dim; ++a)
            mesh.boundary_facets(Index(f), a) = facets[f][a];
        mesh.facet_body[Index(f)] = mesh.vertex_body.size() ? mesh.vertex_body[facets[f][0]] : 0;
    }
}

void append_mesh(Mesh& mesh, const Mesh& other, int body)
{
    if (mesh.dim == 0)
        mesh.dim = other.dim;
    const Index v0 = mesh.num_vertices(), e0 = mesh.num_elements(), f0 = mesh.boundary_facets.rows();
    const int dim = mesh.dim;
    Positions x(v0 + other.num_vertices(), dim);
    x << mesh.rest_positions, other.rest_positions;
    mesh.rest_positions = std::move(x);
    MatrixXi el(e0 + other.num_elements(), dim + 1);
    el.topRows(e0) = mesh.elements;
    el.bottomRows(other.num_elements()) = other.elements.array() + int(v0);
    mesh.elements = std::move(el);
    MatrixXi bf(f0 + other.boundary_facets.rows(), dim);
    bf.topRows(f0) = mesh.boundary_facets;
    bf.bottomRows(other.boundary_facets.rows()) = other.boundary_facets.array() + int(v0);
    mesh.boundary_facets = std::move(bf);
    auto grow = [body](VectorXi& v, Index n) {
        VectorXi w(v.size() + n);
        w << v, VectorXi::Constant(n, body);
        v = std::move(w);
    };
    grow(mesh.vertex_body, other.num_vertices());
    grow(mesh.element_body, other.num_elements());
    grow(mesh.facet_body, other.boundary_facets.rows());
}

void validate_mesh(const Mesh& mesh, const std::string& field)
{
    if (mesh.num_elements() == 0)
        throw InputError(field, "mesh has no elements");
    if (!mesh.rest_positions.allFinite())
        throw InputError(field, "mesh has non-finite vertex coordinates");
    if (mesh.elements.minCoeff() < 0 || mesh.elements.maxCoeff() >= mesh.num_vertices())
        throw InputError(field, "element refers to a vertex index out of range");
    const Eigen::RowVectorXd extent
        = mesh.rest_positions.colwise().maxCoeff() - mesh.rest_positions.colwise().minCoeff();
    const double diag = extent.norm();
    double mean_volume = 0;
    for (Index e = 0; e < mesh.num_elements(); ++e)
        mean_volume += std::abs(signed_volume(mesh.rest_positions, mesh.elements, e));
    mean_volume /= double(mesh.num_elements());
    // An element is degenerate if its volume is negligible both against the
    // mean element and against the bounding box.
    const double tiny = 1e-10 * std::min(mean_volume, std::pow(diag, mesh.dim));
    for (Index e = 0; e < mesh.num_elements(); ++e) {
        const double v = signed_volume(mesh.rest_positions, mesh.elements, e);
        if (v < -tiny)
            throw InputError(
                field, "element " + std::to_string(e) + " is inverted (signed volume " + format_number(v) + ")");
        if (v <= tiny)
            throw InputError(
                field, "element " + std::to_string(e) + " is degenerate (volume " + format_number(v) + ")");
    }
}

} // namespace diffipc
