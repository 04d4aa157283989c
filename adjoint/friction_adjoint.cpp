#include "adjoint/friction_adjoint.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/contact/barrier.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/distance/edge_edge_mollifier.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <vector>

namespace diffipc {

namespace {

    /// rho(y) = f1(y) / y and its derivative (docs/math.md "Friction adjoint").
    void speed_ratio(double y, double eps, double& rho, double& drho)
    {
        if (y < eps) {
            rho = 2 / eps - y / (eps * eps);
            drho = -1 / (eps * eps);
        } else {
            rho = 1 / y;
            drho = -1 / (y * y);
        }
    }

    /// One lagged pair's terms (friction_step_adjoint): d(lambda^T grad D_k)/dy on its dofs, w lam phi (the
    /// coefficient's factor) and its edge-edge rest-shape term.
    struct PairTerms {
        double dY[12] = {};
        double dmu = 0;
        double drest[12] = {};
        bool has_rest = false;
    };

} // namespace

void friction_step_adjoint(
    const Simulator& sim, int k, const VectorXd& mesh_lambda, double weight, const FrictionAdjointTerms& mesh_terms)
{
    const FrictionPotential& D = *sim.friction();
    const ContactPotential& B = *sim.contact();
    const int dim = sim.mesh().dim;
    // With periodic images the contacts index the image surface x_s = T x: work there (lambda^T
    // grad D = (T lambda)^T grad D_s) and map the position terms back by T^T.
    const VectorXd x = B.surface_positions(sim.trajectory().steps[size_t(k - 1)].positions);
    const VectorXd lambda = B.surface_positions(mesh_lambda);
    const VectorXd& y = D.step_start(); // x_{k-1}: the start of the step and the lagged state
    VectorXd previous_surface, rest_surface;
    FrictionAdjointTerms terms = mesh_terms;
    if (B.has_images()) {
        if (mesh_terms.previous_positions)
            terms.previous_positions = &(previous_surface = VectorXd::Zero(x.size()));
        if (mesh_terms.rest_positions)
            terms.rest_positions = &(rest_surface = VectorXd::Zero(x.size()));
    }
    const double eps = D.eps();
    const ContactSettings& cs = B.settings();
    const double dmin2 = cs.min_distance * cs.min_distance;
    const double shat = barrier_activation(cs.dhat, cs.min_distance);
    const double kappa = B.kappa();
    if (terms.coefficients) {
        // A pair with a zero-coefficient side is not lagged, but d sqrt(mu_a mu_b)/dmu_a is
        // unbounded at mu_a = 0 wherever the pair presses: no number is right there.
        // Groups never in contact have a zero derivative, which is exact.
        const std::vector<double>& mu = D.group_coefficients();
        const VectorXi& group = D.vertex_groups();
        for (const Contact& c : B.surface_contacts(y)) {
            const int other = c.kind == ContactKind::EDGE_EDGE ? 2 : 1;
            const int ga = group[c.vertices[0]], gb = group[c.vertices[size_t(other)]];
            if (!(mu[size_t(ga)] > 0) || !(mu[size_t(gb)] > 0))
                throw AdjointError("no gradient: contact group " + std::to_string(mu[size_t(ga)] > 0 ? gb : ga)
                    + " has friction coefficient 0 and is in contact at step " + std::to_string(k - 1)
                    + ", where a pair's coefficient sqrt(mu_a mu_b) is not differentiable");
        }
    }

    // Each pair's terms in parallel, then added in pair order (the serial sum, whatever the thread count).
    const std::vector<FrictionContact>& lagged = D.lagged();
    std::vector<PairTerms> pair_terms(lagged.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, lagged.size(), 64), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t p = range.begin(); p < range.end(); ++p) {
            const FrictionContact& f = lagged[p];
            PairTerms& out = pair_terms[p];
            const int nv = f.num_vertices, L = nv * dim;
            const auto gamma = [&](int i) { return f.weights[size_t(i)]; };
            const auto local = [&](const VectorXd& v, int i) { return v.segment(f.vertices[size_t(i)] * dim, dim); };
            // The contact's terms of lambda^T grad D_k: w mu lam phi, with
            // phi = rho(|t|) abar . t, t = P dx, P = I - n n^T, dx = sum_i gamma_i (x_i - y_i).
            Eigen::VectorXd dx = Eigen::VectorXd::Zero(dim), abar = Eigen::VectorXd::Zero(dim);
            for (int i = 0; i < nv; ++i) {
                dx += gamma(i) * (local(x, i) - local(y, i));
                abar += gamma(i) * local(lambda, i);
            }
            const Eigen::VectorXd n = f.normal.head(dim);
            const Eigen::VectorXd t = dx - n * n.dot(dx);
            const double speed = t.norm();
            double rho, drho;
            speed_ratio(speed, eps, rho, drho);
            const double phi = rho * abar.dot(t);
            // dphi/dt, dphi/ddx = P dphi/dt, dphi/dn (n as a free vector).
            Eigen::VectorXd q_t = rho * abar;
            if (speed > 0)
                q_t += drho * abar.dot(t) / speed * t;
            const Eigen::VectorXd q_dx = q_t - n * n.dot(q_t);
            const Eigen::VectorXd q_n = -n.dot(dx) * q_t - dx * n.dot(q_t);

            const double scale = weight * f.coefficient;
            const double lam = f.normal_force;
            Eigen::VectorXd dY = Eigen::VectorXd::Zero(L); // d(lambda^T grad D_k)/dy, contact dofs
            // The start-of-step positions in dx.
            for (int i = 0; i < nv; ++i)
                dY.segment(i * dim, dim) -= scale * lam * gamma(i) * q_dx;

            const ContactPotential::LocalDistance ld = B.local_distance(f.source, y, true);
            if (f.kind != ContactKind::VERTEX_PLANE) {
                // Closest-point weights and normal. With r = sum_i gamma_i y_i (p - q) and
                // s = |r|^2 for the classified type, ds/dy_i = 2 gamma_i r; side A's weights
                // sum to 1, so dr/dy = 1/2 sum_{i in A} d^2 s/(dy_i dy), and
                // r dgamma_i/dy = 1/2 d^2 s/(dy_i dy) - gamma_i dr/dy.
                Eigen::VectorXd r = Eigen::VectorXd::Zero(dim);
                for (int i = 0; i < nv; ++i)
                    r += gamma(i) * local(y, i);
                const double rr = r.squaredNorm();
                const int side_a = f.kind == ContactKind::EDGE_EDGE ? 2 : 1;
                Eigen::MatrixXd R = Eigen::MatrixXd::Zero(dim, L);
                for (int i = 0; i < side_a; ++i)
                    R += 0.5 * ld.Hs.middleRows(i * dim, dim);
                // dn/dy = (I - n n^T) R / |r|
                const Eigen::VectorXd pq_n = q_n - n * n.dot(q_n);
                dY += scale * lam * R.transpose() * pq_n / std::sqrt(rr);
                for (int i = 0; i < nv; ++i) {
                    const double dphi_dgamma = q_dx.dot(local(x, i) - local(y, i)) + rho * t.dot(local(lambda, i));
                    if (dphi_dgamma == 0)
                        continue;
                    const Eigen::MatrixXd G = 0.5 * ld.Hs.middleRows(i * dim, dim) - gamma(i) * R;
                    dY += scale * lam * dphi_dgamma * (G.transpose() * r) / rr;
                }
            }
            // The normal force lam = kappa m |b'(z)| 2 sqrt(s), z = s - dmin^2.
            const double z = ld.s - dmin2;
            const double b1 = barrier_first_derivative(z, shat), b2 = barrier_second_derivative(z, shat);
            const double sign = b1 < 0 ? -1.0 : 1.0;
            const double d = std::sqrt(ld.s);
            Eigen::VectorXd dlam = kappa * ld.m * (sign * b2 * 2 * d + std::abs(b1) / d) * ld.gs;
            if (ld.gm.size())
                dlam += kappa * std::abs(b1) * 2 * d * ld.gm;
            dY += scale * phi * dlam;

            for (int q = 0; q < L; ++q)
                out.dY[q] = dY[q];
            out.dmu = weight * lam * phi;
            // Edge-edge: m depends on the rest shape through eps_x.
            if (terms.rest_positions && f.kind == ContactKind::EDGE_EDGE) {
                const auto& v = f.vertices;
                const double dm
                    = edge_edge_mollifier_gradient_wrt_eps_x(vertex_point(y, v[0], dim), vertex_point(y, v[1], dim),
                        vertex_point(y, v[2], dim), vertex_point(y, v[3], dim), f.source.mollifier_threshold);
                if (dm != 0) {
                    const double dlam_deps = kappa * std::abs(b1) * 2 * d * dm;
                    const Eigen::Matrix<double, 12, 1> deps = B.mollifier_threshold_gradient(f.source);
                    out.has_rest = true;
                    for (int i = 0; i < 4; ++i)
                        for (int a = 0; a < dim; ++a)
                            out.drest[i * dim + a] = scale * phi * dlam_deps * deps[3 * i + a];
                }
            }
        }
    });
    for (size_t p = 0; p < lagged.size(); ++p) {
        const FrictionContact& f = lagged[p];
        const PairTerms& t = pair_terms[p];
        if (terms.previous_positions)
            for (int i = 0; i < f.num_vertices; ++i)
                terms.previous_positions->segment(f.vertices[size_t(i)] * dim, dim)
                    -= Eigen::Map<const Eigen::VectorXd>(t.dY + i * dim, dim);
        // mu = sqrt(mu_a mu_b) (mu_a alone when both sides are one group).
        if (terms.coefficients) {
            const std::vector<double>& group_mu = D.group_coefficients();
            const int ga = f.groups[0], gb = f.groups[1];
            if (ga == gb)
                (*terms.coefficients)[ga] -= t.dmu;
            else {
                (*terms.coefficients)[ga] -= t.dmu * f.coefficient / (2 * group_mu[size_t(ga)]);
                (*terms.coefficients)[gb] -= t.dmu * f.coefficient / (2 * group_mu[size_t(gb)]);
            }
        }
        if (t.has_rest)
            for (int i = 0; i < 4; ++i)
                terms.rest_positions->segment(f.vertices[size_t(i)] * dim, dim)
                    -= Eigen::Map<const Eigen::VectorXd>(t.drest + i * dim, dim);
    }
    if (B.has_images()) {
        if (mesh_terms.previous_positions)
            *mesh_terms.previous_positions += B.images().transpose() * previous_surface;
        if (mesh_terms.rest_positions)
            *mesh_terms.rest_positions += B.images().transpose() * rest_surface;
    }
}

} // namespace diffipc
