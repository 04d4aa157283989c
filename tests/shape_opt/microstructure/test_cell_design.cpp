// A cushion cell's design objective (shape_opt/microstructure/cell_design.hpp): its gradient
// through the whole pipeline (design -> mesh -> compression with contact -> plateau objective)
// against central differences, the same J for a re-meshed design within the discretization
// error, and its settings' errors.

#include "shape_opt/microstructure/cell_design.hpp"

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace diffipc;

namespace {

const std::string kTopologies = std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/";

CellDesignSettings compression(double size, double strain, int steps, std::vector<int> samples)
{
    CellDesignSettings s;
    s.mesh.size = size;
    s.max_strain = strain;
    s.steps = steps;
    s.samples = std::move(samples);
    s.target_stress = 1000;
    s.free_shear = false;
    s.solver = { { "max_iterations", 400 }, { "residual_tolerance", 1e-11 } };
    return s;
}

/// dJ/dp against central differences over meshes of p +- h moved from `mesh` (a mesh of p),
/// h = 1e-5 times each variable's range.
void expect_gradient_matches_differences(const CellDesign& design, const Mesh& mesh, const VectorXd& p)
{
    const CellFamily& f = design.family();
    const CellEvaluation e = design.evaluate_moved(mesh, p, p, true);
    ASSERT_TRUE(e.ok) << e.message;
    for (Index j = 0; j < f.size(); ++j) {
        const double h = 1e-5 * (f.upper()[j] - f.lower()[j]);
        VectorXd qp = p, qm = p;
        qp[j] += h;
        qm[j] -= h;
        const CellEvaluation ep = design.evaluate_moved(mesh, p, qp, false),
                             em = design.evaluate_moved(mesh, p, qm, false);
        ASSERT_TRUE(ep.ok && em.ok);
        const double fd = (ep.J - em.J) / (2 * h);
        // seen: at most 3e-6 relative (at h = 1e-4 times the range, the stub tip's truncation
        // error reaches 3e-4; with the default residual tolerance 1e-8 the solver's noise 7e-4)
        EXPECT_NEAR(e.gradient[j], fd, 1e-4 * std::abs(fd)) << f.names()[size_t(j)];
    }
}

} // namespace

TEST(CellDesign, WholePipelineGradientMatchesDifferencesWithContactInTheCell)
{
    // dJ/dp (adjoint shape gradient pulled back by the mesh's velocity, plus the width's volume
    // term) against central differences of J over meshes of p +- h moved from the mesh of p
    // (cell_shape_map.hpp: smooth in the design, so the differences see no remeshing noise).
    // Mesh size 0.025 m (height 1 m), h = 1e-5 times each variable's range, residual tolerance
    // 1e-11. The samples are
    // steps where beams touch: diamond_stop's stubs at 22.5% and 25%, the re-entrant cell's
    // folded beams at 44% and 47%.
    struct Case {
        const char* topology;
        CellDesignSettings settings;
    };
    for (const Case& c : { Case { "diamond_stop", compression(0.025, 0.25, 10, { 9, 10 }) },
             Case { "reentrant", compression(0.025, 0.47, 15, { 14, 15 }) } }) {
        SCOPED_TRACE(c.topology);
        const CellDesign design(read_cell_family(kTopologies + c.topology + ".json"), c.settings);
        const CellFamily& f = design.family();
        const VectorXd p = f.initial();
        const Mesh mesh = mesh_design(f, p, c.settings.mesh);
        const CellEvaluation e = design.evaluate_moved(mesh, p, p, true);
        ASSERT_TRUE(e.ok) << e.message;
        for (int k : c.settings.samples)
            EXPECT_GT(e.contacts[k - 1], 0) << "step " << k;
        expect_gradient_matches_differences(design, mesh, p);
    }
}

TEST(CellDesign, ACappedStressCountsOnlyAboveTheTargetAndItsGradientMatchesDifferences)
{
    // cap_samples: only a compressive stress above sigma* counts. The re-entrant cell compressed
    // to 47% in 15 steps, capped at steps 1 (3.1%) and 13 (40.7%), with sigma* between the two
    // stresses, so that one cap is active and one is not: J grows by exactly the active cap's
    // (sigma_13 / sigma* - 1)^2, and its gradient matches the differences.
    const CellFamily f = read_cell_family(kTopologies + "reentrant.json");
    CellDesignSettings s = compression(0.025, 0.47, 15, { 14, 15 });
    const VectorXd p = f.initial();
    const Mesh mesh = mesh_design(f, p, s.mesh);
    const CellEvaluation probe = CellDesign(f, s).evaluate_moved(mesh, p, p, false);
    ASSERT_TRUE(probe.ok) << probe.message;
    const double s1 = probe.stress[0], s13 = probe.stress[12];
    ASSERT_LT(s1, 0.9 * s13) << "the curve must rise from step 1 to 13";
    s.target_stress = 0.5 * (s1 + s13);
    const CellEvaluation plain = CellDesign(f, s).evaluate_moved(mesh, p, p, false);
    s.cap_samples = { 1, 13 };
    const CellDesign capped(f, s);
    const CellEvaluation e = capped.evaluate_moved(mesh, p, p, false);
    ASSERT_TRUE(plain.ok && e.ok);
    const double active = std::pow(s13 / s.target_stress - 1, 2);
    EXPECT_NEAR(e.J - plain.J, active, 1e-9 * active);
    expect_gradient_matches_differences(capped, mesh, p);
}

TEST(CellDesign, ARemeshedDesignAgreesWithinTheDiscretizationError)
{
    // The stress curve of the re-entrant cell at its initial design p (no contact up to 30%), on
    // a new mesh of p and on the mesh of a nearby design p' moved to p: they differ far less than
    // the discretization error, estimated by the change from size 0.04 to 0.02 (seen: 0.1% against
    // 16%).
    const CellFamily f = read_cell_family(kTopologies + "reentrant.json");
    const VectorXd p = f.initial();
    const VectorXd range = f.upper() - f.lower();
    const VectorXd p2 = p + 0.02 * range.cwiseProduct(VectorXd::LinSpaced(p.size(), -1, 1));
    const CellDesign coarse(f, compression(0.04, 0.3, 6, { 5, 6 })), fine(f, compression(0.02, 0.3, 6, { 5, 6 }));
    const CellEvaluation e_coarse = coarse.evaluate(p, false), e_fine = fine.evaluate(p, false);
    const CellEvaluation e_moved = fine.evaluate_moved(mesh_design(f, p2, fine.settings().mesh), p2, p, false);
    ASSERT_TRUE(e_coarse.ok && e_fine.ok && e_moved.ok);
    const double discretization = (e_fine.stress - e_coarse.stress).cwiseAbs().maxCoeff();
    const double remeshing = (e_moved.stress - e_fine.stress).cwiseAbs().maxCoeff();
    EXPECT_GT(discretization, 0.05 * e_fine.stress.maxCoeff());
    EXPECT_LT(remeshing, 0.05 * discretization);
}

TEST(CellDesign, DesignsAtTheBoundsSimulate)
{
    // Every shipped family at its lower and upper bounds (all variables), compressed to 40% in 16
    // static steps with contact, G_xy free and held at 0, the design objective's defaults otherwise
    // (kappa 1e4 E / h^2, the solver's defaults), on the coarsest mesh the thinnest beams allow
    // (0.025 m). (With the former default kappa = 100 E, square_grid and reentrant at their upper
    // bounds stalled past 27% with G_xy held: beams in contact pushed the soft barrier to tiny gaps.)
    for (const char* name : { "square_grid", "diamond", "diamond_stop", "reentrant", "curved_beam" }) {
        const CellFamily f = read_cell_family(kTopologies + name + ".json");
        for (bool free_shear : { true, false }) {
            CellDesignSettings s;
            s.mesh.size = 0.025;
            s.max_strain = 0.4;
            s.steps = 16;
            s.samples = { 16 };
            s.target_stress = 1000;
            s.free_shear = free_shear;
            const CellDesign design(f, s);
            for (const VectorXd& p : { f.lower(), f.upper() }) {
                SCOPED_TRACE(std::string(name) + (p == f.lower() ? " lower" : " upper")
                    + (free_shear ? ", G_xy free" : ", G_xy held"));
                const CellEvaluation e = design.evaluate(p, false);
                EXPECT_TRUE(e.ok) << e.message;
                EXPECT_TRUE(e.stress.allFinite());
                EXPECT_GT(e.stress.minCoeff(), 0);
            }
        }
    }
}

TEST(CellDesign, SettingsErrorsNameTheField)
{
    const auto field = [](const nlohmann::json& j) {
        try {
            parse_cell_design_settings(JsonField(j, "cell"));
        } catch (const InputError& e) {
            return e.field();
        }
        return std::string("(no error)");
    };
    EXPECT_EQ(field({ { "target_stress", 500 } }), "(no error)");
    EXPECT_EQ(field(nlohmann::json::object()), "cell.target_stress");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "steps", 8 }, { "samples", { 4, 9 } } }), "cell.samples[1]");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "steps", 8 }, { "samples", { 8 } }, { "cap_samples", { 1, 12 } } }),
        "cell.cap_samples[1]");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "cap_samples", 3 } }), "cell.cap_samples");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "shear", "sideways" } }), "cell.shear");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "max_strain", 0.95 } }), "cell.max_strain");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "lateral_weight", -1 } }), "cell.lateral_weight");
    EXPECT_EQ(field({ { "target_stress", 500 }, { "material", { { "youngs", 1 } } } }), "cell.material.youngs");
    const CellDesignSettings s = parse_cell_design_settings(JsonField(
        { { "target_stress", 500 }, { "height", 0.01 }, { "shear", "fixed" }, { "samples", { 2, 4 } } }, "cell"));
    EXPECT_EQ(s.mesh.size, 0.01 / 40);
    EXPECT_FALSE(s.free_shear);
    EXPECT_EQ(s.samples, (std::vector<int> { 2, 4 }));
}
