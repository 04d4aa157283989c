#include "objectives/objective_json.hpp"

#include "forward/common/error.hpp"
#include "objective_fd.hpp"
#include "objectives/boundary_smoothness.hpp"
#include "objectives/center_of_mass.hpp"
#include "objectives/combinators.hpp"
#include "objectives/compliance.hpp"
#include "objectives/elastic_energy.hpp"
#include "objectives/kinetic_energy.hpp"
#include "objectives/markers.hpp"
#include "objectives/stress_norm.hpp"
#include "objectives/time_aggregation.hpp"
#include "objectives/volume.hpp"

using namespace diffipc;
using nlohmann::json;

namespace {

/// Two bodies, so that "body" selections mean something; 3 steps.
json two_body_scene()
{
    json s = test::cantilever_scene(2);
    s["bodies"][0]["name"] = "beam";
    s["bodies"].push_back(test::box_body("block", { 0.0, 1.0 }, { 0.5, 1.25 }, { 2, 1 }));
    return s;
}

class ObjectiveJson : public ::testing::Test {
protected:
    void SetUp() override { run = test::run_scene(two_body_scene()); }
    double value(const json& j) const
    {
        return parse_objective(j, "objective", *run.sim)->value(*run.sim, run.trajectory);
    }
    double value(const Objective& J) const { return J.value(*run.sim, run.trajectory); }
    /// The field named by the InputError that parsing `j` throws ("" if none).
    std::string error_field(const json& j) const
    {
        try {
            parse_objective(j, "objective", *run.sim);
        } catch (const InputError& e) {
            return e.field();
        }
        return "";
    }
    test::Run run;
};

TEST_F(ObjectiveJson, PerStateTypesMatchDirectConstruction)
{
    const std::vector<Index> beam = body_elements(run.sim->mesh(), 0);
    StressNormOptions o;
    o.p = 6;
    o.norm = StressNormType::FROBENIUS;
    o.stress = StressMeasure::FIRST_PIOLA;
    o.normalized = true;
    o.elements = beam;
    EXPECT_DOUBLE_EQ(
        value({ { "type", "stress_norm" }, { "p", 6 }, { "norm", "frobenius" }, { "stress", "first_piola" },
            { "normalized", true }, { "body", "beam" }, { "time", { { "max_p", 4 } } } }),
        value(TimeAggregation(std::make_unique<StressNorm>(o), TimeMode::MAX_P, 4)));
    // Defaults: p = 8, von Mises, Cauchy, all elements, final state.
    EXPECT_DOUBLE_EQ(value({ { "type", "stress_norm" } }),
        value(TimeAggregation(std::make_unique<StressNorm>(StressNormOptions {}), TimeMode::FINAL)));
    EXPECT_DOUBLE_EQ(
        value({ { "type", "elastic_energy" }, { "body", 0 }, { "time", "sum" }, { "include_initial", true } }),
        value(TimeAggregation(std::make_unique<ElasticEnergy>(beam), TimeMode::SUM, 8, true)));
    EXPECT_DOUBLE_EQ(value({ { "type", "compliance" }, { "time", "trapezoid" } }),
        value(TimeAggregation(std::make_unique<Compliance>(), TimeMode::TRAPEZOID)));
    EXPECT_DOUBLE_EQ(value({ { "type", "volume" }, { "body", "block" } }),
        value(TimeAggregation(std::make_unique<Volume>(body_elements(run.sim->mesh(), 1)), TimeMode::FINAL)));
    EXPECT_DOUBLE_EQ(value({ { "type", "kinetic_energy" }, { "time", "sum" } }),
        value(TimeAggregation(std::make_unique<KineticEnergy>(), TimeMode::SUM)));
}

TEST_F(ObjectiveJson, TrackingTypesMatchDirectConstruction)
{
    const Mesh& mesh = run.sim->mesh();
    Positions y0(2, 2), y1(2, 2);
    y0 << 1, 0, 0.5, 0.1;
    y1 << 1, -0.1, 0.5, 0.2;
    const MarkerTracking markers({ MarkerPoint::vertex(3), MarkerPoint::barycentric(mesh, 1, { 0.2, 0.3, 0.5 }) },
        { 0, 3 }, { y0, y1 }, (VectorXd(2) << 1.0, 2.0).finished());
    EXPECT_DOUBLE_EQ(value({ { "type", "markers" }, { "vertices", { 3 } },
                         { "points", { { { "element", 1 }, { "weights", { 0.2, 0.3, 0.5 } } } } },
                         { "targets", { { { 1, 0 }, { 0.5, 0.1 } }, { { 1, -0.1 }, { 0.5, 0.2 } } } },
                         { "steps", { 0, 3 } }, { "weights", { 1.0, 2.0 } } }),
        value(markers));
    // Without "steps": one target set per step 1..T.
    Positions y(1, 2);
    y << 1, 0;
    const MarkerTracking every({ MarkerPoint::vertex(2) }, { 1, 2, 3 }, { y, y, y });
    EXPECT_DOUBLE_EQ(value({ { "type", "markers" }, { "vertices", { 2 } },
                         { "targets", { { { 1, 0 } }, { { 1, 0 } }, { { 1, 0 } } } } }),
        value(every));

    Positions c(2, 2);
    c << 0.5, 0.1, 0.5, 0.0;
    EXPECT_DOUBLE_EQ(value({ { "type", "center_of_mass" }, { "targets", { { 0.5, 0.1 }, { 0.5, 0.0 } } },
                         { "steps", { 1, 2 } }, { "weight", 3 }, { "body", "beam" } }),
        value(CenterOfMassTracking({ 1, 2 }, c, 3.0, body_elements(mesh, 0))));
    EXPECT_DOUBLE_EQ(
        value({ { "type", "boundary_smoothness" }, { "body", 1 } }), value(BoundarySmoothness(run.sim->scene(), 1)));
}

TEST_F(ObjectiveJson, CombinatorsMatchDirectConstruction)
{
    const json stress = { { "type", "stress_norm" }, { "time", "sum" } };
    const json kinetic = { { "type", "kinetic_energy" } };
    const double S = value(stress), K = value(kinetic);
    EXPECT_NEAR(value({ { "type", "sum" },
                    { "terms", { { { "weight", 2 }, { "objective", stress } }, { { "objective", kinetic } } } } }),
        2 * S + K, 1e-12 * (2 * S + K));
    EXPECT_NEAR(value({ { "type", "power" }, { "q", 2 }, { "objective", stress } }), S * S, 1e-12 * S * S);
    EXPECT_NEAR(value({ { "type", "constraint" }, { "objective", stress }, { "upper", 0.5 * S }, { "weight", 10 } }),
        10 * 0.25 * S * S, 1e-12 * S * S);
    EXPECT_NEAR(value({ { "type", "constraint" }, { "objective", stress }, { "lower", 2 * S } }), S * S, 1e-12 * S * S);
    EXPECT_EQ(value({ { "type", "constraint" }, { "objective", stress }, { "upper", 2 * S } }), 0);
}

TEST_F(ObjectiveJson, NestedObjectiveGradient)
{
    const json j = { { "type", "sum" },
        { "terms",
            { { { "weight", 1e-3 },
                  { "objective",
                      { { "type", "constraint" }, { "upper", 10 }, { "weight", 2 },
                          { "objective",
                              { { "type", "stress_norm" }, { "body", "beam" }, { "time", { { "max_p", 6 } } } } } } } },
                { { "weight", 100 },
                    { "objective",
                        { { "type", "markers" }, { "vertices", { 5, 7 } },
                            { "targets", { { { 1, 0 }, { 0.5, 0.3 } } } }, { "steps", { 2 } } } } },
                { { "objective",
                    { { "type", "power" }, { "q", 2 }, { "objective", { { "type", "kinetic_energy" } } } } } },
                { { "weight", 0.1 }, { "objective", { { "type", "boundary_smoothness" } } } } } } };
    const std::unique_ptr<Objective> J = parse_objective(j, "objective", *run.sim);
    test::check_state_gradient(*J, run);
    test::check_all_parameter_gradients(*J, run);
}

TEST_F(ObjectiveJson, ErrorsNameTheField)
{
    const json stress = { { "type", "stress_norm" } };
    EXPECT_EQ(error_field(json::array()), "objective");
    EXPECT_EQ(error_field({ { "p", 2 } }), "objective.type");
    EXPECT_EQ(error_field({ { "type", "max_stress" } }), "objective.type");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "exponent", 2 } }), "objective.exponent");
    EXPECT_EQ(
        error_field({ { "type", "sum" },
            { "terms",
                { { { "objective", stress } }, { { "objective", { { "type", "stress_norm" }, { "p", 0.5 } } } } } } }),
        "objective.terms[1].objective.p");
    EXPECT_EQ(error_field({ { "type", "sum" }, { "terms", json::array() } }), "objective.terms");
    EXPECT_EQ(error_field({ { "type", "sum" }, { "terms", { { { "weight", "2" }, { "objective", stress } } } } }),
        "objective.terms[0].weight");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "p", "8" } }), "objective.p");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "norm", "tresca" } }), "objective.norm");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "stress", "kirchhoff" } }), "objective.stress");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "time", "mean" } }), "objective.time");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "time", "max_p" } }), "objective.time");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "time", { { "max_p", 0.5 } } } }), "objective.time.max_p");
    EXPECT_EQ(error_field({ { "type", "stress_norm" }, { "time", { { "p", 4 } } } }), "objective.time.p");
    EXPECT_EQ(error_field({ { "type", "volume" }, { "include_initial", true } }), "objective.include_initial");
    EXPECT_EQ(error_field({ { "type", "volume" }, { "body", "wheel" } }), "objective.body");
    EXPECT_EQ(error_field({ { "type", "volume" }, { "body", 2 } }), "objective.body");
    EXPECT_EQ(error_field({ { "type", "volume" }, { "body", -1 } }), "objective.body");
    EXPECT_EQ(error_field({ { "type", "compliance" }, { "body", 0 } }), "objective.body");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0 } } }), "objective.targets");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "targets", { { { 0, 0 } } } }, { "steps", { 1 } } }), "objective");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0 } }, { "targets", { { { 0, 0 } } } } }),
        "objective.targets"); // 1 target set, 3 steps
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0 } }, { "targets", { { { 0, 0 } }, { { 0, 0 } } } },
                  { "steps", { 1, 4 } } }),
        "objective.steps[1]");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0, 10000 } },
                  { "targets", { { { 0, 0 }, { 0, 0 } } } }, { "steps", { 1 } } }),
        "objective.vertices[1]");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0, 1 } },
                  { "targets", { { { 0, 0 }, { 0, 0, 0 } } } }, { "steps", { 1 } } }),
        "objective.targets[0][1]");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0 } }, { "targets", { { { 0, 0 }, { 0, 0 } } } },
                  { "steps", { 1 } } }),
        "objective.targets[0]");
    EXPECT_EQ(
        error_field({ { "type", "markers" }, { "points", { { { "element", 0 }, { "weights", { 0.5, 0.5, 0.5 } } } } },
            { "targets", { { { 0, 0 } } } }, { "steps", { 1 } } }),
        "objective.points[0].weights");
    EXPECT_EQ(
        error_field({ { "type", "markers" }, { "points", { { { "element", 99999 }, { "weights", { 0.5, 0.5, 0 } } } } },
            { "targets", { { { 0, 0 } } } }, { "steps", { 1 } } }),
        "objective.points[0].element");
    EXPECT_EQ(error_field({ { "type", "markers" }, { "vertices", { 0 } }, { "targets", { { { 0, 0 } } } },
                  { "steps", { 1 } }, { "weights", { -1 } } }),
        "objective.weights[0]");
    EXPECT_EQ(error_field({ { "type", "center_of_mass" }, { "targets", { { 0, 0, 0 } } }, { "steps", { 1 } } }),
        "objective.targets[0]");
    EXPECT_EQ(
        error_field({ { "type", "center_of_mass" }, { "targets", { { 0, 0 } } }, { "steps", { 1 } }, { "weight", 0 } }),
        "objective.weight");
    EXPECT_EQ(error_field({ { "type", "power" }, { "objective", stress } }), "objective.q");
    EXPECT_EQ(error_field({ { "type", "power" }, { "q", 2 } }), "objective.objective");
    EXPECT_EQ(error_field({ { "type", "constraint" }, { "objective", stress } }), "objective");
    EXPECT_EQ(error_field({ { "type", "constraint" }, { "objective", stress }, { "upper", 1 }, { "lower", 0 } }),
        "objective");
    EXPECT_EQ(error_field({ { "type", "constraint" }, { "objective", stress }, { "upper", 1 }, { "weight", -2 } }),
        "objective.weight");
    EXPECT_EQ(error_field({ { "type", "power" }, { "q", 2 },
                  { "objective",
                      { { "type", "constraint" }, { "objective", { { "type", "volume" }, { "time", 3 } } },
                          { "upper", 1 } } } }),
        "objective.objective.objective.time");
}

TEST_F(ObjectiveJson, DocumentationExampleParses)
{
    // The last example of docs/objectives.md.
    const json j = json::parse(R"({"type": "sum", "terms": [
      {"objective": {"type": "stress_norm", "p": 16, "normalized": true, "time": {"max_p": 8}}},
      {"weight": 1e3, "objective": {"type": "constraint", "lower": 0.225,
                                    "objective": {"type": "volume", "body": 0}}},
      {"weight": 10, "objective": {"type": "boundary_smoothness"}}]})");
    const std::unique_ptr<Objective> J = parse_objective(j, "objective", *run.sim);
    EXPECT_GT(J->value(*run.sim, run.trajectory), 0);
}

TEST_F(ObjectiveJson, MessageNamesTheProblem)
{
    try {
        parse_objective({ { "type", "stress_norm" }, { "p", 0.5 } }, "objective", *run.sim);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("objective.p: must be at least 1"), std::string::npos) << e.what();
    }
}

} // namespace
