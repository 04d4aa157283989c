#include "shape_opt/rest_validity.hpp"

#include "forward/contact/broad_phase/broad_phase.hpp"
#include "forward/contact/ccd/ccd.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/fem/fe_space.hpp"

#include <algorithm>

namespace diffipc {

namespace {
    Eigen::Vector3d point(const Positions& X, Index v)
    {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        p.head(X.cols()) = X.row(v).transpose();
        return p;
    }
} // namespace

RestValidity::RestValidity(Mesh bodies)
    : m_mesh(std::move(bodies))
{
    const int groups = m_mesh.vertex_body.size() ? m_mesh.vertex_body.maxCoeff() + 1 : 0;
    // Every body may touch itself and the others: a design must not fold a body onto itself.
    m_collision
        = build_collision_mesh(m_mesh, std::vector<char>(size_t(groups), 1), std::vector<char>(size_t(groups), 0));
}

std::string RestValidity::problem(const VectorXd& X) const
{
    const Positions P = unflatten(X, m_mesh.dim);
    if (!P.allFinite())
        return "rest positions that are not finite";
    if (const Index inverted = count_inverted_elements(m_mesh, P); inverted > 0)
        return std::to_string(inverted) + " inverted or degenerate element" + (inverted > 1 ? "s" : "");
    const std::string crossing = find_intersection(m_collision, P, true);
    if (!crossing.empty())
        return "intersecting boundary: " + crossing;
    return "";
}

double RestValidity::max_step(const VectorXd& X, const VectorXd& dX, double keep) const
{
    double t = std::min(1.0, inversion_free_step(m_mesh, X, dX, keep));
    if (!(t > 0))
        return 0;
    const Positions P0 = unflatten(X, m_mesh.dim), P1 = unflatten(VectorXd(X + t * dX), m_mesh.dim);
    const Candidates pairs = broad_phase_candidates(m_collision, P0, P1, 0.0);
    CCDSettings settings;
    settings.min_distance = 0;
    settings.max_iterations = 100000;
    double s = 1; // fraction of [X, X + t dX] certified free
    for (const auto& [v, e] : pairs.vertex_edge) {
        const auto edge = m_collision.edges.row(e);
        const CCDResult r = point_edge_ccd(point(P0, v), point(P0, edge[0]), point(P0, edge[1]), point(P1, v),
            point(P1, edge[0]), point(P1, edge[1]), settings);
        if (r.collision)
            s = std::min(s, r.toi);
    }
    for (const auto& [v, f] : pairs.vertex_face) {
        const auto face = m_collision.faces.row(f);
        const CCDResult r = point_triangle_ccd(point(P0, v), point(P0, face[0]), point(P0, face[1]), point(P0, face[2]),
            point(P1, v), point(P1, face[0]), point(P1, face[1]), point(P1, face[2]), settings);
        if (r.collision)
            s = std::min(s, r.toi);
    }
    for (const auto& [a, b] : pairs.edge_edge) {
        const auto ea = m_collision.edges.row(a), eb = m_collision.edges.row(b);
        const CCDResult r = edge_edge_ccd(point(P0, ea[0]), point(P0, ea[1]), point(P0, eb[0]), point(P0, eb[1]),
            point(P1, ea[0]), point(P1, ea[1]), point(P1, eb[0]), point(P1, eb[1]), settings);
        if (r.collision)
            s = std::min(s, r.toi);
    }
    return t * s;
}

} // namespace diffipc
