#pragma once
/// @file types.hpp
/// Eigen aliases shared by every module. Positions are stored two ways:
/// as #V by dim matrices (row per vertex) and flattened vertex-major (xyzxyz).

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace diffipc {

using Index = Eigen::Index;
using VectorXd = Eigen::VectorXd;
using VectorXi = Eigen::VectorXi;
using MatrixXd = Eigen::MatrixXd;
using MatrixXi = Eigen::Matrix<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
/// #V by dim, row per vertex.
using Positions = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using SparseMatrixd = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

/// Flattened vertex-major view of a row-major #V by dim matrix.
inline Eigen::Map<const VectorXd> flatten(const Positions& P) { return Eigen::Map<const VectorXd>(P.data(), P.size()); }
inline Eigen::Map<VectorXd> flatten(Positions& P) { return Eigen::Map<VectorXd>(P.data(), P.size()); }

/// Reshape a flattened vertex-major vector into #V by dim.
inline Positions unflatten(const VectorXd& x, int dim)
{
    return Eigen::Map<const Positions>(x.data(), x.size() / dim, dim);
}

} // namespace diffipc
