#include "shape_opt/parametrization/lame_map.hpp"

#include "adjoint/sensitivity.hpp"
#include "forward/common/error.hpp"
#include "forward/materials/material.hpp"

namespace diffipc {

namespace {
    void check_pair(double E, double nu, Index i, const std::string& field)
    {
        if (!(E > 0) || !(nu > -1 && nu < 0.5))
            throw InputError(field,
                "pair " + std::to_string(i) + " has E = " + format_number(E) + ", nu = " + format_number(nu)
                    + ": needs E > 0 and nu in (-1, 0.5)");
    }
} // namespace

VectorXd LameMap::apply(const VectorXd& x) const
{
    check_size(x, in_size(), "design", "lame");
    VectorXd y(out_size());
    for (Index i = 0; i < m_count; ++i) {
        const double E = x[i], nu = x[m_count + i];
        check_pair(E, nu, i, "design");
        y[i] = lame_mu(E, nu);
        y[m_count + i] = lame_lambda(E, nu, m_plane == ElasticityPlane::STRESS);
    }
    return y;
}

VectorXd LameMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", "lame");
    check_size(y_bar, out_size(), "design", "lame's gradient");
    // The adjoint's own chain rule from (mu, lambda) to (E, nu), per element.
    VectorXd dE, dnu;
    lame_to_young_poisson(x.head(m_count), x.tail(m_count), y_bar.head(m_count), y_bar.tail(m_count), dE, dnu,
        std::vector<char>(size_t(m_count), m_plane == ElasticityPlane::STRESS ? 1 : 0));
    VectorXd x_bar(in_size());
    x_bar << dE, dnu;
    return x_bar;
}

VectorXd LameMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, out_size(), field, "lame");
    VectorXd x(in_size());
    const bool plane_stress = m_plane == ElasticityPlane::STRESS;
    for (Index i = 0; i < m_count; ++i) {
        const double mu = y[i], lambda = y[m_count + i];
        if (!(mu > 0))
            throw InputError(field, "pair " + std::to_string(i) + " has mu = " + format_number(mu) + ": needs mu > 0");
        const double E = youngs_modulus_of(mu, lambda, plane_stress), nu = poisson_ratio_of(mu, lambda, plane_stress);
        check_pair(E, nu, i, field);
        x[i] = E;
        x[m_count + i] = nu;
    }
    return x;
}

} // namespace diffipc
