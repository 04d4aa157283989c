// A periodic cell solved in its reduced unknowns (forward/periodic/periodic_potential.hpp) by the
// unchanged Newton solver, against closed forms: a homogeneous cell under a prescribed macro
// gradient has no fluctuation and the material's stress, for every material, 2D and 3D; with the
// lateral components free, uniaxial compression contracts as the material's uniaxial closed form.

#include "forward/fem/fe_space.hpp"
#include "forward/materials/material.hpp"
#include "forward/periodic/periodic_potential.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/newton.hpp"

#include <gtest/gtest.h>

#include <memory>

using namespace diffipc;

namespace {

/// A homogeneous periodic box cell with one material, its full and reduced problems.
struct Cell {
    Mesh mesh;
    PeriodicPairing pairing;
    std::unique_ptr<FESpace> space;
    std::unique_ptr<ElasticPotential> elastic;
    Problem full, reduced;
    SparseAssembler full_assembler, reduced_assembler;
    std::unique_ptr<PeriodicMap> map;
    std::unique_ptr<PeriodicPotential> periodic;
    LinearSolver linear { LinearSolverType::CHOLMOD };
    double mu = 0, lambda = 0;

    Cell(int d, MaterialModel model)
    {
        mesh = d == 2 ? box_mesh(2, VectorXd::Zero(2), (VectorXd(2) << 1.0, 0.8).finished(), (VectorXi(2) << 4, 3).finished())
                      : box_mesh(3, VectorXd::Zero(3), VectorXd::Ones(3), (VectorXi(3) << 2, 2, 3).finished());
        PeriodicBox box;
        box.lower = mesh.rest_positions.colwise().minCoeff().transpose();
        box.upper = mesh.rest_positions.colwise().maxCoeff().transpose();
        pairing = pair_periodic_vertices(mesh, box, 1e-9, "mesh");
        space = std::make_unique<FESpace>(mesh);
        mu = lame_mu(1e5, 0.3);
        lambda = lame_lambda(1e5, 0.3);
        const Index ne = mesh.num_elements();
        elastic = std::make_unique<ElasticPotential>(*space, std::vector<MaterialModel>(size_t(ne), model),
            VectorXd::Constant(ne, mu), VectorXd::Constant(ne, lambda));
        full.add(elastic.get(), 1.0);
        full_assembler.build(d, mesh.num_vertices(), mesh.elements);
        map = std::make_unique<PeriodicMap>(mesh, pairing);
        periodic = std::make_unique<PeriodicPotential>(full, full_assembler, *map);
        reduced.add(periodic.get(), 1.0);
        reduced_assembler.build(d, pairing.num_classes() + d, periodic_elements(mesh, pairing), false);
    }
    int dim() const { return mesh.dim; }
    double volume() const { return dim() == 2 ? 0.8 : 1.0; }

    /// Solves with G's components fixed where `fixed` is set (at G's values), the others free,
    /// and the class of vertex 0 (the box's lower corner) pinned. Returns q.
    VectorXd solve(const MatrixXd& G, const Eigen::MatrixXi& fixed, NewtonResult& result)
    {
        const int d = dim();
        VectorXd q = VectorXd::Zero(map->num_reduced()), target = q;
        std::vector<char> constrained(size_t(q.size()), 0);
        for (int i = 0; i < d; ++i) {
            constrained[size_t(map->fluctuation_dof(pairing.vertex_class[0], i))] = 1;
            for (int j = 0; j < d; ++j)
                if (fixed(i, j)) {
                    constrained[size_t(map->macro_dof(i, j))] = 1;
                    target[map->macro_dof(i, j)] = G(i, j);
                }
        }
        NewtonSettings settings;
        settings.residual_tolerance = 1e-11;
        const NewtonSolver newton(reduced, reduced_assembler, linear, settings);
        result = newton.solve(q, target, constrained, 1e5, 1.0);
        return q;
    }
    MatrixXd macro(const VectorXd& q) const
    {
        MatrixXd G(dim(), dim());
        for (int i = 0; i < dim(); ++i)
            for (int j = 0; j < dim(); ++j)
                G(i, j) = q[map->macro_dof(i, j)];
        return G;
    }
};

template <int d> MatrixXd material_stress(MaterialModel model, const MatrixXd& F, double mu, double lambda)
{
    return make_material<d>(model)->stress(Eigen::Matrix<double, d, d>(F), mu, lambda);
}

} // namespace

TEST(PeriodicCell, HomogeneousCellHasNoFluctuationAndTheMaterialsStress)
{
    for (int d : { 2, 3 })
        for (MaterialModel model :
            { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
            SCOPED_TRACE(std::to_string(d) + "D " + to_string(model));
            Cell cell(d, model);
            MatrixXd G = d == 2 ? (MatrixXd(2, 2) << -0.2, 0.05, 0.03, 0.1).finished()
                                : (MatrixXd(3, 3) << -0.2, 0.05, 0.0, 0.03, 0.1, -0.04, 0.02, 0.0, 0.15).finished();
            NewtonResult r;
            const VectorXd q = cell.solve(G, Eigen::MatrixXi::Ones(d, d), r);
            ASSERT_EQ(r.status, StepStatus::CONVERGED);
            EXPECT_LE((cell.macro(q) - G).lpNorm<Eigen::Infinity>(), 1e-15);
            const VectorXd w = q.head(cell.map->num_classes() * d);
            EXPECT_LE(w.lpNorm<Eigen::Infinity>(), 1e-10) << "a homogeneous cell has no fluctuation";
            // The macro rows of the reduced gradient: |Y| times the cell's average first Piola stress.
            VectorXd g = VectorXd::Zero(q.size());
            cell.periodic->add_gradient(q, 1.0, g);
            const MatrixXd F = MatrixXd::Identity(d, d) + G;
            const MatrixXd P = d == 2 ? material_stress<2>(model, F, cell.mu, cell.lambda)
                                      : material_stress<3>(model, F, cell.mu, cell.lambda);
            for (int i = 0; i < d; ++i)
                for (int j = 0; j < d; ++j)
                    EXPECT_NEAR(g[cell.map->macro_dof(i, j)] / cell.volume(), P(i, j), 1e-8 * P.norm())
                        << "P(" << i << ", " << j << ")";
        }
}

TEST(PeriodicCell, FreeLateralComponentsGiveTheUniaxialContraction)
{
    // Linear elasticity, 1% uniaxial compression along x, the other diagonal components free, the
    // shear components held at 0: plane strain contracts by lambda / (lambda + 2 mu) of the strain
    // (sigma_yy = 0), 3D by nu = lambda / (2 (lambda + mu)), and the free rows carry no stress.
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        Cell cell(d, MaterialModel::LINEAR);
        MatrixXd G = MatrixXd::Zero(d, d);
        G(0, 0) = -0.01;
        Eigen::MatrixXi fixed = Eigen::MatrixXi::Ones(d, d);
        for (int i = 1; i < d; ++i)
            fixed(i, i) = 0;
        NewtonResult r;
        const VectorXd q = cell.solve(G, fixed, r);
        ASSERT_EQ(r.status, StepStatus::CONVERGED);
        const double ratio = d == 2 ? cell.lambda / (cell.lambda + 2 * cell.mu) : cell.lambda / (2 * (cell.lambda + cell.mu));
        for (int i = 1; i < d; ++i)
            EXPECT_NEAR(cell.macro(q)(i, i), 0.01 * ratio, 1e-12);
        VectorXd g = VectorXd::Zero(q.size());
        cell.periodic->add_gradient(q, 1.0, g);
        // The loaded component carries the uniaxial stress: E' eps with the plane-strain modulus
        // 4 mu (lambda + mu) / (lambda + 2 mu), or Young's modulus in 3D.
        const double l = cell.lambda, m = cell.mu;
        const double modulus = d == 2 ? 4 * m * (l + m) / (l + 2 * m) : m * (3 * l + 2 * m) / (l + m);
        EXPECT_NEAR(g[cell.map->macro_dof(0, 0)] / cell.volume(), -0.01 * modulus, 1e-10 * 0.01 * modulus);
        for (int i = 1; i < d; ++i)
            EXPECT_LE(std::abs(g[cell.map->macro_dof(i, i)]), 1e-6);
    }
}
