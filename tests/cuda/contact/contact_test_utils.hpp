#pragma once
// Helpers shared by the tests of cuda/contact: contact scenes built with the CPU Simulator, their
// active pairs as BarrierPair lists, and the CPU ContactPotential's results in comparable form.

#include "cuda/contact/barrier_pairs.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/friction/friction_potential.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "tests/cuda/elastic_test_utils.hpp"
#include "tests/forward/contact/contact_scenes.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/SparseCore>

#include <cmath>
#include <memory>
#include <vector>

namespace diffipc::test {

/// A scene with active contacts: the simulator (its ContactPotential is the CPU reference) and a
/// state x at which contacts of every kind of the dimension are active.
struct ContactScene {
    std::unique_ptr<Simulator> sim;
    VectorXd x;

    const ContactPotential& contact() const { return *sim->contact(); }
    int dim() const { return sim->scene().dim; }
    std::vector<double> x_vector() const { return std::vector<double>(x.data(), x.data() + x.size()); }
    std::vector<double> rest_vector() const
    {
        const VectorXd r = flatten(sim->mesh().rest_positions);
        return std::vector<double>(r.data(), r.data() + r.size());
    }
    /// The planes' unit normals, 3 per plane.
    std::vector<double> plane_normals() const
    {
        std::vector<double> n;
        for (const ContactPlane& p : contact().planes())
            n.insert(n.end(), { p.normal.x(), p.normal.y(), p.normal.z() });
        return n;
    }
    /// The CPU's active set at x, as DeviceBarrier takes it.
    std::vector<gpu::BarrierPair> pairs() const { return pairs_at(x); }
    std::vector<gpu::BarrierPair> pairs_at(const VectorXd& y) const
    {
        std::vector<gpu::BarrierPair> out;
        for (const Contact& c : contact().contacts(y)) {
            gpu::BarrierPair p;
            p.kind = int(c.kind);
            for (int a = 0; a < 4; ++a)
                p.vertices[a] = a < c.num_vertices() ? int(c.vertices[size_t(a)]) : -1;
            p.plane = c.plane;
            out.push_back(p);
        }
        return out;
    }
    /// Active edge-edge pairs whose mollifier is below 1 (nearly parallel edges).
    int mollified() const
    {
        int count = 0;
        for (const Contact& c : contact().contacts(x))
            count += c.kind == ContactKind::EDGE_EDGE && contact().local_distance(c, x, false).m < 1;
        return count;
    }
    /// Counts of the active pairs per kind (ContactKind order).
    std::array<int, 4> kinds() const
    {
        std::array<int, 4> k = { 0, 0, 0, 0 };
        for (const Contact& c : contact().contacts(x))
            ++k[size_t(c.kind)];
        return k;
    }
};

/// Friction lagged at a scene's x (mu 0.3, 0.5, 0.4, 0.6 per contact group, eps_v 1e-3 m/s, h = 0.01 s:
/// eps = 1e-5 m), from the step start x0 = x - motion * a random vector (|u| below eps: sticking pairs;
/// well above: sliding ones).
struct LaggedFriction {
    std::unique_ptr<FrictionPotential> friction;
    VectorXd x0;
};
inline LaggedFriction lagged_friction(const ContactScene& scene, double motion)
{
    const Simulator& sim = *scene.sim;
    const std::vector<double> mu = { 0.3, 0.5, 0.4, 0.6 };
    const std::vector<double> groups(
        mu.begin(), mu.begin() + Index(sim.scene().bodies.size() + sim.scene().obstacles.size()));
    LaggedFriction out;
    out.friction = std::make_unique<FrictionPotential>(scene.dim(), groups, sim.mesh().vertex_body, 1e-3);
    out.x0 = scene.x - motion * random_vector(scene.x.size(), 3);
    out.friction->set_step(out.x0, 0.01);
    out.friction->lag(scene.contact(), scene.x);
    return out;
}

/// Two 3D boxes, the upper one turned by `angle` about the vertical so that edges cross edges,
/// 0.5 mm apart and 0.5 mm above a plane, cells^2 x 2 cells each; positions jiggled by
/// `jiggle` (m). `contact` is the scene's contact block.
inline ContactScene boxes_on_plane(int cells, double angle, double jiggle, const nlohmann::json& contact)
{
    nlohmann::json s;
    s["dimension"] = 3;
    const std::vector<int> c = { cells, 2, cells };
    s["bodies"] = { box_body("a", { 0, 0.0005, 0 }, { 1, 0.5, 1 }, c),
        box_body("b", { 0.1, 0.5005, 0.1 }, { 0.9, 1.0, 0.9 }, c) };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0, 0 } }, { "normal", { 0, 1, 0 } } } } } };
    s["contact"] = contact;
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    ContactScene scene;
    scene.sim = std::make_unique<Simulator>(make_scene(s));
    VectorXd x = scene.sim->positions();
    for (Index v = 0; v < scene.sim->scene().body_vertices; ++v) {
        if (scene.sim->mesh().vertex_body[v] != 1)
            continue;
        const double px = x[v * 3] - 0.5, pz = x[v * 3 + 2] - 0.5;
        x[v * 3] = 0.5 + std::cos(angle) * px - std::sin(angle) * pz;
        x[v * 3 + 2] = 0.5 + std::sin(angle) * px + std::cos(angle) * pz;
    }
    scene.x = x + jiggle * random_vector(x.size(), 11);
    return scene;
}

/// Two 2D rings within 0.5 mm of a plane and of each other (vertex-edge and vertex-plane pairs).
inline ContactScene rings_on_plane(double jiggle, const nlohmann::json& contact)
{
    ContactScene scene;
    scene.sim = std::make_unique<Simulator>(make_scene(test::rings_on_plane(contact)));
    scene.x = scene.sim->positions() + jiggle * random_vector(scene.sim->positions().size(), 7);
    return scene;
}

/// Two 2D boxes, the upper one tilted by `angle` (rad) about its centre, 0.5 mm apart and 0.5 mm
/// above a plane, cells x 2 cells each; positions jiggled by `jiggle` (m): vertex-edge pairs of
/// every closest-feature type and vertex-plane pairs.
inline ContactScene boxes_on_plane_2d(int cells, double angle, double jiggle, const nlohmann::json& contact)
{
    nlohmann::json s;
    s["dimension"] = 2;
    const std::vector<int> c = { cells, 2 };
    s["bodies"] = { box_body("a", { 0, 0.0005 }, { 1, 0.5 }, c), box_body("b", { 0.1, 0.5005 }, { 0.9, 1.0 }, c) };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = contact;
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    ContactScene scene;
    scene.sim = std::make_unique<Simulator>(make_scene(s));
    VectorXd x = scene.sim->positions();
    for (Index v = 0; v < scene.sim->scene().body_vertices; ++v) {
        if (scene.sim->mesh().vertex_body[v] != 1)
            continue;
        const double px = x[v * 2] - 0.5, py = x[v * 2 + 1] - 0.75;
        x[v * 2] = 0.5 + std::cos(angle) * px - std::sin(angle) * py;
        x[v * 2 + 1] = 0.75 + std::sin(angle) * px + std::cos(angle) * py;
    }
    scene.x = x + jiggle * random_vector(x.size(), 13);
    return scene;
}

/// The CPU barrier's full symmetric Hessian (weight * kappa * sum of the pair Hessians, projected
/// or not) at the scene's x.
inline SparseMatrixd cpu_barrier_hessian(const ContactScene& scene, const VectorXd& x, double weight, bool project)
{
    SparseAssembler H;
    const Mesh& mesh = scene.sim->mesh();
    H.build(mesh.dim, mesh.num_vertices(), mesh.elements);
    H.set_zero();
    scene.contact().add_hessian(x, weight, project, H);
    H.finalize();
    return H.matrix().selfadjointView<Eigen::Lower>();
}

/// The CPU barrier's gradient (weight * kappa * dB/dx) at x.
inline VectorXd cpu_barrier_gradient(const ContactScene& scene, const VectorXd& x, double weight)
{
    VectorXd g = VectorXd::Zero(x.size());
    scene.contact().add_gradient(x, weight, g);
    return g;
}

inline Eigen::Map<const VectorXd> as_eigen(const std::vector<double>& v)
{
    return Eigen::Map<const VectorXd>(v.data(), Eigen::Index(v.size()));
}

/// max |a - b| / max |b| over the entries of two sparse matrices (their patterns may differ).
inline double relative_difference(const SparseMatrixd& a, const SparseMatrixd& b)
{
    const SparseMatrixd d = a - b;
    double dmax = 0, bmax = 0;
    for (int k = 0; k < d.outerSize(); ++k)
        for (SparseMatrixd::InnerIterator it(d, k); it; ++it)
            dmax = std::max(dmax, std::abs(it.value()));
    for (int k = 0; k < b.outerSize(); ++k)
        for (SparseMatrixd::InnerIterator it(b, k); it; ++it)
            bmax = std::max(bmax, std::abs(it.value()));
    return bmax > 0 ? dmax / bmax : dmax;
}

} // namespace diffipc::test
