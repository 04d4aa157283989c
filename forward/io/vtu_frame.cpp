#include "forward/io/vtu_frame.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <filesystem>

namespace diffipc {

namespace {

    /// Vertex v of flattened #V*dim values as a 3-vector (z = 0 in 2D).
    Eigen::Vector3d vertex3(const VectorXd& values, Index v, int dim)
    {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        p.head(dim) = values.segment(v * dim, dim);
        return p;
    }

    /// Vertices [0, count) of flattened #V*dim values as #count*3 (z = 0 in 2D), minus `minus` if given.
    std::vector<double> point_vectors(const VectorXd& values, Index count, int dim, const Positions* minus = nullptr)
    {
        std::vector<double> out(size_t(count) * 3, 0.0);
        for (Index v = 0; v < count; ++v)
            for (int c = 0; c < dim; ++c)
                out[size_t(v * 3 + c)] = values[v * dim + c] - (minus ? (*minus)(v, c) : 0.0);
        return out;
    }

    /// Unit vectors t1, t2 with t1 x t2 = n (n a unit 3-vector).
    std::pair<Eigen::Vector3d, Eigen::Vector3d> tangents(const Eigen::Vector3d& n)
    {
        Eigen::Index axis;
        n.cwiseAbs().minCoeff(&axis); // the axis least aligned with n
        const Eigen::Vector3d t1 = n.cross(Eigen::Vector3d::Unit(axis)).normalized();
        return { t1, n.cross(t1) };
    }

    /// Rest bounding box (min, max, as 3-vectors) of the bodies and the obstacle meshes.
    std::pair<Eigen::Vector3d, Eigen::Vector3d> rest_bounding_box(const Scene& scene)
    {
        const int d = scene.dim;
        Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
        lo.head(d).setConstant(INFINITY);
        hi.head(d).setConstant(-INFINITY);
        auto include = [&](Index first, Index count) {
            for (Index v = first; v < first + count; ++v)
                for (int c = 0; c < d; ++c) {
                    lo[c] = std::min(lo[c], scene.mesh.rest_positions(v, c));
                    hi[c] = std::max(hi[c], scene.mesh.rest_positions(v, c));
                }
        };
        include(0, scene.body_vertices);
        for (const ObstacleSpec& o : scene.obstacles)
            if (o.type == ObstacleType::MESH)
                include(o.first_vertex, o.num_vertices);
        return { lo, hi };
    }

} // namespace

FrameState frame_state(const Simulator& simulator)
{
    FrameState s;
    s.positions = simulator.positions();
    s.velocities = simulator.velocities();
    if (simulator.contact())
        s.contact_forces = simulator.contact_forces();
    if (simulator.friction())
        s.friction_forces = simulator.friction_forces();
    return s;
}

double plane_patch_size(const Scene& scene)
{
    const auto [lo, hi] = rest_bounding_box(scene);
    return 2 * (hi - lo).norm();
}

VtuGrid body_grid(const Simulator& simulator, const FrameState& state)
{
    const Scene& scene = simulator.scene();
    const Mesh& mesh = scene.mesh;
    const int d = mesh.dim;
    const Index nv = scene.body_vertices, ne = mesh.num_elements();
    VtuGrid g;
    g.points = point_vectors(state.positions, nv, d);
    g.connectivity.reserve(size_t(ne * (d + 1)));
    for (Index e = 0; e < ne; ++e) {
        Index cell[4];
        for (int a = 0; a <= d; ++a)
            cell[a] = mesh.elements(e, a);
        g.add_cell(d == 2 ? VtkCell::TRIANGLE : VtkCell::TETRA, cell, d + 1);
    }

    g.point_data.push_back({ "displacement", 3, point_vectors(state.positions, nv, d, &mesh.rest_positions) });
    g.point_data.push_back({ "velocity", 3, point_vectors(state.velocities, nv, d) });
    if (state.contact_forces.size())
        g.point_data.push_back({ "contact_force", 3, point_vectors(state.contact_forces, nv, d) });
    if (state.friction_forces.size())
        g.point_data.push_back({ "friction_force", 3, point_vectors(state.friction_forces, nv, d) });

    const size_t cells = static_cast<size_t>(ne);
    std::vector<std::int32_t> body(cells);
    std::vector<double> volume_ratio(cells), stress(cells * 9), von_mises(cells);
    const Positions P = unflatten(state.positions, d);
    const MatrixXd sigma = simulator.elastic().element_cauchy_stresses(state.positions);
    for (Index e = 0; e < ne; ++e) {
        body[size_t(e)] = mesh.element_body[e];
        volume_ratio[size_t(e)] = signed_volume(P, mesh.elements, e) / simulator.space().rest_volume(e);
        Eigen::Matrix3d S;
        for (int k = 0; k < 9; ++k)
            stress[size_t(e * 9 + k)] = S(k / 3, k % 3) = sigma(e, k);
        von_mises[size_t(e)] = von_mises_stress(S);
    }
    g.cell_data.push_back({ "body", 1, std::move(body) });
    g.cell_data.push_back({ "volume_ratio", 1, std::move(volume_ratio) });
    g.cell_data.push_back({ "stress", 9, std::move(stress) });
    g.cell_data.push_back({ "von_mises", 1, std::move(von_mises) });
    return g;
}

VtuGrid obstacle_grid(const Simulator& simulator, const FrameState& state)
{
    const Scene& scene = simulator.scene();
    const Mesh& mesh = scene.mesh;
    const int d = scene.dim;
    const Index nb = Index(scene.bodies.size());
    VtuGrid g;
    std::vector<double> contact, friction;
    std::vector<std::int32_t> obstacle;
    // A point at p carrying the forces on mesh vertex v (none: v < 0).
    auto add_point = [&](const Eigen::Vector3d& p, Index v) {
        const Index i = g.add_point(p.data(), 3);
        auto append = [&](const VectorXd& forces, std::vector<double>& out) {
            if (forces.size() == 0)
                return;
            const Eigen::Vector3d f = v >= 0 ? vertex3(forces, v, d) : Eigen::Vector3d::Zero();
            out.insert(out.end(), f.data(), f.data() + 3);
        };
        append(state.contact_forces, contact);
        append(state.friction_forces, friction);
        return i;
    };

    const auto [lo, hi] = rest_bounding_box(scene);
    const Eigen::Vector3d center = (lo + hi) / 2;
    const double half = plane_patch_size(scene) / 2;
    std::vector<Index> first_point(scene.obstacles.size(), -1);
    for (size_t k = 0; k < scene.obstacles.size(); ++k) {
        const ObstacleSpec& o = scene.obstacles[k];
        if (o.type == ObstacleType::MESH) {
            first_point[k] = g.num_points();
            for (Index v = o.first_vertex; v < o.first_vertex + o.num_vertices; ++v)
                add_point(vertex3(state.positions, v, d), v);
            continue;
        }
        Eigen::Vector3d n = Eigen::Vector3d::Zero();
        n.head(d) = o.normal;
        Eigen::Vector3d rest_point = Eigen::Vector3d::Zero();
        rest_point.head(d) = mesh.rest_positions.row(o.first_vertex).transpose();
        const Eigen::Vector3d point = vertex3(state.positions, o.first_vertex, d);
        // The foot of the rest bounding-box centre on the plane, moved as the plane moved.
        const Eigen::Vector3d c = center - (center - rest_point).dot(n) * n + (point - rest_point);
        if (d == 2) {
            const Eigen::Vector3d t(-n[1], n[0], 0);
            const Index a = add_point(c - half * t, -1), b = add_point(c + half * t, -1);
            g.add_cell(VtkCell::LINE, { a, b });
        } else {
            const auto [t1, t2] = tangents(n);
            Index q[4];
            const double s1[4] = { -1, 1, 1, -1 }, s2[4] = { -1, -1, 1, 1 };
            for (int i = 0; i < 4; ++i)
                q[i] = add_point(c + half * (s1[i] * t1 + s2[i] * t2), -1); // counter-clockwise about n
            g.add_cell(VtkCell::QUAD, q, 4);
        }
        obstacle.push_back(std::int32_t(k));
        g.add_cell(VtkCell::VERTEX, { add_point(point, o.first_vertex) });
        obstacle.push_back(std::int32_t(k));
    }
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        const Index k = mesh.facet_body[f] - nb;
        if (k < 0)
            continue;
        const ObstacleSpec& o = scene.obstacles[size_t(k)];
        Index cell[3];
        for (int a = 0; a < d; ++a)
            cell[a] = first_point[size_t(k)] + mesh.boundary_facets(f, a) - o.first_vertex;
        g.add_cell(d == 2 ? VtkCell::LINE : VtkCell::TRIANGLE, cell, d);
        obstacle.push_back(std::int32_t(k));
    }
    if (state.contact_forces.size())
        g.point_data.push_back({ "contact_force", 3, std::move(contact) });
    if (state.friction_forces.size())
        g.point_data.push_back({ "friction_force", 3, std::move(friction) });
    g.cell_data.push_back({ "obstacle", 1, std::move(obstacle) });
    return g;
}

std::string body_frame_name(int index) { return "frame_" + std::to_string(index) + ".vtu"; }
std::string obstacle_frame_name(int index) { return "obstacles_" + std::to_string(index) + ".vtu"; }

std::vector<PvdEntry> write_vtu_frame(
    const std::string& directory, int index, double time, const Simulator& simulator, VtuEncoding encoding)
{
    namespace fs = std::filesystem;
    const FrameState state = frame_state(simulator);
    std::vector<PvdEntry> entries;
    const std::string bodies = body_frame_name(index);
    write_vtu((fs::path(directory) / bodies).string(), body_grid(simulator, state), encoding);
    entries.push_back({ time, 0, bodies });
    if (!simulator.scene().obstacles.empty()) {
        const std::string obstacles = obstacle_frame_name(index);
        write_vtu((fs::path(directory) / obstacles).string(), obstacle_grid(simulator, state), encoding);
        entries.push_back({ time, 1, obstacles });
    }
    return entries;
}

} // namespace diffipc
