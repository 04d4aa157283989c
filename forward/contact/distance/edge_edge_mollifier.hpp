#pragma once
/// @file edge_edge_mollifier.hpp
/// The edge-edge mollifier of IPC (Li et al. 2020, "Incremental Potential
/// Contact", the mollified edge-edge barrier): the barrier of an edge-edge
/// pair is multiplied by m(x), which vanishes as the edges become parallel.
/// There the edge-edge distance is not smooth (the closest points jump
/// along the edges and the line-line derivatives blow up like
/// 1/angle^2); the product m * b stays C1.
///
/// \f[ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2, \qquad
///     \epsilon_x = 10^{-3} |\bar e_{a1} - \bar e_{a0}|^2 |\bar e_{b1} - \bar e_{b0}|^2, \f]
/// \f[ m(x) = (2 - s)\, s \quad \text{for } s = x / \epsilon_x < 1, \qquad m(x) = 1 \text{ otherwise,} \f]
/// where the bars denote REST positions: eps_x is a constant of the pair
/// during a simulation, but a function of the rest shape in shape
/// optimization, hence the derivatives with respect to eps_x below.
///
/// Vectors are vertex-major over (ea0, ea1, eb0, eb1), xyz per vertex.
/// m is C1 (not C2) at x = eps_x: m'' jumps from -2/eps_x^2 to 0.
/// eps_x <= 0 (a degenerate rest edge) gives m = 1 and zero derivatives.

#include <Eigen/Core>

namespace diffipc {

/// @brief \f$ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2 \f$, the mollifier's argument.
/// @param ea0, ea1  3 end points of edge a, m
/// @param eb0, eb1  3 end points of edge b, m
/// @return x, m^4
double edge_edge_cross_squarednorm(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Gradient of edge_edge_cross_squarednorm.
/// @return 12 vector (d/dea0, d/dea1, d/deb0, d/deb1), m^3
Eigen::Matrix<double, 12, 1> edge_edge_cross_squarednorm_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Hessian of edge_edge_cross_squarednorm.
/// @return 12 x 12, rows and columns ordered (ea0, ea1, eb0, eb1), m^2
Eigen::Matrix<double, 12, 12> edge_edge_cross_squarednorm_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Mollifier threshold \f$ \epsilon_x = 10^{-3} |\bar e_{a1} - \bar e_{a0}|^2 |\bar e_{b1} - \bar e_{b0}|^2 \f$.
/// @param ea0_rest, ea1_rest  3 REST end points of edge a, m
/// @param eb0_rest, eb1_rest  3 REST end points of edge b, m
/// @return eps_x, m^4
double edge_edge_mollifier_threshold(const Eigen::Vector3d& ea0_rest, const Eigen::Vector3d& ea1_rest,
    const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest);

/// @brief Gradient of edge_edge_mollifier_threshold with respect to the rest
/// positions (for shape derivatives), e.g.
/// \f$ \partial \epsilon_x / \partial \bar e_{a1} = 2 \cdot 10^{-3} |\bar e_b|^2 \bar e_a \f$
/// with \f$ \bar e_a = \bar e_{a1} - \bar e_{a0} \f$.
/// @param ea0_rest, ea1_rest, eb0_rest, eb1_rest  as in edge_edge_mollifier_threshold
/// @return 12 vector (d/dea0_rest, d/dea1_rest, d/deb0_rest, d/deb1_rest), m^3
Eigen::Matrix<double, 12, 1> edge_edge_mollifier_threshold_gradient(const Eigen::Vector3d& ea0_rest,
    const Eigen::Vector3d& ea1_rest, const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest);

/// @brief Scalar mollifier m(x).
/// @param x      cross squared norm, m^4 (>= 0)
/// @param eps_x  threshold, m^4
/// @return m in [0, 1], dimensionless
double edge_edge_mollifier(double x, double eps_x);

/// @brief dm/dx \f$ = 2 (1 - x/\epsilon_x) / \epsilon_x \f$ for x < eps_x, else 0.
/// @return m^-4
double edge_edge_mollifier_gradient(double x, double eps_x);

/// @brief d^2m/dx^2 \f$ = -2 / \epsilon_x^2 \f$ for x < eps_x, else 0.
/// @return m^-8
double edge_edge_mollifier_hessian(double x, double eps_x);

/// @brief dm/d eps_x \f$ = -2 (x/\epsilon_x)(1 - x/\epsilon_x) / \epsilon_x \f$ for x < eps_x, else 0.
/// Never positive: a larger threshold mollifies more.
/// @return m^-4
double edge_edge_mollifier_gradient_wrt_eps_x(double x, double eps_x);

/// @brief d^2m/(dx d eps_x) \f$ = 2 (2 x/\epsilon_x - 1) / \epsilon_x^2 \f$ for x < eps_x, else 0.
/// @return m^-8
double edge_edge_mollifier_gradient_jacobian_wrt_eps_x(double x, double eps_x);

/// @brief Mollifier of the edge pair at its current positions, m(x(ea0, ea1, eb0, eb1)).
/// @param ea0, ea1  3 current end points of edge a, m
/// @param eb0, eb1  3 current end points of edge b, m
/// @param eps_x     threshold from edge_edge_mollifier_threshold at the rest positions, m^4
/// @return m in [0, 1], dimensionless
double edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, double eps_x);

/// @brief Gradient of the mollifier with respect to the current positions, \f$ m'(x) \nabla x \f$.
/// @param ea0, ea1, eb0, eb1, eps_x  as in edge_edge_mollifier
/// @return 12 vector, m^-1
Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x);

/// @brief Hessian of the mollifier with respect to the current positions,
/// \f$ m''(x) \nabla x \nabla x^T + m'(x) \nabla^2 x \f$.
/// @param ea0, ea1, eb0, eb1, eps_x  as in edge_edge_mollifier
/// @return 12 x 12, m^-2
Eigen::Matrix<double, 12, 12> edge_edge_mollifier_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x);

/// @brief dm/d eps_x at the current positions (see the scalar overload). Chain with
/// edge_edge_mollifier_threshold_gradient for the shape derivative of m.
/// @param ea0, ea1, eb0, eb1, eps_x  as in edge_edge_mollifier
/// @return m^-4
double edge_edge_mollifier_gradient_wrt_eps_x(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x);

/// @brief Derivative of the position gradient with respect to eps_x,
/// \f$ \partial^2 m / (\partial x \partial \epsilon_x) \nabla x \f$.
/// @param ea0, ea1, eb0, eb1, eps_x  as in edge_edge_mollifier
/// @return 12 vector, m^-5
Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient_jacobian_wrt_eps_x(const Eigen::Vector3d& ea0,
    const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x);

} // namespace diffipc
