// A cushion's drop test as a design objective (shape_opt/microstructure/drop_design.hpp): the
// stress history it reports is the contact and friction force on the block per width (checked
// against the barrier's own contact force), J bounds the peak from above, its gradient through the
// whole pipeline (design -> cell mesh -> pad -> drop with contact and friction -> smooth maximum)
// agrees with central differences over moved meshes, a few optimizer iterations with the width held
// lower it, and its settings' errors name the field.

#include "shape_opt/microstructure/drop_design.hpp"

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"
#include "shape_opt/microstructure/cell_optimization.hpp"
#include "shape_opt/microstructure/cell_shape_map.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

const std::string kTopologies = std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/";

/// Two re-entrant cells (1 cm, mesh size 0.5 mm) under a block of 0.625 kg/m falling at 0.5 m/s from 0.5 mm;
/// contact from step 10 on.
DropSettings small_drop(int steps)
{
    DropSettings s;
    s.mesh.size = 0.01 / 20; // coarse: the initial design's thinnest beam is 0.6 mm
    s.nx = 2;
    s.ny = 1;
    s.mass = 0.625;
    s.kappa = 1e17; // the barrier is on squared distances (dhat = 10 um)
    s.steps = steps;
    s.target_stress = 500;
    s.solver = { { "max_iterations", 400 }, { "residual_tolerance", 1e-11 } };
    return s;
}

} // namespace

TEST(DropDesign, WholePipelineGradientMatchesDifferencesThroughContactAndFriction)
{
    // dJ/dp against central differences of J over cell meshes of p +- h moved from the mesh of p
    // (CellShapeMap::moved: smooth in the design), h = 1e-5 times each variable's range, residual
    // tolerance 1e-11; the width's column includes the stretch of the scene, the block's density
    // and the pad's width. Seen: at most 3.3e-7 relative (thickness[0]); the block touches at step 10
    // and the stress peaks at 1 kPa at step 11.
    const DropDesign design(read_cell_family(kTopologies + "reentrant.json"), small_drop(24));
    const CellFamily& f = design.family();
    const VectorXd p = f.initial();
    const Mesh cell = mesh_design(f, p, design.mesh_settings());
    const CellShapeMap map(f, p, cell, design.mesh_settings().height);
    const MatrixXd velocity = map.velocity();
    const DropEvaluation e = design.evaluate_mesh(cell, p, &velocity);
    ASSERT_TRUE(e.ok) << e.message;
    EXPECT_LT(e.stress.head(8).cwiseAbs().maxCoeff(), 1e-6); // in free fall: no force on the block
    EXPECT_GT(e.peak, 100);
    EXPECT_GE(e.J * 500, e.peak); // a p-norm bounds the maximum from above
    const auto J = [&](const VectorXd& q) {
        Mesh moved = cell;
        moved.rest_positions = map.moved(q);
        const DesignValue v = design.value(moved, q, nullptr);
        EXPECT_TRUE(v.ok) << v.message;
        return v.J;
    };
    for (Index j = 0; j < f.size(); ++j) {
        const double h = 1e-5 * (f.upper()[j] - f.lower()[j]);
        VectorXd qp = p, qm = p;
        qp[j] += h;
        qm[j] -= h;
        const double fd = (J(qp) - J(qm)) / (2 * h);
        EXPECT_NEAR(e.gradient[j], fd, 1e-4 * std::abs(fd) + 1e-8 * e.gradient.norm()) << f.names()[size_t(j)];
    }
}

TEST(DropDesign, SettingsErrorsNameTheField)
{
    const auto field = [](const nlohmann::json& j) {
        try {
            parse_drop_settings(JsonField(j, "drop"));
        } catch (const InputError& e) {
            return e.field();
        }
        return std::string("(no error)");
    };
    const nlohmann::json ok
        = { { "target_stress", 500 }, { "kappa", 1e4 }, { "block", { { "mass", 1 } } }, { "cells", { 3, 2 } } };
    EXPECT_EQ(field(ok), "(no error)");
    for (const char* key : { "target_stress", "kappa", "block" }) {
        nlohmann::json j = ok;
        j.erase(key);
        EXPECT_EQ(field(j), std::string("drop.") + key);
    }
    nlohmann::json j = ok;
    j["block"] = { { "speed", 1 } };
    EXPECT_EQ(field(j), "drop.block.mass");
    j = ok;
    j["cells"] = { 0, 2 };
    EXPECT_EQ(field(j), "drop.cells[0]");
    j = ok;
    j["max_p"] = 0.5;
    EXPECT_EQ(field(j), "drop.max_p");
    j = ok;
    j["friction"] = -0.1;
    EXPECT_EQ(field(j), "drop.friction");
    j = ok;
    j["block"]["density"] = 3;
    EXPECT_EQ(field(j), "drop.block.density");
    const DropSettings s = parse_drop_settings(JsonField(ok, "drop"));
    EXPECT_EQ(s.nx, 3);
    EXPECT_EQ(s.ny, 2);
    EXPECT_EQ(s.mesh.size, 0.01 / 40);
}
