// `diffipc bench --suite scaling --scenes factor`: CHOLMOD's numeric factorization and
// diffipc's parallel one (forward/solver/supernodal_cholesky.hpp) on the same Newton
// matrices, with the same symbolic analysis, per thread count. Prints figures; asserts
// nothing (docs/performance.md).

#include "cli/bench.hpp"
#include "cli/bench_scenes.hpp"

#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "forward/solver/supernodal_cholesky.hpp"

#include <Eigen/CholmodSupport>

#include <algorithm>
#include <cstdio>

namespace diffipc {

namespace {

    /// The projected Newton matrix (constraints applied) at the end of the scene's first step.
    SparseMatrixd newton_matrix(const nlohmann::json& scene, const std::string& name)
    {
        Simulator sim(parse_scene(scene, ".", name));
        if (sim.step() != StepStatus::CONVERGED)
            throw std::runtime_error(name + ": the first step failed");
        SparseAssembler h;
        h.build(sim.scene().dim, sim.mesh().num_vertices(), sim.mesh().elements);
        sim.problem().hessian(sim.positions(), true, h);
        h.apply_constraints(sim.constrained());
        return h.matrix();
    }

    void compare(const std::string& name, const SparseMatrixd& a, const std::vector<int>& counts, int repeats)
    {
        Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower> cholmod;
        cholmod.analyzePattern(a);
        SupernodalCholesky ours;
        ours.analyze(a);
        const auto& st = ours.statistics();
        std::printf("\n%s: %ld dofs, %.3g entries in L, %.3g Gflop per factorization, %ld supernodes (%ld tiled)\n",
            name.c_str(), long(a.rows()), st.factor_entries, st.flops * 1e-9, long(st.supernodes),
            long(st.tiled_supernodes));
        std::printf("  %7s %14s %14s %11s %11s %12s %12s %14s %14s\n", "threads", "cholmod (s)", "diffipc (s)",
            "cholmod eff", "diffipc eff", "ratio", "rel. diff", "solve cholmod", "solve diffipc");
        double cholmod_base = 0, ours_base = 0;
        const VectorXd b = VectorXd::Ones(a.rows());
        for (int t : counts) {
            set_threads(t, ThreadSource::EXPLICIT, "bench --thread-counts");
            double tc = 1e300, to = 1e300;
            for (int r = 0; r < repeats; ++r) {
                Timer timer;
                cholmod.factorize(a);
                tc = std::min(tc, timer.seconds());
                Timer timer2;
                const bool ok = ours.factorize(a);
                to = std::min(to, timer2.seconds());
                if (!ok || cholmod.info() != Eigen::Success) {
                    std::printf("  factorization failed (cholmod %d, diffipc %d)\n", int(cholmod.info()), int(ok));
                    return;
                }
            }
            if (cholmod_base == 0) {
                cholmod_base = tc * t;
                ours_base = to * t;
            }
            VectorXd xc, xo;
            double sc = 1e300, so = 1e300;
            for (int r = 0; r < repeats; ++r) {
                Timer timer;
                xc = cholmod.solve(b);
                sc = std::min(sc, timer.seconds());
                Timer timer2;
                xo = ours.solve(b);
                so = std::min(so, timer2.seconds());
            }
            std::printf("  %7d %14.4f %14.4f %10.0f%% %10.0f%% %11.2fx %12.2e %14.5f %14.5f\n", t, tc, to,
                100 * cholmod_base / (t * tc), 100 * ours_base / (t * to), tc / to, (xc - xo).norm() / xc.norm(), sc,
                so);
            std::fflush(stdout);
        }
        std::printf("  (eff: parallel efficiency t(first) first / (p t(p)); ratio: cholmod / diffipc; rel. diff: of "
                    "the two solutions)\n");
    }

} // namespace

void factorization_comparison(bool full, const std::vector<int>& counts, int repeats)
{
    set_threads(counts.back(), ThreadSource::EXPLICIT, "bench --thread-counts");
    compare(full ? "3d-box-50k" : "3d-box-2k",
        newton_matrix(full ? beam(3, "neo_hookean", { 40, 14, 15 }, { 4.0, 1.4, 1.5 }, 1)
                           : beam(3, "neo_hookean", { 12, 5, 6 }, { 4.0, 1.4, 1.5 }, 1),
            "box"),
        counts, repeats);
    compare(full ? "3d-box-200k" : "3d-box-6k",
        newton_matrix(full ? beam(3, "neo_hookean", { 64, 22, 24 }, { 4.0, 1.4, 1.5 }, 1)
                           : beam(3, "neo_hookean", { 20, 7, 7 }, { 4.0, 1.4, 1.5 }, 1),
            "box"),
        counts, repeats);
    compare(full ? "contact-slabs" : "contact-slabs-small", newton_matrix(contact_slabs(full, 1, 0.0), "contact"),
        counts, repeats);
}

} // namespace diffipc
