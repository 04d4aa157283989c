#include "forward/potentials/inertia_potential.hpp"

#include "forward/solver/sparse_assembler.hpp"

namespace diffipc {

InertiaPotential::InertiaPotential(const FESpace& space, const VectorXd& density, bool consistent)
    : m_space(space)
    , m_consistent(consistent)
    , m_lumped(space.lumped_masses(density))
    , m_density(density)
{
    if (consistent)
        m_matrix = space.consistent_mass(density);
    m_target = flatten(space.mesh().rest_positions);
}

VectorXd InertiaPotential::apply_mass(const VectorXd& v) const
{
    if (m_consistent)
        return m_matrix * v;
    const int d = m_space.dim();
    VectorXd out(v.size());
    for (Index i = 0; i < v.size(); ++i)
        out[i] = m_lumped[i / d] * v[i];
    return out;
}

double InertiaPotential::value(const VectorXd& x) const
{
    const VectorXd dx = x - m_target;
    return 0.5 * dx.dot(apply_mass(dx));
}

void InertiaPotential::add_gradient(const VectorXd& x, double weight, VectorXd& g) const
{
    g += weight * apply_mass(x - m_target);
}

void InertiaPotential::add_hessian(const VectorXd&, double weight, bool, SparseAssembler& H) const
{
    const int d = m_space.dim();
    if (!m_consistent) {
        for (Index i = 0; i < H.size(); ++i)
            H.add_diagonal(i, weight * m_lumped[i / d]);
        return;
    }
    const int L = d * (d + 1);
    Eigen::MatrixXd Me(L, L);
    for (Index e = 0; e < m_space.num_elements(); ++e) {
        const double base = weight * m_density[e] * m_space.rest_volume(e) / ((d + 1) * (d + 2));
        Me.setZero();
        for (int a = 0; a <= d; ++a)
            for (int b = 0; b <= d; ++b)
                for (int c = 0; c < d; ++c)
                    Me(a * d + c, b * d + c) = base * (a == b ? 2.0 : 1.0);
        H.add_element(e, Me.data());
    }
}

} // namespace diffipc
