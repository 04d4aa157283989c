#pragma once
/// @file element_kinematics.hpp
/// Fixed-size P1 element helpers shared by the objectives' .cpp files (include
/// it from .cpp files only: it instantiates Eigen templates).
///
/// With G the (dim+1) by dim shape-function gradients of element e (rows G_a =
/// dN_a/dX), F = \sum_a x_a G_a^T. For a quantity q(F, |e|):
///   dq/dx_a = (dq/dF) G_a,
///   dq/dX_a = (-F^T (dq/dF) + |e| (dq/d|e|) I) G_a,
/// because dF = -F dD_m D_m^{-1} and d|e| = |e| tr(D_m^{-1} dD_m) with
/// D_m = [X_1 - X_0, ..., X_d - X_0] (elements are positively oriented), and the
/// columns of D_m^{-T} are G_1..G_d (G_0 = -\sum_{a>0} G_a).

#include "forward/fem/fe_space.hpp"
#include "forward/materials/material.hpp"

#include <Eigen/Dense>

namespace diffipc::detail {

template <int dim> using Mat = Eigen::Matrix<double, dim, dim>;
template <int dim> using ShapeGradients = Eigen::Matrix<double, dim + 1, dim, Eigen::RowMajor>;

template <int dim> ShapeGradients<dim> shape_gradients(const FESpace& space, Index e)
{
    return Eigen::Map<const ShapeGradients<dim>>(space.shape_gradients(e));
}

/// F = \sum_a x_a G_a^T for flattened positions x.
template <int dim>
Mat<dim> deformation_gradient(const Mesh& mesh, const ShapeGradients<dim>& G, Index e, const VectorXd& x)
{
    Mat<dim> F = Mat<dim>::Zero();
    for (int a = 0; a <= dim; ++a)
        F += x.template segment<dim>(mesh.elements(e, a) * dim) * G.row(a);
    return F;
}

/// g_a += scale * B G_a for the vertices a of element e (B = dq/dF).
template <int dim>
void scatter_positions(
    const Mesh& mesh, const ShapeGradients<dim>& G, Index e, const Mat<dim>& B, double scale, VectorXd& g)
{
    for (int a = 0; a <= dim; ++a)
        g.template segment<dim>(mesh.elements(e, a) * dim) += scale * (B * G.row(a).transpose());
}

/// g_a += scale * (-F^T B + volume_term I) G_a: the rest-position derivative of
/// q(F(x, X), |e|(X)) with B = dq/dF and volume_term = |e| dq/d|e|.
template <int dim>
void scatter_rest_positions(const Mesh& mesh, const ShapeGradients<dim>& G, Index e, const Mat<dim>& F,
    const Mat<dim>& B, double volume_term, double scale, VectorXd& g)
{
    Mat<dim> C = -F.transpose() * B;
    C.diagonal().array() += volume_term;
    for (int a = 0; a <= dim; ++a)
        g.template segment<dim>(mesh.elements(e, a) * dim) += scale * (C * G.row(a).transpose());
}

/// Row-major flattening of a dim by dim matrix (material.hpp's convention).
template <int dim> Eigen::Matrix<double, dim * dim, 1> flatten_row_major(const Mat<dim>& A)
{
    Eigen::Matrix<double, dim * dim, 1> v;
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j)
            v[i * dim + j] = A(i, j);
    return v;
}

template <int dim> Mat<dim> unflatten_row_major(const Eigen::Matrix<double, dim * dim, 1>& v)
{
    Mat<dim> A;
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j)
            A(i, j) = v[i * dim + j];
    return A;
}

/// Cofactor matrix cof F = det(F) F^{-T}, written out so that it holds for singular F.
template <int dim> Mat<dim> cofactor(const Mat<dim>& F)
{
    Mat<dim> C;
    if constexpr (dim == 2) {
        C << F(1, 1), -F(1, 0), -F(0, 1), F(0, 0);
    } else {
        C.col(0) = F.col(1).cross(F.col(2));
        C.col(1) = F.col(2).cross(F.col(0));
        C.col(2) = F.col(0).cross(F.col(1));
    }
    return C;
}

} // namespace diffipc::detail
