#include "forward/periodic/periodic_potential.hpp"

namespace diffipc {

void PeriodicPotential::add_gradient(const VectorXd& q, double weight, VectorXd& g) const
{
    VectorXd full;
    m_full.gradient(m_map.positions(q), full);
    g += weight * m_map.reduce(full);
}

void PeriodicPotential::add_hessian(const VectorXd& q, double weight, bool project_to_psd, SparseAssembler& H) const
{
    // P^T A P is positive semi-definite where A is: the projected full Hessian stays a search matrix.
    m_full.hessian(m_map.positions(q), project_to_psd, m_assembler);
    H.add_matrix(weight * m_map.reduce_matrix(m_assembler.matrix()));
}

MatrixXi periodic_elements(const Mesh& mesh, const PeriodicPairing& pairing)
{
    const int d = mesh.dim, nv = d + 1;
    const int classes = int(pairing.num_classes());
    MatrixXi e(mesh.num_elements(), nv + d);
    for (Index k = 0; k < mesh.num_elements(); ++k) {
        for (int a = 0; a < nv; ++a)
            e(k, a) = pairing.vertex_class[mesh.elements(k, a)];
        for (int i = 0; i < d; ++i)
            e(k, nv + i) = classes + i;
    }
    return e;
}

} // namespace diffipc
