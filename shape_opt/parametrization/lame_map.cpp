#include "shape_opt/parametrization/lame_map.hpp"

#include "forward/common/error.hpp"

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
        y[i] = E / (2 * (1 + nu));
        y[m_count + i]
            = m_plane == ElasticityPlane::STRESS ? E * nu / (1 - nu * nu) : E * nu / ((1 + nu) * (1 - 2 * nu));
    }
    return y;
}

VectorXd LameMap::vjp(const VectorXd& x, const VectorXd& y_bar) const
{
    check_size(x, in_size(), "design", "lame");
    check_size(y_bar, out_size(), "design", "lame's gradient");
    VectorXd x_bar(in_size());
    for (Index i = 0; i < m_count; ++i) {
        const double E = x[i], nu = x[m_count + i];
        const double mu_E = 1 / (2 * (1 + nu)), mu_nu = -E / (2 * (1 + nu) * (1 + nu));
        double lambda_E, lambda_nu;
        if (m_plane == ElasticityPlane::STRESS) {
            const double D = 1 - nu * nu;
            lambda_E = nu / D;
            lambda_nu = E * (1 + nu * nu) / (D * D);
        } else {
            const double D = (1 + nu) * (1 - 2 * nu); // d(nu / D)/dnu = (1 + 2 nu^2) / D^2
            lambda_E = nu / D;
            lambda_nu = E * (1 + 2 * nu * nu) / (D * D);
        }
        x_bar[i] = mu_E * y_bar[i] + lambda_E * y_bar[m_count + i];
        x_bar[m_count + i] = mu_nu * y_bar[i] + lambda_nu * y_bar[m_count + i];
    }
    return x_bar;
}

VectorXd LameMap::inverse(const VectorXd& y, const std::string& field) const
{
    check_size(y, out_size(), field, "lame");
    VectorXd x(in_size());
    for (Index i = 0; i < m_count; ++i) {
        const double mu = y[i], lambda = y[m_count + i];
        if (!(mu > 0))
            throw InputError(field, "pair " + std::to_string(i) + " has mu = " + format_number(mu) + ": needs mu > 0");
        double E, nu;
        if (m_plane == ElasticityPlane::STRESS) {
            nu = lambda / (2 * mu + lambda);
            E = 2 * mu * (1 + nu);
        } else {
            E = mu * (3 * lambda + 2 * mu) / (lambda + mu);
            nu = lambda / (2 * (lambda + mu));
        }
        check_pair(E, nu, i, field);
        x[i] = E;
        x[m_count + i] = nu;
    }
    return x;
}

} // namespace diffipc
