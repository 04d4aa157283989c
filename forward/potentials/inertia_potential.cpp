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

namespace {

    /// d/d(rho_e |e|) of direction^T M_e (x - x~) for element e: lumped mass gives
    /// sum_a direction_a . delta_a / (d+1), consistent mass
    /// sum_ab (1 + delta_ab) direction_a . delta_b / ((d+1)(d+2)).
    double element_mass_sensitivity(
        const Mesh& mesh, Index e, const VectorXd& dir, const VectorXd& delta, bool consistent)
    {
        const int d = mesh.dim;
        double s = 0;
        if (!consistent) {
            for (int a = 0; a <= d; ++a) {
                const Index v = mesh.elements(e, a);
                s += dir.segment(v * d, d).dot(delta.segment(v * d, d));
            }
            return s / (d + 1);
        }
        for (int a = 0; a <= d; ++a)
            for (int b = 0; b <= d; ++b) {
                const Index va = mesh.elements(e, a), vb = mesh.elements(e, b);
                s += (a == b ? 2.0 : 1.0) * dir.segment(va * d, d).dot(delta.segment(vb * d, d));
            }
        return s / ((d + 1) * (d + 2));
    }

} // namespace

void InertiaPotential::add_mass_derivatives(const VectorXd& direction, const VectorXd& delta, double weight,
    VectorXd* d_rest_positions, VectorXd* d_density) const
{
    const Mesh& mesh = m_space.mesh();
    const int d = mesh.dim;
    for (Index e = 0; e < m_space.num_elements(); ++e) {
        const double s = weight * element_mass_sensitivity(mesh, e, direction, delta, m_consistent);
        if (s == 0)
            continue;
        if (d_density)
            (*d_density)[e] += m_space.rest_volume(e) * s;
        if (d_rest_positions) {
            // d|e|/dX_a = |e| G_a
            const double c = m_density[e] * s * m_space.rest_volume(e);
            const double* G = m_space.shape_gradients(e);
            for (int a = 0; a <= d; ++a)
                for (int j = 0; j < d; ++j)
                    (*d_rest_positions)[mesh.elements(e, a) * d + j] += c * G[a * d + j];
        }
    }
}

void InertiaPotential::add_shape_derivative(
    const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const
{
    add_mass_derivatives(direction, x - m_target, weight, &d_rest_positions, nullptr);
}

void InertiaPotential::add_density_derivative(
    const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_density) const
{
    add_mass_derivatives(direction, x - m_target, weight, nullptr, &d_density);
}

} // namespace diffipc
