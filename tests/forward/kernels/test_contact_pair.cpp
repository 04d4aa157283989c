// The contact pair kernel (forward/kernels/contact_pair.hpp), which the CPU's ContactPotential and the
// GPU's barrier both evaluate, directly: for every pair kind and both pair models (IPC's barrier and
// the penalty baseline), at random configurations inside the activation layer,
// - its gradient and Hessian against central differences of its energy and gradient, taken in long
//   double (the kernel is a template over the scalar type) with a step of 1e-6 times the pair's
//   distance, so that neither their truncation error nor their round-off comes near what is checked;
// - the long double instantiation against the double one, to the double's round-off (what dual
//   numbers will build on).

#include "forward/kernels/contact_pair.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

using namespace diffipc;
using kernels::ContactKind;
using kernels::Vec3;

namespace {

using Long = long double;

struct PairCase {
    ContactKind kind;
    int dim;
    std::vector<Vec3<double>> points;
    Vec3<double> normal;
    double eps_x = 0;
    double distance = 0; ///< the pair's distance d (m)
    kernels::PairModel model;
};

std::string name(ContactKind kind, int dim, bool penalty)
{
    const char* kinds[] = { "vertex-edge", "vertex-face", "edge-edge", "vertex-plane" };
    return std::string(kinds[int(kind)]) + " " + std::to_string(dim) + "D " + (penalty ? "penalty" : "barrier");
}

/// Random vertices of a pair of `kind` (z = 0 in 2D); for an edge-edge pair a mollifier threshold
/// that puts about half of the cases inside the mollified range. The model's dhat and dmin are
/// set from the pair's distance d so that the pair lies inside the activation layer:
/// dmin = 0.3 d (barrier) and dmin + dhat = 1.6 d.
PairCase random_case(ContactKind kind, int dim, bool penalty, std::mt19937& rng)
{
    std::uniform_real_distribution<double> u(-1, 1);
    PairCase c;
    c.kind = kind;
    c.dim = dim;
    const int nv = kernels::contact_num_vertices(kind);
    for (int i = 0; i < nv; ++i)
        c.points.emplace_back(u(rng), u(rng), dim == 3 ? u(rng) : 0.0);
    if (kind == ContactKind::VERTEX_PLANE) {
        Vec3<double> n(u(rng), u(rng), dim == 3 ? u(rng) : 0.0);
        c.normal = n / kernels::norm(n);
        // The vertex above the plane (h > 0).
        const double h = kernels::dot(c.points[0] - c.points[1], c.normal);
        if (h < 0)
            c.points[0] = c.points[0] - (2 * h) * c.normal;
    }
    if (kind == ContactKind::EDGE_EDGE) {
        const Vec3<double> a = c.points[1] - c.points[0], b = c.points[3] - c.points[2];
        const double cross2 = kernels::squared_norm(kernels::cross(a, b));
        c.eps_x = (u(rng) > 0 ? 2.0 : 0.5) * cross2; // mollified (cross2 < eps_x) or not
    }
    double s = 0, m = 1;
    kernels::pair_distance<double>(
        kind, c.points.data(), c.normal, c.eps_x, -1, s, m, nullptr, nullptr, nullptr, nullptr);
    const double d = std::sqrt(s);
    c.distance = d;
    const double dmin = penalty ? 0.0 : 0.3 * d;
    c.model = kernels::pair_model(penalty, 1.6 * d - dmin, dmin);
    return c;
}

template <class T> std::vector<Vec3<T>> points_as(const PairCase& c, const std::vector<Long>& x = {})
{
    std::vector<Vec3<T>> p;
    for (size_t i = 0; i < c.points.size(); ++i) {
        Vec3<T> v(T(c.points[i].x), T(c.points[i].y), T(c.points[i].z));
        if (!x.empty()) {
            v.x = T(x[i * size_t(c.dim)]);
            v.y = T(x[i * size_t(c.dim) + 1]);
            if (c.dim == 3)
                v.z = T(x[i * size_t(c.dim) + 2]);
        }
        p.push_back(v);
    }
    return p;
}

template <class T> T energy(const PairCase& c, const std::vector<Vec3<T>>& p, T* g, T* H)
{
    const Vec3<T> n(T(c.normal.x), T(c.normal.y), T(c.normal.z));
    return kernels::pair_energy<T>(c.kind, c.dim, p.data(), n, T(c.eps_x), -1, c.model, g, H);
}

double relative(const std::vector<Long>& a, const std::vector<Long>& b)
{
    Long diff = 0, norm = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        diff += (a[i] - b[i]) * (a[i] - b[i]);
        norm += b[i] * b[i];
    }
    return double(std::sqrt(diff) / std::max(std::sqrt(norm), Long(1e-300)));
}

struct Worst {
    double gradient = 0, hessian = 0, energy_types = 0, gradient_types = 0, hessian_types = 0;
};

void check_case(const PairCase& c, Worst& worst)
{
    const int n = int(c.points.size()) * c.dim;
    const std::string label = name(c.kind, c.dim, c.model.penalty);
    // Long double: the kernel's derivatives and central differences of its energy and gradient.
    std::vector<Long> x(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
        const Vec3<double>& v = c.points[size_t(i / c.dim)];
        x[size_t(i)] = kernels::component(v, i % c.dim);
    }
    std::vector<Long> g(static_cast<size_t>(n)), H(static_cast<size_t>(n * n));
    const Long e = energy<Long>(c, points_as<Long>(c), g.data(), H.data());
    ASSERT_TRUE(std::isfinite(double(e))) << label;
    // A step relative to the distance: the barrier's derivatives vary on the scale of d.
    const Long h = 1e-6L * c.distance;
    std::vector<Long> g_fd(static_cast<size_t>(n)), H_fd(static_cast<size_t>(n * n));
    for (int i = 0; i < n; ++i) {
        std::vector<Long> xp = x, xm = x, gp(static_cast<size_t>(n)), gm(static_cast<size_t>(n));
        xp[size_t(i)] += h;
        xm[size_t(i)] -= h;
        const Long ep = energy<Long>(c, points_as<Long>(c, xp), gp.data(), nullptr);
        const Long em = energy<Long>(c, points_as<Long>(c, xm), gm.data(), nullptr);
        g_fd[size_t(i)] = (ep - em) / (2 * h);
        for (int j = 0; j < n; ++j)
            H_fd[size_t(j * n + i)] = (gp[size_t(j)] - gm[size_t(j)]) / (2 * h);
    }
    const double rg = relative(g, g_fd), rH = relative(H, H_fd);
    EXPECT_LT(rg, 1e-8) << label << ": gradient against central differences";
    EXPECT_LT(rH, 1e-8) << label << ": Hessian against central differences";
    worst.gradient = std::max(worst.gradient, rg);
    worst.hessian = std::max(worst.hessian, rH);

    // Double against long double.
    std::vector<double> gd(static_cast<size_t>(n)), Hd(static_cast<size_t>(n * n));
    const double ed = energy<double>(c, points_as<double>(c), gd.data(), Hd.data());
    const std::vector<Long> gdl(gd.begin(), gd.end()), Hdl(Hd.begin(), Hd.end());
    const double re = double(std::abs(Long(ed) - e) / std::max(std::abs(e), Long(1e-300)));
    const double rgd = relative(gdl, g), rHd = relative(Hdl, H);
    EXPECT_LT(re, 1e-11) << label << ": energy, double against long double";
    EXPECT_LT(rgd, 1e-11) << label << ": gradient, double against long double";
    EXPECT_LT(rHd, 1e-11) << label << ": Hessian, double against long double";
    worst.energy_types = std::max(worst.energy_types, re);
    worst.gradient_types = std::max(worst.gradient_types, rgd);
    worst.hessian_types = std::max(worst.hessian_types, rHd);
}

} // namespace

TEST(ContactPair, DerivativesAgainstDifferencesAndScalarTypes)
{
    struct Kind {
        ContactKind kind;
        int dim;
    };
    const Kind kinds[]
        = { { ContactKind::VERTEX_EDGE, 2 }, { ContactKind::VERTEX_EDGE, 3 }, { ContactKind::VERTEX_FACE, 3 },
              { ContactKind::EDGE_EDGE, 3 }, { ContactKind::VERTEX_PLANE, 2 }, { ContactKind::VERTEX_PLANE, 3 } };
    std::mt19937 rng(2026);
    for (const Kind& k : kinds)
        for (bool penalty : { false, true }) {
            Worst worst;
            for (int trial = 0; trial < 60; ++trial)
                check_case(random_case(k.kind, k.dim, penalty, rng), worst);
            std::printf("%-26s worst relative differences: gradient %.1e, Hessian %.1e against central "
                        "differences; energy %.1e, gradient %.1e, Hessian %.1e double against long double\n",
                name(k.kind, k.dim, penalty).c_str(), worst.gradient, worst.hessian, worst.energy_types,
                worst.gradient_types, worst.hessian_types);
        }
}

/// An intersecting pair has infinite barrier energy and NaN derivatives in every scalar type; the
/// penalty stays finite there.
TEST(ContactPair, IntersectingPairInEveryScalarType)
{
    const Vec3<Long> face[4]
        = { Vec3<Long>(0.2L, 0.2L, 0), Vec3<Long>(0, 0, 0), Vec3<Long>(1, 0, 0), Vec3<Long>(0, 1, 0) };
    Long g[12], H[144];
    const kernels::PairModel barrier = kernels::pair_model(false, 1e-3, 0.0);
    EXPECT_TRUE(std::isinf(
        double(kernels::pair_energy<Long>(ContactKind::VERTEX_FACE, 3, face, Vec3<Long>(), 0, -1, barrier, g, H))));
    EXPECT_TRUE(std::isnan(double(g[0])) && std::isnan(double(H[0])));
    const kernels::PairModel penalty = kernels::pair_model(true, 1e-3, 0.0);
    const Long e = kernels::pair_energy<Long>(ContactKind::VERTEX_FACE, 3, face, Vec3<Long>(), 0, -1, penalty, g, H);
    EXPECT_TRUE(std::isfinite(double(e)) && e > 0);
}
