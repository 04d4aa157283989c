// cuda/contact/pair_barrier.cuh, one pair at a time, on the CPU: the pair's distance, mollifier and
// their derivatives against ContactPotential::local_distance for every active pair of a 3D scene
// (vertex-face, edge-edge, vertex-plane) and a 2D scene (vertex-edge, vertex-plane); the pair's
// projected Hessian against the CPU's project_psd; the gradient and Hessian against finite
// differences of the pair energy.

#include "cuda/contact/pair_barrier.cuh"
#include "forward/materials/material.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"
#include "tests/forward/kernels/kernel_test_utils.hpp"

#include <Eigen/Eigenvalues>

using namespace diffipc;

namespace {

/// The pair's vertices at x (z = 0 in 2D) and its plane normal.
void load(const test::ContactScene& scene, const Contact& c, const VectorXd& x, gpu::vec3* points, gpu::vec3& normal)
{
    for (int a = 0; a < c.num_vertices(); ++a)
        points[a] = test::to_gpu(vertex_point(x, c.vertices[size_t(a)], scene.dim()));
    normal = c.plane >= 0 ? test::to_gpu(scene.contact().planes()[size_t(c.plane)].normal) : gpu::vec3();
}

double eps_x(const test::ContactScene& scene, const Contact& c)
{
    if (c.kind != ContactKind::EDGE_EDGE)
        return 0;
    const Positions& X = scene.sim->mesh().rest_positions;
    auto p = [&](int a) { return test::to_gpu(X.row(c.vertices[size_t(a)]).transpose()); };
    return gpu::edge_edge_mollifier_threshold(p(0), p(1), p(2), p(3));
}

int compare_local_distances(const test::ContactScene& scene)
{
    const int dim = scene.dim();
    test::Tally t;
    int count = 0;
    for (const Contact& c : scene.contact().contacts(scene.x)) {
        if (c.kind == ContactKind::EDGE_EDGE)
            EXPECT_EQ(eps_x(scene, c), c.mollifier_threshold);
        const ContactPotential::LocalDistance ld = scene.contact().local_distance(c, scene.x, true);
        gpu::vec3 points[4], normal;
        load(scene, c, scene.x, points, normal);
        double s = 0, m = 1, gs[12], Hs[144], gm[12], Hm[144];
        const bool ee = c.kind == ContactKind::EDGE_EDGE;
        gpu::pair_distance(gpu::ContactKind(int(c.kind)), points, normal, eps_x(scene, c), -1, s, m, gs, Hs,
            ee ? gm : nullptr, ee ? Hm : nullptr);
        if (dim == 2)
            gpu::pair_barrier_detail::compress_2d(c.num_vertices(), gs, Hs);
        t.add(s, ld.s);
        t.add(m, ld.m);
        t.add(gs, ld.gs.transpose());
        t.add(Hs, ld.Hs);
        if (ee) {
            t.add(gm, ld.gm.transpose());
            t.add(Hm, ld.Hm);
        }
        ++count;
    }
    t.expect(1e-12, "local distances of " + std::to_string(count) + " pairs");
    return count;
}

} // namespace

TEST(GpuPairBarrier, LocalDistancesEqualCpu3D)
{
    const test::ContactScene scene = test::boxes_on_plane(2, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 1.0 } });
    const std::array<int, 4> k = scene.kinds();
    EXPECT_GT(k[1], 0);
    EXPECT_GT(k[2], 0);
    EXPECT_GT(k[3], 0);
    EXPECT_GT(compare_local_distances(scene), 50);
}

TEST(GpuPairBarrier, LocalDistancesEqualCpu2D)
{
    for (int which = 0; which < 2; ++which) {
        const nlohmann::json settings = { { "dhat", 1e-3 }, { "kappa", 1.0 } };
        const test::ContactScene scene
            = which == 0 ? test::rings_on_plane(1e-5, settings) : test::boxes_on_plane_2d(8, 3e-4, 1e-5, settings);
        const std::array<int, 4> k = scene.kinds();
        EXPECT_GT(k[0], 0);
        EXPECT_GT(k[3], 0);
        EXPECT_GT(compare_local_distances(scene), which == 0 ? 4 : 20);
    }
}

TEST(GpuPairBarrier, ProjectionMatchesCpuAndDerivativesMatchFiniteDifferences)
{
    const double dhat = 1e-3;
    for (double dmin : { 0.0, 2e-4 })
        for (int dim : { 3, 2 }) {
            const nlohmann::json settings = { { "dhat", dhat }, { "kappa", 1.0 }, { "min_distance", dmin } };
            // With dmin the scenes' gaps (0.5 mm) still exceed dmin and stay within dmin + dhat.
            const test::ContactScene scene = dim == 3 ? test::boxes_on_plane(2, 0.3, 5e-5, settings)
                                                      : test::boxes_on_plane_2d(8, 3e-4, 1e-5, settings);
            const double dmin2 = dmin * dmin, shat = gpu::barrier_activation(dhat, dmin);
            double worst_projection = 0, worst_gradient = 0, worst_hessian = 0, worst_eigenvalue = 0;
            int count = 0;
            for (const Contact& c : scene.contact().contacts(scene.x)) {
                const gpu::ContactKind kind = gpu::ContactKind(int(c.kind));
                const int n = c.num_vertices() * dim;
                const double eps = eps_x(scene, c);
                gpu::vec3 points[4], normal;
                load(scene, c, scene.x, points, normal);
                double g[12], H[144], P[144];
                const double e = gpu::pair_barrier(kind, dim, points, normal, eps, dmin2, shat, g, H);
                ASSERT_TRUE(std::isfinite(e));
                gpu::pair_barrier_hessian(kind, dim, points, normal, eps, dmin2, shat, true, 1.0, P);
                // Row-major n x n as Eigen matrices (symmetric, so the storage order does not matter
                // for the comparisons below, but map them row-major anyway).
                using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
                const Eigen::MatrixXd Hm = Eigen::Map<const RowMatrix>(H, n, n);
                const Eigen::MatrixXd Pm = Eigen::Map<const RowMatrix>(P, n, n);
                const Eigen::MatrixXd Pcpu = project_psd(Hm);
                worst_projection
                    = std::max(worst_projection, (Pm - Pcpu).cwiseAbs().maxCoeff() / Hm.cwiseAbs().maxCoeff());
                const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Pm).eigenvalues().minCoeff();
                worst_eigenvalue = std::min(worst_eigenvalue, lmin / Hm.cwiseAbs().maxCoeff());
                // Central differences along a random direction of the pair's dofs, 1e-8 m.
                const Eigen::VectorXd dir = test::random_vector(n, unsigned(count + 1));
                const double h = 1e-8;
                auto moved = [&](double t, gpu::vec3* q) {
                    for (int a = 0; a < c.num_vertices(); ++a) {
                        q[a] = points[a];
                        q[a].x += t * dir[a * dim];
                        q[a].y += t * dir[a * dim + 1];
                        if (dim == 3)
                            q[a].z += t * dir[a * dim + 2];
                    }
                };
                gpu::vec3 qp[4], qm[4];
                moved(h, qp);
                moved(-h, qm);
                double gp[12], gmi[12];
                const double ep = gpu::pair_barrier(kind, dim, qp, normal, eps, dmin2, shat, gp, nullptr);
                const double em = gpu::pair_barrier(kind, dim, qm, normal, eps, dmin2, shat, gmi, nullptr);
                const Eigen::Map<const Eigen::VectorXd> gv(g, n), gpv(gp, n), gmv(gmi, n);
                const double gnorm = gv.norm() * dir.norm();
                worst_gradient = std::max(worst_gradient, std::abs((ep - em) / (2 * h) - gv.dot(dir)) / gnorm);
                const Eigen::VectorXd Hd = Hm * dir;
                worst_hessian = std::max(worst_hessian, ((gpv - gmv) / (2 * h) - Hd).norm() / Hd.norm());
                ++count;
            }
            std::printf("  dim %d, dmin %.0e, %d pairs: projection vs CPU %.2e, min eigenvalue %.2e, finite "
                        "differences: gradient %.2e, Hessian %.2e\n",
                dim, dmin, count, worst_projection, worst_eigenvalue, worst_gradient, worst_hessian);
            EXPECT_GT(count, 10);
            EXPECT_LE(worst_projection, 1e-12);
            EXPECT_GE(worst_eigenvalue, -1e-13);
            EXPECT_LE(worst_gradient, 1e-5);
            EXPECT_LE(worst_hessian, 1e-5);
        }
}

TEST(GpuPairBarrier, IntersectingPairIsInfinite)
{
    // A vertex behind its plane, and a vertex-face pair closer than dmin.
    const gpu::vec3 plane_pair[2] = { gpu::vec3(0, -1e-3, 0), gpu::vec3(0, 0, 0) };
    double g[6], H[36];
    EXPECT_TRUE(std::isinf(
        gpu::pair_barrier(gpu::ContactKind::VERTEX_PLANE, 3, plane_pair, gpu::vec3(0, 1, 0), 0, 0, 1e-6, g, H)));
    EXPECT_TRUE(std::isnan(g[0]) && std::isnan(H[35]));
    const gpu::vec3 face_pair[4]
        = { gpu::vec3(0.2, 1e-4, 0.2), gpu::vec3(0, 0, 0), gpu::vec3(1, 0, 0), gpu::vec3(0, 0, 1) };
    EXPECT_TRUE(std::isinf(gpu::pair_barrier(gpu::ContactKind::VERTEX_FACE, 3, face_pair, gpu::vec3(), 0, 4e-8,
        gpu::barrier_activation(1e-3, 2e-4), nullptr, nullptr)));
    EXPECT_TRUE(std::isfinite(gpu::pair_barrier(gpu::ContactKind::VERTEX_FACE, 3, face_pair, gpu::vec3(), 0, 0,
        gpu::barrier_activation(1e-3, 0.0), nullptr, nullptr)));
}
