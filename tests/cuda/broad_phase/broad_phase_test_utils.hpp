#pragma once
// Helpers of the GPU broad phase and step bound tests: the CPU collision mesh and candidates in the plain layouts
// of cuda/broad_phase/, and the contact scenes the tests share.

#include "cuda/broad_phase/device_broad_phase.hpp"
#include "cuda/broad_phase/step_bound.hpp"
#include "cuda/common/device.hpp"
#include "forward/contact/broad_phase/broad_phase.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/simulation/device_conversion.hpp"
#include "forward/simulation/device_solver.hpp"
#include "tests/forward/periodic/post_cell.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

namespace diffipc::test {

#define REQUIRE_GPU_FOR_BROAD_PHASE()                                                                                  \
    do {                                                                                                               \
        if (!gpu::cuda_device_available())                                                                             \
            GTEST_SKIP() << gpu::cuda_device_description()                                                             \
                         << " (this test runs the GPU broad phase / step bound; the *Host tests run their "            \
                            "__host__ __device__ code on the CPU)";                                                    \
    } while (0)

/// The CPU CollisionMesh in cuda/broad_phase's plain arrays (DeviceSolver's conversion).
inline gpu::CollisionMeshData to_gpu(const CollisionMesh& m) { return to_device(m); }

/// The CPU planes as the step bound takes them (DeviceSolver's conversion).
inline std::vector<gpu::PlaneObstacle> to_gpu(const std::vector<ContactPlane>& planes) { return to_device(planes); }

inline gpu::StepBoundSettings to_gpu(const ContactSettings& s)
{
    gpu::StepBoundSettings g;
    g.dhat = s.dhat;
    g.min_distance = s.min_distance;
    g.ccd_max_iterations = s.ccd_max_iterations;
    g.ccd_rescaling = s.ccd_rescaling;
    return g;
}

using PairList = std::vector<std::array<int, 2>>;

inline PairList to_int_pairs(const std::vector<std::array<Index, 2>>& pairs)
{
    PairList out;
    out.reserve(pairs.size());
    for (const auto& p : pairs)
        out.push_back({ int(p[0]), int(p[1]) });
    return out;
}

inline std::vector<double> to_std(const VectorXd& x) { return std::vector<double>(x.data(), x.data() + x.size()); }

inline Positions as_positions(const VectorXd& x, int dim) { return unflatten(x, dim); }

/// x plus uniform noise of the given amplitude (m) in every coordinate, fixed seed.
inline VectorXd perturbed(const VectorXd& x, double amplitude, unsigned seed)
{
    return x + amplitude * random_vector(x.size(), seed);
}

/// A contact scene's simulator pieces: the collision mesh, positions, planes and settings the tests use.
struct ContactScene {
    std::string name;
    int dim = 3;
    CollisionMesh mesh;
    std::vector<ContactPlane> planes;
    ContactSettings settings;
    VectorXd x; ///< start positions (#V dim), or surface positions with periodic images
    double size = 1; ///< a typical length (m) for perturbations
};

/// Two neo-Hookean boxes a gap apart (2D: rectangles) along y, with or without a ground plane.
inline nlohmann::json two_boxes(int dim, double gap, bool plane, bool self_contact)
{
    nlohmann::json s;
    s["dimension"] = dim;
    if (dim == 2)
        s["bodies"] = { box_body("lower", { 0, 0 }, { 1, 0.3 }, { 12, 4 }),
            box_body("upper", { 0.25, 0.3 + gap }, { 0.85, 0.6 + gap }, { 9, 5 }) };
    else
        s["bodies"] = { box_body("lower", { 0, 0, 0 }, { 1, 0.2, 1 }, { 6, 2, 6 }),
            box_body("upper", { 0.2, 0.2 + gap, 0.15 }, { 0.8, 0.5 + gap, 0.75 }, { 5, 3, 4 }) };
    for (auto& b : s["bodies"])
        b["self_contact"] = self_contact;
    if (plane) {
        std::vector<double> point(size_t(dim), 0.0), normal(size_t(dim), 0.0);
        point[1] = -0.01;
        normal[1] = 1;
        s["obstacles"] = { { { "name", "ground" }, { "plane", { { "point", point }, { "normal", normal } } } } };
    }
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e5 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    return s;
}

/// Three 2D rings (annuli) stacked close together with self contact, above a ground plane.
inline nlohmann::json rings_2d()
{
    auto ring = [](const std::string& name, double cx, double cy) {
        return nlohmann::json { { "name", name },
            { "mesh",
                { { "annulus",
                    { { "center", { cx, cy } }, { "inner_radius", 0.3 }, { "outer_radius", 0.4 }, { "segments", 48 },
                        { "layers", 2 } } } } },
            { "material", { { "model", "neo_hookean" }, { "E", 5e4 }, { "nu", 0.4 }, { "density", 1000 } } } };
    };
    nlohmann::json s;
    s["dimension"] = 2;
    s["bodies"] = { ring("ring0", 0.0, 0.41), ring("ring1", 0.15, 1.2105), ring("ring2", -0.1, 2.0112) };
    s["obstacles"] = { { { "name", "ground" }, { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e5 }, { "self_contact", true } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    return s;
}

/// The pieces of a Simulator's contact potential for a scene file (positions: the initial ones, or their
/// periodic images' surface positions).
inline ContactScene contact_scene(const std::string& name, const nlohmann::json& j, double size)
{
    Simulator sim(make_scene(j));
    const ContactPotential* contact = sim.contact();
    if (!contact)
        throw std::logic_error(name + ": the scene has no contact");
    ContactScene s;
    s.name = name;
    s.dim = sim.mesh().dim;
    s.mesh = contact->collision_mesh();
    s.planes = contact->planes();
    s.settings = contact->settings();
    s.x = contact->surface_positions(sim.positions());
    s.size = size;
    return s;
}

/// The scenes of the candidate-set comparisons: 2D and 3D, between bodies, with self contact, with planes, with
/// periodic images (2D and 3D cells), and with two kinematic groups (obstacle-obstacle pairs excluded).
inline std::vector<ContactScene> broad_phase_scenes()
{
    std::vector<ContactScene> scenes;
    scenes.push_back(contact_scene("2D boxes", two_boxes(2, 5e-4, false, false), 0.05));
    scenes.push_back(contact_scene("2D boxes, self contact, plane", two_boxes(2, 5e-4, true, true), 0.05));
    scenes.push_back(contact_scene("2D rings, self contact", rings_2d(), 0.03));
    scenes.push_back(contact_scene("3D boxes", two_boxes(3, 5e-4, false, false), 0.1));
    scenes.push_back(contact_scene("3D boxes, self contact, plane", two_boxes(3, 5e-4, true, true), 0.1));
    // Periodic images: the collision mesh is the image surface, with `point` and `edge_source` set. 2D: the post
    // cell of tests/forward/periodic/post_cell.hpp (posts 0.1 m apart across the cell's boundary); 3D: a bar
    // periodic along x, whose side faces meet their images at the faces x = 0 and 1 (the 3D post cell's 18k
    // surface edges would make the brute-force references slow).
    {
        const std::string path = (std::filesystem::temp_directory_path()
            / ("diffipc_broad_phase_post_cell_" + std::to_string(::getpid()) + ".msh"))
                                     .string();
        scenes.push_back(contact_scene("2D periodic post cell", post_cell_scene(2, path, -0.1, 1, 1e3), 0.6));
        std::filesystem::remove(path);
        nlohmann::json bar = box_scene(3, { 1, 0.3, 0.3 }, { 4, 2, 2 });
        bar["periodic"] = { { "gradient", { { "-0.1*t", 0, 0 }, { 0, 0, 0 }, { 0, 0, 0 } } }, { "axes", { "x" } } };
        bar["contact"] = { { "dhat", 1e-2 }, { "kappa", 1e3 } };
        scenes.push_back(contact_scene("3D periodic bar", bar, 0.3));
    }
    // Obstacle-obstacle: the 3D boxes with both groups kinematic and a third body: no pair between the two
    // kinematic groups may appear.
    {
        ContactScene s = contact_scene("3D boxes, kinematic pair", two_boxes(3, 5e-4, false, true), 0.1);
        s.mesh.group_kinematic.assign(s.mesh.group_kinematic.size(), 1);
        scenes.push_back(s);
        s.name = "3D boxes, one kinematic";
        s.mesh.group_kinematic.assign(s.mesh.group_kinematic.size(), 0);
        s.mesh.group_kinematic[1] = 1;
        scenes.push_back(s);
    }
    return scenes;
}

/// A step of a scene: every vertex moves by a random amount of the given amplitude, and the upper body (group 1)
/// also moves by `drop` along -y (into the lower one when drop exceeds the gap).
inline VectorXd scene_step(const ContactScene& s, double amplitude, double drop, unsigned seed)
{
    VectorXd p = amplitude * random_vector(s.x.size(), seed);
    const Index n = s.x.size() / s.dim;
    for (Index v = 0; v < n && v < Index(s.mesh.vertex_group.size()); ++v)
        if (s.mesh.vertex_group[size_t(v)] == 1)
            p[v * s.dim + 1] -= drop;
    return p;
}

} // namespace diffipc::test
