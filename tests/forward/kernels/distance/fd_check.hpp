#pragma once
// Finite-difference checks shared by the distance tests. A derivative is
// compared with central differences at several step sizes; the report keeps
// the whole table (step, relative error, observed order) so that a failure
// shows how the error behaves, not just that it is too large.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace diffipc::test {

template <int N> using Vec = Eigen::Matrix<double, N, 1>;
template <int N> using Mat = Eigen::Matrix<double, N, N>;

/// Central-difference gradient of a scalar function of N variables.
template <int N, class F> Vec<N> fd_gradient(const F& f, const Vec<N>& x, double h)
{
    Vec<N> g;
    for (int i = 0; i < N; ++i) {
        Vec<N> xp = x, xm = x;
        xp[i] += h;
        xm[i] -= h;
        g[i] = (f(xp) - f(xm)) / (2 * h);
    }
    return g;
}

/// Central-difference Jacobian (M x N) of a vector function of N variables.
template <int M, int N, class G> Eigen::Matrix<double, M, N> fd_jacobian(const G& g, const Vec<N>& x, double h)
{
    Eigen::Matrix<double, M, N> J;
    for (int i = 0; i < N; ++i) {
        Vec<N> xp = x, xm = x;
        xp[i] += h;
        xm[i] -= h;
        J.col(i) = (g(xp) - g(xm)) / (2 * h);
    }
    return J;
}

struct FdReport {
    std::vector<double> steps;
    std::vector<double> errors; ///< max-norm error relative to max(|exact|_max, floor)
    double best = std::numeric_limits<double>::infinity();

    std::string table() const
    {
        std::string s = "      step       rel.error   order\n";
        char line[128];
        for (size_t i = 0; i < steps.size(); ++i) {
            const double order
                = i == 0 ? NAN : std::log10(errors[i - 1] / errors[i]) / std::log10(steps[i - 1] / steps[i]);
            std::snprintf(line, sizeof(line), "  %10.3e  %10.3e  %6.2f\n", steps[i], errors[i], order);
            s += line;
        }
        return s;
    }

    /// True if some pair of consecutive steps whose larger-step error is
    /// still dominated by truncation (above `truncation_floor`) shows an
    /// observed order in [1.7, 2.3], or if the error is at round-off level
    /// from the largest step on (the function is locally quadratic).
    bool second_order(double truncation_floor = 1e-8) const
    {
        if (errors.front() <= truncation_floor)
            return true;
        for (size_t i = 1; i < steps.size(); ++i) {
            if (errors[i - 1] <= truncation_floor)
                break;
            const double order = std::log10(errors[i - 1] / errors[i]) / std::log10(steps[i - 1] / steps[i]);
            if (order >= 1.7 && order <= 2.3)
                return true;
        }
        return false;
    }
};

/// Compare `exact` with `fd_at(h)` for each step h; errors are relative to
/// max(|exact|_max, floor) (floor > 0 keeps an exactly zero derivative testable).
template <class Exact, class FdAt>
FdReport compare_fd(const Exact& exact, const FdAt& fd_at, const std::vector<double>& steps, double floor)
{
    FdReport r;
    const double scale = std::max(exact.cwiseAbs().maxCoeff(), floor);
    for (double h : steps) {
        const auto fd = fd_at(h);
        double err = (fd - exact).cwiseAbs().maxCoeff() / scale;
        if (!std::isfinite(err))
            err = std::numeric_limits<double>::infinity();
        r.steps.push_back(h);
        r.errors.push_back(err);
        r.best = std::min(r.best, err);
    }
    return r;
}

/// Steps 1e-2 .. 1e-7 times `scale` (the length over which the function varies).
inline std::vector<double> fd_steps(double scale = 1)
{
    std::vector<double> s;
    for (double h = 1e-2; h > 0.5e-7; h /= 10)
        s.push_back(h * scale);
    return s;
}

struct FdOptions {
    double gradient_tolerance = 1e-7; ///< on the best relative error over the steps
    double hessian_tolerance = 1e-7;
    bool check_order = true; ///< also require an observed order near 2
    double step_scale = 1; ///< steps are fd_steps(step_scale)
    double floor = 1e-300; ///< see compare_fd
};

/// Check gradient g (by differencing f) and Hessian H (by differencing g) at
/// x; also that both are finite and H is symmetric. `what` labels failures.
template <int N, class F, class G, class H>
void expect_derivatives(
    const F& f, const G& g, const H& hess, const Vec<N>& x, const FdOptions& opt, const std::string& what)
{
    SCOPED_TRACE(what);
    const double value = f(x);
    const Vec<N> grad = g(x);
    const Mat<N> hessian = hess(x);
    ASSERT_TRUE(std::isfinite(value));
    ASSERT_TRUE(grad.allFinite()) << grad.transpose();
    ASSERT_TRUE(hessian.allFinite()) << hessian;
    const double hnorm = std::max(hessian.cwiseAbs().maxCoeff(), opt.floor);
    EXPECT_LE((hessian - hessian.transpose()).cwiseAbs().maxCoeff(), 1e-12 * hnorm) << "Hessian not symmetric";

    const std::vector<double> steps = fd_steps(opt.step_scale);
    const FdReport rg = compare_fd(
        grad, [&](double h) { return fd_gradient<N>(f, x, h); }, steps, opt.floor);
    EXPECT_LE(rg.best, opt.gradient_tolerance) << "gradient vs central differences of the value\n" << rg.table();
    const FdReport rh = compare_fd(
        hessian, [&](double h) { return fd_jacobian<N, N>(g, x, h); }, steps, opt.floor);
    EXPECT_LE(rh.best, opt.hessian_tolerance) << "Hessian vs central differences of the gradient\n" << rh.table();
    if (opt.check_order) {
        EXPECT_TRUE(rg.second_order()) << "gradient: no O(h^2) convergence\n" << rg.table();
        EXPECT_TRUE(rh.second_order()) << "Hessian: no O(h^2) convergence\n" << rh.table();
    }
}

/// Uniform random points in [-1, 1]^3 from a seeded generator.
class RandomPoints {
public:
    explicit RandomPoints(unsigned seed)
        : m_rng(seed)
    {
    }
    Eigen::Vector3d operator()() { return Eigen::Vector3d(m_u(m_rng), m_u(m_rng), m_u(m_rng)); }
    double uniform(double lo, double hi) { return lo + (hi - lo) * (m_u(m_rng) + 1) / 2; }
    /// A random unit vector.
    Eigen::Vector3d direction()
    {
        Eigen::Vector3d v;
        do
            v = (*this)();
        while (v.squaredNorm() < 1e-2 || v.squaredNorm() > 1);
        return v.normalized();
    }
    /// A random rotation (from a normalized random quaternion).
    Eigen::Matrix3d rotation()
    {
        const Eigen::Vector3d v = (*this)();
        return Eigen::Quaterniond(uniform(-1, 1), v.x(), v.y(), v.z()).normalized().toRotationMatrix();
    }

private:
    std::mt19937 m_rng;
    std::uniform_real_distribution<double> m_u { -1.0, 1.0 };
};

/// Stack points into one vertex-major vector and back.
template <class... P> Vec<3 * sizeof...(P)> stack(const P&... p)
{
    Vec<3 * sizeof...(P)> x;
    int i = 0;
    ((x.template segment<3>(3 * i++) = p), ...);
    return x;
}

template <int N> Eigen::Vector3d vertex(const Vec<N>& x, int i) { return x.template segment<3>(3 * i); }

} // namespace diffipc::test
