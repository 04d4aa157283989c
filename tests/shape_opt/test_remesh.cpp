// shape_opt/remesh.hpp: gmsh remeshing of a body's domain with its boundary kept, the
// free-form deformation's pull-back, and a remesh inside a design problem that keeps the
// design variables and changes J by a discretization amount. Areas, volumes and distances
// to the old boundary are computed here from coordinates, not by the code under test.

#include "forward/common/error.hpp"
#include "shape_opt/design_problem.hpp"
#include "shape_opt/parametrization/free_form_deformation.hpp"
#include "shape_opt/reduced_functional.hpp"
#include "shape_opt/remesh.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include <unistd.h>

using namespace diffipc;

namespace {

double triangle_area(const Positions& x, int a, int b, int c)
{
    const Eigen::Vector2d u = (x.row(b) - x.row(a)).transpose(), v = (x.row(c) - x.row(a)).transpose();
    return 0.5 * (u[0] * v[1] - u[1] * v[0]);
}

double tet_volume(const Positions& x, int a, int b, int c, int d)
{
    const Eigen::Vector3d u = (x.row(b) - x.row(a)).transpose(), v = (x.row(c) - x.row(a)).transpose(),
                          w = (x.row(d) - x.row(a)).transpose();
    return u.dot(v.cross(w)) / 6;
}

double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b)
{
    const Eigen::Vector2d ab = b - a;
    const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    return (p - (a + t * ab)).norm();
}

/// A 2D box mesh whose interior vertices are moved far enough to make slivers.
Mesh distorted_square(double shift)
{
    Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0.5), Eigen::Vector2i(8, 4));
    for (Index v = 0; v < m.rest_positions.rows(); ++v) {
        const double x = m.rest_positions(v, 0), y = m.rest_positions(v, 1);
        if (x > 1e-9 && x < 1 - 1e-9 && y > 1e-9 && y < 0.5 - 1e-9)
            m.rest_positions(v, 0) += shift * std::sin(7 * y) * 0.125;
    }
    return m;
}

} // namespace

TEST(Remesh, QualityOfRegularAndFlatSimplices)
{
    Positions tri(3, 2);
    tri << 0, 0, 1, 0, 0.5, std::sqrt(3.0) / 2;
    MatrixXi t(1, 3);
    t << 0, 1, 2;
    EXPECT_NEAR(element_quality(tri, t, 0), 1.0, 1e-14);
    tri(2, 1) = 0; // flat
    EXPECT_EQ(element_quality(tri, t, 0), 0.0);
    Positions tet(4, 3);
    tet << 1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1;
    MatrixXi e(1, 4);
    e << 0, 1, 2, 3;
    if (tet_volume(tet, 0, 1, 2, 3) < 0)
        std::swap(e(0, 0), e(0, 1));
    EXPECT_NEAR(element_quality(tet, e, 0), 1.0, 1e-14);
}

TEST(Remesh, TwoDimensionalDomainKeepsItsBoundaryAndArea)
{
    const Mesh old = distorted_square(0.9);
    const double worst = min_quality(old.rest_positions, old.elements);
    const Mesh fresh = remesh_domain(old.rest_positions, old.boundary_facets, 2, 0.06);
    double area = 0;
    for (Index e = 0; e < fresh.elements.rows(); ++e) {
        const double a
            = triangle_area(fresh.rest_positions, fresh.elements(e, 0), fresh.elements(e, 1), fresh.elements(e, 2));
        ASSERT_GT(a, 0) << "element " << e;
        area += a;
    }
    EXPECT_NEAR(area, 0.5, 1e-12);
    // Every new boundary vertex lies on an old boundary edge.
    for (Index f = 0; f < fresh.boundary_facets.rows(); ++f) {
        const Eigen::Vector2d p = fresh.rest_positions.row(fresh.boundary_facets(f, 0)).transpose();
        double distance = 1e9;
        for (Index g = 0; g < old.boundary_facets.rows(); ++g)
            distance = std::min(distance,
                segment_distance(p, old.rest_positions.row(old.boundary_facets(g, 0)).transpose(),
                    old.rest_positions.row(old.boundary_facets(g, 1)).transpose()));
        EXPECT_LT(distance, 1e-12);
    }
    EXPECT_LT(worst, 0.3);
    EXPECT_GT(min_quality(fresh.rest_positions, fresh.elements), 0.5);
    EXPECT_GT(fresh.elements.rows(), 100);
}

TEST(Remesh, TwoDimensionalDomainWithAHole)
{
    // An annulus: two boundary loops; the hole must stay empty.
    const Mesh ring = annulus_mesh(Eigen::Vector2d(0, 0), 0.5, 1.0, 48, 3);
    const Mesh fresh = remesh_domain(ring.rest_positions, ring.boundary_facets, 2, 0.08);
    double area = 0, ring_area = 0;
    for (Index e = 0; e < fresh.elements.rows(); ++e) {
        const double a
            = triangle_area(fresh.rest_positions, fresh.elements(e, 0), fresh.elements(e, 1), fresh.elements(e, 2));
        ASSERT_GT(a, 0);
        area += a;
    }
    for (Index e = 0; e < ring.elements.rows(); ++e)
        ring_area += triangle_area(ring.rest_positions, ring.elements(e, 0), ring.elements(e, 1), ring.elements(e, 2));
    EXPECT_NEAR(area, ring_area, 1e-12);
    for (Index v = 0; v < fresh.rest_positions.rows(); ++v)
        EXPECT_GT(fresh.rest_positions.row(v).norm(), 0.5 * std::cos(M_PI / 48) - 1e-12);
}

TEST(Remesh, ThreeDimensionalDomainKeepsItsSurface)
{
    Mesh old = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0.5, 0.5), Eigen::Vector3i(6, 3, 3));
    // Shear the interior vertices: the surface stays, the interior degrades.
    for (Index v = 0; v < old.rest_positions.rows(); ++v) {
        const auto p = old.rest_positions.row(v);
        if (p[0] > 1e-9 && p[0] < 1 - 1e-9 && p[1] > 1e-9 && p[1] < 0.5 - 1e-9 && p[2] > 1e-9 && p[2] < 0.5 - 1e-9)
            old.rest_positions(v, 0) += 0.12 * std::sin(9 * p[1]);
    }
    const double worst = min_quality(old.rest_positions, old.elements);
    const Mesh fresh = remesh_domain(old.rest_positions, old.boundary_facets, 3, 0.15);
    double volume = 0;
    for (Index e = 0; e < fresh.elements.rows(); ++e) {
        const double v = tet_volume(fresh.rest_positions, fresh.elements(e, 0), fresh.elements(e, 1),
            fresh.elements(e, 2), fresh.elements(e, 3));
        ASSERT_GT(v, 0) << "element " << e;
        volume += v;
    }
    EXPECT_NEAR(volume, 0.25, 1e-12);
    // The surface triangulation is kept: every new boundary vertex is an old boundary vertex.
    std::vector<Eigen::Vector3d> old_surface;
    for (Index f = 0; f < old.boundary_facets.rows(); ++f)
        for (int a = 0; a < 3; ++a)
            old_surface.push_back(old.rest_positions.row(old.boundary_facets(f, a)).transpose());
    EXPECT_EQ(fresh.boundary_facets.rows(), old.boundary_facets.rows());
    for (Index f = 0; f < fresh.boundary_facets.rows(); ++f) {
        const Eigen::Vector3d p = fresh.rest_positions.row(fresh.boundary_facets(f, 0)).transpose();
        double distance = 1e9;
        for (const auto& q : old_surface)
            distance = std::min(distance, (p - q).norm());
        EXPECT_EQ(distance, 0.0);
    }
    EXPECT_GT(min_quality(fresh.rest_positions, fresh.elements), worst);
}

TEST(Remesh, ThreeDimensionalSurfaceMeshedAnew)
{
    // A block stretched to three times its height at one end: the surface triangles degrade too.
    Mesh old = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0.2, 0.2), Eigen::Vector3i(10, 2, 2));
    for (Index v = 0; v < old.rest_positions.rows(); ++v)
        old.rest_positions(v, 1) *= 1 + 2 * old.rest_positions(v, 0);
    const double worst = min_quality(old.rest_positions, old.elements);
    double old_volume = 0;
    for (Index e = 0; e < old.elements.rows(); ++e)
        old_volume += tet_volume(
            old.rest_positions, old.elements(e, 0), old.elements(e, 1), old.elements(e, 2), old.elements(e, 3));
    const Mesh fresh = remesh_domain(old.rest_positions, old.boundary_facets, 3, 0.08, true);
    double volume = 0;
    for (Index e = 0; e < fresh.elements.rows(); ++e) {
        const double v = tet_volume(fresh.rest_positions, fresh.elements(e, 0), fresh.elements(e, 1),
            fresh.elements(e, 2), fresh.elements(e, 3));
        ASSERT_GT(v, 0) << "element " << e;
        volume += v;
    }
    EXPECT_NEAR(volume, old_volume, 1e-9);
    EXPECT_GT(min_quality(fresh.rest_positions, fresh.elements), worst);
}

TEST(Remesh, OpenBoundaryIsAnError)
{
    const Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(2, 2));
    const MatrixXi open = m.boundary_facets.topRows(m.boundary_facets.rows() - 1);
    EXPECT_THROW(remesh_domain(m.rest_positions, open, 2, 0.1), RemeshError);
}

TEST(Remesh, FreeFormDeformationPullBackInvertsTheMap)
{
    for (int dim : { 2, 3 }) {
        const Mesh m = dim == 2
            ? box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0.4), Eigen::Vector2i(10, 4))
            : box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0.4, 0.4), Eigen::Vector3i(5, 2, 2));
        FfdLattice lattice;
        lattice.lower = VectorXd::Constant(dim, -0.1);
        lattice.upper = VectorXd::Constant(dim, 1.1);
        lattice.degree = VectorXi::Constant(dim, 3);
        lattice.axes = dim == 2 ? std::vector<int> { 0, 1 } : std::vector<int> { 0, 1, 2 };
        lattice.fixed_border = true;
        const FreeFormDeformation ffd(m.rest_positions, lattice, "ffd");
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> u(-0.08, 0.08);
        VectorXd x(ffd.in_size());
        for (Index i = 0; i < x.size(); ++i)
            x[i] = u(rng);
        const VectorXd moved = ffd.apply(x);
        Positions current(m.rest_positions.rows(), dim);
        for (Index v = 0; v < current.rows(); ++v)
            current.row(v) = moved.segment(v * dim, dim).transpose();
        const Positions back = ffd.pull_back(current, x);
        EXPECT_LT((back - m.rest_positions).cwiseAbs().maxCoeff(), 1e-12) << dim << "D";
        // A lattice told that the moved mesh is the shape at x ("mesh_at") is the same map of x.
        FfdLattice at_x = lattice;
        at_x.mesh_at = x;
        const FreeFormDeformation rebased(current, at_x, "ffd");
        EXPECT_LT((rebased.apply(x) - moved).cwiseAbs().maxCoeff(), 1e-12);
        VectorXd other(x.size());
        for (Index i = 0; i < x.size(); ++i)
            other[i] = u(rng);
        EXPECT_LT((rebased.apply(other) - ffd.apply(other)).cwiseAbs().maxCoeff(), 1e-12) << dim << "D";
    }
}

TEST(Remesh, PullBackFarFromTheOriginAndWithMovingFaces)
{
    // A lattice whose faces move (no fixed border) around a mesh 3 km from the origin: the
    // pull-back still inverts the map (its tolerance is above the coordinates' rounding).
    for (double offset : { 0.0, 3000.0 }) {
        Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0.4), Eigen::Vector2i(10, 4));
        m.rest_positions.array() += offset;
        FfdLattice lattice;
        lattice.lower = VectorXd::Constant(2, offset - 0.1);
        lattice.upper = VectorXd::Constant(2, offset + 1.1);
        lattice.degree = Eigen::Vector2i(3, 2);
        lattice.axes = { 0, 1 };
        const FreeFormDeformation ffd(m.rest_positions, lattice, "ffd");
        std::mt19937 rng(5);
        std::uniform_real_distribution<double> u(-0.05, 0.05);
        VectorXd x(ffd.in_size());
        for (Index i = 0; i < x.size(); ++i)
            x[i] = u(rng);
        const VectorXd moved = ffd.apply(x);
        Positions current(m.rest_positions.rows(), 2);
        for (Index v = 0; v < current.rows(); ++v)
            current.row(v) = moved.segment<2>(2 * v).transpose();
        const Positions back = ffd.pull_back(current, x);
        EXPECT_LT((back - m.rest_positions).cwiseAbs().maxCoeff(), 1e-9 * (1 + offset)) << offset;
    }
}

namespace {

const char* beam_problem = R"({
  "scene": {
    "dimension": 2,
    "bodies": [ { "name": "beam", "mesh": { "box": { "min": [0, 0], "max": [1.0, 0.2], "cells": [40, 8] } },
                  "material": { "model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": 1000 } } ],
    "dirichlet": [ { "body": "beam", "region": { "min": [-1, -1], "max": [1e-6, 1] }, "displacement": [0, 0] } ],
    "neumann": [ { "body": "beam", "region": { "min": [0.999, -1], "max": [2, 2] }, "traction": [0, "-4e4*t"] } ],
    "time": { "integrator": "static", "dt": 0.5, "steps": 2 },
    "solver": { "residual_tolerance": 1e-10 }
  },
  "objective": { "type": "compliance", "time": "final" },
  "parameters": [ { "type": "shape", "lower": -0.1, "upper": 0.1, "maps": [
    { "type": "ffd", "box": { "min": [-0.01, -0.05], "max": [1.01, 0.25] }, "degree": [4, 2], "axes": [1],
      "fixed_border": true } ] } ],
  "constraints": [ { "name": "area", "objective": { "type": "volume", "configuration": "rest" }, "upper": 0.25 } ],
  "remesh": { "quality": 0.5, "size": 0.025 }
})";

} // namespace

TEST(Remesh, DesignProblemKeepsItsVariablesAndJAcrossARemesh)
{
    const ReducedFunctional rf(nlohmann::json::parse(beam_problem), ".", "test");
    DesignProblem problem(rf);
    const std::string dir
        = (std::filesystem::temp_directory_path() / ("diffipc_test_remesh_" + std::to_string(::getpid()))).string();
    std::filesystem::remove_all(dir);
    problem.set_remesh_directory(dir);
    VectorXd x = VectorXd::Zero(rf.design_size());
    for (Index i = 0; i < x.size(); ++i)
        x[i] = 0.04 * std::sin(1.0 + 2.0 * double(i));
    OptimizationValues before;
    ASSERT_TRUE(problem.evaluate(x, before));
    // Not below the threshold: no remesh unless forced.
    EXPECT_FALSE(problem.remesh_if_needed(x, 3));
    ASSERT_TRUE(problem.remesh_if_needed(x, 3, true)) << problem.remesh_failure();
    ASSERT_EQ(problem.remeshes().size(), 1u);
    const RemeshRecord& r = problem.remeshes()[0];
    EXPECT_EQ(r.iteration, 3);
    EXPECT_NE(r.elements_after, r.elements_before);
    EXPECT_TRUE(std::filesystem::exists(r.files.at(0)));
    EXPECT_EQ(problem.functional().design_size(), rf.design_size());
    EXPECT_NE(problem.functional().scene().mesh.num_elements(), rf.scene().mesh.num_elements());
    // The domain is the same at x: the rest area agrees to round-off, and the compliance
    // (P1 on meshes of size 0.025: the discretization tolerance is 1%) to the discretization error.
    EXPECT_NEAR(r.constraints_after[0], r.constraints_before[0], 1e-12 * r.constraints_before[0]);
    // Measured: 7038.04 -> 7061.73 (0.34%; 640 structured -> 754 unstructured triangles, h = 0.025).
    EXPECT_NEAR(r.J_after, r.J_before, 0.01 * r.J_before);
    // Evaluating through the problem now uses the new mesh, with the same design vector.
    OptimizationValues after;
    ASSERT_TRUE(problem.evaluate(x, after));
    EXPECT_NEAR(after.f * problem.objective_scale(), r.J_after, 1e-10 * r.J_after);
    EXPECT_EQ(after.gradient.size(), before.gradient.size());
    // The new mesh at x is valid (positive areas computed here).
    const Scene& scene = problem.functional().scene();
    const VectorXd X = problem.functional().rest_positions_of(problem.functional().parameters_of(x));
    Positions P(scene.body_vertices, 2);
    for (Index v = 0; v < P.rows(); ++v)
        P.row(v) = X.segment<2>(2 * v).transpose();
    for (Index e = 0; e < scene.mesh.num_elements(); ++e)
        EXPECT_GT(triangle_area(P, scene.mesh.elements(e, 0), scene.mesh.elements(e, 1), scene.mesh.elements(e, 2)), 0);
    std::filesystem::remove_all(dir);
}

TEST(Remesh, BadSettingsAndProblemsThatCannotBeRemeshed)
{
    auto doc = nlohmann::json::parse(beam_problem);
    doc["remesh"]["quality"] = 1.5;
    EXPECT_THROW(ReducedFunctional(doc, ".", "t"), InputError);
    doc = nlohmann::json::parse(beam_problem);
    doc["remesh"]["colour"] = 1;
    EXPECT_THROW(ReducedFunctional(doc, ".", "t"), InputError);
    // A shape driven by the mesh's vertices cannot keep its variables across a remesh.
    doc = nlohmann::json::parse(beam_problem);
    doc["parameters"][0]["maps"] = nlohmann::json::parse(
        R"([{"type": "boundary_extension", "vertices": {"region": {"min": [0.01, 0.199], "max": [2, 1]}}, "axes": [1]}])");
    try {
        ReducedFunctional bad(doc, ".", "t");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "remesh");
        EXPECT_NE(std::string(e.what()).find("ffd"), std::string::npos) << e.what();
    }
    // The free-form deformation must give the rest positions: last in its chain.
    doc = nlohmann::json::parse(beam_problem);
    doc["parameters"][0]["maps"].push_back(nlohmann::json::parse(R"({"type": "scale", "scale": 1.0})"));
    try {
        ReducedFunctional bad(doc, ".", "t");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("needs the \"ffd\" map last"), std::string::npos) << e.what();
    }
    // Values per element change in number with the mesh, unless a map takes them from values a
    // remesh keeps (one per body).
    doc = nlohmann::json::parse(beam_problem);
    doc["parameters"].push_back(
        nlohmann::json::parse(R"({"type": "density", "per": "element", "maps": [{"type": "exp"}]})"));
    try {
        ReducedFunctional bad(doc, ".", "t");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("one per element, vertex or prescribed value"), std::string::npos)
            << e.what();
    }
    doc["parameters"][1]["maps"].push_back(nlohmann::json::parse(R"({"type": "per_body"})"));
    EXPECT_NO_THROW(ReducedFunctional(doc, ".", "t"));
    // Markers selected by vertex index would be renumbered.
    doc = nlohmann::json::parse(beam_problem);
    doc["objective"]
        = nlohmann::json::parse(R"({"type": "markers", "vertices": [3], "targets": [[[1.0, 0.1]]], "steps": [2]})");
    try {
        ReducedFunctional bad(doc, ".", "t");
        FAIL() << "expected an InputError";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("objective.vertices"), std::string::npos) << e.what();
    }
}
