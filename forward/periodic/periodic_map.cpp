#include "forward/periodic/periodic_map.hpp"

#include <Eigen/SparseCore>

#include <stdexcept>
#include <vector>

namespace diffipc {

PeriodicMap::PeriodicMap(const Mesh& mesh, const PeriodicPairing& pairing, const VectorXd& origin, double length)
    : m_dim(mesh.dim)
    , m_classes(pairing.num_classes())
    , m_rest(mesh.num_dofs())
    , m_origin(origin.size() ? origin : VectorXd::Zero(mesh.dim))
    , m_length(length)
{
    if (m_origin.size() != mesh.dim || !(length > 0))
        throw std::invalid_argument("PeriodicMap: the origin needs " + std::to_string(mesh.dim)
            + " coordinates and the length must be positive");
    const int d = m_dim;
    const Index nv = mesh.num_vertices();
    if (pairing.vertex_class.size() != nv)
        throw std::invalid_argument("PeriodicMap: the pairing has " + std::to_string(pairing.vertex_class.size())
            + " vertices, the mesh " + std::to_string(nv));
    std::vector<Eigen::Triplet<double, int>> entries;
    entries.reserve(size_t(nv) * size_t(d) * size_t(d + 1));
    for (Index v = 0; v < nv; ++v)
        for (int i = 0; i < d; ++i) {
            const int row = int(v * d + i);
            m_rest[row] = mesh.rest_positions(v, i);
            entries.emplace_back(row, int(fluctuation_dof(pairing.vertex_class[v], i)), 1.0);
            for (int j = 0; j < d; ++j) {
                const double lever = (mesh.rest_positions(v, j) - m_origin[j]) / m_length;
                if (lever != 0)
                    entries.emplace_back(row, int(macro_dof(i, j)), lever);
            }
        }
    m_representative = pairing.representative;
    m_P.resize(nv * d, num_reduced());
    m_P.setFromTriplets(entries.begin(), entries.end());
}

VectorXd PeriodicMap::positions(const VectorXd& q) const
{
    if (q.size() != num_reduced())
        throw std::invalid_argument("PeriodicMap::positions: expected " + std::to_string(num_reduced()) + " values");
    return m_rest + m_P * q;
}

VectorXd PeriodicMap::reduced(const VectorXd& x, const VectorXd& G) const
{
    const int d = m_dim;
    if (x.size() != m_rest.size() || G.size() != d * d)
        throw std::invalid_argument("PeriodicMap::reduced: expected " + std::to_string(m_rest.size())
            + " positions and " + std::to_string(d * d) + " gradient values");
    VectorXd q(num_reduced());
    q.tail(d * d) = m_length * G;
    for (Index c = 0; c < m_classes; ++c) {
        const Index r = m_representative[c];
        for (int i = 0; i < d; ++i) {
            double affine = m_rest[r * d + i];
            for (int j = 0; j < d; ++j)
                affine += G[i * d + j] * (m_rest[r * d + j] - m_origin[j]);
            q[fluctuation_dof(c, i)] = x[r * d + i] - affine;
        }
    }
    return q;
}

SparseMatrixd PeriodicMap::reduce_matrix(const SparseMatrixd& lower) const
{
    const SparseMatrixd full = lower.selfadjointView<Eigen::Lower>();
    const SparseMatrixd reduced = m_P.transpose() * full * m_P;
    return reduced.triangularView<Eigen::Lower>();
}

} // namespace diffipc
