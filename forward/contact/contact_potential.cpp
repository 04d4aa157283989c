#include "forward/contact/contact_potential.hpp"

#include "forward/common/parallel.hpp"
#include "forward/common/timer.hpp"
#include "forward/contact/barrier.hpp"
#include "forward/contact/broad_phase/broad_phase.hpp"
#include "forward/contact/ccd/ccd.hpp"
#include "forward/contact/distance/distance.hpp"
#include "forward/contact/penalty.hpp"
#include "forward/kernels/contact_pair.hpp"
#include "forward/kernels/eigen_bridge.hpp"
#include "forward/materials/material.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace diffipc {

namespace {

    constexpr double INF = std::numeric_limits<double>::infinity();

    Eigen::Vector3d rest_point(const Positions& X, Index v)
    {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        p.head(X.cols()) = X.row(v).transpose();
        return p;
    }

} // namespace

struct ContactPotential::Segment {
    VectorXd x0, p;
    Candidates candidates;
    double tolerance = 0;
    bool valid = false;
};

bool ContactPotential::on_segment(const VectorXd& y) const
{
    const Segment& s = *m_segment;
    if (!s.valid || y.size() != s.x0.size())
        return false;
    Index k = 0;
    const double pmax = s.p.cwiseAbs().maxCoeff(&k);
    if (!(pmax > 0))
        return false;
    // fl(x0 + p) can give alpha = 1 + 1 ulp: accept a sliver beyond the ends, then clamp.
    double alpha = (y[k] - s.x0[k]) / s.p[k];
    if (!(alpha >= -1e-12 && alpha <= 1 + 1e-12))
        return false;
    alpha = std::clamp(alpha, 0.0, 1.0);
    return (y - s.x0 - alpha * s.p).lpNorm<Eigen::Infinity>() <= s.tolerance;
}

ContactPotential::ContactPotential(
    CollisionMesh mesh, const Positions& rest_positions, std::vector<ContactPlane> planes, ContactSettings settings)
    : m_mesh(std::move(mesh))
    , m_rest(rest_positions)
    , m_planes(std::move(planes))
    , m_settings(settings)
    , m_segment(std::make_unique<Segment>())
{
    for (Index k = 0; k < m_mesh.vertices.size(); ++k) {
        const Index v = m_mesh.vertices[k];
        const int g = m_mesh.vertex_group[size_t(v)];
        if (g >= 0 && !m_mesh.group_kinematic[size_t(g)])
            m_plane_vertices.push_back(v);
    }
}

ContactPotential::~ContactPotential() = default;

void ContactPotential::build_contacts(const VectorXd& x, ContactSet& out, double radius) const
{
    const int dim = m_mesh.dim;
    const Positions X = unflatten(x, dim);
    Candidates owned;
    const bool reuse = radius <= m_settings.min_distance + m_settings.dhat && on_segment(x);
    if (!reuse) {
        Timer t;
        owned = broad_phase_candidates(m_mesh, X, X, radius);
        t.add_to(m_times.broad_phase);
    }
    const Candidates& candidates = reuse ? m_segment->candidates : owned;
    Timer t;
    const double r2 = radius * radius;
    const auto& ve = candidates.vertex_edge;
    const auto& vf = candidates.vertex_face;
    const auto& ee = candidates.edge_edge;
    const size_t n_ve = ve.size(), n_vf = vf.size(), n_ee = ee.size();
    const size_t n_plane = m_planes.size() * m_plane_vertices.size();
    // In candidate order (vertex-edge, vertex-face, edge-edge, planes), whatever the thread count;
    // a pair is kept if it is closer than the radius (a plane pair: its signed distance is below it).
    out = parallel_collect<Contact>(n_ve + n_vf + n_ee + n_plane, 512, [&](size_t k, std::vector<Contact>& kept) {
        Contact c;
        if (k < n_ve) {
            const auto& [v, e] = ve[k];
            c = classify(ContactKind::VERTEX_EDGE, { v, m_mesh.edges(e, 0), m_mesh.edges(e, 1), -1 }, -1, x);
        } else if (k < n_ve + n_vf) {
            const auto& [v, f] = vf[k - n_ve];
            c = classify(
                ContactKind::VERTEX_FACE, { v, m_mesh.faces(f, 0), m_mesh.faces(f, 1), m_mesh.faces(f, 2) }, -1, x);
        } else if (k < n_ve + n_vf + n_ee) {
            const auto& [ea, eb] = ee[k - n_ve - n_vf];
            c = classify(ContactKind::EDGE_EDGE,
                { m_mesh.edges(ea, 0), m_mesh.edges(ea, 1), m_mesh.edges(eb, 0), m_mesh.edges(eb, 1) }, -1, x,
                /*threshold=*/false);
        } else {
            const size_t q = k - n_ve - n_vf - n_ee;
            const size_t k_plane = q / m_plane_vertices.size();
            c = classify(ContactKind::VERTEX_PLANE,
                { m_plane_vertices[q % m_plane_vertices.size()], m_planes[k_plane].vertex, -1, -1 }, int(k_plane), x);
        }
        // s < r^2; for a plane pair h < radius, i.e. h^2 < r^2 in front of the plane and s = -1 behind it.
        if (!(c.distance_squared < r2))
            return;
        if (c.kind == ContactKind::EDGE_EDGE) // the mollifier threshold of the kept pairs only
            c.mollifier_threshold
                = edge_edge_mollifier_threshold(rest_point(m_rest, c.vertices[0]), rest_point(m_rest, c.vertices[1]),
                    rest_point(m_rest, c.vertices[2]), rest_point(m_rest, c.vertices[3]));
        kept.push_back(c);
    });
    t.add_to(m_times.barrier);
}

Contact ContactPotential::classify(
    ContactKind kind, const std::array<Index, 4>& vertices, int plane, const VectorXd& x, bool threshold) const
{
    const int dim = m_mesh.dim;
    Contact c;
    c.kind = kind;
    c.vertices = vertices;
    c.plane = plane;
    const auto point = [&](int a) { return vertex_point(x, vertices[size_t(a)], dim); };
    switch (kind) {
    case ContactKind::VERTEX_EDGE: {
        const Eigen::Vector3d p = point(0), a = point(1), b = point(2);
        const PointEdgeDistanceType type = point_edge_distance_type(p, a, b);
        c.distance_type = int(type);
        c.distance_squared = point_edge_distance(p, a, b, type);
        break;
    }
    case ContactKind::VERTEX_FACE: {
        const Eigen::Vector3d p = point(0), a = point(1), b = point(2), t = point(3);
        const PointTriangleDistanceType type = point_triangle_distance_type(p, a, b, t);
        c.distance_type = int(type);
        c.distance_squared = point_triangle_distance(p, a, b, t, type);
        break;
    }
    case ContactKind::EDGE_EDGE: {
        const Eigen::Vector3d pa0 = point(0), pa1 = point(1), pb0 = point(2), pb1 = point(3);
        const EdgeEdgeDistanceType type = edge_edge_distance_type(pa0, pa1, pb0, pb1);
        c.distance_type = int(type);
        c.distance_squared = edge_edge_distance(pa0, pa1, pb0, pb1, type);
        if (threshold)
            c.mollifier_threshold = edge_edge_mollifier_threshold(rest_point(m_rest, vertices[0]),
                rest_point(m_rest, vertices[1]), rest_point(m_rest, vertices[2]), rest_point(m_rest, vertices[3]));
        break;
    }
    case ContactKind::VERTEX_PLANE: {
        const double h = (point(0) - point(1)).dot(m_planes[size_t(plane)].normal);
        // A vertex on the wrong side is an intersection: no finite barrier (NaN stays NaN: never active).
        c.distance_squared = h > 0 ? h * h : h <= 0 ? -1.0 : h;
        break;
    }
    }
    return c;
}

void ContactPotential::set_images(SparseMatrixd T)
{
    if (T.rows() != m_rest.size())
        throw std::invalid_argument("ContactPotential::set_images: T must have a row per surface dof");
    m_images = SurfaceImages(std::move(T), m_mesh.dim);
    m_cache_valid = false;
    m_segment->valid = false;
}

const ContactSet& ContactPotential::contacts(const VectorXd& x) const
{
    VectorXd storage;
    return surface_contacts(surface(x, storage));
}

const ContactSet& ContactPotential::surface_contacts(const VectorXd& x) const
{
    if (!m_cache_valid || m_cache_x.size() != x.size() || m_cache_x != x) {
        m_cache_valid = false; // stays invalid if the broad phase throws (non-finite positions)
        build_contacts(x, m_cache, m_settings.min_distance + m_settings.dhat);
        m_cache_x = x;
        m_cache_valid = true;
    }
    return m_cache;
}

namespace {

    /// A contact's vertices at x as the kernels take them (z = 0 in 2D), and its plane's normal.
    void load_pair(const Contact& c, const VectorXd& x, int dim, const std::vector<ContactPlane>& planes,
        kernels::vec3* points, kernels::vec3& normal)
    {
        for (int a = 0; a < c.num_vertices(); ++a)
            points[a] = kernels::to_vec3(vertex_point(x, c.vertices[size_t(a)], dim));
        normal
            = c.kind == ContactKind::VERTEX_PLANE ? kernels::to_vec3(planes[size_t(c.plane)].normal) : kernels::vec3();
        if (dim == 2)
            normal.z = 0;
    }

    /// A row-major n-vector or n by n matrix of a kernel as Eigen's.
    Eigen::MatrixXd from_row_major(const double* a, int rows, int cols)
    {
        return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(a, rows, cols);
    }

} // namespace

ContactPotential::LocalDistance ContactPotential::local_distance(
    const Contact& c, const VectorXd& x, bool derivatives) const
{
    const int dim = m_mesh.dim, nv = c.num_vertices(), n = nv * dim;
    const bool mollified = c.kind == ContactKind::EDGE_EDGE;
    kernels::vec3 points[4], normal;
    load_pair(c, x, dim, m_planes, points, normal);
    double gs[kernels::CONTACT_MAX_DOFS], gm[kernels::CONTACT_MAX_DOFS];
    double Hs[kernels::CONTACT_MAX_DOFS * kernels::CONTACT_MAX_DOFS];
    double Hm[kernels::CONTACT_MAX_DOFS * kernels::CONTACT_MAX_DOFS];
    LocalDistance out;
    kernels::pair_distance(c.kind, points, normal, c.mollifier_threshold,
        c.kind == ContactKind::VERTEX_PLANE ? -1 : c.distance_type, out.s, out.m, derivatives ? gs : nullptr,
        derivatives ? Hs : nullptr, derivatives && mollified ? gm : nullptr, derivatives && mollified ? Hm : nullptr);
    if (!derivatives || (c.kind == ContactKind::VERTEX_PLANE && !(out.s > 0)))
        return out; // a vertex behind its plane: s = 0 and no derivatives (the caller sees s - dmin^2 <= 0)
    if (dim == 2) {
        kernels::pair_barrier_detail::compress_2d(nv, gs, Hs);
        if (mollified)
            kernels::pair_barrier_detail::compress_2d(nv, gm, Hm);
    }
    out.gs = from_row_major(gs, n, 1);
    out.Hs = from_row_major(Hs, n, n);
    if (mollified) {
        out.gm = from_row_major(gm, n, 1);
        out.Hm = from_row_major(Hm, n, n);
    }
    return out;
}

ContactPotential::PairEnergy ContactPotential::pair_energy(double z, bool second) const
{
    const kernels::EnergyTerms<> e = kernels::pair_outer_energy(pair_model(), z, true, second);
    return { e.value, e.first, e.second };
}

kernels::PairModel ContactPotential::pair_model() const
{
    return kernels::pair_model(m_settings.penalty, m_settings.dhat, m_settings.min_distance);
}

double ContactPotential::normal_force_per_stiffness(double d) const
{
    if (m_settings.penalty)
        return penalty_force(d, m_settings.dhat);
    const double dmin2 = m_settings.min_distance * m_settings.min_distance;
    const double shat = barrier_activation(m_settings.dhat, m_settings.min_distance);
    return std::abs(barrier_first_derivative(d * d - dmin2, shat)) * 2 * d;
}

double ContactPotential::local_barrier(
    const Contact& c, const VectorXd& x, Eigen::VectorXd* grad, Eigen::MatrixXd* hess) const
{
    const int dim = m_mesh.dim, n = c.num_vertices() * dim;
    kernels::vec3 points[4], normal;
    load_pair(c, x, dim, m_planes, points, normal);
    double g[kernels::CONTACT_MAX_DOFS], H[kernels::CONTACT_MAX_DOFS * kernels::CONTACT_MAX_DOFS];
    const double e = kernels::pair_energy(c.kind, dim, points, normal, c.mollifier_threshold,
        c.kind == ContactKind::VERTEX_PLANE ? -1 : c.distance_type, pair_model(), grad ? g : nullptr,
        hess ? H : nullptr);
    if (grad)
        *grad = from_row_major(g, n, 1);
    if (hess)
        *hess = from_row_major(H, n, n);
    return std::isfinite(e) ? e : INF;
}

double ContactPotential::barrier_value(const VectorXd& mesh_x) const
{
    VectorXd storage;
    const VectorXd& x = surface(mesh_x, storage);
    const ContactSet& set = surface_contacts(x);
    Timer t;
    // Fixed reduction tree: the same sum for any thread count; an intersecting pair makes it infinite.
    const double sum
        = parallel_sum(set.size(), 64, [&](size_t k) { return local_barrier(set[k], x, nullptr, nullptr); });
    t.add_to(m_times.barrier);
    return std::isfinite(sum) ? sum : INF;
}

double ContactPotential::value(const VectorXd& x) const
{
    const double b = barrier_value(x);
    return std::isfinite(b) ? m_settings.kappa * b : INF;
}

void ContactPotential::scatter_gradient(const VectorXd& x, double scale, VectorXd& g) const
{
    const ContactSet& set = surface_contacts(x);
    Timer t;
    const int dim = m_mesh.dim;
    // Local gradients in parallel, then gathered per vertex in contact order (the serial sum).
    std::vector<double>& locals = m_gradient_buffer;
    locals.assign(set.size() * 4 * size_t(dim), 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.size(), 32), [&](const tbb::blocked_range<size_t>& r) {
        Eigen::VectorXd local;
        for (size_t k = r.begin(); k < r.end(); ++k) {
            local_barrier(set[k], x, &local, nullptr);
            std::copy_n(local.data(), local.size(), locals.data() + k * 4 * size_t(dim));
        }
    });
    m_scatter.build(x.size() / dim, set.size(), 4,
        [&](size_t k, int a) { return a < set[k].num_vertices() ? set[k].vertices[size_t(a)] : Index(-1); });
    m_scatter.add(locals.data(), dim, scale, g);
    t.add_to(m_times.barrier);
}

void ContactPotential::add_barrier_gradient(const VectorXd& x, double scale, VectorXd& g) const
{
    if (!has_images()) {
        scatter_gradient(x, scale, g);
        return;
    }
    VectorXd storage;
    const VectorXd& y = surface(x, storage);
    VectorXd gs = VectorXd::Zero(y.size());
    scatter_gradient(y, scale, gs);
    m_images.add_back(gs, g);
}

VectorXd ContactPotential::barrier_gradient(const VectorXd& x) const
{
    VectorXd g = VectorXd::Zero(x.size());
    add_barrier_gradient(x, 1.0, g);
    return g;
}

void ContactPotential::add_gradient(const VectorXd& x, double weight, VectorXd& g) const
{
    add_barrier_gradient(x, weight * m_settings.kappa, g);
}

void ContactPotential::add_hessian(
    const VectorXd& mesh_x, double weight, bool project_to_psd, SparseAssembler& mesh_H) const
{
    VectorXd storage;
    const VectorXd& x = surface(mesh_x, storage);
    const ContactSet& set = surface_contacts(x);
    if (set.empty())
        return;
    Timer t;
    const double scale = weight * m_settings.kappa;
    // With images the locals go into the surface's assembler first, then T^T H_s T into mesh_H.
    SparseAssembler& H = m_images.hessian_target(mesh_H);
    const size_t first = H.reserve_locals(set.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
        Eigen::MatrixXd local;
        for (size_t k = r.begin(); k < r.end(); ++k) {
            local_barrier(set[k], x, nullptr, &local);
            if (project_to_psd)
                local = project_psd(local);
            local *= scale;
            H.set_local(first + k, set[k].vertices.data(), set[k].num_vertices(), local.data());
        }
    });
    m_images.finish_hessian(mesh_H);
    t.add_to(m_times.barrier);
}

double ContactPotential::max_step(const VectorXd& mesh_x, const VectorXd& mesh_p) const
{
    if (m_settings.penalty) {
        // The penalty baseline has no CCD: any step is admissible (surfaces may pass through).
        m_segment->valid = false;
        m_ccd_budget_exhausted = m_ccd_unresolved = false;
        return 1.0;
    }
    const int dim = m_mesh.dim;
    VectorXd x_storage, p_storage;
    const VectorXd& x = surface(mesh_x, x_storage);
    const VectorXd& p = surface(mesh_p, p_storage);
    const VectorXd x1 = x + p;
    const Positions X0 = unflatten(x, dim), X1 = unflatten(x1, dim);
    Segment& segment = *m_segment;
    segment.valid = false;
    // Points within `tolerance` of the segment count as on it (x + alpha p is
    // rounded); the boxes are inflated by that much more.
    segment.tolerance = 1e-12 * (x.lpNorm<Eigen::Infinity>() + p.lpNorm<Eigen::Infinity>());
    {
        Timer t;
        segment.candidates
            = broad_phase_candidates(m_mesh, X0, X1, m_settings.min_distance + m_settings.dhat + 4 * segment.tolerance);
        t.add_to(m_times.broad_phase);
    }
    segment.x0 = x;
    segment.p = p;
    segment.valid = true;
    const Candidates& candidates = segment.candidates;
    Timer t;
    CCDSettings settings;
    settings.min_distance = m_settings.min_distance;
    settings.max_iterations = m_settings.ccd_max_iterations;
    settings.conservative_rescaling = m_settings.ccd_rescaling;
    struct Outcome {
        double toi = 1;
        bool exhausted = false;
    };
    auto combine = [](Outcome a, const Outcome& b) {
        a.toi = std::min(a.toi, b.toi);
        a.exhausted = a.exhausted || b.exhausted;
        return a;
    };
    auto accept = [](Outcome& o, const CCDResult& r) {
        if (r.collision) {
            o.toi = std::min(o.toi, r.toi);
            o.exhausted = o.exhausted || r.budget_exhausted;
        }
    };
    const auto& ve = candidates.vertex_edge;
    const auto& vf = candidates.vertex_face;
    const auto& ee = candidates.edge_edge;
    const size_t n_ve = ve.size(), n_vf = vf.size(), n_ee = ee.size();
    const size_t n_plane = m_planes.size() * m_plane_vertices.size();
    const size_t total = n_ve + n_vf + n_ee + n_plane;
    const Outcome outcome = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, total, 64), Outcome {},
        [&](const tbb::blocked_range<size_t>& r, Outcome o) {
            for (size_t k = r.begin(); k < r.end(); ++k) {
                if (k < n_ve) {
                    const auto& [v, e] = ve[k];
                    const Index a = m_mesh.edges(e, 0), b = m_mesh.edges(e, 1);
                    accept(o,
                        point_edge_ccd(vertex_point(x, v, dim), vertex_point(x, a, dim), vertex_point(x, b, dim),
                            vertex_point(x1, v, dim), vertex_point(x1, a, dim), vertex_point(x1, b, dim), settings));
                } else if (k < n_ve + n_vf) {
                    const auto& [v, f] = vf[k - n_ve];
                    const Index a = m_mesh.faces(f, 0), b = m_mesh.faces(f, 1), c = m_mesh.faces(f, 2);
                    accept(o,
                        point_triangle_ccd(vertex_point(x, v, dim), vertex_point(x, a, dim), vertex_point(x, b, dim),
                            vertex_point(x, c, dim), vertex_point(x1, v, dim), vertex_point(x1, a, dim),
                            vertex_point(x1, b, dim), vertex_point(x1, c, dim), settings));
                } else if (k < n_ve + n_vf + n_ee) {
                    const auto& [ea, eb] = ee[k - n_ve - n_vf];
                    const Index a0 = m_mesh.edges(ea, 0), a1 = m_mesh.edges(ea, 1);
                    const Index b0 = m_mesh.edges(eb, 0), b1 = m_mesh.edges(eb, 1);
                    accept(o,
                        edge_edge_ccd(vertex_point(x, a0, dim), vertex_point(x, a1, dim), vertex_point(x, b0, dim),
                            vertex_point(x, b1, dim), vertex_point(x1, a0, dim), vertex_point(x1, a1, dim),
                            vertex_point(x1, b0, dim), vertex_point(x1, b1, dim), settings));
                } else {
                    const size_t q = k - n_ve - n_vf - n_ee;
                    const ContactPlane& plane = m_planes[q / m_plane_vertices.size()];
                    const Index v = m_plane_vertices[q % m_plane_vertices.size()];
                    accept(o,
                        point_plane_ccd(vertex_point(x, v, dim), vertex_point(x1, v, dim),
                            vertex_point(x, plane.vertex, dim), vertex_point(x1, plane.vertex, dim), plane.normal,
                            settings));
                }
            }
            return o;
        },
        combine);
    t.add_to(m_times.ccd);
    m_ccd_budget_exhausted = outcome.exhausted;
    m_ccd_unresolved = !(outcome.toi > 0);
    return outcome.toi;
}

double ContactPotential::min_distance(const VectorXd& mesh_x, double radius) const
{
    VectorXd storage;
    const VectorXd& x = surface(mesh_x, storage);
    ContactSet set;
    build_contacts(x, set, std::max(radius, m_settings.min_distance + m_settings.dhat));
    double best = INF;
    for (const Contact& c : set)
        best = std::min(best, c.distance_squared < 0 ? 0.0 : std::sqrt(c.distance_squared));
    return best;
}

bool ContactPotential::end_iteration(const VectorXd& x)
{
    if (!m_adaptive)
        return false;
    const ContactSet& set = contacts(x); // m_rule takes the mesh's positions
    if (!m_rule_applied && !set.empty() && m_rule) {
        // Contact appeared during this step: balance the barrier now rather than
        // waiting for the gap to collapse to the doubling threshold.
        m_rule_applied = true;
        const double kappa = std::min(std::max(m_settings.kappa, m_rule(x)), m_kappa_max);
        m_previous_min_distance_squared = -1;
        if (kappa != m_settings.kappa) {
            m_settings.kappa = kappa;
            return true;
        }
        return false;
    }
    double gap2 = INF;
    for (const Contact& c : set) {
        const double gap = std::sqrt(std::max(c.distance_squared, 0.0)) - m_settings.min_distance;
        gap2 = std::min(gap2, gap * gap);
    }
    const double previous = m_previous_min_distance_squared;
    m_previous_min_distance_squared = gap2;
    if (previous < 0)
        return false;
    const double kappa
        = update_barrier_stiffness(previous, gap2, m_settings.kappa, m_kappa_max, m_bbox_diagonal, /*dmin=*/0.0);
    if (kappa == m_settings.kappa)
        return false;
    m_settings.kappa = kappa;
    return true;
}

Eigen::Matrix<double, 12, 1> ContactPotential::mollifier_threshold_gradient(const Contact& c) const
{
    const auto& v = c.vertices;
    return edge_edge_mollifier_threshold_gradient(
        rest_point(m_rest, v[0]), rest_point(m_rest, v[1]), rest_point(m_rest, v[2]), rest_point(m_rest, v[3]));
}

void ContactPotential::add_shape_derivative(
    const VectorXd& mesh_x, const VectorXd& mesh_direction, double weight, VectorXd& d_mesh_rest) const
{
    const int dim = m_mesh.dim;
    if (dim != 3)
        return;
    // With images the surface's rest positions are T X: d/dX = T^T d/dX_s.
    VectorXd x_storage, direction_storage, d_surface;
    const VectorXd& x = surface(mesh_x, x_storage);
    const VectorXd& direction = surface(mesh_direction, direction_storage);
    if (has_images())
        d_surface = VectorXd::Zero(x.size());
    VectorXd& d_rest_positions = has_images() ? d_surface : d_mesh_rest;
    const double dmin2 = m_settings.min_distance * m_settings.min_distance;
    const double scale = weight * m_settings.kappa;
    const ContactSet& set = surface_contacts(x);
    // Per contact in parallel, gathered per vertex in contact order.
    std::vector<double>& locals = m_gradient_buffer;
    locals.assign(set.size() * 12, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, set.size(), 32), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const Contact& c = set[k];
            if (c.kind != ContactKind::EDGE_EDGE)
                continue;
            const auto& v = c.vertices;
            const Eigen::Vector3d a0 = vertex_point(x, v[0], dim), a1 = vertex_point(x, v[1], dim),
                                  b0 = vertex_point(x, v[2], dim), b1 = vertex_point(x, v[3], dim);
            const double eps = c.mollifier_threshold;
            const double dm = edge_edge_mollifier_gradient_wrt_eps_x(a0, a1, b0, b1, eps);
            const Eigen::Matrix<double, 12, 1> dgm
                = edge_edge_mollifier_gradient_jacobian_wrt_eps_x(a0, a1, b0, b1, eps);
            if (dm == 0 && dgm.isZero())
                continue;
            const auto type = EdgeEdgeDistanceType(c.distance_type);
            const double z = edge_edge_distance(a0, a1, b0, b1, type) - dmin2;
            const Eigen::Matrix<double, 12, 1> gs = edge_edge_distance_gradient(a0, a1, b0, b1, type);
            Eigen::Matrix<double, 12, 1> local;
            for (int i = 0; i < 4; ++i)
                local.segment<3>(3 * i) = direction.segment(v[size_t(i)] * dim, dim);
            // d/d eps_x of grad(m b) = dm/deps b'(z) grad s + b(z) d(grad m)/deps
            const PairEnergy e = pair_energy(z, false);
            const double sens = scale * (dm * e.first * local.dot(gs) + e.value * local.dot(dgm));
            Eigen::Map<Eigen::Matrix<double, 12, 1>>(locals.data() + 12 * k) = sens * mollifier_threshold_gradient(c);
        }
    });
    m_scatter.build(x.size() / dim, set.size(), 4, [&](size_t k, int a) {
        return set[k].kind == ContactKind::EDGE_EDGE ? set[k].vertices[size_t(a)] : Index(-1);
    });
    m_scatter.add(locals.data(), dim, 1.0, d_rest_positions);
    if (has_images())
        m_images.add_back(d_surface, d_mesh_rest);
}

} // namespace diffipc
