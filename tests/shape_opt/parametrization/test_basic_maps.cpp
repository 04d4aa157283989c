// shape_opt/parametrization/basic_maps.hpp and the chain in parameter_map.hpp: values,
// vector-Jacobian products against central differences, inverses, size errors.

#include "shape_opt/parametrization/basic_maps.hpp"
#include "shape_opt/parametrization/lame_map.hpp"
#include "tests/shape_opt/parametrization/map_check.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {
std::vector<std::unique_ptr<ParameterMap>> maps_of(std::unique_ptr<ParameterMap> a, std::unique_ptr<ParameterMap> b)
{
    std::vector<std::unique_ptr<ParameterMap>> v;
    v.push_back(std::move(a));
    v.push_back(std::move(b));
    return v;
}
} // namespace

TEST(GatherMap, SpreadsPerBodyValuesToElementsAndSumsBack)
{
    // Three elements of body 1, two of body 0.
    const GatherMap m(2, { 1, 1, 0, 1, 0 }, "p", "per_element");
    EXPECT_EQ(m.apply(Eigen::Vector2d(3, 7)), (VectorXd(5) << 7, 7, 3, 7, 3).finished());
    VectorXd y_bar(5);
    y_bar << 1, 2, 3, 4, 5;
    EXPECT_EQ(m.vjp(Eigen::Vector2d(3, 7), y_bar), Eigen::Vector2d(8, 7));
    test::expect_vjp_matches_differences(m, Eigen::Vector2d(3, 7));
    EXPECT_TRUE(m.invertible());
    EXPECT_EQ(m.inverse((VectorXd(5) << 7, 7, 3, 7, 3).finished(), "f"), Eigen::Vector2d(3, 7));
    // Values that differ within a body have no per-body design.
    EXPECT_THROW(m.inverse((VectorXd(5) << 7, 8, 3, 7, 3).finished(), "f"), InputError);
    EXPECT_THROW(GatherMap(2, { 0, 2 }, "p"), InputError);
    EXPECT_FALSE(GatherMap(3, { 0, 2 }, "p").invertible()); // a slice drops value 1
}

TEST(InsertConstantsMap, InsertsAndDropsTheConstants)
{
    const InsertConstantsMap m(5, { 1, 3 }, Eigen::Vector2d(-1, -2), "p");
    EXPECT_EQ(m.in_size(), 3);
    const Eigen::Vector3d x(10, 20, 30);
    EXPECT_EQ(m.apply(x), (VectorXd(5) << 10, -1, 20, -2, 30).finished());
    EXPECT_EQ(m.inverse(m.apply(x), "f"), VectorXd(x));
    test::expect_vjp_matches_differences(m, x);
    EXPECT_THROW(InsertConstantsMap(5, { 1, 1 }, Eigen::Vector2d(0, 0), "p"), InputError);
    EXPECT_THROW(InsertConstantsMap(5, { 5 }, VectorXd::Zero(1), "p"), InputError);
}

TEST(ScaleOffsetMap, PerEntryAndScalar)
{
    const ScaleOffsetMap m(3, Eigen::Vector3d(2, -1, 0.5), VectorXd::Constant(1, 4), "p");
    const Eigen::Vector3d x(1, 2, 3);
    EXPECT_EQ(m.apply(x), Eigen::Vector3d(6, 2, 5.5));
    EXPECT_TRUE(m.inverse(m.apply(x), "f").isApprox(x));
    test::expect_vjp_matches_differences(m, x);
    EXPECT_THROW(ScaleOffsetMap(3, Eigen::Vector2d(1, 1), VectorXd::Zero(1), "p"), InputError);
    EXPECT_FALSE(ScaleOffsetMap(2, Eigen::Vector2d(1, 0), VectorXd::Zero(1), "p").invertible());
}

TEST(ExpMap, LogSpaceRoundTripAndDerivative)
{
    const ExpMap m(3);
    const Eigen::Vector3d x(std::log(1e5), 0.3, -2);
    EXPECT_NEAR(m.apply(x)[0], 1e5, 1e-9);
    EXPECT_TRUE(m.inverse(m.apply(x), "f").isApprox(x, 1e-14));
    test::expect_vjp_matches_differences(m, x);
    EXPECT_THROW(m.inverse(Eigen::Vector3d(1, 0, 2), "f"), InputError);
}

TEST(LameMap, MatchesTheTextbookFormulasAndItsDifferences)
{
    const Index n = 3;
    VectorXd x(2 * n);
    x << 1e5, 2e6, 7e3, 0.3, -0.2, 0.45;
    for (ElasticityPlane plane : { ElasticityPlane::NONE, ElasticityPlane::STRESS }) {
        const LameMap m(n, plane);
        const VectorXd y = m.apply(x);
        for (Index i = 0; i < n; ++i) {
            const double E = x[i], nu = x[n + i];
            // Independent: the 3D bulk modulus K = E / (3 (1 - 2 nu)) = lambda + 2 mu / 3, and
            // the plane-stress lambda = 2 lambda_3D mu / (lambda_3D + 2 mu).
            const double mu = E / (2 * (1 + nu)), K = E / (3 * (1 - 2 * nu)), lambda3 = K - 2 * mu / 3;
            EXPECT_NEAR(y[i], mu, 1e-12 * mu);
            const double lambda = plane == ElasticityPlane::STRESS ? 2 * lambda3 * mu / (lambda3 + 2 * mu) : lambda3;
            EXPECT_NEAR(y[n + i], lambda, 1e-10 * std::abs(lambda) + 1e-9);
        }
        EXPECT_TRUE(m.inverse(y, "f").isApprox(x, 1e-12));
        // Directions of comparable effect in E and nu: E in units of its value (else the
        // nu terms, 1e5 times larger per unit, would hide an error in dmu/dE).
        VectorXd unit(2 * n), scale(2 * n);
        for (Index i = 0; i < n; ++i) {
            unit[i] = 1.0;
            scale[i] = x[i];
            unit[n + i] = x[n + i];
            scale[n + i] = 1.0;
        }
        ParameterChain scaled(maps_of(std::make_unique<ScaleOffsetMap>(2 * n, scale, VectorXd::Zero(1), "p"),
                                  std::make_unique<LameMap>(n, plane)),
            { "maps[0]", "maps[1]" });
        test::expect_vjp_matches_differences(scaled, unit, 1e-6, 1e-7, 8, 3, 0.1);
    }
    VectorXd bad = x;
    bad[n + 1] = 0.5;
    EXPECT_THROW(LameMap(n, ElasticityPlane::NONE).apply(bad), InputError);
}

TEST(ParameterChain, ComposesInReverseForTheGradient)
{
    // log E per body -> E per body -> E per element.
    ParameterChain chain(maps_of(std::make_unique<ExpMap>(2),
                             std::make_unique<GatherMap>(2, std::vector<Index> { 0, 1, 1, 0 }, "p", "per_element")),
        { "maps[0]", "maps[1]" });
    const Eigen::Vector2d x(std::log(2e5), std::log(5e4));
    const VectorXd y = chain.apply(x);
    EXPECT_NEAR(y[1], 5e4, 1e-8);
    test::expect_vjp_matches_differences(chain, x);
    EXPECT_TRUE(chain.inverse(y, "f").isApprox(x, 1e-14));
}

TEST(ParameterChain, SizesThatDoNotLineUpNameTheEntry)
{
    try {
        ParameterChain chain(maps_of(std::make_unique<ExpMap>(2), std::make_unique<ExpMap>(3)), { "maps[0]", "maps[1]" });
        FAIL() << "accepted a chain of sizes 2 -> 2, 3 -> 3";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "maps[1]");
        EXPECT_NE(std::string(e.what()).find("reads 3 values"), std::string::npos) << e.what();
    }
    const ParameterChain identity(4);
    EXPECT_THROW(identity.apply(VectorXd::Zero(3)), InputError);
}

TEST(Concatenation, BlocksSideBySide)
{
    std::vector<std::unique_ptr<ParameterMap>> parts;
    parts.push_back(std::make_unique<ExpMap>(2));
    parts.push_back(std::make_unique<ScaleOffsetMap>(3, VectorXd::Constant(1, 1e-3), VectorXd::Zero(1), "p"));
    const Concatenation c(std::move(parts));
    EXPECT_EQ(c.in_size(), 5);
    VectorXd x(5);
    x << 1, 2, 3, 4, 5;
    const VectorXd y = c.apply(x);
    EXPECT_NEAR(y[1], std::exp(2.0), 1e-12);
    EXPECT_NEAR(y[4], 5e-3, 1e-15);
    test::expect_vjp_matches_differences(c, x);
    EXPECT_TRUE(c.inverse(y, "f").isApprox(x, 1e-14));
}
