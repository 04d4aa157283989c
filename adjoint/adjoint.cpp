#include "adjoint/adjoint.hpp"

#include "adjoint/friction_adjoint.hpp"
#include "forward/common/parallel.hpp"
#include "forward/common/timer.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

namespace {

    /// An entry (row >= col) of the lower-triangle Hessian.
    struct Coupling {
        Index row, col;
        double value;
    };

    bool nonzero(const VectorXd& v) { return v.size() > 0 && !v.isZero(0.0); }

    /// The constrained entries of `bar` less their couplings to the free ones times lambda (the
    /// couplings are the lower-triangle entries of the system with a constrained row or column).
    void subtract_couplings(const std::vector<Coupling>& couplings, const std::vector<char>& constrained,
        const VectorXd& lambda, VectorXd& bar)
    {
        for (const Coupling& c : couplings) {
            if (constrained[size_t(c.row)])
                bar[c.row] -= c.value * lambda[c.col];
            if (c.row != c.col && constrained[size_t(c.col)])
                bar[c.col] -= c.value * lambda[c.row];
        }
    }

    void check_run(const Simulator& sim)
    {
        const Trajectory& tr = sim.trajectory();
        if (tr.final_status != StepStatus::CONVERGED)
            throw AdjointError("no gradient: the forward run failed at step " + std::to_string(tr.failed_step) + " ("
                + tr.failure_message + ")");
        if (sim.steps_done() != sim.scene().time.steps)
            throw AdjointError("no gradient: the forward run committed " + std::to_string(sim.steps_done()) + " of "
                + std::to_string(sim.scene().time.steps) + " steps");
        if (sim.contact() && sim.contact()->penalty())
            throw AdjointError("no gradient: penalty contact (contact.model \"penalty\") is a forward baseline; "
                               "the adjoint differentiates IPC's barrier");
        if (sim.contact() && sim.scene().contact.adaptive_kappa)
            throw AdjointError("no gradient: the barrier stiffness must be fixed during a differentiated run "
                               "(give contact.kappa a number, or SimulationParameters::kappa)");
        for (const StepRecord& r : tr.steps) {
            if (!r.positions.allFinite())
                throw AdjointError("no gradient: non-finite state at step " + std::to_string(r.index));
            if (sim.friction() && r.substeps > 0)
                throw AdjointError("no gradient: step " + std::to_string(r.index)
                    + " was solved in sub-steps with friction (time.adaptive); its friction slid from the start of "
                      "its last sub-step, not from the previous step's state as the adjoint differentiates");
            if (sim.friction() && r.friction_iterations > 1)
                throw AdjointError("no gradient: step " + std::to_string(r.index)
                    + " re-lagged friction within the step (friction.iterations > 1); the adjoint differentiates "
                      "friction lagged once at the start of each step");
        }
    }

    void check_sweep(const Simulator& sim, const ParameterRequest& request)
    {
        check_run(sim);
        // Periodic cells (docs/math.md, "Periodic cells"): the adjoint sweeps the cell's reduced
        // unknowns. A cell has no prescribed dofs and starts at rest.
        if (sim.periodic() && (request.prescribed || request.initial_displacement))
            throw AdjointError("no gradient: a periodic cell has no prescribed-value or initial-displacement "
                               "gradients (it has no Dirichlet conditions and starts at rest; its macro gradient "
                               "has its own)");
        if (request.macro && !sim.periodic())
            throw AdjointError("no gradient: only a periodic cell has a macro gradient");
        if (request.friction && sim.contact() && !sim.friction())
            throw AdjointError("no gradient: every friction coefficient is 0, where a pair's coefficient "
                               "sqrt(mu_a mu_b) is not differentiable");
    }

    /// Zero-sized blocks for what was not requested, zeros for what was.
    ParameterGradient allocate(const Simulator& sim, const ParameterRequest& request)
    {
        ParameterGradient g;
        const Index n = sim.mesh().num_dofs(), ne = sim.space().num_elements();
        if (request.rest_positions)
            g.rest_positions = VectorXd::Zero(n);
        if (request.lame) {
            g.mu = VectorXd::Zero(ne);
            g.lambda = VectorXd::Zero(ne);
        }
        if (request.density)
            g.density = VectorXd::Zero(ne);
        if (request.friction)
            g.friction = VectorXd::Zero(sim.num_groups());
        if (request.initial_displacement)
            g.initial_displacement = VectorXd::Zero(n);
        if (request.initial_velocity)
            g.initial_velocity = VectorXd::Zero(n);
        if (request.prescribed)
            g.prescribed = MatrixXd::Zero(sim.scene().time.steps, Index(sim.prescribed_dofs().size()));
        if (request.macro)
            g.macro = MatrixXd::Zero(sim.scene().time.steps, sim.mesh().dim * sim.mesh().dim);
        return g;
    }

    void add_requested(VectorXd& block, const VectorXd& v)
    {
        if (block.size() && v.size())
            block += v;
    }

} // namespace

/// The adjoint system of one step: the true Hessian with the constraints applied, its
/// factorization and the couplings of prescribed dofs. Sweeps of several objectives over
/// one run share it (adjoint_gradients()), so each step is assembled and factorized once.
struct AdjointStepSystem {
    LinearSolver linear;
    std::vector<Coupling> couplings;
    int step = -1; ///< the step whose system is factorized (-1: none)
    int substep = 0; ///< and its sub-step (0: the step's own problem)
    /// The GPU path (scene "device": "gpu"): the system is solved on the device (Simulator::device_solver;
    /// with contact, the barrier's Hessian at the step's kappa), factorized on the CPU only if that fails;
    /// `weight` is the step's w for it.
    bool on_device = false;
    bool factorized = false;
    /// The CPU has assembled the step's system and its couplings (the GPU path only for its fallback).
    bool assembled = false;
    double weight = 0;
    SparseMatrixd reduced; ///< a periodic cell's P^T H P (lower triangle, constraints applied)

    explicit AdjointStepSystem(const Simulator& sim)
        : linear(sim.scene().solver.linear_solver)
        , mesh(sim.mesh())
    {
    }

    /// The CPU's assembler of the system, its pattern built on first use (a GPU run's adjoint that
    /// solves every step on the device never needs it: at 200k tets the pattern costs 0.3 s).
    SparseAssembler& assembler()
    {
        if (!built) {
            cpu_assembler.build(mesh.dim, mesh.num_vertices(), mesh.elements);
            built = true;
        }
        return cpu_assembler;
    }

private:
    const Mesh& mesh;
    SparseAssembler cpu_assembler;
    bool built = false;
};

struct AdjointSweep::Impl {
    Simulator& sim;
    const ParameterRequest request;
    const int T;
    const Index n;
    const int d;
    ParameterGradient grad;
    /// dJ/dx_k, dJ/dv_k, dJ/da_k for k = 0..T; empty reads as zero.
    std::vector<VectorXd> xbar, vbar, abar;
    const std::vector<char>& constrained;
    const std::vector<Index> prescribed;
    std::shared_ptr<AdjointStepSystem> system;
    AdjointStatistics st;
    VectorXd* d_rest = nullptr;
    VectorXd* d_density = nullptr;
    int next; ///< the step that step() takes next (0: finish())
    size_t bytes = 0; ///< held by xbar, vbar, abar

    static Simulator& with_records(Simulator& s)
    {
        if (s.trajectory().first_index != 1)
            throw std::logic_error("the adjoint needs the records of every step; this simulator forgot them "
                                   "(Simulator::forget_records)");
        return s;
    }

    Impl(Simulator& s, const ParameterRequest& r, std::shared_ptr<AdjointStepSystem> shared)
        : sim(with_records(s))
        , request(r)
        , T(s.steps_done())
        , n(s.mesh().num_dofs())
        , d(s.mesh().dim)
        , grad(allocate(s, r))
        , xbar(size_t(T) + 1)
        , vbar(size_t(T) + 1)
        , abar(size_t(T) + 1)
        , constrained(s.constrained())
        , prescribed(s.prescribed_dofs())
        , system(shared ? std::move(shared) : std::make_shared<AdjointStepSystem>(s))
        , next(T)
    {
        d_rest = grad.rest_positions.size() ? &grad.rest_positions : nullptr;
        d_density = grad.density.size() ? &grad.density : nullptr;
    }

    /// Adds s * v to bar (allocating zeros if bar is empty).
    void push(VectorXd& bar, double s, const VectorXd& v)
    {
        if (s == 0)
            return;
        if (bar.size() == 0) {
            bar = VectorXd::Zero(v.size());
            grew(bar);
        }
        bar += s * v;
    }
    void grew(const VectorXd& v)
    {
        bytes += sizeof(double) * size_t(v.size());
        st.peak_adjoint_bytes = std::max(st.peak_adjoint_bytes, bytes);
    }
    void release(VectorXd& v)
    {
        bytes -= sizeof(double) * size_t(v.size());
        v = VectorXd();
    }

    /// The adjoint bars of one state: dJ/dx, dJ/dv, dJ/da (null pointers: no such state).
    struct StateBars {
        VectorXd* x = nullptr;
        VectorXd* v = nullptr;
        VectorXd* a = nullptr;
    };

    /// How a state's prescribed positions depend on X and g_k (per dof, the same for all) and
    /// on state k - 1's.
    struct PrescribedMap {
        double rest = 1, g = 1, previous = 0;
    };

    void step(int k);
    /// @brief Sweeps one state back: state k's own (j = 0), or sub-step j's of a sub-stepped step k
    /// (j = m: the step's own). v and a into x through the scheme s, the adjoint solve, the
    /// history's and the parameters' terms, and the prescribed dofs (through `map`).
    void sweep_state(int k, int j, const VectorXd& x, double time, const StepScheme& s, StateBars cur, StateBars prev,
        StateBars prev2, PrescribedMap map);
    void finish();
    /// A periodic cell's shape terms of state (k, j) beyond the potentials' (docs/math.md).
    void periodic_shape_terms(int k, int j, const VectorXd& x, const VectorXd& xb, const VectorXd& lq,
        const VectorXd& lambda, VectorXd& d_rest);
    /// Assembles and factorizes the adjoint system of step k (j = 0) or of its sub-step j at x,
    /// unless the shared system holds it.
    void factorize(int k, int j, const VectorXd& x);
    /// Factorizes the assembled system of step k on the CPU (the GPU path's fallback).
    void factorize_on_cpu(int k);
    /// Assembles step k's system on the CPU with its couplings, constraints applied (the CPU path, and
    /// the GPU path's fallback); the step's problem must be set (factorize()).
    void assemble_on_cpu(const Problem& problem, const VectorXd& x);
};

void AdjointSweep::Impl::factorize(int k, int j, const VectorXd& x)
{
    AdjointStepSystem& a = *system;
    if (a.step == k && a.substep == j)
        return;
    a.step = -1;
    Timer tsetup;
    const Problem& problem = j == 0 ? sim.step_problem(k) : sim.substep_problem(k, j);
    tsetup.add_to(st.setup_time);
    Timer ta;
    if (const PeriodicCell* cell = sim.periodic()) {
        problem.hessian(x, false, a.assembler());
        // The system in the cell's unknowns: P^T H P, its constrained entries replaced by identity rows.
        a.reduced = cell->map().reduce_matrix(a.assembler().matrix());
        const std::vector<char>& fixed = cell->constrained();
        // The couplings of q's constrained entries (in q's indices), before the identity rows replace them.
        a.couplings.clear();
        for (Index col = 0; col < a.reduced.outerSize(); ++col)
            for (SparseMatrixd::InnerIterator it(a.reduced, col); it; ++it)
                if (fixed[size_t(it.row())] || fixed[size_t(col)]) {
                    a.couplings.push_back({ it.row(), col, it.value() });
                    it.valueRef() = it.row() == col ? 1.0 : 0.0;
                }
        ta.add_to(st.assembly_time);
        Timer tf;
        if (!a.linear.factorize(a.reduced, true))
            throw AdjointError("no gradient: the adjoint system of step " + std::to_string(k)
                + " is singular (true Hessian of the periodic cell at the converged state)");
        tf.add_to(st.factorization_time);
        a.step = k;
        a.substep = j;
        return;
    }
    a.factorized = false;
    a.assembled = false;
    a.on_device = sim.device_solver() && j == 0;
    a.weight = problem.weight(&sim.elastic());
    if (a.on_device && sim.friction()) // the step's lagged friction (step_problem(k) set it) in the device's matrix
        sim.device_solver()->set_friction(*sim.friction());
    if (!a.on_device) {
        assemble_on_cpu(problem, x);
        ta.add_to(st.assembly_time);
        factorize_on_cpu(k);
    }
    a.step = k;
    a.substep = j;
}

void AdjointSweep::Impl::assemble_on_cpu(const Problem& problem, const VectorXd& x)
{
    AdjointStepSystem& a = *system;
    problem.hessian(x, false, a.assembler());
    // The couplings of prescribed dofs (lower triangle), before the constraints replace them.
    const SparseMatrixd& A = a.assembler().matrix();
    a.couplings = parallel_collect<Coupling>(size_t(A.cols()), 256, [&](size_t col, std::vector<Coupling>& out) {
        for (SparseMatrixd::InnerIterator it(A, Index(col)); it; ++it)
            if (constrained[size_t(it.row())] || constrained[col])
                out.push_back({ it.row(), Index(col), it.value() });
    });
    a.assembler().apply_constraints(constrained);
    a.assembled = true;
}

void AdjointSweep::Impl::factorize_on_cpu(int k)
{
    AdjointStepSystem& a = *system;
    Timer tf;
    if (!a.linear.factorize(a.assembler().matrix(), true))
        throw AdjointError("no gradient: the adjoint system of step " + std::to_string(k)
            + " is singular (true Hessian at the converged state)");
    tf.add_to(st.factorization_time);
    a.factorized = true;
}

AdjointSweep::AdjointSweep(Simulator& sim, const ParameterRequest& request)
{
    Timer total;
    check_sweep(sim, request);
    m = std::make_unique<Impl>(sim, request, nullptr);
    total.add_to(m->st.setup_time);
    total.add_to(m->st.total_time);
}

AdjointSweep::AdjointSweep(Simulator& sim, const ParameterRequest& request, const AdjointSweep& share_with)
{
    Timer total;
    if (&share_with.m->sim != &sim)
        throw std::logic_error("AdjointSweep: a shared step system must come from a sweep over the same simulator");
    check_sweep(sim, request);
    m = std::make_unique<Impl>(sim, request, share_with.m->system);
    total.add_to(m->st.setup_time);
    total.add_to(m->st.total_time);
}

AdjointSweep::~AdjointSweep() = default;

const AdjointStatistics& AdjointSweep::statistics() const { return m->st; }

void AdjointSweep::add_seed(const StateSeed& seed, int first, int last)
{
    Timer total;
    const int T = m->T;
    if (seed.positions.size() != size_t(T) + 1 || seed.velocities.size() != size_t(T) + 1)
        throw AdjointError("the state seed must have T + 1 = " + std::to_string(T + 1) + " entries");
    if (first < 0 || last > T)
        throw std::out_of_range("AdjointSweep::add_seed: states " + std::to_string(first) + ".." + std::to_string(last)
            + " outside 0.." + std::to_string(T));
    for (int k = first; k <= last; ++k) {
        const VectorXd* entries[2] = { &seed.positions[size_t(k)], &seed.velocities[size_t(k)] };
        VectorXd* bars[2] = { &m->xbar[size_t(k)], &m->vbar[size_t(k)] };
        for (int which = 0; which < 2; ++which) {
            if (!nonzero(*entries[which]))
                continue;
            if (k > m->next)
                throw std::logic_error(
                    "AdjointSweep::add_seed: state " + std::to_string(k) + " is seeded after its step was swept");
            m->push(*bars[which], 1.0, *entries[which]);
        }
    }
    // J's explicit partials, restricted to the requested blocks.
    const ParameterGradient& ex = seed.explicit_partials;
    ParameterGradient& grad = m->grad;
    add_requested(grad.rest_positions, ex.rest_positions);
    add_requested(grad.mu, ex.mu);
    add_requested(grad.lambda, ex.lambda);
    add_requested(grad.density, ex.density);
    add_requested(grad.friction, ex.friction);
    total.add_to(m->st.total_time);
}

void AdjointSweep::step(int k)
{
    if (k != m->next || k < 1)
        throw std::logic_error("AdjointSweep::step: expected step " + std::to_string(m->next) + ", got "
            + std::to_string(k) + " (steps are swept from T down to 1)");
    Timer total;
    m->step(k);
    --m->next;
    total.add_to(m->st.total_time);
}

void AdjointSweep::Impl::step(int k)
{
    const Trajectory& tr = sim.trajectory();
    const StepRecord& record = tr.steps[size_t(k - 1)];
    if (!record.holds_state())
        throw std::logic_error("AdjointSweep::step: the record of step " + std::to_string(k) + " was released");
    const auto bars_of = [this](int j) {
        return j < 0 ? StateBars {} : StateBars { &xbar[size_t(j)], &vbar[size_t(j)], &abar[size_t(j)] };
    };
    const int m = int(record.substep_times.size());
    if (m == 0) {
        sweep_state(k, 0, record.positions, record.time, sim.step_scheme(k), bars_of(k), bars_of(k - 1), bars_of(k - 2),
            PrescribedMap {});
    } else {
        // A dynamic step taken in sub-steps: its states j = m (the step's own) .. 1, each a step of
        // the integrator from state j - 1 (j = 1: from step k - 1), swept back in turn.
        const double dt = sim.scene().time.dt, t0 = (k - 1) * dt;
        std::vector<VectorXd> lx(static_cast<size_t>(m)), lv(static_cast<size_t>(m)), la(static_cast<size_t>(m));
        for (int j = m; j >= 1; --j) {
            const bool own = j == m;
            const StepRecord::SubState* sub = own ? nullptr : &record.path[size_t(j - 1)];
            const StateBars cur = own ? bars_of(k) : StateBars { &lx[size_t(j)], &lv[size_t(j)], &la[size_t(j)] };
            const StateBars prev
                = j == 1 ? bars_of(k - 1) : StateBars { &lx[size_t(j - 1)], &lv[size_t(j - 1)], &la[size_t(j - 1)] };
            const double t = own ? record.time : sub->time;
            // The prescribed positions inside the step, as a run with g overridden takes them
            // (SimulationParameters::prescribed): interpolated from step k - 1's to X + g_k by
            // the fraction s of the step. Without an override they are the expressions at t; their
            // derivative in X is the same (s + (1 - s) through x_{k-1}), and the one in g is that
            // of the run with g overridden.
            PrescribedMap map;
            if (!own) {
                const double s = (t - t0) / dt;
                map = { s, s, 1 - s };
            }
            sweep_state(k, j, own ? record.positions : sub->positions, t, sim.substep_scheme(k, j), cur, prev,
                StateBars {}, map);
            if (!own) {
                release(lx[size_t(j)]);
                release(lv[size_t(j)]);
                release(la[size_t(j)]);
            }
        }
    }
    // Nothing reads the adjoint of state k after its step.
    release(xbar[size_t(k)]);
    release(vbar[size_t(k)]);
    release(abar[size_t(k)]);
}

void AdjointSweep::Impl::sweep_state(int k, int j, const VectorXd& x, double time, const StepScheme& s, StateBars cur,
    StateBars prev, StateBars prev2, PrescribedMap map)
{
    const StateBars history[3] = { {}, prev, prev2 };
    // v and a are linear in x and the history.
    for (int which = 0; which < 2; ++which) {
        VectorXd& bar = which == 0 ? *cur.a : *cur.v;
        if (!nonzero(bar))
            continue;
        const double* cx = which == 0 ? s.ax : s.vx;
        const double* cv = which == 0 ? s.av : s.vv;
        const double* ca = which == 0 ? s.aa : s.va;
        push(*cur.x, cx[0], bar);
        for (int h = 1; h <= 2 && history[h].x; ++h) {
            push(*history[h].x, cx[h], bar);
            push(*history[h].v, cv[h], bar);
            push(*history[h].a, ca[h], bar);
        }
    }
    VectorXd& xb = *cur.x;
    if (xb.size() == 0) {
        xb = VectorXd::Zero(n);
        grew(xb);
    }
    VectorXd rhs = xb;
    for (Index i = 0; i < n; ++i)
        if (constrained[size_t(i)])
            rhs[i] = 0;
    if (!rhs.isZero(0.0)) {
        factorize(k, j, x);
        Timer ts;
        double fallback_time = 0; // the CPU fallback's set-up, assembly and factorization (timed on their own)
        VectorXd lambda, device_coupling;
        int pcg_iterations = 0;
        if (const PeriodicCell* cell = sim.periodic()) {
            // dJ/dq = P^T dJ/dx on q's free entries; the full-space adjoint is P lambda_q.
            const std::vector<char>& fixed = cell->constrained();
            VectorXd xq = cell->map().reduce(rhs), rq = xq;
            for (Index i = 0; i < rq.size(); ++i)
                if (fixed[size_t(i)])
                    rq[i] = 0;
            const VectorXd lq = system->linear.solve(rq);
            lambda = cell->map().expand(lq);
            if (d_rest)
                periodic_shape_terms(k, j, x, xb, lq, lambda, *d_rest);
            if (grad.macro.size()) {
                // G's prescribed components are q's constrained entries L G_ij: dJ/dq_c less the
                // coupling (P^T H P lambda_q)_c, times L.
                subtract_couplings(system->couplings, fixed, lq, xq);
                for (int i = 0; i < d; ++i)
                    for (int jj = 0; jj < d; ++jj)
                        if (cell->prescribed(i, jj))
                            grad.macro(k - 1, i * d + jj) += cell->map().length() * xq[cell->map().macro_dof(i, jj)];
            }
        } else if (system->on_device
            && (system->factorized
                || !sim.device_solver()->solve_adjoint(x, system->weight, rhs, lambda, &pcg_iterations,
                    sim.contact() ? sim.contact()->kappa() : 0.0, &device_coupling))) {
            // The device's PCG did not converge (a true Hessian that is not positive definite):
            // the CPU's assembly and factorization with its LDL^T fallback.
            if (!system->factorized) {
                Timer tf;
                Timer tsetup;
                const Problem& problem = j == 0 ? sim.step_problem(k) : sim.substep_problem(k, j);
                tsetup.add_to(st.setup_time);
                Timer ta;
                assemble_on_cpu(problem, x);
                ta.add_to(st.assembly_time);
                factorize_on_cpu(k);
                fallback_time = tf.seconds();
            }
            lambda = system->linear.solve(rhs);
        } else if (!system->on_device) {
            lambda = system->linear.solve(rhs);
        }
        st.solve_time += ts.seconds() - fallback_time;
        st.device_pcg_iterations += pcg_iterations;
        if (!lambda.allFinite())
            throw AdjointError("no gradient: non-finite adjoint at step " + std::to_string(k));
        for (Index i = 0; i < n; ++i)
            if (constrained[size_t(i)])
                lambda[i] = 0;
        ++st.steps;
        Timer tp;
        // Prescribed entries of x enter every free row through H: (H lambda)_i for prescribed i
        // (lambda vanishes on prescribed dofs, so only their couplings to free dofs count). A
        // periodic cell's couplings are those of q's entries, used above.
        if (system->on_device && !system->assembled) {
            // The device's product (H lambda) on the prescribed dofs: the same sum as the couplings'.
            for (Index i = 0; i < n; ++i)
                if (constrained[size_t(i)])
                    xb[i] -= device_coupling[i];
        } else if (!sim.periodic()) {
            subtract_couplings(system->couplings, constrained, lambda, xb);
        }
        // History: g contains -M x~.
        if (s.inertia) {
            const VectorXd Ml = sim.inertia().apply_mass(lambda);
            for (int h = 1; h <= 2 && history[h].x; ++h) {
                push(*history[h].x, s.tx[h], Ml);
                push(*history[h].v, s.tv[h], Ml);
                push(*history[h].a, s.ta[h], Ml);
            }
        }
        // Parameters: dJ/dp -= lambda^T dg/dp.
        const double w = s.weight;
        const ElasticPotential& elastic = sim.elastic();
        if (d_rest) {
            elastic.add_shape_derivative(x, lambda, -w, *d_rest);
            if (s.inertia)
                sim.inertia().add_shape_derivative(x, lambda, -1.0, *d_rest);
            if (sim.contact())
                sim.contact()->add_shape_derivative(x, lambda, -w, *d_rest);
        }
        if (request.lame)
            elastic.add_lame_derivative(x, lambda, -w, grad.mu, grad.lambda);
        if (d_density && s.inertia)
            sim.inertia().add_density_derivative(x, lambda, -1.0, *d_density);
        // g contains -w f_ext(t).
        if (d_rest || d_density)
            sim.external_force_derivatives(time, w * lambda, d_rest, d_density);
        // The friction potential of step k depends on x_{k-1} (start of step and lagged data);
        // sub-stepped steps with friction are refused (check_run).
        if (j == 0 && sim.friction() && (!sim.friction()->lagged().empty() || grad.friction.size())) {
            if (prev.x->size() == 0) {
                *prev.x = VectorXd::Zero(n);
                grew(*prev.x);
            }
            FrictionAdjointTerms terms { prev.x, grad.friction.size() ? &grad.friction : nullptr, d_rest };
            friction_step_adjoint(sim, k, lambda, w, terms);
        }
        tp.add_to(st.assembly_time);
        tp.add_to(st.parameter_time);
    }
    // Prescribed dofs: x = X + g_k at the step's own state; inside a sub-stepped step,
    // x = (1 - s) x_{k-1} + s (X + g_k).
    for (size_t q = 0; q < prescribed.size(); ++q) {
        const Index i = prescribed[q];
        if (d_rest)
            (*d_rest)[i] += map.rest * xb[i];
        if (grad.prescribed.size())
            grad.prescribed(k - 1, Index(q)) += map.g * xb[i];
    }
    if (map.previous != 0) {
        VectorXd part = VectorXd::Zero(n);
        for (const Index i : prescribed)
            part[i] = map.previous * xb[i];
        push(xbar[size_t(k - 1)], 1.0, part);
    }
}

void AdjointSweep::Impl::periodic_shape_terms(
    int k, int j, const VectorXd& x, const VectorXd& xb, const VectorXd& lq, const VectorXd& lambda, VectorXd& d_rest)
{
    // The state is q and x = X + G (X - X_o) + w depends on X at fixed q (docs/math.md, "Periodic
    // cells"): beyond -lambda^T dg/dX at fixed x (the potentials' shape derivatives, below in
    // sweep_state), dJ/dX gains (I + G)^T (xbar - H lambda)_v per vertex, and the residual's map
    // P(X)^T, whose macro columns hold X_v - X_o, gives -Lambda^T g_v with Lambda_ij = lambda_q(L G_ij) / L.
    const PeriodicCell& cell = *sim.periodic();
    const PeriodicMap& map = cell.map();
    const MatrixXd G = Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(
        sim.trajectory().step(k).macro_gradient.data(), d, d);
    MatrixXd Lambda(d, d);
    for (int i = 0; i < d; ++i)
        for (int jj = 0; jj < d; ++jj)
            Lambda(i, jj) = lq[map.macro_dof(i, jj)] / map.length();
    const VectorXd r = xb - system->assembler().matrix().selfadjointView<Eigen::Lower>() * lambda;
    VectorXd g;
    (j == 0 ? sim.step_problem(k) : sim.substep_problem(k, j)).gradient(x, g);
    const MatrixXd F = MatrixXd::Identity(d, d) + G;
    for (Index v = 0; v < n / d; ++v)
        d_rest.segment(v * d, d) += F.transpose() * r.segment(v * d, d) - Lambda.transpose() * g.segment(v * d, d);
}

ParameterGradient AdjointSweep::finish()
{
    if (m->next != 0)
        throw std::logic_error(
            "AdjointSweep::finish: step " + std::to_string(m->next) + " was not swept (steps go from T down to 1)");
    Timer total;
    m->finish();
    m->next = -1;
    total.add_to(m->st.total_time);
    return std::move(m->grad);
}

void AdjointSweep::Impl::finish()
{
    // Initial state: x_0 = X + u0 (free dofs; prescribed ones X + g(0)), v_0 free, and
    // Newmark's a_0 = M_ff^-1 (f(0) - grad Psi(x_0))_f.
    const Trajectory& tr = sim.trajectory();
    const ElasticPotential& elastic = sim.elastic();
    const InertiaPotential& inertia = sim.inertia();
    VectorXd& xb0 = xbar[0];
    if (xb0.size() == 0)
        xb0 = VectorXd::Zero(n);
    if (nonzero(abar[0]) && sim.scene().time.integrator == IntegratorType::NEWMARK
        && std::isfinite(elastic.value(tr.initial_positions))) {
        VectorXd mu = VectorXd::Zero(n);
        const VectorXd& m = inertia.lumped_masses();
        if (!inertia.consistent()) {
            for (Index i = 0; i < n; ++i)
                mu[i] = constrained[size_t(i)] ? 0.0 : abar[0][i] / m[i / d];
        } else {
            SparseMatrixd M = inertia.consistent_matrix();
            for (Index c = 0; c < M.outerSize(); ++c)
                for (SparseMatrixd::InnerIterator it(M, c); it; ++it)
                    if (constrained[size_t(it.row())] || constrained[size_t(it.col())])
                        it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
            VectorXd b = abar[0];
            for (Index i = 0; i < n; ++i)
                if (constrained[size_t(i)])
                    b[i] = 0;
            Eigen::SimplicialLDLT<SparseMatrixd> ldlt(M);
            mu = ldlt.solve(b);
        }
        const VectorXd& x0 = tr.initial_positions;
        // d a0 = M^-1 (df - d grad Psi - dM a0)
        SparseAssembler& assembler = system->assembler();
        system->step = -1;
        assembler.set_zero();
        elastic.add_hessian(x0, 1.0, false, assembler);
        assembler.finalize();
        xb0 -= assembler.matrix().selfadjointView<Eigen::Lower>() * mu;
        if (d_rest) {
            elastic.add_shape_derivative(x0, mu, -1.0, *d_rest);
        }
        if (request.lame)
            elastic.add_lame_derivative(x0, mu, -1.0, grad.mu, grad.lambda);
        if (d_rest || d_density) {
            sim.external_force_derivatives(0.0, mu, d_rest, d_density);
            inertia.add_mass_derivatives(mu, tr.initial_accelerations, -1.0, d_rest, d_density);
        }
    }
    if (d_rest)
        *d_rest += xb0;
    if (grad.initial_displacement.size())
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                grad.initial_displacement[i] += xb0[i];
    if (grad.initial_velocity.size() && vbar[0].size())
        for (Index i = 0; i < n; ++i)
            if (!constrained[size_t(i)])
                grad.initial_velocity[i] += vbar[0][i];
}

ParameterGradient adjoint_gradient(
    Simulator& sim, const StateSeed& seed, const ParameterRequest& request, AdjointStatistics* stats)
{
    AdjointSweep sweep(sim, request);
    const int T = sim.steps_done();
    sweep.add_seed(seed, 0, T);
    for (int k = T; k >= 1; --k)
        sweep.step(k);
    ParameterGradient grad = sweep.finish();
    if (stats)
        *stats = sweep.statistics();
    return grad;
}

std::vector<ParameterGradient> adjoint_gradients(
    Simulator& sim, const std::vector<StateSeed>& seeds, const ParameterRequest& request, AdjointStatistics* stats)
{
    std::vector<ParameterGradient> out;
    if (seeds.empty())
        return out;
    std::vector<std::unique_ptr<AdjointSweep>> sweeps;
    for (const StateSeed& seed : seeds) {
        sweeps.push_back(sweeps.empty() ? std::make_unique<AdjointSweep>(sim, request)
                                        : std::make_unique<AdjointSweep>(sim, request, *sweeps.front()));
        sweeps.back()->add_seed(seed, 0, sim.steps_done());
    }
    for (int k = sim.steps_done(); k >= 1; --k)
        for (auto& sweep : sweeps)
            sweep->step(k);
    AdjointStatistics total;
    for (auto& sweep : sweeps) {
        out.push_back(sweep->finish());
        const AdjointStatistics& s = sweep->statistics();
        total.assembly_time += s.assembly_time;
        total.parameter_time += s.parameter_time;
        total.factorization_time += s.factorization_time;
        total.solve_time += s.solve_time;
        total.setup_time += s.setup_time;
        total.device_pcg_iterations += s.device_pcg_iterations;
        total.total_time += s.total_time;
        total.steps += s.steps;
        total.peak_adjoint_bytes += s.peak_adjoint_bytes;
    }
    if (stats)
        *stats = total;
    return out;
}

} // namespace diffipc
