// Optimizing a cushion cell (shape_opt/microstructure/cell_optimization.hpp) on a coarse mesh:
// L-BFGS-B and MMA lower J within the family's bounds, accepted iterates on one mesh never raise
// J, a mesh that degrades is replaced (and the restart's J on the new mesh is recorded), and the
// reported final design is evaluated on a new mesh of it; variables named as held keep their values
// (on the drop test's objective), and an unknown name is an input error; designs the objective
// refuses are rejected, each recorded with its reason, and never accepted.

#include "shape_opt/microstructure/cell_optimization.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/microstructure/cell_design.hpp"
#include "shape_opt/microstructure/drop_design.hpp"

#include <gtest/gtest.h>

#include <algorithm>

using namespace diffipc;

namespace {
/// The re-entrant cell's plateau objective on a coarse mesh (0.04 of the cell), 8 steps to 40%.
CellDesign coarse_plateau()
{
    CellDesignSettings s;
    s.mesh.size = 0.04;
    s.max_strain = 0.4;
    s.steps = 8;
    s.samples = { 2, 4, 6, 8 };
    s.target_stress = 500;
    s.free_shear = false;
    return CellDesign(
        read_cell_family(std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/reentrant.json"), s);
}
} // namespace

TEST(CellOptimization, LbfgsbAndMmaLowerThePlateauObjectiveWithinTheBounds)
{
    const CellDesign design = coarse_plateau();
    const CellFamily& f = design.family();
    for (OptimizerAlgorithm algorithm : { OptimizerAlgorithm::LBFGSB, OptimizerAlgorithm::MMA }) {
        SCOPED_TRACE(to_string(algorithm));
        CellOptimizationSettings o;
        o.optimizer.algorithm = algorithm;
        o.optimizer.max_iterations = 6;
        o.remesh_quality = 0.3; // a new coarse mesh has 0.34
        int calls = 0;
        const CellOptimizationResult r = optimize_cell(design, f.initial(), o, [&](const CellIteration&) { ++calls; });
        ASSERT_FALSE(r.history.empty());
        EXPECT_EQ(calls, int(r.history.size()));
        const double J0 = r.history.front().J;
        EXPECT_LT(r.history.back().J, 0.5 * J0);
        for (size_t k = 1; k < r.history.size(); ++k) {
            if (r.history[k].mesh == r.history[k - 1].mesh) {
                EXPECT_LE(r.history[k].J, r.history[k - 1].J * (1 + 1e-12));
                // an iterate whose mesh fell below the threshold is the last on that mesh (a new
                // mesh is used as it comes)
                if (k >= 2 && r.history[k - 2].mesh == r.history[k - 1].mesh)
                    EXPECT_GE(r.history[k - 1].quality, o.remesh_quality);
            } else { // a restart on a new mesh: the same design, a better mesh
                EXPECT_EQ(r.history[k].x, r.history[k - 1].x);
                EXPECT_LT(r.history[k - 1].quality, o.remesh_quality);
                EXPECT_GT(r.history[k].quality, r.history[k - 1].quality);
            }
        }
        EXPECT_EQ(r.history.back().mesh, r.remeshes);
        if (algorithm == OptimizerAlgorithm::LBFGSB)
            EXPECT_GT(r.remeshes, 0); // seen: 1 (MMA's shorter steps: none in 6 iterations)
        EXPECT_TRUE((r.x.array() >= f.lower().array()).all() && (r.x.array() <= f.upper().array()).all());
        ASSERT_TRUE(r.final.ok);
        EXPECT_LT(r.final.J, 0.5 * J0); // on a new mesh of the final design too
        EXPECT_EQ(r.final.gradient.size(), f.size());
    }
}

TEST(CellOptimization, HeldVariablesKeepTheirValues)
{
    DropSettings s; // two cells under a block of 0.625 kg/m at 0.5 m/s, 24 steps (test_drop_design.cpp)
    s.mesh.size = 0.01 / 20; // coarse: thickness down to 0.1 of the cell's half-height can be meshed
    s.nx = 2;
    s.ny = 1;
    s.mass = 0.625;
    s.kappa = 1e17;
    s.steps = 24;
    s.target_stress = 500;
    const DropDesign design(
        read_cell_family(std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/reentrant.json"), s);
    const CellFamily& f = design.family();
    CellOptimizationSettings o;
    o.optimizer.algorithm = OptimizerAlgorithm::LBFGSB;
    o.optimizer.max_iterations = 3;
    o.fixed = { "width", "blend" };
    const CellOptimizationResult r = optimize_cell(design, f.initial(), o);
    ASSERT_GE(r.history.size(), 2u);
    EXPECT_LT(r.history.back().J, r.history.front().J);
    EXPECT_NE(r.x, f.initial());
    for (const CellIteration& it : r.history) {
        EXPECT_EQ(it.x[f.width_index()], f.initial()[f.width_index()]);
        EXPECT_EQ(it.x[f.width_index() - 1], f.initial()[f.width_index() - 1]); // the blend
    }
    o.fixed = { "width", "height" };
    try {
        optimize_cell(design, f.initial(), o);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "fixed[1]");
    }
}

namespace {
/// The plateau objective, refusing every design whose thickness[2] exceeds a cap (a stand-in
/// for a region where simulations fail).
class CappedDesign : public CellObjective {
public:
    CappedDesign(const CellDesign& design, Index j, double cap)
        : m_design(design)
        , m_j(j)
        , m_cap(cap)
    {
    }
    const CellFamily& family() const override { return m_design.family(); }
    const CellMeshSettings& mesh_settings() const override { return m_design.mesh_settings(); }
    DesignValue value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const override
    {
        if (p[m_j] > m_cap) {
            DesignValue refused;
            refused.message = "refused: thickness[2] = " + std::to_string(p[m_j]);
            return refused;
        }
        return m_design.value(cell, p, velocity);
    }

private:
    const CellDesign& m_design;
    Index m_j;
    double m_cap;
};
} // namespace

TEST(CellOptimization, RefusedDesignsAreRejectedAndRecordedWithTheirReason)
{
    const CellDesign design = coarse_plateau();
    const CellFamily& f = design.family();
    const auto& names = f.names();
    const Index j = Index(std::find(names.begin(), names.end(), "thickness[2]") - names.begin());
    ASSERT_LT(j, f.size());
    // the unconstrained optimum thickens thickness[2] from 0.12 towards 0.29 (study 408)
    const double cap = f.initial()[j] + 0.01;
    const CappedDesign capped(design, j, cap);
    CellOptimizationSettings o;
    o.optimizer.algorithm = OptimizerAlgorithm::LBFGSB;
    o.optimizer.max_iterations = 4;
    const CellOptimizationResult r = optimize_cell(capped, f.initial(), o);
    ASSERT_GE(r.rejected(), 1);
    int refused = 0; // the others: trial designs the moved mesh cannot follow
    for (const CellRejection& k : r.rejections) {
        EXPECT_FALSE(k.reason.empty());
        if (k.reason.rfind("refused", 0) == 0) {
            ++refused;
            EXPECT_GT(k.x[j], cap);
            EXPECT_EQ(k.reason, "refused: thickness[2] = " + std::to_string(k.x[j]));
        }
    }
    EXPECT_GE(refused, 1);
    for (const CellIteration& it : r.history)
        EXPECT_LE(it.x[j], cap);
    EXPECT_LT(r.history.back().J, r.history.front().J);
}
