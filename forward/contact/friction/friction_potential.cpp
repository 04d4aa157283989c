#include "forward/contact/friction/friction_potential.hpp"

#include "forward/common/parallel.hpp"

#include "forward/contact/barrier.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/distance/distance.hpp"
#include "forward/kernels/friction_pair.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

namespace {

    /// Parameter of the projection of p onto the line through a, b (not clamped).
    double line_parameter(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b)
    {
        const Eigen::Vector3d e = b - a;
        return (p - a).dot(e) / e.squaredNorm();
    }

    /// Closest points of the two lines (parameters along a and along b), clamped to
    /// [0, 1]. D = |u x v|^2 as in the classifier: a*c - b*b cancels to 0 for
    /// edges within ~1e-8 rad of parallel that the classifier still calls EA_EB.
    Eigen::Vector2d line_line_parameters(
        const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& b0, const Eigen::Vector3d& b1)
    {
        const Eigen::Vector3d u = a1 - a0, v = b1 - b0, w = a0 - b0;
        const double b = u.dot(v), a = u.dot(u), c = v.dot(v), d = u.dot(w), e = v.dot(w);
        const double D = u.cross(v).squaredNorm();
        if (!(D > 0))
            return { 0.5, std::clamp(line_parameter(0.5 * (a0 + a1), b0, b1), 0.0, 1.0) };
        return { std::clamp((b * e - c * d) / D, 0.0, 1.0), std::clamp((a * e - b * d) / D, 0.0, 1.0) };
    }

} // namespace

std::array<double, 4> closest_point_weights(const Contact& c, const VectorXd& x, int dim)
{
    {
        const auto& v = c.vertices;
        switch (c.kind) {
        case ContactKind::VERTEX_PLANE:
            return { 1, -1, 0, 0 };
        case ContactKind::VERTEX_EDGE: {
            const auto type = PointEdgeDistanceType(c.distance_type);
            if (type == PointEdgeDistanceType::P_E0)
                return { 1, -1, 0, 0 };
            if (type == PointEdgeDistanceType::P_E1)
                return { 1, 0, -1, 0 };
            const double a
                = line_parameter(vertex_point(x, v[0], dim), vertex_point(x, v[1], dim), vertex_point(x, v[2], dim));
            return { 1, -(1 - a), -a, 0 };
        }
        case ContactKind::VERTEX_FACE: {
            using PT = PointTriangleDistanceType;
            const Eigen::Vector3d p = vertex_point(x, v[0], dim), t0 = vertex_point(x, v[1], dim),
                                  t1 = vertex_point(x, v[2], dim), t2 = vertex_point(x, v[3], dim);
            switch (PT(c.distance_type)) {
            case PT::P_T0:
                return { 1, -1, 0, 0 };
            case PT::P_T1:
                return { 1, 0, -1, 0 };
            case PT::P_T2:
                return { 1, 0, 0, -1 };
            case PT::P_E0: {
                const double a = line_parameter(p, t0, t1);
                return { 1, -(1 - a), -a, 0 };
            }
            case PT::P_E1: {
                const double a = line_parameter(p, t1, t2);
                return { 1, 0, -(1 - a), -a };
            }
            case PT::P_E2: {
                const double a = line_parameter(p, t2, t0);
                return { 1, -a, 0, -(1 - a) };
            }
            case PT::P_T: {
                // Barycentric coordinates of the projection of p onto the plane.
                // q = t0 + b1 (t1 - t0) + b2 (t2 - t0); b1, b2 from ratios of signed areas.
                const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
                const double nn = n.squaredNorm();
                const double b1 = (p - t0).cross(t2 - t0).dot(n) / nn;
                const double b2 = (t1 - t0).cross(p - t0).dot(n) / nn;
                return { 1, -(1 - b1 - b2), -b1, -b2 };
            }
            }
            break;
        }
        case ContactKind::EDGE_EDGE: {
            using EE = EdgeEdgeDistanceType;
            const Eigen::Vector3d a0 = vertex_point(x, v[0], dim), a1 = vertex_point(x, v[1], dim),
                                  b0 = vertex_point(x, v[2], dim), b1 = vertex_point(x, v[3], dim);
            switch (EE(c.distance_type)) {
            case EE::EA0_EB0:
                return { 1, 0, -1, 0 };
            case EE::EA0_EB1:
                return { 1, 0, 0, -1 };
            case EE::EA1_EB0:
                return { 0, 1, -1, 0 };
            case EE::EA1_EB1:
                return { 0, 1, 0, -1 };
            case EE::EA_EB0: {
                const double s = line_parameter(b0, a0, a1);
                return { 1 - s, s, -1, 0 };
            }
            case EE::EA_EB1: {
                const double s = line_parameter(b1, a0, a1);
                return { 1 - s, s, 0, -1 };
            }
            case EE::EA0_EB: {
                const double t = line_parameter(a0, b0, b1);
                return { 1, 0, -(1 - t), -t };
            }
            case EE::EA1_EB: {
                const double t = line_parameter(a1, b0, b1);
                return { 0, 1, -(1 - t), -t };
            }
            case EE::EA_EB: {
                const Eigen::Vector2d st = line_line_parameters(a0, a1, b0, b1);
                return { 1 - st[0], st[0], -(1 - st[1]), -st[1] };
            }
            }
            break;
        }
        }
        throw std::logic_error("closest_point_weights: unknown contact");
    }
}

namespace {

    /// Orthonormal columns spanning the plane normal to n (2D: one column).
    Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& n, int dim)
    {
        Eigen::Matrix<double, 3, 2> T = Eigen::Matrix<double, 3, 2>::Zero();
        if (dim == 2) {
            T.col(0) << -n[1], n[0], 0;
            return T;
        }
        Eigen::Index axis;
        n.cwiseAbs().minCoeff(&axis);
        const Eigen::Vector3d t0 = n.cross(Eigen::Vector3d::Unit(axis)).normalized();
        T.col(0) = t0;
        T.col(1) = n.cross(t0);
        return T;
    }

} // namespace

double FrictionPotential::f0(double y, double eps) { return kernels::friction_f0(y, eps); }

double FrictionPotential::f1(double y, double eps) { return kernels::friction_f1(y, eps); }

double FrictionPotential::f1_derivative(double y, double eps) { return kernels::friction_f1_derivative(y, eps); }

kernels::FrictionPair friction_pair(const FrictionContact& c)
{
    kernels::FrictionPair f;
    f.num_vertices = c.num_vertices;
    for (int a = 0; a < 4; ++a)
        f.weights[a] = c.weights[size_t(a)];
    for (int col = 0; col < 2; ++col)
        for (int i = 0; i < 3; ++i)
            f.tangent[3 * col + i] = c.tangent(i, col);
    f.scale = c.coefficient * c.normal_force;
    return f;
}

FrictionPotential::FrictionPotential(
    int dim, std::vector<double> group_coefficient, VectorXi vertex_group, double eps_v)
    : m_dim(dim)
    , m_group_coefficient(std::move(group_coefficient))
    , m_vertex_group(std::move(vertex_group))
    , m_eps_v(eps_v)
{
}

void FrictionPotential::set_images(SparseMatrixd T, VectorXi surface_group)
{
    if (T.rows() != surface_group.size() * m_dim)
        throw std::invalid_argument("FrictionPotential::set_images: T must have a row per surface dof");
    m_images = SurfaceImages(std::move(T), m_dim);
    m_vertex_group = std::move(surface_group);
    m_contacts.clear();
}

void FrictionPotential::set_step(const VectorXd& x_start, double dt)
{
    VectorXd storage;
    m_x_start = surface(x_start, storage);
    m_eps = m_eps_v * dt;
}

void FrictionPotential::lag(const ContactPotential& contact, const VectorXd& mesh_x_lagged)
{
    lag(contact, contact.contacts(mesh_x_lagged), mesh_x_lagged);
}

void FrictionPotential::lag(const ContactPotential& contact, const ContactSet& set, const VectorXd& mesh_x_lagged)
{
    if (contact.has_images() != has_images())
        throw std::logic_error("FrictionPotential::lag: the barrier and the friction differ in periodic images");
    const VectorXd x_lagged = contact.surface_positions(mesh_x_lagged); // the contacts' indices
    const ContactSettings& s = contact.settings();
    const double dmin2 = s.min_distance * s.min_distance;
    // In contact order, whatever the thread count.
    m_contacts = parallel_collect<FrictionContact>(set.size(), 64, [&](size_t k, std::vector<FrictionContact>& out) {
        const Contact& c = set[k];
        const int other = c.kind == ContactKind::EDGE_EDGE ? 2 : 1;
        const int ga = m_vertex_group[c.vertices[0]], gb = m_vertex_group[c.vertices[size_t(other)]];
        const double mu = std::sqrt(m_group_coefficient[size_t(ga)] * m_group_coefficient[size_t(gb)]);
        if (!(mu > 0) || !(c.distance_squared > dmin2))
            return;
        FrictionContact f;
        f.kind = c.kind;
        f.vertices = c.vertices;
        f.num_vertices = c.num_vertices();
        f.weights = closest_point_weights(c, x_lagged, m_dim);
        Eigen::Vector3d r = Eigen::Vector3d::Zero();
        for (int i = 0; i < f.num_vertices; ++i)
            r += f.weights[size_t(i)] * vertex_point(x_lagged, f.vertices[size_t(i)], m_dim);
        f.normal = c.kind == ContactKind::VERTEX_PLANE ? contact.planes()[size_t(c.plane)].normal : r.normalized();
        bool finite = f.normal.allFinite();
        for (double g : f.weights)
            finite = finite && std::isfinite(g);
        if (!finite)
            return; // a degenerate pair (its barrier is finite; it simply exerts no friction)
        f.tangent = tangent_basis(f.normal, m_dim);
        // lambda = kappa m |d b / d d| = kappa m |b'(s)| 2 d, with s = d^2 - dmin^2 (the barrier;
        // the penalty's is kappa m (dhat - d)).
        const double d = std::sqrt(c.distance_squared);
        double m = 1;
        if (c.kind == ContactKind::EDGE_EDGE)
            m = edge_edge_mollifier(vertex_point(x_lagged, c.vertices[0], m_dim),
                vertex_point(x_lagged, c.vertices[1], m_dim), vertex_point(x_lagged, c.vertices[2], m_dim),
                vertex_point(x_lagged, c.vertices[3], m_dim), c.mollifier_threshold);
        f.normal_force = contact.kappa() * m * contact.normal_force_per_stiffness(d);
        f.coefficient = mu;
        f.groups = { ga, gb };
        f.source = c;
        if (f.normal_force > 0)
            out.push_back(f);
    });
}

double FrictionPotential::pair(const FrictionContact& c, const VectorXd& x, double* gradient, double* hessian) const
{
    kernels::vec3 dx[4];
    for (int i = 0; i < c.num_vertices; ++i) {
        const Index v = c.vertices[size_t(i)];
        double d[3] = { 0, 0, 0 };
        for (int a = 0; a < m_dim; ++a)
            d[a] = x[v * m_dim + a] - m_x_start[v * m_dim + a];
        dx[i] = kernels::vec3(d[0], d[1], d[2]);
    }
    return kernels::pair_friction(m_dim, friction_pair(c), dx, m_eps, gradient, hessian);
}

double FrictionPotential::value(const VectorXd& mesh_x) const
{
    VectorXd storage;
    const VectorXd& x = surface(mesh_x, storage);
    return parallel_sum(m_contacts.size(), 64, [&](size_t k) { return pair(m_contacts[k], x, nullptr, nullptr); });
}

void FrictionPotential::add_gradient(const VectorXd& mesh_x, double weight, VectorXd& mesh_g) const
{
    VectorXd storage, surface_g;
    const VectorXd& x = surface(mesh_x, storage);
    if (has_images())
        surface_g = VectorXd::Zero(x.size());
    VectorXd& g = has_images() ? surface_g : mesh_g;
    // Local forces in parallel, gathered per vertex in contact order (the serial sum).
    std::vector<double>& locals = m_gradient_buffer;
    locals.assign(m_contacts.size() * 4 * size_t(m_dim), 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m_contacts.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        double local[12];
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const FrictionContact& c = m_contacts[k];
            pair(c, x, local, nullptr);
            for (int i = 0; i < c.num_vertices * m_dim; ++i)
                locals[4 * k * size_t(m_dim) + size_t(i)] = weight * local[i];
        }
    });
    m_scatter.build(x.size() / m_dim, m_contacts.size(), 4, [&](size_t k, int a) {
        return a < m_contacts[k].num_vertices ? m_contacts[k].vertices[size_t(a)] : Index(-1);
    });
    m_scatter.add(locals.data(), m_dim, 1.0, g);
    if (has_images())
        m_images.add_back(surface_g, mesh_g);
}

void FrictionPotential::add_hessian(
    const VectorXd& mesh_x, double weight, bool project_to_psd, SparseAssembler& mesh_H) const
{
    (void)project_to_psd; // PSD by construction (see the file comment)
    VectorXd storage;
    const VectorXd& x = surface(mesh_x, storage);
    // With images the locals go into the surface's assembler first, then T^T H_s T into mesh_H.
    SparseAssembler& H = m_images.hessian_target(mesh_H);
    const size_t first = H.reserve_locals(m_contacts.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m_contacts.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        double row_major[144], local[144];
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const FrictionContact& c = m_contacts[k];
            pair(c, x, nullptr, row_major);
            const int n = c.num_vertices * m_dim;
            for (int i = 0; i < n; ++i) // column-major for set_local
                for (int j = 0; j < n; ++j)
                    local[j * n + i] = weight * row_major[i * n + j];
            H.set_local(first + k, c.vertices.data(), c.num_vertices, local);
        }
    });
    m_images.finish_hessian(mesh_H);
}

} // namespace diffipc
