#pragma once
/// @file lame_map.hpp
/// Young's modulus and Poisson's ratio to the Lame parameters (docs/parametrizations.md):
///
///   mu = E / (2 (1 + nu)),
///   lambda = E nu / ((1 + nu)(1 - 2 nu))   (3D, and 2D plane strain),
///   lambda = E nu / (1 - nu^2)             (2D plane stress: the in-plane lambda of a thin
///                                           sheet with zero normal stress),
///
/// per entry: the input is [E_1 .. E_n, nu_1 .. nu_n], the output [mu_1 .. mu_n,
/// lambda_1 .. lambda_n], the layout of the problem's "mu" and "lambda" parameters.

#include "shape_opt/parametrization/parameter_map.hpp"

namespace diffipc {

enum class ElasticityPlane { NONE, STRAIN, STRESS }; ///< NONE: 3D (the plane-strain formula)

class LameMap : public ParameterMap {
public:
    /// @param count n, the number of (E, nu) pairs
    LameMap(Index count, ElasticityPlane plane)
        : m_count(count)
        , m_plane(plane)
    {
    }
    Index in_size() const override { return 2 * m_count; }
    Index out_size() const override { return 2 * m_count; }
    /// @throws InputError ("design") for E <= 0 or nu outside (-1, 0.5)
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override { return true; }
    /// E = mu (3 lambda + 2 mu) / (lambda + mu), nu = lambda / (2 (lambda + mu)) (3D, plane strain);
    /// nu = lambda / (2 mu + lambda), E = 2 mu (1 + nu) (plane stress).
    /// @throws InputError naming `field` for mu <= 0 or a pair with no E > 0, nu in (-1, 0.5)
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "lame"; }

private:
    Index m_count;
    ElasticityPlane m_plane;
};

} // namespace diffipc
