// The periodic cell's map x = X + P q on the device (cuda/periodic/device_periodic_map.hpp) against the
// CPU's PeriodicMap (forward/periodic/periodic_map.hpp), its sparse matrix P: the entry functions of
// periodic_reduction.cuh on the host (in CI), the device's kernels on the GPU (skipped without one).

#include "cuda/common/device.hpp"
#include "cuda/periodic/device_periodic_map.hpp"
#include "forward/periodic/contact_images.hpp"
#include "forward/periodic/periodic_map.hpp"
#include "tests/cuda/elastic_test_utils.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

using namespace diffipc;

namespace {

/// A periodic cell (a box mesh, periodic along every axis) with an origin and a length.
struct Cell {
    Mesh mesh;
    PeriodicPairing pairing;
    VectorXd origin;
    double length = 0.7;
};

Cell cell(int dim)
{
    Cell c;
    c.mesh = dim == 2
        ? box_mesh(2, (VectorXd(2) << -0.3, 0.1).finished(), (VectorXd(2) << 0.7, 0.6).finished(),
            (VectorXi(2) << 4, 3).finished())
        : box_mesh(3, VectorXd::Constant(3, 0.2), VectorXd::Constant(3, 1.2), (VectorXi(3) << 2, 3, 2).finished());
    PeriodicBox box;
    box.lower = c.mesh.rest_positions.colwise().minCoeff().transpose();
    box.upper = c.mesh.rest_positions.colwise().maxCoeff().transpose();
    c.pairing = pair_periodic_vertices(c.mesh, box, 1e-9, "mesh");
    c.origin = 0.3 * test::random_vector(dim, 21);
    return c;
}

std::vector<int> classes_of(const Cell& c)
{
    return { c.pairing.vertex_class.data(), c.pairing.vertex_class.data() + c.pairing.vertex_class.size() };
}

std::vector<double> rest_of(const Cell& c)
{
    std::vector<double> rest;
    for (Index v = 0; v < c.mesh.num_vertices(); ++v)
        for (int i = 0; i < c.mesh.dim; ++i)
            rest.push_back(c.mesh.rest_positions(v, i));
    return rest;
}

} // namespace

TEST(PeriodicReduction, EntriesEqualTheSparseMapsProducts)
{
    // The host view built here independently of DevicePeriodicMap (a loop per class, not a counting
    // sort); the entry functions against P q and P^T g of the CPU's sparse P.
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        const Cell c = cell(d);
        const PeriodicMap map(c.mesh, c.pairing, c.origin, c.length);
        const int nv = int(c.mesh.num_vertices()), classes = int(c.pairing.num_classes());
        std::vector<int> start { 0 }, members;
        for (int k = 0; k < classes; ++k) {
            for (int v = 0; v < nv; ++v)
                if (c.pairing.vertex_class[v] == k)
                    members.push_back(v);
            start.push_back(int(members.size()));
        }
        std::vector<double> lever;
        for (int v = 0; v < nv; ++v)
            for (int j = 0; j < d; ++j)
                lever.push_back((c.mesh.rest_positions(v, j) - c.origin[j]) / c.length);
        const std::vector<int> vertex_class = classes_of(c);
        gpu::PeriodicView view;
        view.dim = d;
        view.num_vertices = nv;
        view.num_classes = classes;
        view.vertex_class = vertex_class.data();
        view.lever = lever.data();
        view.class_start = start.data();
        view.class_vertices = members.data();
        ASSERT_EQ(gpu::num_reduced(view), map.num_reduced());
        for (int k = 0; k < classes; ++k)
            for (int i = 0; i < d; ++i)
                ASSERT_EQ(gpu::fluctuation_dof(view, k, i), map.fluctuation_dof(k, i));
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                ASSERT_EQ(gpu::macro_dof(view, i, j), map.macro_dof(i, j));

        const VectorXd q = test::random_vector(map.num_reduced(), 5 + unsigned(d));
        const VectorXd Pq = map.expand(q);
        double worst = 0;
        for (int v = 0; v < nv; ++v)
            for (int i = 0; i < d; ++i)
                worst = std::max(worst, std::abs(gpu::expand_entry(view, q.data(), v, i) - Pq[v * d + i]));
        EXPECT_LE(worst, 1e-14 * Pq.lpNorm<Eigen::Infinity>()) << "P q";

        const VectorXd g = test::random_vector(nv * d, 7 + unsigned(d));
        const VectorXd PTg = map.reduce(g);
        VectorXd mine(map.num_reduced());
        for (int k = 0; k < classes; ++k)
            for (int i = 0; i < d; ++i)
                mine[gpu::fluctuation_dof(view, k, i)] = gpu::reduce_fluctuation(view, g.data(), k, i);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j) {
                double s = 0;
                for (int v = 0; v < nv; ++v)
                    s += gpu::macro_term(view, g.data(), v, i, j);
                mine[gpu::macro_dof(view, i, j)] = s;
            }
        EXPECT_LE((mine - PTg).lpNorm<Eigen::Infinity>(), 1e-13 * PTg.lpNorm<Eigen::Infinity>()) << "P^T g";
        // The adjoint identity the reduced Newton's slope relies on: g . P q = P^T g . q.
        EXPECT_NEAR(g.dot(Pq), mine.dot(q), 1e-12 * std::abs(g.dot(Pq)));
    }
}

TEST(PeriodicReduction, ContactImagesAreVerticesOfTheirSourcesClasses)
{
    // What contact across the boundary on the device will build on (cuda/README.md, "Periodic cells on the
    // device"): the image surface's positions T x = T (X + P q) are X_s + P_s q, P_s the periodic map of
    // the surface's vertices with their rest positions T X and each vertex in its source's class. So the
    // contact can run on the surface's own DevicePeriodicMap. Checked: T P = P_s entry by entry, on cells
    // periodic along x (their other faces are the contact surface), 2D and 3D.
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        Mesh mesh = d == 2
            ? box_mesh(2, (VectorXd(2) << -0.3, 0.1).finished(), (VectorXd(2) << 0.7, 0.6).finished(),
                (VectorXi(2) << 4, 3).finished())
            : box_mesh(3, VectorXd::Constant(3, 0.2), VectorXd::Constant(3, 1.2), (VectorXi(3) << 2, 3, 2).finished());
        PeriodicBox box;
        box.lower = mesh.rest_positions.colwise().minCoeff().transpose();
        box.upper = mesh.rest_positions.colwise().maxCoeff().transpose();
        box.periodic = { { true, false, false } };
        const PeriodicPairing pairing = pair_periodic_vertices(mesh, box, 1e-9, "mesh");
        remove_periodic_facets(mesh, box, 1e-9);
        const ContactImages images = build_contact_images(mesh, box, pairing, { 1 }, { 0 });
        const double L = (box.upper - box.lower).maxCoeff();
        const PeriodicMap map(mesh, pairing, box.lower, L);

        Mesh surface;
        surface.dim = d;
        surface.rest_positions = images.rest;
        PeriodicPairing classes;
        classes.vertex_class.resize(images.rest.rows());
        for (Index t = 0; t < images.rest.rows(); ++t)
            classes.vertex_class[t] = pairing.vertex_class[images.source[size_t(t)]];
        classes.representative = pairing.representative;
        const PeriodicMap surface_map(surface, classes, box.lower, L);
        ASSERT_GT(images.rest.rows(), mesh.num_vertices()) << "no image vertices";
        const SparseMatrixd TP = images.map * map.matrix();
        const double difference = MatrixXd(TP - surface_map.matrix()).cwiseAbs().maxCoeff();
        EXPECT_LE(difference, 1e-14) << "T P differs from the surface's periodic map";
        EXPECT_LE((flatten(images.rest) - images.map * flatten(mesh.rest_positions)).lpNorm<Eigen::Infinity>(), 1e-14);
    }
}

TEST(DevicePeriodicMap, BadInputIsRefusedNamingIt)
{
    // Checked before anything is uploaded: runs without a GPU too.
    const std::vector<double> rest2 = { 0, 0, 1, 0, 0, 1 };
    const std::vector<double> origin2 = { 0, 0 };
    auto refused = [](auto make, const std::string& expected) {
        try {
            make();
            ADD_FAILURE() << "accepted; expected a message with '" << expected << "'";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
        }
    };
    refused([&] { gpu::DevicePeriodicMap(4, { 0, 1, 2 }, rest2, origin2, 1.0); }, "dim");
    refused([&] { gpu::DevicePeriodicMap(2, {}, {}, origin2, 1.0); }, "vertex_class is empty");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, 1 }, rest2, origin2, 1.0); }, "rest has 6 values");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, 1, 2 }, rest2, { 0 }, 1.0); }, "origin has 1 values");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, 1, 2 }, rest2, origin2, 0.0); }, "length");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, -1, 2 }, rest2, origin2, 1.0); }, "vertex_class[1] = -1");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, 2, 2 }, rest2, origin2, 1.0); }, "class 1 has no vertex");
    refused([&] { gpu::DevicePeriodicMap(2, { 0, 1, 2 }, { 0, 0, 1, NAN, 0, 1 }, origin2, 1.0); }, "not finite");
}

TEST(DevicePeriodicMap, ExpandAndReduceEqualTheSparseMaps)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        const Cell c = cell(d);
        const PeriodicMap map(c.mesh, c.pairing, c.origin, c.length);
        gpu::DevicePeriodicMap device(
            d, classes_of(c), rest_of(c), std::vector<double>(c.origin.data(), c.origin.data() + d), c.length);
        ASSERT_EQ(device.num_classes(), c.pairing.num_classes());
        ASSERT_EQ(device.num_reduced(), map.num_reduced());
        const VectorXd q = test::random_vector(map.num_reduced(), 5 + unsigned(d));
        const int n = int(c.mesh.num_vertices()) * d;
        gpu::DeviceArray<double> dq(std::vector<double>(q.data(), q.data() + q.size()));
        gpu::DeviceArray<double> dx { size_t(n) }, dg { size_t(n) }, dgq { size_t(map.num_reduced()) };
        double expand_error = 0;
        for (const bool with_rest : { false, true }) {
            device.expand(dq.data(), dx.data(), with_rest);
            const std::vector<double> x = dx.download();
            const VectorXd expected = with_rest ? map.positions(q) : map.expand(q);
            double worst = 0;
            for (int k = 0; k < n; ++k)
                worst = std::max(worst, std::abs(x[size_t(k)] - expected[k]));
            EXPECT_LE(worst, 1e-14 * expected.lpNorm<Eigen::Infinity>()) << "with_rest " << with_rest;
            expand_error = std::max(expand_error, worst);
        }
        const VectorXd g = test::random_vector(n, 7 + unsigned(d));
        dg.upload(std::vector<double>(g.data(), g.data() + n));
        device.reduce(dg.data(), dgq.data());
        const std::vector<double> gq = dgq.download();
        const VectorXd expected = map.reduce(g);
        double worst = 0;
        for (Index k = 0; k < expected.size(); ++k)
            worst = std::max(worst, std::abs(gq[size_t(k)] - expected[k]));
        EXPECT_LE(worst, 1e-13 * expected.lpNorm<Eigen::Infinity>());
        // Deterministic: a second call gives the same bits.
        device.reduce(dg.data(), dgq.data());
        const std::vector<double> again = dgq.download();
        EXPECT_EQ(std::memcmp(gq.data(), again.data(), gq.size() * sizeof(double)), 0);
        std::printf("  %dD cell: %d vertices, %d classes; P q within %.1e, P^T g within %.1e of the CPU's\n", d,
            device.num_vertices(), device.num_classes(), expand_error, worst);
    }
}
