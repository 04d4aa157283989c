#include "forward/contact/intersection.hpp"

#include "forward/mesh/mesh.hpp"

#include <Eigen/Geometry>
#include <gmpxx.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

namespace diffipc {

namespace {

    int sign(const mpq_class& v) { return sgn(v); }

    // Floating-point determinant with a bound on its rounding error (a few ulps
    // of the permanent, well above Shewchuk's o3derrboundA); outside the bound
    // the double sign is certain, inside it GMP decides.
    int orient3d_filtered(const double* a, const double* b, const double* c, const double* d)
    {
        const double bx = b[0] - a[0], by = b[1] - a[1], bz = b[2] - a[2];
        const double cx = c[0] - a[0], cy = c[1] - a[1], cz = c[2] - a[2];
        const double dx = d[0] - a[0], dy = d[1] - a[1], dz = d[2] - a[2];
        const double det = bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx);
        const double permanent = std::abs(bx) * (std::abs(cy * dz) + std::abs(cz * dy))
            + std::abs(by) * (std::abs(cx * dz) + std::abs(cz * dx))
            + std::abs(bz) * (std::abs(cx * dy) + std::abs(cy * dx));
        if (std::abs(det) > 1e-14 * permanent)
            return det > 0 ? 1 : -1;
        mpq_class m[3][3];
        for (int k = 0; k < 3; ++k) {
            m[0][k] = mpq_class(b[k]) - mpq_class(a[k]);
            m[1][k] = mpq_class(c[k]) - mpq_class(a[k]);
            m[2][k] = mpq_class(d[k]) - mpq_class(a[k]);
        }
        const mpq_class e = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        return sign(e);
    }

    int orient2d_filtered(const double* a, const double* b, const double* c)
    {
        const double det = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        const double permanent = std::abs((b[0] - a[0]) * (c[1] - a[1])) + std::abs((b[1] - a[1]) * (c[0] - a[0]));
        if (std::abs(det) > 1e-14 * permanent)
            return det > 0 ? 1 : -1;
        const mpq_class e = (mpq_class(b[0]) - mpq_class(a[0])) * (mpq_class(c[1]) - mpq_class(a[1]))
            - (mpq_class(b[1]) - mpq_class(a[1])) * (mpq_class(c[0]) - mpq_class(a[0]));
        return sign(e);
    }

    // Is c (collinear with a, b) within the closed segment (a, b)?
    bool on_segment(const double* a, const double* b, const double* c)
    {
        return std::min(a[0], b[0]) <= c[0] && c[0] <= std::max(a[0], b[0]) && std::min(a[1], b[1]) <= c[1]
            && c[1] <= std::max(a[1], b[1]);
    }

    // Coplanar case: drop the axis along which the triangle's normal is largest and test in 2D.
    bool coplanar_segment_triangle(const double* p, const double* q, const double* a, const double* b, const double* c)
    {
        mpq_class n[3];
        {
            const mpq_class u[3] = { mpq_class(b[0]) - a[0], mpq_class(b[1]) - a[1], mpq_class(b[2]) - a[2] };
            const mpq_class v[3] = { mpq_class(c[0]) - a[0], mpq_class(c[1]) - a[1], mpq_class(c[2]) - a[2] };
            n[0] = u[1] * v[2] - u[2] * v[1];
            n[1] = u[2] * v[0] - u[0] * v[2];
            n[2] = u[0] * v[1] - u[1] * v[0];
        }
        int drop = 0;
        for (int k = 1; k < 3; ++k)
            if (abs(n[k]) > abs(n[drop]))
                drop = k;
        if (sgn(n[drop]) == 0) {
            // Degenerate triangle: test against its three edges as segments in 3D
            // is not needed for valid meshes (validate_mesh rejects zero-area facets).
            return false;
        }
        const int i0 = (drop + 1) % 3, i1 = (drop + 2) % 3;
        auto proj = [&](const double* v) { return std::array<double, 2> { v[i0], v[i1] }; };
        const auto P = proj(p), Q = proj(q), A = proj(a), B = proj(b), C = proj(c);
        auto inside = [&](const std::array<double, 2>& X) {
            const int s0 = orient2d_filtered(A.data(), B.data(), X.data());
            const int s1 = orient2d_filtered(B.data(), C.data(), X.data());
            const int s2 = orient2d_filtered(C.data(), A.data(), X.data());
            return (s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0);
        };
        if (inside(P) || inside(Q))
            return true;
        return segments_intersect_2d(P.data(), Q.data(), A.data(), B.data())
            || segments_intersect_2d(P.data(), Q.data(), B.data(), C.data())
            || segments_intersect_2d(P.data(), Q.data(), C.data(), A.data());
    }

    struct Box {
        double lo[3], hi[3];
        Index id;
    };

    template <typename Visit> void overlapping_pairs(std::vector<Box> a, std::vector<Box> b, Visit visit)
    {
        // Sort-and-sweep along x: written separately from the contact broad phase on purpose.
        auto by_x = [](const Box& u, const Box& v) { return u.lo[0] < v.lo[0]; };
        std::sort(a.begin(), a.end(), by_x);
        std::sort(b.begin(), b.end(), by_x);
        double width = 0; // the widest box of b bounds how far left an overlapping box can start
        for (const Box& v : b)
            width = std::max(width, v.hi[0] - v.lo[0]);
        for (const Box& u : a) {
            Box key;
            key.lo[0] = u.lo[0] - width;
            const size_t start = size_t(std::lower_bound(b.begin(), b.end(), key, by_x) - b.begin());
            for (size_t k = start; k < b.size() && b[k].lo[0] <= u.hi[0]; ++k) {
                const Box& v = b[k];
                bool overlap = true;
                for (int c = 0; c < 3; ++c)
                    overlap = overlap && u.lo[c] <= v.hi[c] && v.lo[c] <= u.hi[c];
                if (overlap && !visit(u.id, v.id))
                    return;
            }
        }
    }

    Box box_of(const Positions& X, const int* vertices, int n, Index id)
    {
        Box box;
        box.id = id;
        for (int c = 0; c < 3; ++c) {
            box.lo[c] = c < X.cols() ? INFINITY : 0;
            box.hi[c] = c < X.cols() ? -INFINITY : 0;
        }
        for (int k = 0; k < n; ++k)
            for (int c = 0; c < X.cols(); ++c) {
                box.lo[c] = std::min(box.lo[c], X(vertices[k], c));
                box.hi[c] = std::max(box.hi[c], X(vertices[k], c));
            }
        return box;
    }

} // namespace

int orient3d_exact(const double* a, const double* b, const double* c, const double* d)
{
    return orient3d_filtered(a, b, c, d);
}

int orient2d_exact(const double* a, const double* b, const double* c) { return orient2d_filtered(a, b, c); }

bool segments_intersect_2d(const double* a, const double* b, const double* c, const double* d)
{
    const int o1 = orient2d_filtered(a, b, c), o2 = orient2d_filtered(a, b, d);
    const int o3 = orient2d_filtered(c, d, a), o4 = orient2d_filtered(c, d, b);
    if (o1 * o2 < 0 && o3 * o4 < 0)
        return true;
    return (o1 == 0 && on_segment(a, b, c)) || (o2 == 0 && on_segment(a, b, d)) || (o3 == 0 && on_segment(c, d, a))
        || (o4 == 0 && on_segment(c, d, b));
}

bool segment_triangle_intersect(const double* p, const double* q, const double* a, const double* b, const double* c)
{
    const int sp = orient3d_filtered(a, b, c, p), sq = orient3d_filtered(a, b, c, q);
    if (sp * sq > 0)
        return false;
    if (sp == 0 && sq == 0)
        return coplanar_segment_triangle(p, q, a, b, c);
    // The segment meets the plane: it hits the closed triangle iff the line pq
    // sees the three edges with the same orientation (zeros allowed).
    const int s0 = orient3d_filtered(p, q, a, b), s1 = orient3d_filtered(p, q, b, c),
              s2 = orient3d_filtered(p, q, c, a);
    return (s0 >= 0 && s1 >= 0 && s2 >= 0) || (s0 <= 0 && s1 <= 0 && s2 <= 0);
}

std::string find_intersection(const CollisionMesh& mesh, const Positions& X, bool all_pairs)
{
    auto allowed = [&](Index va, Index vb) {
        const int ga = mesh.vertex_group[size_t(va)], gb = mesh.vertex_group[size_t(vb)];
        if (ga < 0 || gb < 0)
            return false;
        if (ga == gb)
            return all_pairs ? !mesh.group_kinematic[size_t(ga)] : bool(mesh.group_self_contact[size_t(ga)]);
        return !(mesh.group_kinematic[size_t(ga)] && mesh.group_kinematic[size_t(gb)]);
    };
    std::vector<Box> edges;
    for (Index e = 0; e < mesh.edges.rows(); ++e)
        edges.push_back(box_of(X, mesh.edges.row(e).data(), 2, e));
    std::string found;
    auto point3 = [&](Index v) {
        std::array<double, 3> p { 0, 0, 0 };
        for (int c = 0; c < X.cols(); ++c)
            p[size_t(c)] = X(v, c);
        return p;
    };
    if (mesh.dim == 2) {
        overlapping_pairs(edges, edges, [&](Index a, Index b) {
            if (a >= b)
                return true;
            const Index a0 = mesh.edges(a, 0), a1 = mesh.edges(a, 1), b0 = mesh.edges(b, 0), b1 = mesh.edges(b, 1);
            if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1 || !allowed(a0, b0))
                return true;
            const auto p = point3(a0), q = point3(a1), r = point3(b0), s = point3(b1);
            if (segments_intersect_2d(p.data(), q.data(), r.data(), s.data())) {
                found = "edges (" + std::to_string(a0) + ", " + std::to_string(a1) + ") and (" + std::to_string(b0)
                    + ", " + std::to_string(b1) + ") intersect";
                return false;
            }
            return true;
        });
        return found;
    }
    std::vector<Box> faces;
    for (Index f = 0; f < mesh.faces.rows(); ++f)
        faces.push_back(box_of(X, mesh.faces.row(f).data(), 3, f));
    overlapping_pairs(edges, faces, [&](Index e, Index f) {
        const Index e0 = mesh.edges(e, 0), e1 = mesh.edges(e, 1);
        for (int k = 0; k < 3; ++k)
            if (mesh.faces(f, k) == e0 || mesh.faces(f, k) == e1)
                return true;
        if (!allowed(e0, mesh.faces(f, 0)))
            return true;
        const auto p = point3(e0), q = point3(e1), a = point3(mesh.faces(f, 0)), b = point3(mesh.faces(f, 1)),
                   c = point3(mesh.faces(f, 2));
        if (segment_triangle_intersect(p.data(), q.data(), a.data(), b.data(), c.data())) {
            found = "edge (" + std::to_string(e0) + ", " + std::to_string(e1) + ") intersects face ("
                + std::to_string(mesh.faces(f, 0)) + ", " + std::to_string(mesh.faces(f, 1)) + ", "
                + std::to_string(mesh.faces(f, 2)) + ")";
            return false;
        }
        return true;
    });
    return found;
}

std::string find_containment(const CollisionMesh& mesh, const Positions& X)
{
    const int dim = mesh.dim;
    const MatrixXi& facets = dim == 3 ? mesh.faces : mesh.edges;
    const size_t groups = mesh.group_kinematic.size();
    // Facets per group, and whether each group's surface is closed (every edge
    // shared by two faces in 3D, every vertex by two edges in 2D).
    std::vector<std::vector<Index>> group_facets(groups);
    for (Index f = 0; f < facets.rows(); ++f)
        group_facets[size_t(mesh.vertex_group[size_t(facets(f, 0))])].push_back(f);
    std::vector<char> closed(groups, 0);
    std::vector<Index> representative(groups, -1);
    for (size_t g = 0; g < groups; ++g) {
        if (group_facets[g].empty())
            continue;
        representative[g] = facets(group_facets[g].front(), 0);
        std::map<std::pair<int, int>, int> count;
        for (Index f : group_facets[g])
            for (int a = 0; a < dim; ++a) {
                const int u = facets(f, a), w = dim == 3 ? facets(f, (a + 1) % 3) : u;
                ++count[{ std::min(u, w), std::max(u, w) }];
            }
        closed[g] = std::all_of(count.begin(), count.end(), [](const auto& c) { return c.second == 2; });
    }
    auto winding = [&](size_t g, Index v) {
        double sum = 0;
        if (dim == 3) {
            const Eigen::Vector3d p = X.row(v).transpose();
            for (Index f : group_facets[g]) {
                // Van Oosterom and Strackee: tan(Omega / 2) = a . (b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| +
                // (c.a)|b|).
                const Eigen::Vector3d a = X.row(facets(f, 0)).transpose() - p, b = X.row(facets(f, 1)).transpose() - p,
                                      c = X.row(facets(f, 2)).transpose() - p;
                const double la = a.norm(), lb = b.norm(), lc = c.norm();
                const double num = a.dot(b.cross(c));
                const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
                sum += 2 * std::atan2(num, den);
            }
            return sum / (4 * M_PI);
        }
        const Eigen::Vector2d p = X.row(v).transpose();
        for (Index f : group_facets[g]) {
            const Eigen::Vector2d a = X.row(facets(f, 0)).transpose() - p, b = X.row(facets(f, 1)).transpose() - p;
            sum += std::atan2(a[0] * b[1] - a[1] * b[0], a.dot(b));
        }
        return sum / (2 * M_PI);
    };
    for (size_t g = 0; g < groups; ++g) {
        if (!closed[g])
            continue;
        for (size_t h = 0; h < groups; ++h) {
            if (h == g || representative[h] < 0 || (mesh.group_kinematic[g] && mesh.group_kinematic[h]))
                continue;
            if (std::abs(winding(g, representative[h])) > 0.5)
                return "contact group " + std::to_string(h) + " lies inside the closed surface of group "
                    + std::to_string(g);
        }
    }
    return "";
}

Index count_inverted_elements(const Mesh& mesh, const Positions& X)
{
    Index count = 0;
    for (Index e = 0; e < mesh.num_elements(); ++e) {
        if (mesh.dim == 2) {
            const int s = orient2d_filtered(X.row(mesh.elements(e, 0)).data(), X.row(mesh.elements(e, 1)).data(),
                X.row(mesh.elements(e, 2)).data());
            count += s <= 0;
        } else {
            const int s = orient3d_filtered(X.row(mesh.elements(e, 0)).data(), X.row(mesh.elements(e, 1)).data(),
                X.row(mesh.elements(e, 2)).data(), X.row(mesh.elements(e, 3)).data());
            // Elements are positively oriented when det[x1 - x0, x2 - x0, x3 - x0] > 0 (mesh.hpp).
            count += s <= 0;
        }
    }
    return count;
}

} // namespace diffipc
