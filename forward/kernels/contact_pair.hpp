#pragma once
/// @file contact_pair.hpp
/// The contact energy of one pair (IPC's barrier, or the penalty baseline: PairModel), its gradient
/// and its true Hessian, on the host and the device: ContactPotential (forward/contact/
/// contact_potential.cpp) and the GPU's barrier (cuda/contact/) evaluate this code. Per pair,
/// without kappa:
///   B_k = m_k b(s_k - dmin^2, shat),  shat = (2 dmin + dhat) dhat,
/// with s_k the squared distance of the pair's closest-feature type, m_k the edge-edge mollifier
/// (1 for other kinds) and, for a vertex-plane pair, s = h^2 with the signed distance
/// h = (x_v - x_plane) . n (an intersection where h <= 0). There are no per-pair weights (no area
/// weighting); the caller multiplies the sum by kappa (and its potential weight). The PSD
/// projection of a pair's Hessian is the caller's (Eigen on the CPU, cyclic Jacobi on the GPU).
///
/// Layouts: a pair has contact_num_vertices(kind) vertices (vertex-edge: v, e0, e1; vertex-face:
/// v, t0, t1, t2; edge-edge: ea0, ea1, eb0, eb1; vertex-plane: v, the plane's point); its local
/// dofs are vertex-major, dim per vertex (n = #vertices * dim); Hessians are n by n, row-major.
///
/// The pair's distance, energy and derivatives are templates over the scalar T of the positions
/// (double today; dual numbers give their directional derivatives); the pair model's settings
/// (PairModel: dmin^2, shat, dhat) stay doubles.

#include "forward/kernels/barrier.hpp"
#include "forward/kernels/contact_kind.hpp"
#include "forward/kernels/distance/edge_edge.hpp"
#include "forward/kernels/distance/edge_edge_mollifier.hpp"
#include "forward/kernels/distance/point_edge.hpp"
#include "forward/kernels/distance/point_triangle.hpp"

namespace diffipc::kernels {

/// @brief The squared distance s of a pair for its closest-feature type (0 for a vertex on the
/// wrong side of its plane), the mollifier m (1 unless edge-edge),
/// and, where the pointers are given, their derivatives in the 3D-padded local layout (3 dofs per
/// vertex, n3 = 3 #vertices; Hessians n3 by n3 row-major). gm and Hm are written only for an
/// edge-edge pair.
/// @param points  the pair's vertices (z = 0 in 2D)
/// @param normal  VERTEX_PLANE: the plane's unit normal (z = 0 in 2D); unused otherwise
/// @param eps_x   EDGE_EDGE: the mollifier threshold at rest (edge_edge_mollifier_threshold)
/// @param type    the closest-feature type as int (Contact::distance_type), or -1 to classify at
///                these positions
template <class T>
DIFFIPC_HD inline void pair_distance(ContactKind kind, const Vec3<T>* points, const Vec3<T>& normal,
    non_deduced<T> eps_x, int type, non_deduced<T>& s, non_deduced<T>& m, non_deduced<T>* gs, non_deduced<T>* Hs,
    non_deduced<T>* gm, non_deduced<T>* Hm)
{
    const Vec3<T>* p = points;
    s = 0;
    m = 1;
    switch (kind) {
    case ContactKind::VERTEX_PLANE: {
        const T h = dot(p[0] - p[1], normal);
        if (!(h > 0))
            return; // s = 0: intersecting (the caller sees s - dmin^2 <= 0)
        s = h * h;
        if (gs) {
            const Vec3<T> g = 2 * h * normal, minus = -2 * h * normal;
            store(g, gs);
            store(minus, gs + 3);
        }
        if (Hs)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) {
                    const T nn = (2 * component(normal, i)) * component(normal, j);
                    Hs[i * 6 + j] = nn;
                    Hs[i * 6 + 3 + j] = -nn;
                    Hs[(3 + i) * 6 + j] = -nn;
                    Hs[(3 + i) * 6 + 3 + j] = nn;
                }
        return;
    }
    case ContactKind::VERTEX_EDGE: {
        const PointEdgeDistanceType t
            = type >= 0 ? PointEdgeDistanceType(type) : point_edge_distance_type(p[0], p[1], p[2]);
        s = point_edge_distance(p[0], p[1], p[2], t);
        if (gs)
            point_edge_distance_gradient(p[0], p[1], p[2], t, gs);
        if (Hs)
            point_edge_distance_hessian(p[0], p[1], p[2], t, Hs);
        return;
    }
    case ContactKind::VERTEX_FACE: {
        const PointTriangleDistanceType t
            = type >= 0 ? PointTriangleDistanceType(type) : point_triangle_distance_type(p[0], p[1], p[2], p[3]);
        s = point_triangle_distance(p[0], p[1], p[2], p[3], t);
        if (gs)
            point_triangle_distance_gradient(p[0], p[1], p[2], p[3], t, gs);
        if (Hs)
            point_triangle_distance_hessian(p[0], p[1], p[2], p[3], t, Hs);
        return;
    }
    case ContactKind::EDGE_EDGE: {
        const EdgeEdgeDistanceType t
            = type >= 0 ? EdgeEdgeDistanceType(type) : edge_edge_distance_type(p[0], p[1], p[2], p[3]);
        s = edge_edge_distance(p[0], p[1], p[2], p[3], t);
        m = edge_edge_mollifier(p[0], p[1], p[2], p[3], eps_x);
        if (gs)
            edge_edge_distance_gradient(p[0], p[1], p[2], p[3], t, gs);
        if (Hs)
            edge_edge_distance_hessian(p[0], p[1], p[2], p[3], t, Hs);
        if (gm)
            edge_edge_mollifier_gradient(p[0], p[1], p[2], p[3], eps_x, gm);
        if (Hm)
            edge_edge_mollifier_hessian(p[0], p[1], p[2], p[3], eps_x, Hm);
        return;
    }
    }
}

namespace pair_barrier_detail {
    /// In place: drops the z rows (and columns) of a 3D-padded gradient (Hessian) of nv vertices
    /// (each entry moves to a lower index, so the copy runs forward).
    template <class T> DIFFIPC_HD inline void compress_2d(int nv, T* g, T* H)
    {
        const int n2 = 2 * nv, n3 = 3 * nv;
        if (g)
            for (int a = 0; a < n2; ++a)
                g[a] = g[(a / 2) * 3 + a % 2];
        if (H)
            for (int a = 0; a < n2; ++a)
                for (int b = 0; b < n2; ++b)
                    H[a * n2 + b] = H[((a / 2) * 3 + a % 2) * n3 + (b / 2) * 3 + b % 2];
    }
} // namespace pair_barrier_detail

/// @brief The penalty baseline's P(sqrt(s)) = 1/2 (dhat - d)^2 for d < dhat (0 beyond) and its
/// first two derivatives in s, P' = -(dhat - d) / (2 d), P'' = dhat / (4 d^3) (docs/math.md
/// "Penalty contact"). A distance below 1e-9 dhat is taken as 1e-9 dhat (surfaces that touch
/// exactly: the force's direction is undefined there, its size is k dhat).
template <class T = double> struct EnergyTerms {
    T value = 0, first = 0, second = 0; ///< a function of s or z and its first two derivatives
};
template <class T> DIFFIPC_HD inline EnergyTerms<T> penalty_of_squared_distance(T s, non_deduced<T> dhat)
{
    EnergyTerms<T> p;
    if (!(s < dhat * dhat))
        return p;
    const T d = fmax(sqrt(fmax(s, T(0))), T(1e-9) * dhat);
    const T gap = dhat - d;
    p.value = 0.5 * gap * gap;
    p.first = -gap / (2 * d);
    p.second = dhat / (4 * d * d * d);
    return p;
}

/// @brief |dP/dd| = dhat - d for d < dhat, else 0: the penalty's normal force of one pair per unit
/// stiffness.
template <class T> DIFFIPC_HD inline T penalty_force(T d, non_deduced<T> dhat) { return d < dhat ? dhat - d : T(0); }

/// The model of a pair's energy (ContactSettings): IPC's barrier m b(s - dmin^2, shat), or the
/// penalty baseline (`"model": "penalty"`): m P(s - dmin^2) for the distance pairs and 1/2 (dhat - h)^2
/// on the signed height h of a vertex-plane pair (it pushes back a vertex that passed the plane).
struct PairModel {
    bool penalty = false;
    double dmin2 = 0; ///< dmin^2 (m^2)
    double shat = 0; ///< the barrier's barrier_activation(dhat, dmin) (m^2)
    double dhat = 0; ///< the penalty's activation distance (m)
};

/// The pair model of the contact settings (dhat, dmin: m; `penalty`: the baseline instead of the barrier).
DIFFIPC_HD inline PairModel pair_model(bool penalty, double dhat, double dmin)
{
    PairModel model;
    model.penalty = penalty;
    model.dmin2 = dmin * dmin;
    model.shat = barrier_activation(dhat, dmin);
    model.dhat = dhat;
    return model;
}

/// @brief The energy of a pair without kappa and the mollifier as a function of z = s - dmin^2, and
/// its first and second derivatives in z where asked (0 otherwise): IPC's barrier b(z, shat), or
/// the penalty P(sqrt(z)). For the barrier, z must be positive.
template <class T>
DIFFIPC_HD inline EnergyTerms<T> pair_outer_energy(const PairModel& model, T z, bool first, bool second)
{
    if (model.penalty)
        return penalty_of_squared_distance(z, T(model.dhat));
    const T shat = model.shat;
    EnergyTerms<T> e;
    e.value = barrier(z, shat);
    if (first)
        e.first = barrier_first_derivative(z, shat);
    if (second)
        e.second = barrier_second_derivative(z, shat);
    return e;
}

namespace pair_barrier_detail {

    /// grad = m e1 gs (+ e gm), hess = m (e2 gs gs^T + e1 Hs) (+ e1 (gm gs^T + gs gm^T) + e Hm), with
    /// e, e1, e2 the outer function and its derivatives in s (local dofs, n of them).
    template <class T>
    DIFFIPC_HD inline void chain_rule(int n, bool mollified, T m, T e, T e1, T e2, const T* gs, const T* Hs,
        const T* gm, const T* Hm, T* grad, T* hess)
    {
        if (grad)
            for (int k = 0; k < n; ++k) {
                grad[k] = m * e1 * gs[k];
                if (mollified)
                    grad[k] += e * gm[k];
            }
        if (hess)
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    T v = m * ((e2 * gs[i]) * gs[j] + e1 * Hs[i * n + j]);
                    if (mollified)
                        v += e1 * (gm[i] * gs[j] + gs[i] * gm[j]) + e * Hm[i * n + j];
                    hess[i * n + j] = v;
                }
    }

    /// A vertex-plane pair of penalty contact: 1/2 (dhat - h)^2 for h < dhat, h = (x_v - x_plane) . n, with
    /// dh/d(x_v, x_plane) = (n, -n) and the Hessian (dh)(dh)^T inside the layer.
    template <class T>
    DIFFIPC_HD inline T plane_penalty(
        int dim, const Vec3<T>* points, const Vec3<T>& normal, non_deduced<T> dhat, T* grad, T* hess)
    {
        const Vec3<T> d = points[0] - points[1];
        const T h = d.x * normal.x + d.y * normal.y + (dim == 3 ? d.z * normal.z : T(0));
        const T gap = h < dhat ? dhat - h : T(0);
        const T nc[3] = { normal.x, normal.y, normal.z };
        T dh[6];
        for (int i = 0; i < dim; ++i) {
            dh[i] = nc[i];
            dh[dim + i] = -nc[i];
        }
        const int n = 2 * dim;
        for (int k = 0; grad && k < n; ++k)
            grad[k] = -gap * dh[k];
        for (int i = 0; hess && i < n; ++i)
            for (int j = 0; j < n; ++j)
                hess[i * n + j] = gap > 0 ? dh[i] * dh[j] : T(0);
        return 0.5 * gap * gap;
    }

} // namespace pair_barrier_detail

/// @brief The energy of one pair without kappa under `model`, and where the pointers are given its
/// gradient and (true) Hessian in the pair's local dofs (n = #vertices * dim; Hessian n by n
/// row-major).
/// @param dim     2 or 3
/// @param points, normal, eps_x, type  as in pair_distance
/// @return the barrier: +inf for an intersecting pair (s - dmin^2 <= 0), grad and hess NaN then;
///         the penalty is finite everywhere
template <class T>
DIFFIPC_HD inline T pair_energy(ContactKind kind, int dim, const Vec3<T>* points, const Vec3<T>& normal,
    non_deduced<T> eps_x, int type, const PairModel& model, non_deduced<T>* grad, non_deduced<T>* hess)
{
    if (model.penalty && kind == ContactKind::VERTEX_PLANE)
        return pair_barrier_detail::plane_penalty(dim, points, normal, model.dhat, grad, hess);
    const int nv = contact_num_vertices(kind), n = nv * dim;
    const bool mollified = kind == ContactKind::EDGE_EDGE;
    T s = 0, m = 1;
    T gs[CONTACT_MAX_DOFS], gm[CONTACT_MAX_DOFS];
    T Hs[CONTACT_MAX_DOFS * CONTACT_MAX_DOFS], Hm[CONTACT_MAX_DOFS * CONTACT_MAX_DOFS];
    const bool derivatives = grad || hess;
    pair_distance<T>(kind, points, normal, eps_x, type, s, m, derivatives ? gs : nullptr, hess ? Hs : nullptr,
        derivatives && mollified ? gm : nullptr, hess && mollified ? Hm : nullptr);
    const T z = s - T(model.dmin2);
    if (!model.penalty && !(z > 0)) {
        for (int k = 0; grad && k < n; ++k)
            grad[k] = NAN;
        for (int k = 0; hess && k < n * n; ++k)
            hess[k] = NAN;
        return infinity<T>();
    }
    const EnergyTerms<T> outer = pair_outer_energy(model, z, derivatives, hess != nullptr);
    const T e = outer.value, e1 = outer.first, e2 = outer.second;
    if (!derivatives)
        return m * e;
    if (dim == 2) {
        pair_barrier_detail::compress_2d(nv, gs, hess ? Hs : nullptr);
        if (mollified)
            pair_barrier_detail::compress_2d(nv, gm, hess ? Hm : nullptr);
    }
    pair_barrier_detail::chain_rule<T>(n, mollified, m, e, e1, e2, gs, Hs, gm, Hm, grad, hess);
    return m * e;
}

/// @brief pair_energy for the barrier model, m b(s - dmin^2, shat), the type classified at points.
/// @param dmin2   dmin^2 (m^2), @param shat barrier_activation(dhat, dmin) (m^2)
template <class T>
DIFFIPC_HD inline T pair_barrier(ContactKind kind, int dim, const Vec3<T>* points, const Vec3<T>& normal,
    non_deduced<T> eps_x, double dmin2, double shat, non_deduced<T>* grad, non_deduced<T>* hess)
{
    PairModel model;
    model.dmin2 = dmin2;
    model.shat = shat;
    return pair_energy<T>(kind, dim, points, normal, eps_x, -1, model, grad, hess);
}

} // namespace diffipc::kernels
