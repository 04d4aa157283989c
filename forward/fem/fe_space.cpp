#include "forward/fem/fe_space.hpp"

#include "forward/kernels/element.hpp"
#include "forward/kernels/inversion_bound.hpp"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace diffipc {

FESpace::FESpace(const Mesh& mesh)
    : m_mesh(mesh)
    , m_dim(mesh.dim)
{
    const Index ne = mesh.num_elements();
    const int d = m_dim;
    const size_t per_element = size_t((d + 1) * d);
    m_volumes.resize(size_t(ne));
    m_gradients.resize(size_t(ne) * per_element);
    for (Index e = 0; e < ne; ++e) {
        double rest[4 * 3];
        for (int a = 0; a <= d; ++a)
            for (int i = 0; i < d; ++i)
                rest[a * d + i] = mesh.rest_positions(mesh.elements(e, a), i);
        double* G = m_gradients.data() + size_t(e) * per_element;
        if (d == 2)
            kernels::element_rest_data<2>(rest, G, m_volumes[size_t(e)]);
        else
            kernels::element_rest_data<3>(rest, G, m_volumes[size_t(e)]);
    }
}

void FESpace::deformation_gradient(Index e, const VectorXd& x, double* F) const
{
    const int d = m_dim;
    const double* G = shape_gradients(e);
    std::fill_n(F, d * d, 0.0);
    for (int a = 0; a <= d; ++a) {
        const Index v = m_mesh.elements(e, a);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                F[i * d + j] += x[v * d + i] * G[a * d + j];
    }
}

VectorXd FESpace::lumped_masses(const VectorXd& density) const
{
    VectorXd m = VectorXd::Zero(m_mesh.num_vertices());
    for (Index e = 0; e < num_elements(); ++e)
        for (int a = 0; a <= m_dim; ++a)
            m[m_mesh.elements(e, a)] += density[e] * m_volumes[size_t(e)] / (m_dim + 1);
    return m;
}

SparseMatrixd FESpace::consistent_mass(const VectorXd& density) const
{
    std::vector<Eigen::Triplet<double>> triplets;
    const int d = m_dim;
    for (Index e = 0; e < num_elements(); ++e) {
        const double base = density[e] * m_volumes[size_t(e)] / ((d + 1) * (d + 2));
        for (int a = 0; a <= d; ++a)
            for (int b = 0; b <= d; ++b)
                for (int c = 0; c < d; ++c)
                    triplets.emplace_back(
                        m_mesh.elements(e, a) * d + c, m_mesh.elements(e, b) * d + c, base * (a == b ? 2.0 : 1.0));
    }
    SparseMatrixd M(m_mesh.num_dofs(), m_mesh.num_dofs());
    M.setFromTriplets(triplets.begin(), triplets.end());
    return M;
}

double FESpace::min_volume_ratio(const VectorXd& x) const
{
    // In parallel: the minimum does not depend on the order, so the result is the serial loop's for
    // any thread count (a GPU step records it after every solve: at 200k tetrahedra the serial loop
    // was a visible share of the step).
    const Positions P = unflatten(x, m_dim);
    return tbb::parallel_reduce(
        tbb::blocked_range<Index>(0, num_elements(), 4096), std::numeric_limits<double>::infinity(),
        [&](const tbb::blocked_range<Index>& range, double r) {
            for (Index e = range.begin(); e < range.end(); ++e)
                r = std::min(r, signed_volume(P, m_mesh.elements, e) / m_volumes[size_t(e)]);
            return r;
        },
        [](double a, double b) { return std::min(a, b); });
}

namespace {

    /// Element e's vertex positions and step components, flattened vertex-major (the kernel's layout).
    void gather_element(const Mesh& mesh, Index e, const VectorXd& x, const VectorXd& p, double* xe, double* pe)
    {
        const int d = mesh.dim;
        for (int a = 0; a <= d; ++a)
            for (int i = 0; i < d; ++i) {
                const Index k = mesh.elements(e, a) * d + i;
                xe[a * d + i] = x[k];
                pe[a * d + i] = p[k];
            }
    }

} // namespace

Eigen::Vector4d volume_polynomial(const Mesh& mesh, Index e, const VectorXd& x, const VectorXd& p)
{
    double xe[12], pe[12], c[4];
    gather_element(mesh, e, x, p, xe, pe);
    if (mesh.dim == 2)
        kernels::volume_polynomial<2>(xe, pe, c);
    else
        kernels::volume_polynomial<3>(xe, pe, c);
    return Eigen::Vector4d(c[0], c[1], c[2], c[3]);
}

double inversion_free_step(const Mesh& mesh, const VectorXd& x, const VectorXd& p, double keep)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<Index>(0, mesh.num_elements(), 1024), 1.0,
        [&](const tbb::blocked_range<Index>& r, double t) {
            double xe[12], pe[12];
            for (Index e = r.begin(); e < r.end(); ++e) {
                gather_element(mesh, e, x, p, xe, pe);
                t = std::min(t,
                    mesh.dim == 2 ? kernels::element_step_bound<2>(xe, pe, keep)
                                  : kernels::element_step_bound<3>(xe, pe, keep));
                if (!(t > 0))
                    return 0.0; // an element already not positive: no step is admissible
            }
            return t;
        },
        [](double a, double b) { return std::min(a, b); });
}

} // namespace diffipc
