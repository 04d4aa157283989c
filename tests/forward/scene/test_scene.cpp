// Scene validation: a valid scene loads; each malformed variant is rejected
// with an InputError whose message names the offending field.

#include "forward/common/error.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>

using namespace diffipc;
using nlohmann::json;

namespace {

json valid_scene()
{
    json s = test::box_scene(3, { 1.0, 0.2, 0.2 }, { 4, 1, 1 });
    s["gravity"] = { 0, -9.81, 0 };
    s["dirichlet"] = { { { "body", "body" }, { "region", test::region({ -1, -1, -1 }, { 1e-6, 1, 1 }) },
        { "displacement", { "0", 0, nullptr } } } };
    s["neumann"] = { { { "body", 0 }, { "region", test::region({ 1, -1, -1 }, { 2, 1, 1 }) },
        { "traction", { "1e3*t", 0, 0 } } } };
    s["output"] = { { "directory", "out" }, { "vtu_every", 2 } };
    return s;
}

struct Malformed {
    std::string name;
    std::function<void(json&)> mutate;
    std::string field; // must appear in the error message
};

std::vector<Malformed> malformed_cases()
{
    return {
        { "unknown_top_level_key",
            [](json& s) {
                s["gravty"] = { 0, 0, 0 };
            },
            "gravty" },
        { "missing_dimension", [](json& s) { s.erase("dimension"); }, "dimension" },
        { "dimension_four", [](json& s) { s["dimension"] = 4; }, "dimension" },
        { "dimension_string", [](json& s) { s["dimension"] = "3"; }, "dimension" },
        { "no_bodies", [](json& s) { s["bodies"] = json::array(); }, "bodies" },
        { "unknown_body_key", [](json& s) { s["bodies"][0]["colour"] = "red"; }, "bodies[0].colour" },
        { "negative_E", [](json& s) { s["bodies"][0]["material"]["E"] = -5.0; }, "bodies[0].material.E" },
        { "zero_E", [](json& s) { s["bodies"][0]["material"]["E"] = 0.0; }, "bodies[0].material.E" },
        { "nu_half", [](json& s) { s["bodies"][0]["material"]["nu"] = 0.5; }, "bodies[0].material.nu" },
        { "nu_below_minus_one", [](json& s) { s["bodies"][0]["material"]["nu"] = -1.0; }, "bodies[0].material.nu" },
        { "zero_density", [](json& s) { s["bodies"][0]["material"]["density"] = 0.0; }, "bodies[0].material.density" },
        { "unknown_model", [](json& s) { s["bodies"][0]["material"]["model"] = "mooney"; },
            "bodies[0].material.model" },
        { "missing_material", [](json& s) { s["bodies"][0].erase("material"); }, "bodies[0].material" },
        { "box_and_file", [](json& s) { s["bodies"][0]["mesh"]["file"] = "x.msh"; }, "bodies[0].mesh" },
        { "missing_mesh_file",
            [](json& s) {
                s["bodies"][0]["mesh"] = { { "file", "no_such_mesh.msh" } };
            },
            "bodies[0].mesh.file" },
        { "unsupported_mesh_format",
            [](json& s) {
                s["bodies"][0]["mesh"] = { { "file", "CMakeLists.txt" } };
            },
            "bodies[0].mesh.file" },
        { "zero_cells",
            [](json& s) {
                s["bodies"][0]["mesh"]["box"]["cells"] = { 4, 0, 1 };
            },
            "bodies[0].mesh.box.cells[1]" },
        { "degenerate_box",
            [](json& s) {
                s["bodies"][0]["mesh"]["box"]["max"] = { 1.0, 0.0, 0.2 };
            },
            "bodies[0].mesh.box.max" },
        { "wrong_vector_length",
            [](json& s) {
                s["gravity"] = { 0, -9.81 };
            },
            "gravity" },
        { "velocity_not_numbers",
            [](json& s) {
                s["bodies"][0]["initial_velocity"] = { 0, "fast", 0 };
            },
            "bodies[0].initial_velocity[1]" },
        { "zero_dt", [](json& s) { s["time"]["dt"] = 0.0; }, "time.dt" },
        { "negative_dt", [](json& s) { s["time"]["dt"] = -0.1; }, "time.dt" },
        { "zero_steps", [](json& s) { s["time"]["steps"] = 0; }, "time.steps" },
        { "fractional_steps", [](json& s) { s["time"]["steps"] = 2.5; }, "time.steps" },
        { "unknown_integrator", [](json& s) { s["time"]["integrator"] = "rk4"; }, "time.integrator" },
        { "dirichlet_unknown_body", [](json& s) { s["dirichlet"][0]["body"] = "wall"; }, "dirichlet[0].body" },
        { "dirichlet_body_index_out_of_range", [](json& s) { s["dirichlet"][0]["body"] = 3; }, "dirichlet[0].body" },
        { "dirichlet_empty_region",
            [](json& s) {
                s["dirichlet"][0]["region"] = test::region({ 5, 5, 5 }, { 6, 6, 6 });
            },
            "dirichlet[0].region" },
        { "dirichlet_bad_expression", [](json& s) { s["dirichlet"][0]["displacement"][0] = "sin(t"; },
            "dirichlet[0].displacement[0]" },
        { "dirichlet_unknown_variable", [](json& s) { s["dirichlet"][0]["displacement"][0] = "2*w"; },
            "dirichlet[0].displacement[0]" },
        { "dirichlet_all_null",
            [](json& s) {
                s["dirichlet"][0]["displacement"] = { nullptr, nullptr, nullptr };
            },
            "dirichlet[0].displacement" },
        { "dirichlet_nonfinite_expression", [](json& s) { s["dirichlet"][0]["displacement"][0] = "1/t"; },
            "dirichlet[0].displacement[0]" },
        { "expression_assigns_time", [](json& s) { s["neumann"][0]["traction"][0] = "t=5"; },
            "neumann[0].traction[0]" },
        { "expression_adds_to_x", [](json& s) { s["dirichlet"][0]["displacement"][0] = "x+=1"; },
            "dirichlet[0].displacement[0]" },
        { "expression_two_values", [](json& s) { s["neumann"][0]["traction"][0] = "1,2"; }, "neumann[0].traction[0]" },
        { "expression_nul_character", [](json& s) { s["neumann"][0]["traction"][0] = std::string("1\0+t", 4); },
            "neumann[0].traction[0]" },
        { "obstacle_named_like_body",
            [](json& s) {
                s["obstacles"]
                    = { { { "name", "body" }, { "plane", { { "point", { 0, -1, 0 } }, { "normal", { 0, 1, 0 } } } } } };
            },
            "obstacles[0].name" },
        { "obstacle_name_twice",
            [](json& s) {
                const json plane
                    = { { "name", "floor" }, { "plane", { { "point", { 0, -1, 0 } }, { "normal", { 0, 1, 0 } } } } };
                s["obstacles"] = { plane, plane };
            },
            "obstacles[1].name" },
        { "neumann_wrong_length",
            [](json& s) {
                s["neumann"][0]["traction"] = { 1, 2 };
            },
            "neumann[0].traction" },
        { "neumann_region_no_facet",
            [](json& s) {
                s["neumann"][0]["region"] = test::region({ 0.5, -1, -1 }, { 0.5, 1, 1 });
            },
            "neumann[0].region" },
        { "solver_negative_tolerance", [](json& s) { s["solver"]["residual_tolerance"] = -1e-8; },
            "solver.residual_tolerance" },
        { "solver_unknown_linear_solver", [](json& s) { s["solver"]["linear_solver"] = "pardiso"; },
            "solver.linear_solver" },
        { "solver_unknown_gpu_adjoint_preconditioner",
            [](json& s) { s["solver"]["gpu_adjoint_preconditioner"] = "ilu"; }, "solver.gpu_adjoint_preconditioner" },
        { "solver_step_extension_not_a_bool", [](json& s) { s["solver"]["step_extension"] = "yes"; },
            "solver.step_extension" },
        { "output_negative_vtu_every", [](json& s) { s["output"]["vtu_every"] = -1; }, "output.vtu_every" },
        { "output_zero_flush_interval", [](json& s) { s["output"]["flush_interval"] = 0; }, "output.flush_interval" },
        { "time_step_tiny", [](json& s) { s["time"]["dt"] = 1e-300; }, "time.dt" },
        { "body_translated_far",
            [](json& s) {
                s["bodies"][0]["translation"] = { 1e300, 0, 0 };
            },
            "bodies[0]" },
        { "body_translation_loses_digits",
            [](json& s) {
                s["bodies"][0]["translation"] = { 0, 1e11, 0 }; // y = 0.2 is not a binary fraction
            },
            "bodies[0]" },
        { "dhat_huge",
            [](json& s) {
                s["contact"] = { { "dhat", 1e300 } };
            },
            "contact.dhat" },
        { "youngs_modulus_huge", [](json& s) { s["bodies"][0]["material"]["E"] = 1e308; }, "bodies[0].material.E" },
        { "density_huge", [](json& s) { s["bodies"][0]["material"]["density"] = 1e300; },
            "bodies[0].material.density" },
        { "output_text_flush_interval", [](json& s) { s["output"]["flush_interval"] = "1"; }, "output.flush_interval" },
        { "output_unknown_vtu_encoding", [](json& s) { s["output"]["vtu_encoding"] = "base64"; },
            "output.vtu_encoding: expected \"binary\" or \"ascii\", got \"base64\"" },
        { "output_numeric_vtu_encoding", [](json& s) { s["output"]["vtu_encoding"] = 1; },
            "output.vtu_encoding: expected a string" },
        { "output_misspelled_vtu_key", [](json& s) { s["output"]["vtu_encode"] = "ascii"; }, "vtu_encode" },
        { "mass_unknown", [](json& s) { s["mass"] = "heavy"; }, "mass" },
        { "device_unknown", [](json& s) { s["device"] = "tpu"; }, "device: expected \"cpu\" or \"gpu\", got \"tpu\"" },
        { "device_gpu_with_periodic_friction",
            [](json& s) {
                s = test::compressed_periodic_cell(3, "static");
                s["contact"] = { { "dhat", 1e-3 } };
                s["friction"] = { { "coefficient", 0.3 } };
                s["device"] = "gpu";
            },
            "device: \"gpu\" does not support friction across a periodic cell's boundary" },
        { "duplicate_body_name", [](json& s) { s["bodies"].push_back(s["bodies"][0]); }, "bodies[1].name" },
        { "region_max_below_min",
            [](json& s) {
                s["dirichlet"][0]["region"] = test::region({ 1, 1, 1 }, { 0, 0, 0 });
            },
            "dirichlet[0].region.max" },
    };
}

class MalformedScene : public testing::TestWithParam<Malformed> { };

TEST_P(MalformedScene, IsRejectedNamingTheField)
{
    json s = valid_scene();
    GetParam().mutate(s);
    try {
        parse_scene(s, DIFFIPC_SOURCE_DIR, "<test>");
        FAIL() << "accepted a malformed scene";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(GetParam().field), std::string::npos)
            << "message '" << e.what() << "' does not name " << GetParam().field;
    }
}

INSTANTIATE_TEST_SUITE_P(Scene, MalformedScene, testing::ValuesIn(malformed_cases()),
    [](const testing::TestParamInfo<Malformed>& info) { return info.param.name; });

TEST(Scene, ValidSceneLoads)
{
    const Scene s = parse_scene(valid_scene(), ".", "<test>");
    EXPECT_EQ(s.dim, 3);
    EXPECT_EQ(s.mesh.num_elements(), 24);
    EXPECT_EQ(s.dirichlet.size(), 1u);
    EXPECT_FALSE(s.dirichlet[0].displacement[2].has_value());
    EXPECT_EQ(s.output.vtu_every, 2);
    EXPECT_EQ(s.output.vtu_encoding, VtuEncoding::BINARY); // the default
}

TEST(Scene, VtuEncodingIsRead)
{
    json j = valid_scene();
    j["output"]["vtu_encoding"] = "ascii";
    EXPECT_EQ(parse_scene(j, ".", "<test>").output.vtu_encoding, VtuEncoding::ASCII);
    j["output"]["vtu_encoding"] = "binary";
    EXPECT_EQ(parse_scene(j, ".", "<test>").output.vtu_encoding, VtuEncoding::BINARY);
}

TEST(Scene, GpuAdjointPreconditionerIsRead)
{
    json j = valid_scene();
    EXPECT_FALSE(parse_scene(j, ".", "<test>").solver.gpu_adjoint_multigrid) << "block-Jacobi by default";
    j["solver"]["gpu_adjoint_preconditioner"] = "multigrid";
    EXPECT_TRUE(parse_scene(j, ".", "<test>").solver.gpu_adjoint_multigrid);
    j["solver"]["gpu_adjoint_preconditioner"] = "block_jacobi";
    EXPECT_FALSE(parse_scene(j, ".", "<test>").solver.gpu_adjoint_multigrid);
}

// Comparisons contain '=' and are not assignments; the conditional operator is one value.
TEST(Scene, ExpressionComparisonsAreAccepted)
{
    for (const char* text : { "t>=1", "t<=1", "t==0", "t!=0", "(t>1) ? 1e3 : 0" }) {
        json s = valid_scene();
        s["neumann"][0]["traction"][0] = text;
        EXPECT_NO_THROW(parse_scene(s, DIFFIPC_SOURCE_DIR, "<test>")) << text;
    }
}

TEST(Scene, InvalidJsonTextNamesTheSource)
{
    try {
        parse_scene_text("{\"dimension\": 3, ", ".", "broken.json");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "broken.json");
    }
    // NaN is not JSON: rejected at parse time.
    EXPECT_THROW(parse_scene_text("{\"dimension\": NaN}", ".", "nan.json"), InputError);
}

TEST(Scene, DeviceIsCpuUnlessTheSceneSaysGpu)
{
    EXPECT_EQ(parse_scene(valid_scene(), ".", "<test>").device, DeviceType::CPU);
    json s = valid_scene();
    s["device"] = "gpu";
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU); // parsing needs no GPU
    // Contact with lagged friction (the scene's coefficient or a body's) is on the GPU path too.
    s["contact"] = { { "dhat", 1e-3 } };
    s["friction"] = { { "coefficient", 0.3 } };
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    s.erase("friction");
    s["bodies"][0]["friction"] = { { "coefficient", 0.2 } };
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    // Automatic load stepping of a static scene, with a fixed and with the adaptive kappa.
    s["time"]["integrator"] = "static";
    s["time"]["adaptive"] = true;
    s["contact"]["kappa"] = 1e6;
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    s["contact"]["kappa"] = "adaptive";
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    // Adaptive time stepping of a dynamic scene, with the adaptive kappa too; the consistent mass.
    s["time"]["integrator"] = "implicit_euler";
    s["mass"] = "consistent";
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    // The penalty contact baseline.
    s["contact"] = { { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 1e6 } };
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    Scene scene = parse_scene(valid_scene(), ".", "<test>");
    select_device(scene, "gpu", "--device");
    EXPECT_EQ(scene.device, DeviceType::GPU);
    select_device(scene, "cpu", "--device");
    EXPECT_EQ(scene.device, DeviceType::CPU);
}

TEST(Scene, GpuSceneWithoutAUsableGpuIsAnErrorNamingTheDevice)
{
    json s = test::box_scene(2, { 1, 0.2 }, { 4, 1 });
    s["device"] = "gpu";
    std::string why;
    if (DeviceSolver::available(&why))
        GTEST_SKIP() << "a GPU is usable here; tests/cuda/simulation runs the GPU path";
    try {
        Simulator sim(test::make_scene(s));
        FAIL() << "a GPU scene ran without a GPU";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("device: \"gpu\""), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
}

TEST(Scene, GpuRefusesFrictionAcrossAPeriodicBoundaryHoweverItIsGiven)
{
    // A periodic cell with contact runs on the GPU path; friction across its boundary does not yet.
    json s = test::compressed_periodic_cell(2, "static");
    s["contact"] = { { "dhat", 1e-3 } };
    s["device"] = "gpu";
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    // The effective coefficients count: a body's own 0 overrides the scene's 0.3.
    s["friction"] = { { "coefficient", 0.3 } };
    s["bodies"][0]["friction"] = { { "coefficient", 0.0 } };
    EXPECT_EQ(parse_scene(s, ".", "<test>").device, DeviceType::GPU);
    // Coefficients given as parameters are refused when the simulator is made, before any GPU is
    // looked for (so here with or without one).
    s.erase("friction");
    s["bodies"][0].erase("friction");
    SimulationParameters parameters;
    parameters.friction = VectorXd::Constant(1, 0.3);
    try {
        Simulator sim(test::make_scene(s), parameters);
        FAIL() << "friction across a periodic boundary ran on the GPU path";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("device: \"gpu\" does not support friction across a periodic cell's"),
            std::string::npos)
            << e.what();
    }
}

TEST(Scene, MissingFileIsReported) { EXPECT_THROW(load_scene("/nonexistent/scene.json"), InputError); }

TEST(Scene, FileErrorsArePrefixedWithTheFileName)
{
    const std::string path = testing::TempDir() + "bad_scene.json";
    json s = valid_scene();
    s["time"]["dt"] = -1.0;
    std::ofstream(path) << s.dump();
    try {
        load_scene(path);
        FAIL();
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(path), std::string::npos) << what;
        EXPECT_NE(what.find("time.dt"), std::string::npos) << what;
    }
}

TEST(Scene, InvertedFileMeshIsRejected)
{
    const std::string path = testing::TempDir() + "inverted.msh";
    std::ofstream(path)
        << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n"
           "$Elements\n1\n1 4 0 1 3 2 4\n$EndElements\n";
    json s = valid_scene();
    s.erase("dirichlet");
    s.erase("neumann");
    s["bodies"][0]["mesh"] = { { "file", path } };
    try {
        parse_scene(s, ".", "<test>");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("inverted"), std::string::npos) << e.what();
        EXPECT_EQ(e.field(), "bodies[0].mesh");
    }
}

// Every example scene shipped in the repository validates.
TEST(Scene, ExampleScenesValidate)
{
    namespace fs = std::filesystem;
    int count = 0;
    for (const auto& entry : fs::recursive_directory_iterator(fs::path(DIFFIPC_SOURCE_DIR) / "studies")) {
        if (entry.path().extension() != ".json" || entry.path().filename() == "summary.json")
            continue;
        if (entry.path().filename().string().rfind("scene", 0) != 0)
            continue;
        EXPECT_NO_THROW(load_scene(entry.path().string())) << entry.path();
        ++count;
    }
    EXPECT_GE(count, 1);
}

} // namespace
