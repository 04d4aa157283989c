#include "adjoint/sensitivity.hpp"

namespace diffipc {

void accumulate(VectorXd& block, const VectorXd& v, double scale)
{
    if (v.size() == 0)
        return;
    if (block.size() == 0)
        block = VectorXd::Zero(v.size());
    block += scale * v;
}

void accumulate(MatrixXd& block, const MatrixXd& v, double scale)
{
    if (v.size() == 0)
        return;
    if (block.size() == 0)
        block = MatrixXd::Zero(v.rows(), v.cols());
    block += scale * v;
}

void ParameterGradient::add(const ParameterGradient& other, double scale)
{
    accumulate(rest_positions, other.rest_positions, scale);
    accumulate(mu, other.mu, scale);
    accumulate(lambda, other.lambda, scale);
    accumulate(density, other.density, scale);
    accumulate(friction, other.friction, scale);
    accumulate(initial_displacement, other.initial_displacement, scale);
    accumulate(initial_velocity, other.initial_velocity, scale);
    accumulate(prescribed, other.prescribed, scale);
    accumulate(macro, other.macro, scale);
}

void lame_to_young_poisson(const VectorXd& E, const VectorXd& nu, const VectorXd& dmu, const VectorXd& dlambda,
    VectorXd& dE, VectorXd& dnu, const std::vector<char>& plane_stress)
{
    // mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu)).
    dE.resize(E.size());
    dnu.resize(E.size());
    for (Index e = 0; e < E.size(); ++e) {
        const double n = nu[e], a = 1 + n, b = 1 - 2 * n;
        const double dmu_dE = 1 / (2 * a), dmu_dnu = -E[e] / (2 * a * a);
        double dl_dE = n / (a * b);
        // d/dnu [nu / ((1 + nu)(1 - 2 nu))] = (1 + 2 nu^2) / ((1 + nu)^2 (1 - 2 nu)^2)
        double dl_dnu = E[e] * (1 + 2 * n * n) / (a * a * b * b);
        if (!plane_stress.empty() && plane_stress[size_t(e)]) {
            // lambda = E nu / (1 - nu^2): d/dnu [nu / (1 - nu^2)] = (1 + nu^2) / (1 - nu^2)^2
            const double c = 1 - n * n;
            dl_dE = n / c;
            dl_dnu = E[e] * (1 + n * n) / (c * c);
        }
        const double gm = dmu.size() ? dmu[e] : 0.0, gl = dlambda.size() ? dlambda[e] : 0.0;
        dE[e] = gm * dmu_dE + gl * dl_dE;
        dnu[e] = gm * dmu_dnu + gl * dl_dnu;
    }
}

std::vector<std::string> computed_blocks(const ParameterGradient& g)
{
    std::vector<std::string> out;
    const std::pair<const char*, bool> blocks[] = { { "rest_positions", g.rest_positions.size() > 0 },
        { "lame", g.mu.size() > 0 || g.lambda.size() > 0 }, { "density", g.density.size() > 0 },
        { "friction", g.friction.size() > 0 }, { "initial_displacement", g.initial_displacement.size() > 0 },
        { "initial_velocity", g.initial_velocity.size() > 0 }, { "prescribed", g.prescribed.size() > 0 },
        { "macro", g.macro.size() > 0 } };
    for (const auto& [name, held] : blocks)
        if (held)
            out.push_back(name);
    return out;
}

} // namespace diffipc
