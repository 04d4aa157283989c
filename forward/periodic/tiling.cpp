#include "forward/periodic/tiling.hpp"

#include <array>
#include <map>
#include <stdexcept>

namespace diffipc {

std::vector<std::array<int, 3>> lattice_shifts(const PeriodicBox& box, int dim, int copies)
{
    std::vector<std::array<int, 3>> shifts { { 0, 0, 0 } };
    for (int a = 0; a < dim; ++a) {
        if (!box.periodic[size_t(a)])
            continue;
        std::vector<std::array<int, 3>> more;
        for (const auto& s : shifts)
            for (int k = -copies; k <= copies; ++k) {
                auto t = s;
                t[size_t(a)] = k;
                more.push_back(t);
            }
        shifts = std::move(more);
    }
    return shifts;
}

Tiling tile_cell(const Mesh& mesh, const PeriodicBox& box, const PeriodicPairing& pairing, const VectorXd& x,
    const VectorXd& G, int copies)
{
    const int d = mesh.dim;
    const Index nv = mesh.num_vertices();
    if (x.size() != nv * d || G.size() != d * d || copies < 0)
        throw std::invalid_argument("tile_cell: expected #V d positions, d^2 gradient values and copies >= 0");
    const std::vector<std::array<int, 3>> shifts = lattice_shifts(box, d, copies);
    Eigen::MatrixXd F = Eigen::MatrixXd::Identity(d, d);
    for (int i = 0; i < d; ++i)
        for (int j = 0; j < d; ++j)
            F(i, j) += G[i * d + j];
    // Welded vertices: key (class, lattice position of the vertex).
    std::map<std::array<int, 4>, Index> index;
    std::vector<Eigen::VectorXd> rest, deformed;
    std::vector<int> body;
    Tiling t;
    t.mesh.dim = d;
    std::vector<std::array<int, 4>> elements;
    std::vector<int> element_body;
    for (const auto& s : shifts) {
        Eigen::VectorXd shift = Eigen::VectorXd::Zero(d);
        for (int a = 0; a < d; ++a)
            shift[a] = s[size_t(a)] * box.length(a);
        const Eigen::VectorXd deformed_shift = F * shift;
        std::vector<Index> local(static_cast<size_t>(nv));
        for (Index v = 0; v < nv; ++v) {
            std::array<int, 4> key { pairing.vertex_class[v], 0, 0, 0 };
            for (int a = 0; a < d; ++a)
                key[size_t(a + 1)] = s[size_t(a)] + pairing.offset(v, a);
            const auto [it, fresh] = index.emplace(key, Index(rest.size()));
            if (fresh) {
                rest.push_back(mesh.rest_positions.row(v).transpose() + shift);
                deformed.push_back(x.segment(v * d, d) + deformed_shift);
                body.push_back(mesh.vertex_body[v]);
            }
            local[size_t(v)] = it->second;
        }
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            std::array<int, 4> el { -1, -1, -1, -1 };
            for (int k = 0; k <= d; ++k)
                el[size_t(k)] = int(local[size_t(mesh.elements(e, k))]);
            elements.push_back(el);
            element_body.push_back(mesh.element_body[e]);
        }
    }
    const Index n = Index(rest.size());
    t.mesh.rest_positions.resize(n, d);
    t.positions.resize(n, d);
    t.mesh.vertex_body.resize(n);
    for (Index v = 0; v < n; ++v) {
        t.mesh.rest_positions.row(v) = rest[size_t(v)].transpose();
        t.positions.row(v) = deformed[size_t(v)].transpose();
        t.mesh.vertex_body[v] = body[size_t(v)];
    }
    t.mesh.elements.resize(Index(elements.size()), d + 1);
    t.mesh.element_body.resize(Index(elements.size()));
    for (size_t e = 0; e < elements.size(); ++e) {
        for (int k = 0; k <= d; ++k)
            t.mesh.elements(Index(e), k) = elements[e][size_t(k)];
        t.mesh.element_body[Index(e)] = element_body[e];
    }
    compute_boundary(t.mesh);
    return t;
}

} // namespace diffipc
