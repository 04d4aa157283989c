#pragma once
/// @file distance_kernels.hpp
/// Internal to forward/contact/distance: the rational functions behind every
/// squared distance, written in difference vectors (r = p - e0, a = t1 - t0,
/// ...), where their derivatives are short, plus the maps that carry those
/// derivatives back to vertex-major coordinates. Not part of the public API;
/// include distance.hpp instead.
///
/// Why difference vectors: every distance is translation invariant, so its
/// vertex derivatives are a fixed +-1 combination of the derivatives in 2 or
/// 3 edge vectors. Differentiating in the edge vectors keeps the closed forms
/// small (the cross products stay intact, which also keeps them accurate when
/// the distance is tiny) and the pull-back is a handful of 3x3 block copies.

#include <Eigen/Core>

#include <array>

namespace diffipc::distance_kernels {

/// 3K stacked difference vectors.
template <int K> using Vector = Eigen::Matrix<double, 3 * K, 1>;
template <int K> using Matrix = Eigen::Matrix<double, 3 * K, 3 * K>;

/// @brief \f$ |a \times b|^2 \f$ with gradient and Hessian in the stacked (a, b).
/// @param grad 6, or nullptr; @param hess 6 x 6, or nullptr
double cross_squarednorm(const Eigen::Vector3d& a, const Eigen::Vector3d& b, Vector<2>* grad, Matrix<2>* hess);

/// @brief \f$ |r \times e|^2 / |e|^2 \f$ (squared distance of the point r from the
/// line through the origin along e) with derivatives in the stacked (r, e).
/// Requires e != 0.
double point_line(const Eigen::Vector3d& r, const Eigen::Vector3d& e, Vector<2>* grad, Matrix<2>* hess);

/// @brief \f$ (r \cdot (a \times b))^2 / |a \times b|^2 \f$ (squared distance of the
/// point r from the plane through the origin spanned by a, b) with
/// derivatives in the stacked (r, a, b).
/// Point-plane and line-line distances are both this function. Requires a x b != 0.
double point_plane(
    const Eigen::Vector3d& r, const Eigen::Vector3d& a, const Eigen::Vector3d& b, Vector<3>* grad, Matrix<3>* hess);

/// @brief Chain rule for kernel variables that share one vertex,
/// x_k = X[plus[k]] - X[minus] (k < K, K + 1 vertices X): the 3(K+1) gradient.
template <int K>
Eigen::Matrix<double, 3 * (K + 1), 1> pull_back_gradient(const Vector<K>& g, const std::array<int, K>& plus, int minus)
{
    Eigen::Matrix<double, 3 * (K + 1), 1> out;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < K; ++k) {
        out.template segment<3>(3 * plus[k]) = g.template segment<3>(3 * k);
        sum += g.template segment<3>(3 * k);
    }
    out.template segment<3>(3 * minus) = -sum;
    return out;
}

/// @brief Chain rule for kernel variables that share one vertex (see
/// pull_back_gradient): the 3(K+1) x 3(K+1) Hessian J^T H J. Every output
/// block is written once, which measured 2-3x faster than accumulating
/// +-H blocks into a zeroed matrix (this runs for every contact).
template <int K>
Eigen::Matrix<double, 3 * (K + 1), 3 * (K + 1)> pull_back_hessian(
    const Matrix<K>& H, const std::array<int, K>& plus, int minus)
{
    Eigen::Matrix<double, 3 * (K + 1), 3 * (K + 1)> out;
    Eigen::Matrix<double, 3 * K, 3> row_sums = Eigen::Matrix<double, 3 * K, 3>::Zero();
    for (int l = 0; l < K; ++l)
        row_sums += H.template middleCols<3>(3 * l);
    Eigen::Matrix3d total = Eigen::Matrix3d::Zero();
    for (int k = 0; k < K; ++k) {
        for (int l = 0; l < K; ++l)
            out.template block<3, 3>(3 * plus[k], 3 * plus[l]) = H.template block<3, 3>(3 * k, 3 * l);
        const Eigen::Matrix3d S = row_sums.template middleRows<3>(3 * k);
        out.template block<3, 3>(3 * plus[k], 3 * minus) = -S;
        out.template block<3, 3>(3 * minus, 3 * plus[k]) = -S.transpose();
        total += S;
    }
    out.template block<3, 3>(3 * minus, 3 * minus) = total;
    return out;
}

/// @brief Place the 3L gradient of a sub-distance on L of the V vertices (ids), zeros elsewhere.
template <int V, int L>
Eigen::Matrix<double, 3 * V, 1> scatter_gradient(
    const Eigen::Matrix<double, 3 * L, 1>& g, const std::array<int, L>& ids)
{
    Eigen::Matrix<double, 3 * V, 1> out = Eigen::Matrix<double, 3 * V, 1>::Zero();
    for (int i = 0; i < L; ++i)
        out.template segment<3>(3 * ids[i]) = g.template segment<3>(3 * i);
    return out;
}

/// @brief Place the 3L x 3L Hessian of a sub-distance on L of the V vertices (ids), zeros elsewhere.
template <int V, int L>
Eigen::Matrix<double, 3 * V, 3 * V> scatter_hessian(
    const Eigen::Matrix<double, 3 * L, 3 * L>& H, const std::array<int, L>& ids)
{
    Eigen::Matrix<double, 3 * V, 3 * V> out = Eigen::Matrix<double, 3 * V, 3 * V>::Zero();
    for (int i = 0; i < L; ++i)
        for (int j = 0; j < L; ++j)
            out.template block<3, 3>(3 * ids[i], 3 * ids[j]) = H.template block<3, 3>(3 * i, 3 * j);
    return out;
}

} // namespace diffipc::distance_kernels
