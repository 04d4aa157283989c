#include "cuda/solver/device_newton.hpp"

#include "cuda/common/device.hpp"
#include "cuda/common/kernels.cuh"
#include "cuda/contact/sum_operator.hpp"
#include "cuda/linalg/device_amg.hpp"
#include "cuda/linalg/reduction.hpp"
#include "cuda/periodic/device_periodic_map.hpp"
#include "cuda/periodic/reduced_operator.hpp"
#include "forward/kernels/inversion_bound.hpp"
#include "forward/kernels/material/material.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;
    constexpr double EPS = std::numeric_limits<double>::epsilon();
    // NewtonSolver's constants (forward/solver/newton.cpp).
    constexpr double ROUNDOFF_STEP = 128 * EPS;
    constexpr double ENERGY_RESOLUTION = 1e-10;
    constexpr double EXTENSION_RATIO = 0.9;
    constexpr int MAX_EXTENSIONS = 12;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    // ---- Deterministic reductions of several quantities in one pass ----
    //
    // The order is reduction.hpp's fixed tree (it depends only on n): B = min(ceil(n / 256), 256)
    // blocks, thread t of block b combines the terms k = b 256 + t + m (256 B) in increasing m, each
    // block halves its 256 values pairwise, one block then reduces the B block values the same way.
    // Sums therefore have a fixed rounding; maxima and minima propagate NaN (a NaN term makes the
    // result NaN, unlike fmax), so a non-finite vector cannot hide behind a max-norm.

    enum ReduceOp : int { SUM = 0, MAX = 1, MIN = 2 };

    template <int N> struct Ops {
        int op[N];
    };

    __device__ inline double reduce_identity(int op) { return op == SUM ? 0.0 : op == MAX ? -INFINITY : INFINITY; }

    __device__ inline double combine(int op, double a, double b)
    {
        if (op == SUM)
            return a + b;
        if (op == MAX)
            return (b > a || b != b) ? b : a;
        return (b < a || b != b) ? b : a;
    }

    template <int N> __device__ void block_tree(double (&s)[N][THREADS], const Ops<N>& ops)
    {
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (threadIdx.x < h)
                for (int q = 0; q < N; ++q)
                    s[q][threadIdx.x] = combine(ops.op[q], s[q][threadIdx.x], s[q][threadIdx.x + h]);
        }
        __syncthreads();
    }

    template <int N, typename Term> __global__ void reduce_partials(Term term, size_t n, Ops<N> ops, double* partials)
    {
        __shared__ double s[N][THREADS];
        double acc[N];
        for (int q = 0; q < N; ++q)
            acc[q] = reduce_identity(ops.op[q]);
        const size_t stride = size_t(gridDim.x) * THREADS;
        for (size_t k = size_t(blockIdx.x) * THREADS + threadIdx.x; k < n; k += stride) {
            double v[N];
            term(k, v);
            for (int q = 0; q < N; ++q)
                acc[q] = combine(ops.op[q], acc[q], v[q]);
        }
        for (int q = 0; q < N; ++q)
            s[q][threadIdx.x] = acc[q];
        block_tree<N>(s, ops);
        if (threadIdx.x == 0)
            for (int q = 0; q < N; ++q)
                partials[q * THREADS + blockIdx.x] = s[q][0];
    }

    template <int N> __global__ void reduce_final(const double* partials, int blocks, Ops<N> ops, double* result)
    {
        __shared__ double s[N][THREADS];
        for (int q = 0; q < N; ++q)
            s[q][threadIdx.x]
                = int(threadIdx.x) < blocks ? partials[q * THREADS + threadIdx.x] : reduce_identity(ops.op[q]);
        block_tree<N>(s, ops);
        if (threadIdx.x == 0)
            for (int q = 0; q < N; ++q)
                result[q] = s[q][0];
    }

    /// d_result[q] = the reduction (ops.op[q]) over k < n of term(k)[q]. Asynchronous.
    /// @param d_partials device scratch of N * THREADS doubles
    template <int N, typename Term>
    void reduce(const Term& term, size_t n, const Ops<N>& ops, double* d_partials, double* d_result)
    {
        const int blocks = int(std::max<size_t>(1, std::min<size_t>((n + THREADS - 1) / THREADS, THREADS)));
        reduce_partials<N><<<blocks, THREADS>>>(term, n, ops, d_partials);
        check_launch("launch of a Newton reduction");
        reduce_final<N><<<1, THREADS>>>(d_partials, blocks, ops, d_result);
        check_launch("launch of a Newton reduction");
    }

    constexpr int MAX_REDUCED = 5; // the most quantities one reduction computes (partials: MAX_REDUCED * THREADS)

    // ---- Reduction terms ----

    /// Per dof, at the iterate: writes pD = target - x on constrained dofs (0 on free ones) and gives
    /// [ |g| on free dofs (max), g^2 on free dofs (sum), |pD| (max), g not finite (max) ].
    struct GradientTerm {
        const double *g, *x, *target;
        const unsigned char* fixed;
        double* pD;
        __device__ void operator()(size_t k, double* v) const
        {
            const double gk = g[k];
            const bool f = fixed[k] != 0;
            const double d = f ? target[k] - x[k] : 0.0;
            pD[k] = d;
            v[0] = f ? 0.0 : fabs(gk);
            v[1] = f ? 0.0 : gk * gk;
            v[2] = fabs(d);
            v[3] = isfinite(gk) ? 0.0 : 1.0;
        }
    };
    const Ops<4> GRADIENT_OPS { { MAX, SUM, MAX, MAX } };

    /// Per dof: [ |g| on free dofs (max), g not finite (max) ].
    struct ResidualTerm {
        const double* g;
        const unsigned char* fixed;
        __device__ void operator()(size_t k, double* v) const
        {
            v[0] = fixed[k] ? 0.0 : fabs(g[k]);
            v[1] = isfinite(g[k]) ? 0.0 : 1.0;
        }
    };
    const Ops<2> RESIDUAL_OPS { { MAX, MAX } };

    /// Per dof: [ g p (sum: the slope), |p| (max), |p| on free dofs (max), |x| (max), p not finite (max) ].
    struct DirectionTerm {
        const double *g, *p, *x;
        const unsigned char* fixed;
        __device__ void operator()(size_t k, double* v) const
        {
            const double pk = p[k];
            v[0] = g[k] * pk;
            v[1] = fabs(pk);
            v[2] = fixed[k] ? 0.0 : fabs(pk);
            v[3] = fabs(x[k]);
            v[4] = isfinite(pk) ? 0.0 : 1.0;
        }
    };
    const Ops<5> DIRECTION_OPS { { SUM, MAX, MAX, MAX, MAX } };

    /// Per element: [ its inversion bound along p (min) ] (forward/kernels/inversion_bound.hpp).
    template <int dim> struct StepBoundTerm {
        const int* elements; // (dim+1) * #E, vertex a of element e at a #E + e
        int ne;
        const double *x, *p;
        double keep;
        __device__ void operator()(size_t e, double* v) const
        {
            double xe[(dim + 1) * dim], pe[(dim + 1) * dim];
            for (int a = 0; a <= dim; ++a) {
                const size_t vtx = size_t(elements[size_t(a) * size_t(ne) + e]);
                for (int i = 0; i < dim; ++i) {
                    xe[a * dim + i] = x[vtx * dim + i];
                    pe[a * dim + i] = p[vtx * dim + i];
                }
            }
            v[0] = element_step_bound<dim>(xe, pe, keep);
        }
    };
    const Ops<1> BOUND_OPS { { MIN } };

    /// Per dof at y: [ (y - xt) m (y - xt) (sum; 0 when static), f (y - x_ref) (sum) ]; with a consistent
    /// mass, Md = M (y - xt) replaces m (y - xt).
    struct EnergyTerm {
        const double *y, *xt, *mass, *f, *reference, *Md;
        bool dynamic;
        __device__ void operator()(size_t k, double* v) const
        {
            if (dynamic) {
                const double d = y[k] - xt[k];
                v[0] = Md ? d * Md[k] : d * (mass[k] * d);
            } else {
                v[0] = 0.0;
            }
            v[1] = f[k] * (y[k] - reference[k]);
        }
    };
    const Ops<2> ENERGY_OPS { { SUM, SUM } };

    /// Per dof: [ gB gE (sum), gB gB (sum) ] on the free dofs.
    struct BalanceTerm {
        const double *gb, *ge;
        const unsigned char* fixed;
        __device__ void operator()(size_t k, double* v) const
        {
            const bool f = fixed[k] != 0;
            v[0] = f ? 0.0 : gb[k] * ge[k];
            v[1] = f ? 0.0 : gb[k] * gb[k];
        }
    };
    const Ops<2> BALANCE_OPS { { SUM, SUM } };

    // ---- Vector kernels ----

    /// g = M (x - xt) - w f (the inertial and external terms; the elastic one is gathered on top); Md:
    /// M (x - xt) of a consistent mass, else nullptr (the lumped masses).
    __global__ void inertia_force_gradient(size_t n, bool dynamic, const double* __restrict__ x,
        const double* __restrict__ xt, const double* __restrict__ mass, const double* __restrict__ Md,
        const double* __restrict__ f, double w, double* __restrict__ g)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        g[k] = (dynamic ? (Md ? Md[k] : mass[k] * (x[k] - xt[k])) : 0.0) - w * f[k];
    }

    /// out = a - b.
    __global__ void difference(size_t n, const double* __restrict__ a, const double* __restrict__ b, double* out)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            out[k] = a[k] - b[k];
    }

    /// values += mass_values (the consistent mass's blocks, in the same pattern).
    __global__ void add_values(size_t count, const double* __restrict__ mass_values, double* __restrict__ values)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < count)
            values[k] += mass_values[k];
    }

    /// The lumped mass on the diagonal of each vertex's diagonal block.
    __global__ void add_mass_diagonal(size_t n, int dim, const int* __restrict__ diagonal_slots,
        const double* __restrict__ mass, double* __restrict__ values)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        const int v = int(k / size_t(dim)), i = int(k % size_t(dim));
        values[size_t(diagonal_slots[v]) * size_t(dim * dim) + size_t(i * dim + i)] += mass[k];
    }

    /// rhs = -g - coupling (coupling = H pD while lifting, else null).
    __global__ void newton_rhs(
        size_t n, const double* __restrict__ g, const double* __restrict__ coupling, double* __restrict__ rhs)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        rhs[k] = coupling ? -g[k] - coupling[k] : -g[k];
    }

    /// p = pD on the constrained dofs (PCG leaves them 0).
    __global__ void set_prescribed(
        size_t n, const unsigned char* __restrict__ fixed, const double* __restrict__ pD, double* __restrict__ p)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        if (fixed[k])
            p[k] = pD[k];
    }

    /// y = x + alpha p
    __global__ void step(
        size_t n, const double* __restrict__ x, double alpha, const double* __restrict__ p, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        y[k] = x[k] + alpha * p[k];
    }

    /// y += x
    __global__ void add_into(size_t n, const double* __restrict__ x, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            y[k] += x[k];
    }

    /// y += a x
    __global__ void add_scaled(size_t n, double a, const double* __restrict__ x, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            y[k] += a * x[k];
    }

    /// y = a x
    __global__ void scale_into(size_t n, double a, const double* __restrict__ x, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        y[k] = a * x[k];
    }

    /// y_D = target_D
    __global__ void snap_to_target(
        size_t n, const unsigned char* __restrict__ fixed, const double* __restrict__ target, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        if (fixed[k])
            y[k] = target[k];
    }

    /// p = -scale g on free dofs, 0 on constrained ones.
    __global__ void gradient_direction(size_t n, const unsigned char* __restrict__ fixed, const double* __restrict__ g,
        double scale, double* __restrict__ p)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k >= n)
            return;
        p[k] = fixed[k] ? 0.0 : -scale * g[k];
    }

    using Clock = std::chrono::steady_clock;

    /// Adds the time since `start` to `total`, after the GPU has finished the work queued so far.
    void phase_end(Clock::time_point start, double& total)
    {
        check_cuda(cudaDeviceSynchronize(), "synchronization at the end of a Newton phase");
        total += std::chrono::duration<double>(Clock::now() - start).count();
    }

    // Device scalar slots.
    constexpr int S_GRADIENT = 0; // 4
    constexpr int S_DIRECTION = 4; // 5
    constexpr int S_BOUND = 9; // 1
    constexpr int S_ENERGY = 10; // 2
    constexpr int S_RESIDUAL = 12; // 2
    constexpr int S_BALANCE = 14; // 2
    constexpr int S_CONTROL = 16; // 2
    constexpr int NUM_SCALARS = 18;

} // namespace

struct DeviceNewton::Impl {
    size_t n = 0;
    int dim = 0, ne = 0, nv = 0;
    bool dynamic = false;
    double material_scale = 0;
    DeviceArray<double> mass, x, trial, longer, xt, f, target, reference, g, g_trial, p, pD, rhs, coupling;
    DeviceArray<double> partials, scalars;
    DeviceArray<unsigned char> fixed;
    DeviceArray<int> elements, diagonal_slots;
    DeviceBsrMatrix H;
    DeviceBsrMatrix M; // the consistent mass (H's pattern), when `consistent`
    bool consistent = false;
    DeviceArray<double> mass_difference, mass_product; // y - xt and M (y - xt)
    DevicePCG pcg;
    // The adjoint's multigrid (set_adjoint_multigrid): planned at the first adjoint solve after the
    // constraints are set, from that solve's state; `multigrid_unavailable` once planning failed.
    bool multigrid = false, multigrid_unavailable = false;
    int multigrid_threads = 0; // for the plan's patterns (0: the hardware's)
    int multigrid_coarsest = AmgPlanSettings().max_coarsest_dofs; // the plan's max_coarsest_dofs
    std::unique_ptr<DeviceAmg> amg;
    std::vector<char> constrained;
    // Load control (solve()'s `control`, for that solve only): a on the device and a^T a.
    DeviceLoadControl* control = nullptr;
    DeviceArray<double> control_a;
    double control_aa = 0;
    /// Under load control: lambda = a^T v / a^T a, returned, and v -= lambda a (its multiplier's share,
    /// the load the constraint carries, is no residual); a^T x into *ax if given. 0 without control.
    double remove_carried(double* v, double* ax = nullptr)
    {
        if (!control)
            return 0;
        deterministic_dot2(
            control_a.data(), v, control_a.data(), x.data(), n, partials.data(), scalars.data() + S_CONTROL);
        double products[2];
        detail::copy_device_to_host(products, scalars.data() + S_CONTROL, sizeof(products));
        const double lambda = products[0] / control_aa;
        add_scaled<<<grid(n), THREADS>>>(n, -lambda, control_a.data(), v);
        check_launch("launch of the carried load's removal");
        if (ax)
            *ax = products[1];
        return lambda;
    }
    DeviceContact* contact = nullptr;
    DeviceFriction* friction = nullptr; // lagged friction (needs contact)
    SumOperator sum; // H + the contact Hessian (+ the friction Hessian)

    // A periodic cell (set_periodic): the unknowns are its q, whose vectors mirror the position-space
    // ones below; without it the unknowns are the positions and these accessors return those.
    DevicePeriodicMap* periodic = nullptr;
    size_t nq = 0;
    ReducedOperator reduced; // P^T (the Newton matrix) P
    DevicePCG pcg_q; // with q's fixed mask
    DeviceArray<unsigned char> fixed_q;
    DeviceArray<double> q, trial_q, longer_q, target_q, g_q, g_trial_q, p_q, pD_q, rhs_q, coupling_q;
    // Contact across a cell's boundary (set_periodic_contact): the contact runs on its image surface's
    // positions y = X_s + P_s q (cuda/README.md, "Periodic cells on the device"), kept beside x, trial
    // and longer; its gradient gc and Hessian go back through P_s.
    DevicePeriodicMap* surface = nullptr;
    ReducedOperator reduced_contact; // P_s^T C P_s
    OperatorSum reduced_sum; // P^T A P + P_s^T C P_s
    DeviceArray<double> ys, ys_trial, ys_longer, gc, gc_q, ps, dir_scaled, p_q_scaled;
    /// The contact's positions of the state whose positions are xp (x, trial or longer): xp itself
    /// without an image surface.
    const double* contact_positions(const double* xp) const
    {
        if (!surface)
            return xp;
        if (xp == x.data())
            return ys.data();
        if (xp == trial.data())
            return ys_trial.data();
        if (xp == longer.data())
            return ys_longer.data();
        throw std::logic_error("DeviceNewton: no image surface positions for this state");
    }
    /// X + P u into into_x, and the image surface's positions beside it.
    void expand_state(const DeviceArray<double>& from_u, DeviceArray<double>& into_x)
    {
        periodic->expand(from_u.data(), into_x.data(), true);
        if (surface)
            surface->expand(from_u.data(), const_cast<double*>(contact_positions(into_x.data())), true);
    }
    size_t nu() const { return periodic ? nq : n; }
    DeviceArray<double>& u() { return periodic ? q : x; }
    DeviceArray<double>& u_trial() { return periodic ? trial_q : trial; }
    DeviceArray<double>& u_target() { return periodic ? target_q : target; }
    DeviceArray<double>& u_g() { return periodic ? g_q : g; }
    DeviceArray<double>& u_g_trial() { return periodic ? g_trial_q : g_trial; }
    DeviceArray<double>& u_p() { return periodic ? p_q : p; }
    DeviceArray<double>& u_pD() { return periodic ? pD_q : pD; }
    DeviceArray<double>& u_rhs() { return periodic ? rhs_q : rhs; }
    DeviceArray<double>& u_coupling() { return periodic ? coupling_q : coupling; }
    const unsigned char* u_fixed() const { return periodic ? fixed_q.data() : fixed.data(); }
    DevicePCG& u_pcg() { return periodic ? pcg_q : pcg; }
    /// The Newton matrix in the unknowns (bind_unknowns() first; with an image surface the contact's
    /// part is bound by assemble_contact()).
    const DeviceLinearOperator& u_system(const DeviceContact* with_contact) const
    {
        if (!periodic)
            return system(with_contact);
        if (surface && with_contact)
            return reduced_sum;
        return reduced;
    }
    void bind_unknowns(const DeviceContact* with_contact)
    {
        if (periodic)
            reduced.bind(surface ? static_cast<const DeviceLinearOperator&>(H) : system(with_contact), *periodic);
    }
    /// A position-space gradient into the unknowns' (P^T g, plus P_s^T gc, the contact's part on the image
    /// surface from the last gradient(); nothing to do without a cell).
    void gradient_to_unknowns(const DeviceArray<double>& gx, DeviceArray<double>& gu)
    {
        if (!periodic)
            return;
        periodic->reduce(gx.data(), gu.data());
        if (surface) {
            surface->reduce(gc.data(), gc_q.data());
            add_into<<<grid(nq), THREADS>>>(nq, gc_q.data(), gu.data());
            check_launch("launch of the contact's reduced gradient");
        }
    }
    /// The unknowns' step p_u into positions (p = P p_q; p is p_u without a cell).
    void step_to_positions()
    {
        if (periodic)
            periodic->expand(p_q.data(), p.data(), false);
    }
    /// The state at u + alpha p_u into (into_u, into_x): x + alpha p without a cell, else
    /// q + alpha p_q and X + P of it (as the CPU's PeriodicPotential evaluates its trials).
    void make_trial(double alpha, DeviceArray<double>& into_u, DeviceArray<double>& into_x);
    /// The accepted trial becomes the iterate.
    void accept_trial()
    {
        std::swap(x, trial);
        if (periodic)
            std::swap(q, trial_q);
        if (surface)
            std::swap(ys, ys_trial);
    }
    bool active_current = false; // the contact's active set was built at x's current contents
    DeviceArray<double> gb; // the barrier gradient (balancing)
    double w = 1; // the weight of the solve in progress (or of balance_at)

    int kernel_grid() const { return grid(n); }

    /// Energy terms at y: the inertia 1/2 (y - xt)^T M (y - xt), Psi(y), the barrier B(y) and the
    /// work f^T (y - x_ref). on_segment: y lies on the last contact step bound's segment.
    struct Energy {
        double total = 0, inertia = 0, elastic = 0, contact = 0, friction = 0, work = 0;
    };
    /// M (y - xt) of the consistent mass into mass_product (nullptr: lumped masses, or static).
    const double* consistent_product(const double* y)
    {
        if (!dynamic || !consistent)
            return nullptr;
        difference<<<kernel_grid(), THREADS>>>(n, y, xt.data(), mass_difference.data());
        check_launch("launch of the inertial difference");
        M.multiply(mass_difference.data(), mass_product.data());
        return mass_product.data();
    }

    /// H += the mass matrix (lumped: on the diagonal; consistent: its blocks).
    void add_mass(DeviceBsrMatrix& target)
    {
        if (!dynamic)
            return;
        if (consistent) {
            const size_t count = size_t(M.num_blocks()) * size_t(dim * dim);
            add_values<<<grid(count), THREADS>>>(count, M.device_values(), target.device_values());
            check_launch("launch of the consistent mass");
            return;
        }
        add_mass_diagonal<<<kernel_grid(), THREADS>>>(
            n, dim, diagonal_slots.data(), mass.data(), target.device_values());
        check_launch("launch of the mass diagonal");
    }

    Energy energy(const DeviceElasticMesh& mesh, const double* y, double w, bool on_segment = false)
    {
        const double* Md = consistent_product(y);
        reduce<2>(EnergyTerm { y, xt.data(), mass.data(), f.data(), reference.data(), Md, dynamic }, n, ENERGY_OPS,
            partials.data(), scalars.data() + S_ENERGY);
        Energy e;
        e.elastic = mesh.energy_device(y);
        if (contact)
            e.contact = contact->energy(contact_positions(y), on_segment);
        if (friction)
            e.friction = friction->energy_device(y);
        double s[2];
        detail::copy_device_to_host(s, scalars.data() + S_ENERGY, sizeof(s));
        e.inertia = 0.5 * s[0];
        e.work = s[1];
        // The CPU Problem's sum, term by term in the order the simulator adds them.
        e.total = (dynamic ? e.inertia : 0.0) + w * e.elastic + (contact ? w * e.contact : 0.0) + w * -e.work
            + (friction ? w * e.friction : 0.0);
        return e;
    }

    /// The Newton matrix: H, plus the contact Hessian (and the friction Hessian) by a SumOperator in a
    /// contact scene.
    const DeviceLinearOperator& system(const DeviceContact* with_contact) const
    {
        if (with_contact)
            return sum;
        return H;
    }

    /// Assembles the contact (and friction) Hessians at x with weight w and binds them to the sum.
    void assemble_contact(double w, bool project)
    {
        contact->assemble_hessian(contact_positions(x.data()), w, project);
        if (surface) { // no friction across the boundary (set_periodic_contact)
            reduced_contact.bind(contact->hessian(), *surface);
            reduced_sum.bind(reduced, reduced_contact);
            return;
        }
        if (friction)
            friction->assemble_hessian(x.data(), w);
        sum.bind(H, contact->hessian(), friction ? &friction->hessian() : nullptr);
    }

    /// Uploads a host state (x, the inertial target, the force, the weight) between solves and builds the
    /// contact's active set there. @throws std::invalid_argument naming `who` on a size mismatch
    void load_state(const char* who, DeviceContact* with_contact, const std::vector<double>& x_host,
        const std::vector<double>& inertial_target, double weight, const std::vector<double>& force)
    {
        if (periodic)
            throw std::logic_error(std::string("DeviceNewton::") + who
                + ": not for a periodic cell (its state is q: solve_periodic, balance_at_periodic)");
        if (x_host.size() != n || force.size() != n || (dynamic && inertial_target.size() != n))
            throw std::invalid_argument(std::string("DeviceNewton::") + who
                + ": x, inertial_target and force need #dofs = " + std::to_string(n) + " entries");
        x.upload(x_host);
        take_terms(with_contact, inertial_target, weight, force);
        activate_at_x();
    }

    /// A solve's (or a balance's) terms: the contact in use, the inertial target (dynamic), the weight
    /// and the external force; the active set is then stale.
    void take_terms(DeviceContact* with_contact, const std::vector<double>& inertial_target, double weight,
        const std::vector<double>& force)
    {
        contact = with_contact;
        if (dynamic)
            xt.upload(inertial_target);
        f.upload(force);
        w = weight;
        active_current = false;
    }

    /// Builds the contact's active set at the iterate x (if there is contact and it is not current).
    void activate_at_x()
    {
        if (contact && !active_current) {
            contact->update_active(contact_positions(x.data()));
            active_current = true;
        }
    }

    /// The step bound along scale p at x: min(1, inversion bound, CCD bound); `unresolved` if the CCD
    /// could not certify any step (the CPU's step_unresolved()). With an image surface the CCD runs along
    /// P_s (scale p_q) from its positions.
    double max_step(double scale, double keep, bool& unresolved)
    {
        const double* dir = p.data();
        if (scale != 1.0) {
            scale_into<<<grid(n), THREADS>>>(n, scale, p.data(), dir_scaled.data());
            check_launch("launch of a scaled step");
            dir = dir_scaled.data();
        }
        double alpha = std::min(1.0, step_bound(x.data(), dir, keep));
        unresolved = false;
        if (contact) {
            const double* contact_dir = dir;
            if (surface) {
                scale_into<<<grid(nq), THREADS>>>(nq, scale, p_q.data(), p_q_scaled.data());
                check_launch("launch of a scaled step");
                surface->expand(p_q_scaled.data(), ps.data(), false);
                contact_dir = ps.data();
            }
            const StepBoundResult r = contact->max_step(contact_positions(x.data()), contact_dir);
            alpha = std::min(alpha, r.alpha);
            unresolved = r.unresolved;
        }
        return alpha;
    }

    /// NewtonSolver::extend on the device. The full step trial = x + p was accepted with new_energy; tries
    /// x + 2p, x + 4p, ... (built in `longer`) while the energy keeps falling (Armijo against the start)
    /// and the step bound admits the longer step. Returns the step length taken; trial then holds that
    /// state and new_energy its energy.
    double extend(const DeviceElasticMesh& mesh, double w, double length, const DeviceNewtonSettings& s,
        double start_energy, double slope, double& new_energy, DeviceNewtonResult& result)
    {
        double alpha = 1.0;
        for (int k = 0; k < MAX_EXTENSIONS; ++k) {
            const double a = 2 * alpha;
            if (s.max_displacement > 0 && a * length > s.max_displacement)
                break;
            bool unresolved = false;
            if (max_step(a, s.inversion_keep, unresolved) < 1.0)
                break;
            make_trial(a, periodic ? longer_q : longer, longer);
            const double e = energy(mesh, longer.data(), w, true).total;
            if (!(e < new_energy) || e > start_energy + s.armijo * a * slope)
                break;
            alpha = a;
            new_energy = e;
            std::swap(trial, longer);
            if (periodic)
                std::swap(trial_q, longer_q);
            if (surface)
                std::swap(ys_trial, ys_longer);
        }
        result.extended_steps += alpha > 1.0;
        return alpha;
    }

    /// The balancing products at x with weight w (the active set at x must be current).
    ContactBalance balance(const DeviceElasticMesh& mesh, double w)
    {
        ContactBalance b;
        if (!contact)
            return b;
        b.active = contact->num_active();
        // gE: the gradient without the barrier (g_trial is free between iterations).
        gradient(mesh, x.data(), w, g_trial.data(), /*with_contact=*/false);
        if (surface) { // balanced in the cell's unknowns, as the CPU balances a periodic cell
            gradient_to_unknowns(g_trial, g_trial_q); // gc is zero: gradient() without contact
            gc.set_zero();
            contact->add_barrier_gradient(ys.data(), 1.0, gc.data());
            gb.resize(nq);
            surface->reduce(gc.data(), gb.data());
            gc.set_zero();
            reduce<2>(BalanceTerm { gb.data(), g_trial_q.data(), fixed_q.data() }, nq, BALANCE_OPS, partials.data(),
                scalars.data() + S_BALANCE);
        } else {
            gb.resize(n);
            gb.set_zero();
            contact->add_barrier_gradient(x.data(), 1.0, gb.data());
            reduce<2>(BalanceTerm { gb.data(), g_trial.data(), fixed.data() }, n, BALANCE_OPS, partials.data(),
                scalars.data() + S_BALANCE);
        }
        double out[2];
        detail::copy_device_to_host(out, scalars.data() + S_BALANCE, sizeof(out));
        b.gb_ge = out[0];
        b.gb_gb = out[1];
        return b;
    }

    /// g = dE/dx at y (the contact's active set must have been built at y); with_contact false: without
    /// the barrier and friction (the balancing rule's gE, as the CPU's, which leaves friction out).
    void gradient(const DeviceElasticMesh& mesh, const double* y, double w, double* out, bool with_contact = true)
    {
        const double* Md = consistent_product(y);
        inertia_force_gradient<<<kernel_grid(), THREADS>>>(n, dynamic, y, xt.data(), mass.data(), Md, f.data(), w, out);
        check_launch("launch of the inertial gradient");
        mesh.add_gradient_device(y, w, out);
        if (surface) {
            gc.set_zero();
            if (contact && with_contact)
                contact->add_gradient(contact_positions(y), w, gc.data());
            return;
        }
        if (contact && with_contact)
            contact->add_gradient(y, w, out);
        if (friction && with_contact)
            friction->add_gradient_device(y, w, out);
    }

    /// The inversion bound along p at y (min over the elements, 1 if none).
    double step_bound(const double* y, const double* dir, double keep)
    {
        if (dim == 2)
            reduce<1>(StepBoundTerm<2> { elements.data(), ne, y, dir, keep }, size_t(ne), BOUND_OPS, partials.data(),
                scalars.data() + S_BOUND);
        else
            reduce<1>(StepBoundTerm<3> { elements.data(), ne, y, dir, keep }, size_t(ne), BOUND_OPS, partials.data(),
                scalars.data() + S_BOUND);
        double bound = 1;
        detail::copy_device_to_host(&bound, scalars.data() + S_BOUND, sizeof(double));
        return bound;
    }

    /// [max |g_free|, g not finite] of the position-space gradient g_trial, in the unknowns.
    void residual_of_trial(double* out)
    {
        gradient_to_unknowns(g_trial, u_g_trial());
        remove_carried(g_trial.data()); // under load control (never a periodic cell's)
        reduce<2>(ResidualTerm { u_g_trial().data(), u_fixed() }, nu(), RESIDUAL_OPS, partials.data(),
            scalars.data() + S_RESIDUAL);
        detail::copy_device_to_host(out, scalars.data() + S_RESIDUAL, 2 * sizeof(double));
    }

    /// [slope g.p, |p|_inf, |p_free|_inf, |u|_inf, p not finite] in the unknowns.
    void direction_scalars(double* out)
    {
        reduce<5>(DirectionTerm { u_g().data(), u_p().data(), u().data(), u_fixed() }, nu(), DIRECTION_OPS,
            partials.data(), scalars.data() + S_DIRECTION);
        detail::copy_device_to_host(out, scalars.data() + S_DIRECTION, 5 * sizeof(double));
    }

    struct NewtonLoop; // iterate()'s steps and the state they share (below)
};

void DeviceNewton::Impl::make_trial(double alpha, DeviceArray<double>& into_u, DeviceArray<double>& into_x)
{
    if (!periodic) {
        step<<<grid(n), THREADS>>>(n, x.data(), alpha, p.data(), into_x.data());
        check_launch("launch of a Newton step");
        return;
    }
    step<<<grid(nq), THREADS>>>(nq, q.data(), alpha, p_q.data(), into_u.data());
    check_launch("launch of a Newton step");
    expand_state(into_u, into_x);
}

DeviceNewton::DeviceNewton(const DeviceElasticMesh& mesh, const std::vector<double>& lumped_mass)
    : m_mesh(mesh)
    , m_impl(nullptr)
{
    const size_t n = size_t(mesh.num_dofs());
    if (n == 0)
        throw std::invalid_argument("DeviceNewton: the mesh has no dofs (upload it first)");
    if (!lumped_mass.empty() && lumped_mass.size() != n)
        throw std::invalid_argument("DeviceNewton: lumped_mass has " + std::to_string(lumped_mass.size())
            + " entries, expected #dofs = " + std::to_string(n) + " (or none for a static solve)");
    for (size_t k = 0; k < lumped_mass.size(); ++k)
        if (!(lumped_mass[k] >= 0) || !std::isfinite(lumped_mass[k]))
            throw std::invalid_argument("DeviceNewton: lumped_mass[" + std::to_string(k)
                + "] = " + std::to_string(lumped_mass[k]) + " is not a finite mass >= 0");

    // The element vertices, from the pattern's vertex incidences (codes e n + a), structure of arrays.
    const ElementBsrPattern& pattern = mesh.pattern();
    const int dim = mesh.dim(), nv = mesh.num_vertices(), ne = mesh.num_elements(), nper = dim + 1;
    std::vector<int> elements(size_t(ne) * size_t(nper), -1);
    for (int v = 0; v < nv; ++v)
        for (int c = pattern.vertex_offsets[size_t(v)]; c < pattern.vertex_offsets[size_t(v) + 1]; ++c) {
            const int code = pattern.vertex_codes[size_t(c)];
            elements[size_t(code % nper) * size_t(ne) + size_t(code / nper)] = v;
        }
    std::vector<int> diagonal(size_t(nv), -1);
    for (int v = 0; v < nv; ++v)
        for (int k = pattern.row_offsets[size_t(v)]; k < pattern.row_offsets[size_t(v) + 1]; ++k)
            if (pattern.col_indices[size_t(k)] == v)
                diagonal[size_t(v)] = k;
    for (int v = 0; v < nv; ++v)
        if (diagonal[size_t(v)] < 0)
            throw std::logic_error(
                "DeviceNewton: the Hessian pattern has no diagonal block for vertex " + std::to_string(v));

    auto impl = std::make_unique<Impl>();
    impl->n = n;
    impl->dim = dim;
    impl->ne = ne;
    impl->nv = nv;
    impl->dynamic = !lumped_mass.empty();
    if (impl->dynamic)
        impl->mass.upload(lumped_mass);
    impl->elements.upload(elements);
    impl->diagonal_slots.upload(diagonal);
    for (auto* v : { &impl->x, &impl->trial, &impl->longer, &impl->dir_scaled, &impl->xt, &impl->f, &impl->target,
             &impl->reference, &impl->g, &impl->g_trial, &impl->p, &impl->pD, &impl->rhs, &impl->coupling })
        v->resize(n);
    impl->reference.set_zero();
    impl->fixed.resize(n);
    impl->fixed.set_zero();
    impl->partials.resize(size_t(MAX_REDUCED) * THREADS);
    impl->scalars.resize(NUM_SCALARS);
    impl->H = mesh.make_hessian_matrix();
    m_impl = impl.release();
}

void DeviceNewton::set_consistent_mass(
    const std::vector<int>& rows, const std::vector<int>& cols, const std::vector<double>& values)
{
    Impl& m = *m_impl;
    if (!m.dynamic)
        throw std::invalid_argument("DeviceNewton::set_consistent_mass: a static solver has no mass");
    if (rows.size() != cols.size() || rows.size() != values.size())
        throw std::invalid_argument("DeviceNewton::set_consistent_mass: rows, cols and values differ in size");
    const int b = m.dim;
    HostBsrMatrix host;
    host.block_size = b;
    host.num_block_rows = m.H.num_block_rows();
    host.row_offsets = m.H.row_offsets();
    host.col_indices = m.H.col_indices();
    host.values.assign(host.col_indices.size() * size_t(b * b), 0.0);
    for (size_t e = 0; e < rows.size(); ++e) {
        const int r = rows[e], c = cols[e];
        if (r < 0 || c < 0 || size_t(r) >= m.n || size_t(c) >= m.n || !std::isfinite(values[e]))
            throw std::invalid_argument(
                "DeviceNewton::set_consistent_mass: entry " + std::to_string(e) + " is out of range or not finite");
        const int br = r / b, bc = c / b;
        const auto begin = host.col_indices.begin() + host.row_offsets[size_t(br)];
        const auto end = host.col_indices.begin() + host.row_offsets[size_t(br) + 1];
        const auto it = std::lower_bound(begin, end, bc);
        if (it == end || *it != bc)
            throw std::invalid_argument("DeviceNewton::set_consistent_mass: entry (" + std::to_string(r) + ", "
                + std::to_string(c) + ") couples vertices outside the Hessian's pattern");
        host.values[size_t(it - host.col_indices.begin()) * size_t(b * b) + size_t((r % b) * b + c % b)] += values[e];
    }
    m.M.upload(host);
    m.mass_difference.resize(m.n);
    m.mass_product.resize(m.n);
    m.consistent = true;
}

DeviceNewton::~DeviceNewton() { delete m_impl; }

void DeviceNewton::set_lumped_mass(const std::vector<double>& lumped_mass)
{
    Impl& m = *m_impl;
    if (m.consistent)
        throw std::logic_error("DeviceNewton::set_lumped_mass: the solver has a consistent mass");
    if (m.periodic)
        throw std::logic_error("DeviceNewton::set_lumped_mass: not for a periodic cell");
    if (!lumped_mass.empty() && lumped_mass.size() != m.n)
        throw std::invalid_argument("DeviceNewton::set_lumped_mass: " + std::to_string(lumped_mass.size())
            + " masses for " + std::to_string(m.n) + " dofs");
    for (size_t i = 0; i < lumped_mass.size(); ++i)
        if (!(lumped_mass[i] >= 0) || !std::isfinite(lumped_mass[i]))
            throw std::invalid_argument(
                "DeviceNewton::set_lumped_mass: mass " + std::to_string(i) + " is negative or not finite");
    if (!lumped_mass.empty())
        m.mass.upload(lumped_mass); // before the flag: a failed upload leaves the solver as it was
    m.dynamic = !lumped_mass.empty();
}

void DeviceNewton::set_constrained(const std::vector<char>& constrained)
{
    if (constrained.size() != m_impl->n)
        throw std::invalid_argument("DeviceNewton::set_constrained: " + std::to_string(constrained.size())
            + " flags, expected #dofs = " + std::to_string(m_impl->n));
    std::vector<unsigned char> flags(constrained.size());
    for (size_t k = 0; k < flags.size(); ++k)
        flags[k] = constrained[k] ? 1 : 0;
    m_impl->fixed.upload(flags);
    m_impl->pcg.set_fixed_dofs(constrained);
    m_impl->constrained = constrained;
    m_impl->amg.reset();
    m_impl->multigrid_unavailable = false;
}

void DeviceNewton::set_adjoint_multigrid(bool on, int plan_threads, int max_coarsest_dofs)
{
    if (plan_threads < 0 || max_coarsest_dofs < 0)
        throw std::invalid_argument(
            "DeviceNewton::set_adjoint_multigrid: plan_threads and max_coarsest_dofs must be >= 0");
    Impl& m = *m_impl;
    m.multigrid = on;
    m.multigrid_threads = plan_threads;
    const int coarsest = max_coarsest_dofs > 0 ? max_coarsest_dofs : AmgPlanSettings().max_coarsest_dofs;
    if (coarsest != m.multigrid_coarsest) {
        m.multigrid_coarsest = coarsest;
        m.amg.reset();
        m.multigrid_unavailable = false;
    }
}

bool DeviceNewton::adjoint_multigrid() const { return m_impl->multigrid; }

int DeviceNewton::adjoint_multigrid_levels() const { return m_impl->amg ? m_impl->amg->num_levels() : -1; }

void DeviceNewton::set_force_reference(const std::vector<double>& reference)
{
    if (reference.empty()) {
        m_impl->reference.set_zero();
        return;
    }
    if (reference.size() != m_impl->n)
        throw std::invalid_argument("DeviceNewton::set_force_reference: " + std::to_string(reference.size())
            + " entries, expected #dofs = " + std::to_string(m_impl->n));
    m_impl->reference.upload(reference);
}

void DeviceNewton::set_material_scale(const std::vector<MaterialModel>& models, const std::vector<double>& mu)
{
    const size_t ne = size_t(m_mesh.num_elements());
    if (models.size() != ne || mu.size() != ne)
        throw std::invalid_argument(
            "DeviceNewton::set_material_scale: expected one model and one mu per element (" + std::to_string(ne) + ")");
    const std::vector<double>& volumes = m_mesh.rest_volumes();
    double scale = 0;
    for (size_t e = 0; e < ne; ++e)
        if (models[e] == MaterialModel::NEO_HOOKEAN || models[e] == MaterialModel::STABLE_NEO_HOOKEAN)
            scale += volumes[e] * mu[e] * m_mesh.dim();
    m_impl->material_scale = scale;
}

double DeviceNewton::material_scale() const { return m_impl->material_scale; }

PcgResult DeviceNewton::solve_true_hessian(const std::vector<double>& x_host, double weight,
    const std::vector<double>& b_host, std::vector<double>& y_host, double relative_tolerance, int max_iterations,
    std::vector<double>* product)
{
    Impl& m = *m_impl;
    if (m.periodic)
        throw std::logic_error("DeviceNewton::solve_true_hessian: not built yet for a periodic cell");
    const size_t n = m.n;
    if (x_host.size() != n || b_host.size() != n)
        throw std::invalid_argument("DeviceNewton::solve_true_hessian: x and b need #dofs = " + std::to_string(n)
            + " entries, got " + std::to_string(x_host.size()) + " and " + std::to_string(b_host.size()));
    if (!(weight > 0) || !std::isfinite(weight) || !(relative_tolerance > 0) || max_iterations < 0)
        throw std::invalid_argument("DeviceNewton::solve_true_hessian: weight and tolerance must be positive");
    m.x.upload(x_host);
    m.rhs.upload(b_host);
    m.H.set_zero();
    m_mesh.add_hessian_device(m.x.data(), weight, /*project=*/false, m.H);
    m.add_mass(m.H);
    if (m_contact) {
        // The barrier's true Hessian of the active set at x (the committed step's set).
        m_contact->update_active(m.x.data());
        m.active_current = false;
        m.contact = m_contact;
        m.assemble_contact(weight, /*project=*/false);
    }
    m.pcg.settings() = PcgSettings { relative_tolerance, max_iterations };
    // The multigrid is built from H (elasticity and mass); with contact it preconditions the sum.
    const DevicePreconditioner* multigrid = nullptr;
    // DIFFIPC_NEWTON_TRACE: the multigrid's planning, set-up and solve times on stderr.
    static const bool trace = std::getenv("DIFFIPC_NEWTON_TRACE") != nullptr;
    const auto since = [](Clock::time_point t) {
        check_cuda(cudaDeviceSynchronize(), "synchronization for the adjoint's trace");
        return std::chrono::duration<double>(Clock::now() - t).count();
    };
    Clock::time_point start = Clock::now();
    double planned = 0, set_up = 0;
    if (m.multigrid && !m.multigrid_unavailable) {
        if (!m.amg) {
            try {
                const std::vector<char> constrained = m.constrained.empty() ? std::vector<char>(n, 0) : m.constrained;
                AmgPlanSettings plan;
                plan.threads = m.multigrid_threads;
                plan.max_coarsest_dofs = m.multigrid_coarsest;
                m.amg = std::make_unique<DeviceAmg>(
                    plan_amg(m.dim, BlockPattern { m.H.row_offsets(), m.H.col_indices() }, x_host, constrained, plan));
            } catch (const std::exception&) {
                // E.g. a coarsest level too large to invert densely, or too little memory: block-Jacobi.
                m.multigrid_unavailable = true;
            }
        }
        planned = trace ? since(start) : 0;
        if (m.amg && m.amg->setup(m.H))
            multigrid = m.amg.get();
        set_up = trace ? since(start) - planned : 0;
    }
    // A multigrid solve gets at most MULTIGRID_ITERATIONS: it converges in tens, and one that does not (a
    // preconditioner that lost definiteness on an indefinite true Hessian) must not crawl before the fallback.
    constexpr int MULTIGRID_ITERATIONS = 1000;
    if (multigrid)
        m.pcg.settings().max_iterations = std::min(max_iterations, MULTIGRID_ITERATIONS);
    PcgResult r = m.pcg.solve_device(m.system(m_contact), m.rhs.data(), m.p.data(), multigrid);
    m.pcg.settings().max_iterations = max_iterations;
    if (trace) {
        std::fprintf(stderr, "adjoint solve: %s, plan %.4f s, set-up %.4f s, PCG %d iterations %.4f s",
            multigrid ? "multigrid" : "block-Jacobi", planned, set_up, r.iterations, since(start) - planned - set_up);
        if (m.amg)
            for (int l = 0; l <= m.amg->num_levels(); ++l)
                std::fprintf(stderr, "%s%d", l ? " -> " : "; levels ", m.amg->level_size(l));
        std::fprintf(stderr, "\n");
    }
    if (multigrid && (!r.converged || r.breakdown)) {
        // Block-Jacobi decides: a breakdown there means the matrix itself is not positive definite.
        const int first = r.iterations;
        r = m.pcg.solve_device(m.system(m_contact), m.rhs.data(), m.p.data());
        r.iterations += first;
    }
    y_host = m.p.download();
    if (product) {
        m.system(m_contact).multiply(m.p.data(), m.coupling.data(), nullptr);
        *product = m.coupling.download();
    }
    return r;
}

namespace {

    /// The checks of solve() and solve_periodic() before any GPU work.
    void check_solve_arguments(
        const char* who, double weight, double force_scale, double step_scale, const DeviceNewtonSettings& settings)
    {
        for (const double s : { weight, force_scale, step_scale })
            if (!(s > 0) || !std::isfinite(s))
                throw std::invalid_argument(std::string("DeviceNewton::") + who
                    + ": weight, force_scale and step_scale must be positive and finite");
        if (!(settings.residual_tolerance >= 0) || settings.max_iterations < 0 || settings.line_search_max_halvings < 0
            || !(settings.forcing_max > 0) || !(settings.forcing_min > 0) || settings.forcing_min > settings.forcing_max
            || !(settings.inversion_keep >= 0 && settings.inversion_keep < 1) || settings.pcg_max_iterations < 0
            || !(settings.max_displacement >= 0) || !(settings.terminal_factor >= 0) || !(settings.terminal_window >= 1)
            || !(settings.lifting_forcing_max > 0))
            throw std::invalid_argument(std::string("DeviceNewton::") + who
                + ": invalid settings (tolerances >= 0, 0 < forcing_min <= forcing_max, 0 < lifting_forcing_max, "
                  "0 <= inversion_keep < 1, counts >= 0, max_displacement >= 0, terminal_factor >= 0, "
                  "terminal_window >= 1)");
    }

} // namespace

DeviceNewtonResult DeviceNewton::solve(std::vector<double>& x_host, const std::vector<double>& inertial_target,
    double weight, const std::vector<double>& force, const std::vector<double>& target_host, double force_scale,
    double step_scale, const DeviceNewtonSettings& settings, DeviceLoadControl* control)
{
    Impl& m = *m_impl;
    if (m.periodic)
        throw std::logic_error(
            "DeviceNewton::solve: a periodic cell's solver (set_periodic) solves with solve_periodic");
    const size_t n = m.n;
    auto check_size = [n](const std::vector<double>& v, const char* name) {
        if (v.size() != n)
            throw std::invalid_argument(std::string("DeviceNewton::solve: ") + name + " has " + std::to_string(v.size())
                + " entries, expected #dofs = " + std::to_string(n));
    };
    check_size(x_host, "x");
    check_size(force, "force");
    check_size(target_host, "target");
    if (m.dynamic)
        check_size(inertial_target, "inertial_target");
    check_solve_arguments("solve", weight, force_scale, step_scale, settings);
    if (control) {
        check_size(control->direction, "the load control's direction");
        double aa = 0;
        for (size_t k = 0; k < n; ++k) {
            const double a = control->direction[k];
            if (!std::isfinite(a) || (a != 0 && !m.constrained.empty() && m.constrained[k]))
                throw std::invalid_argument("DeviceNewton::solve: the load control's direction is "
                    + std::string(std::isfinite(a) ? "nonzero on constrained" : "not finite at") + " dof "
                    + std::to_string(k));
            aa += a * a;
        }
        if (!(aa > 0) || !std::isfinite(aa) || !std::isfinite(control->level) || !(control->tolerance >= 0)
            || !std::isfinite(control->tolerance))
            throw std::invalid_argument("DeviceNewton::solve: the load control needs a nonzero direction, a finite "
                                        "level and a finite tolerance >= 0");
        m.control_a.upload(control->direction);
        m.control_aa = aa;
    }
    // The control holds for this solve only, however it ends.
    struct Controlled {
        Impl& m;
        Controlled(Impl& impl, DeviceLoadControl* c)
            : m(impl)
        {
            m.control = c;
            m.pcg.set_constraint(c ? m.control_a.data() : nullptr);
        }
        ~Controlled()
        {
            m.control = nullptr;
            m.pcg.set_constraint(nullptr);
        }
    } controlled(m, control);
    m.x.upload(x_host);
    m.target.upload(target_host);
    const DeviceNewtonResult result = iterate(inertial_target, weight, force, force_scale, step_scale, settings);
    if (result.status == DeviceStepStatus::CONVERGED)
        detail::copy_device_to_host(x_host.data(), m.x.data(), n * sizeof(double));
    return result;
}

DeviceNewtonResult DeviceNewton::solve_periodic(std::vector<double>& q_host, const std::vector<double>& target_q,
    const std::vector<double>& inertial_target, double weight, const std::vector<double>& force, double force_scale,
    double step_scale, const DeviceNewtonSettings& settings)
{
    Impl& m = *m_impl;
    if (!m.periodic)
        throw std::logic_error("DeviceNewton::solve_periodic: no periodic cell (set_periodic)");
    if (q_host.size() != m.nq || target_q.size() != m.nq)
        throw std::invalid_argument("DeviceNewton::solve_periodic: q and target_q need the cell's "
            + std::to_string(m.nq) + " reduced unknowns");
    if (force.size() != m.n || (m.dynamic && inertial_target.size() != m.n))
        throw std::invalid_argument(
            "DeviceNewton::solve_periodic: force and inertial_target need #dofs = " + std::to_string(m.n) + " entries");
    check_solve_arguments("solve_periodic", weight, force_scale, step_scale, settings);
    m.q.upload(q_host);
    m.target_q.upload(target_q);
    m.expand_state(m.q, m.x);
    const DeviceNewtonResult result = iterate(inertial_target, weight, force, force_scale, step_scale, settings);
    if (result.status == DeviceStepStatus::CONVERGED)
        detail::copy_device_to_host(q_host.data(), m.q.data(), m.nq * sizeof(double));
    return result;
}

/// iterate()'s Newton loop: the state its iterations share, and one member function per step of an
/// iteration, in the order iterate() takes them. A step that ends the solve returns its status.
struct DeviceNewton::Impl::NewtonLoop {
    /// One iteration's quantities, from the gradient at its iterate to its accepted step.
    struct Iteration {
        int index = 0; // of the iteration, from 0
        double gap = 0; // under load control: level - a^T x
        double gmax = 0, gnorm = 0; // max |g_free|, |g_free|_2
        bool lifting = false; // constrained dofs (or the control's level) not yet reached
        double forcing = 0; // PCG's relative tolerance
        bool try_true = false; // the true Hessian first (adaptive_projection)
        double ds[5] = {}; // direction_scalars() of the step
        double slope = 0, pmax = 0; // g^T p (full_slope), |p|_inf
        double length = 0; // |p_free|_inf
        double alpha = 0; // the step length: bounded, then halved by the line search
        Clock::time_point t_ls; // the start of the line-search phase
        double new_energy = 0; // E at the accepted trial
        double roundoff = 0; // of the energy differences
        bool unresolvable = false; // the full step's predicted decrease is below the energy's resolution
        bool active_at_trial = false; // the active set was built at the accepted trial
    };

    NewtonLoop(Impl& impl, const DeviceElasticMesh& elastic_mesh, DeviceContact* with_contact,
        const std::function<bool()>& end_iteration_hook, double weight, double residual_scale, double newton_scale,
        const DeviceNewtonSettings& newton_settings)
        : m(impl)
        , mesh(elastic_mesh)
        , contact(with_contact)
        , hook(end_iteration_hook)
        , settings(newton_settings)
        , w(weight)
        , force_scale(residual_scale)
        , step_scale(newton_scale)
        , control(impl.control)
        , nu(impl.nu())
        , Gu(grid(nu))
        , fixed(impl.u_fixed())
        , trace(trace_requested())
    {
    }

    /// E at the start x and its magnitude (the round-off allowance's).
    std::optional<DeviceStepStatus> evaluate_start();
    /// The gradient at x, the residual and the convergence test; pD the lifting step (plus p0 under control).
    std::optional<DeviceStepStatus> evaluate_residual(Iteration& iter);
    /// PCG's relative tolerance (DeviceNewtonSettings::forcing_max).
    void choose_forcing(Iteration& iter);
    /// Whether the true Hessian is tried before the projected one.
    void choose_matrix(Iteration& iter);
    /// The Newton direction p in the unknowns, from the true or the projected search matrix.
    std::optional<DeviceStepStatus> solve_direction(Iteration& iter);
    /// The search matrix M + w (H_Psi + H_B) and the right-hand side -(g + H pD).
    void assemble_system(const Iteration& iter, bool project);
    /// PCG on the assembled system into p, with the prescribed (and the control's) part of the step.
    PcgResult solve_system(const Iteration& iter);
    /// The step is within round-off of x (roundoff_step() takes it instead of the line search).
    bool below_roundoff(const Iteration& iter) const;
    std::optional<DeviceStepStatus> roundoff_step(Iteration& iter);
    /// The negative gradient in place of a direction that does not descend.
    void ensure_descent(Iteration& iter);
    /// The largest step length the inversion and the CCD bounds (and max_displacement) admit.
    std::optional<DeviceStepStatus> bound_step(Iteration& iter);
    /// Armijo backtracking from the bounded step; trial then holds the accepted state.
    std::optional<DeviceStepStatus> line_search(Iteration& iter);
    /// Lengthens an accepted full step (DeviceNewtonSettings::step_extension).
    void extend_step(Iteration& iter);
    /// The accepted trial becomes the iterate.
    void commit(const Iteration& iter);
    void snap_lifted(const Iteration& iter);
    /// [max |g_free|, g not finite] at the trial, with the active set built there.
    void residual_at_trial(double* rs);
    /// After each accepted iterate: the hook (adaptive kappa) sees the active set at the new x.
    void end_iteration();
    void trace_iteration(const Iteration& iter) const;
    /// The slope g^T p of the energy the line search tests, from direction_scalars' (g - lambda a)^T p:
    /// under load control a Newton step has a^T p = gap, so g^T p adds lambda gap (the CPU's slope).
    double full_slope(const Iteration& iter, double carried_free) const
    {
        return control ? carried_free + control->multiplier * iter.gap : carried_free;
    }
    // DIFFIPC_NEWTON_TRACE=1: one line per iteration on stderr (a diagnostic for failing steps).
    static bool trace_requested()
    {
        static const bool requested = std::getenv("DIFFIPC_NEWTON_TRACE") != nullptr;
        return requested;
    }

    Impl& m;
    const DeviceElasticMesh& mesh;
    DeviceContact* const contact;
    const std::function<bool()>& hook; // set_end_iteration's
    const DeviceNewtonSettings& settings;
    const double w, force_scale, step_scale;
    DeviceLoadControl* const control;
    // The unknowns: the positions, or a periodic cell's q (Impl's u_ accessors).
    const size_t nu;
    const int Gu;
    const unsigned char* const fixed;
    const bool trace;

    DeviceNewtonResult result;
    double energy = 0; // E at x
    double magnitude = 0; // the start's energy magnitude (file comment)
    double reference_gradient_norm = 0; // |g_free,0|_2 of the forcing (DeviceNewtonSettings)
    bool full_step_taken = false;
    int true_hessian_pause = 0;
    // True-Hessian steps that lower neither the energy beyond its round-off nor the residual by a tenth:
    // near a bifurcation (two boxes meeting face to face) the true Hessian's step can jump between two
    // states of equal energy, each step accepted within the energy's round-off. After STALLS such steps in
    // a row the projected matrix is used for stall_pause iterations, doubled at each recurrence.
    static constexpr int STALLS = 3;
    bool last_true = false;
    double last_gmax = INFINITY, last_drop = INFINITY, last_roundoff = 0;
    int stalls = 0, stall_pause = 2;
};

DeviceNewtonResult DeviceNewton::iterate(const std::vector<double>& inertial_target, double weight,
    const std::vector<double>& force, double force_scale, double step_scale, const DeviceNewtonSettings& settings)
{
    Impl& m = *m_impl;
    m.take_terms(m_contact, inertial_target, weight, force);
    m.bind_unknowns(m_contact);
    Impl::NewtonLoop loop(m, m_mesh, m_contact, m_end_iteration, weight, force_scale, step_scale, settings);
    auto finish = [&](DeviceStepStatus status) {
        loop.result.status = status;
        return loop.result;
    };
    if (const auto end = loop.evaluate_start())
        return finish(*end);
    for (int it = 0;; ++it) {
        Impl::NewtonLoop::Iteration iter;
        iter.index = it;
        if (const auto end = loop.evaluate_residual(iter))
            return finish(*end);
        loop.choose_forcing(iter);
        loop.choose_matrix(iter);
        if (const auto end = loop.solve_direction(iter))
            return finish(*end);
        if (loop.below_roundoff(iter)) {
            if (const auto end = loop.roundoff_step(iter))
                return finish(*end);
            continue;
        }
        loop.ensure_descent(iter);
        if (const auto end = loop.bound_step(iter))
            return finish(*end);
        if (const auto end = loop.line_search(iter))
            return finish(*end);
        loop.extend_step(iter);
        loop.commit(iter);
    }
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::evaluate_start()
{
    Impl::Energy start_energy;
    {
        const auto t = Clock::now();
        start_energy = m.energy(mesh, m.x.data(), w);
        phase_end(t, result.line_search_time);
    }
    energy = start_energy.total;
    if (!std::isfinite(energy))
        return DeviceStepStatus::INVALID_INITIAL_STATE;
    // Round-off of energy differences scales with the terms, not with their (possibly cancelling) sum.
    magnitude = (m.dynamic ? std::abs(start_energy.inertia) : 0.0)
        + w * (std::abs(start_energy.elastic) + m.material_scale) + w * std::abs(start_energy.contact)
        + w * std::abs(start_energy.work) + w * std::abs(start_energy.friction);
    return std::nullopt;
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::evaluate_residual(Iteration& iter)
{
    double gs[4];
    {
        const auto t = Clock::now();
        m.activate_at_x();
        m.gradient(mesh, m.x.data(), w, m.g.data());
        m.gradient_to_unknowns(m.g, m.u_g());
        if (control) {
            double ax = 0;
            control->multiplier = m.remove_carried(m.g.data(), &ax);
            iter.gap = control->level - ax;
        }
        reduce<4>(GradientTerm { m.u_g().data(), m.u().data(), m.u_target().data(), fixed, m.u_pD().data() }, nu,
            GRADIENT_OPS, m.partials.data(), m.scalars.data() + S_GRADIENT);
        // Under load control, pD also holds p0 = gap a / a^T a on the free dofs (file comment).
        if (control) {
            add_scaled<<<Gu, THREADS>>>(nu, iter.gap / m.control_aa, m.control_a.data(), m.u_pD().data());
            check_launch("launch of the control's lift");
        }
        detail::copy_device_to_host(gs, m.scalars.data() + S_GRADIENT, sizeof(gs));
        phase_end(t, result.assembly_time);
    }
    if (gs[3] != 0)
        return DeviceStepStatus::NON_FINITE;
    iter.gmax = gs[0];
    iter.gnorm = std::sqrt(gs[1]);
    const double dmax = gs[2];
    iter.lifting = dmax > 0 || (control && std::abs(iter.gap) > control->tolerance);
    result.residual = iter.gmax / force_scale;
    if (!std::isfinite(result.residual))
        return DeviceStepStatus::NON_FINITE;
    if (!iter.lifting && result.residual <= settings.residual_tolerance)
        return DeviceStepStatus::CONVERGED;
    if (iter.index >= settings.max_iterations)
        return DeviceStepStatus::NEWTON_EXHAUSTED;
    return std::nullopt;
}

void DeviceNewton::Impl::NewtonLoop::choose_forcing(Iteration& iter)
{
    // Inexact Newton (Eisenstat-Walker): the linear solve is as accurate as the progress so far warrants.
    reference_gradient_norm = std::max(reference_gradient_norm, iter.gnorm);
    double forcing = settings.forcing_max;
    if (reference_gradient_norm > 0 && std::isfinite(iter.gnorm))
        forcing = std::min(forcing, std::sqrt(iter.gnorm / reference_gradient_norm));
    if (settings.terminal_factor > 0 && result.residual > 0
        && result.residual <= settings.terminal_window * settings.residual_tolerance)
        forcing = std::min(forcing, settings.terminal_factor * settings.residual_tolerance / result.residual);
    if (iter.lifting)
        forcing = std::min(forcing, settings.lifting_forcing_max);
    iter.forcing = std::max(forcing, settings.forcing_min);
}

void DeviceNewton::Impl::NewtonLoop::choose_matrix(Iteration& iter)
{
    // Projected Newton converges linearly where elements (or contact pairs) are strongly compressed;
    // once a full step has been accepted, the true Hessian is tried (NewtonSolver's adaptive
    // projection): kept if PCG meets no negative curvature and its step descends, otherwise the
    // projected matrix is used and the true one skipped for the next two iterations.
    stalls = last_true && iter.gmax > 0.9 * last_gmax && last_drop <= last_roundoff ? stalls + 1 : 0;
    if (stalls >= STALLS) {
        true_hessian_pause = std::max(true_hessian_pause, stall_pause);
        stall_pause *= 2;
        stalls = 0;
    }
    last_gmax = iter.gmax;
    last_true = false;
    iter.try_true = settings.adaptive_projection && full_step_taken && !iter.lifting && true_hessian_pause == 0;
    if (true_hessian_pause > 0)
        --true_hessian_pause;
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::solve_direction(Iteration& iter)
{
    for (int attempt = iter.try_true ? 0 : 1; attempt < 2; ++attempt) {
        const bool project = attempt == 1;
        assemble_system(iter, project);
        const PcgResult pcg = solve_system(iter);
        if (!project) {
            // The true Hessian: kept only without negative curvature and with a finite descent step.
            bool kept = !pcg.breakdown;
            if (kept) {
                m.direction_scalars(iter.ds);
                kept = iter.ds[4] == 0 && full_slope(iter, iter.ds[0]) < 0;
            }
            if (kept) {
                ++result.true_hessian_steps;
                last_true = true;
                break;
            }
            true_hessian_pause = 2;
            continue;
        }
        if (pcg.breakdown && pcg.iterations == 0)
            return DeviceStepStatus::LINEAR_BREAKDOWN;
        m.direction_scalars(iter.ds);
    }
    if (iter.ds[4] != 0)
        return DeviceStepStatus::LINEAR_BREAKDOWN;
    iter.slope = full_slope(iter, iter.ds[0]);
    iter.pmax = iter.ds[1];
    return std::nullopt;
}

void DeviceNewton::Impl::NewtonLoop::assemble_system(const Iteration& iter, bool project)
{
    const auto t = Clock::now();
    m.H.set_zero();
    mesh.add_hessian_device(m.x.data(), w, project, m.H);
    m.add_mass(m.H);
    if (contact)
        m.assemble_contact(w, project);
    const bool coupled = iter.lifting || control; // pD (and p0) not zero
    if (coupled)
        m.u_system(contact).multiply(m.u_pD().data(), m.u_coupling().data(), nullptr);
    newton_rhs<<<Gu, THREADS>>>(nu, m.u_g().data(), coupled ? m.u_coupling().data() : nullptr, m.u_rhs().data());
    check_launch("launch of the Newton right-hand side");
    phase_end(t, result.assembly_time);
}

PcgResult DeviceNewton::Impl::NewtonLoop::solve_system(const Iteration& iter)
{
    const auto t = Clock::now();
    m.u_pcg().settings() = PcgSettings { iter.forcing, settings.pcg_max_iterations };
    const PcgResult pcg = m.u_pcg().solve_device(m.u_system(contact), m.u_rhs().data(), m.u_p().data());
    result.pcg_iterations += pcg.iterations;
    result.pcg_capped += !pcg.converged && !pcg.breakdown;
    set_prescribed<<<Gu, THREADS>>>(nu, fixed, m.u_pD().data(), m.u_p().data());
    check_launch("launch of the prescribed step");
    if (control) { // p = p0 + d, d on the hyperplane: a^T p = gap
        add_scaled<<<Gu, THREADS>>>(nu, iter.gap / m.control_aa, m.control_a.data(), m.u_p().data());
        check_launch("launch of the control's step");
    }
    phase_end(t, result.solve_time);
    return pcg;
}

bool DeviceNewton::Impl::NewtonLoop::below_roundoff(const Iteration& iter) const
{
    return !iter.lifting && iter.pmax <= ROUNDOFF_STEP * iter.ds[3];
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::roundoff_step(Iteration& iter)
{
    // The remaining correction is within a few hundred ulps of the largest position, below what
    // the energy resolves: still taken while it halves the residual (NewtonSolver's rule).
    const auto t = Clock::now();
    m.step_to_positions();
    m.make_trial(1.0, m.u_trial(), m.trial);
    bool unresolved = false;
    bool improves = m.max_step(1.0, settings.inversion_keep, unresolved) >= 1.0;
    const double trial_energy = improves ? m.energy(mesh, m.trial.data(), w, true).total : INFINITY;
    improves = improves && std::isfinite(trial_energy);
    double rs[2] = { 0, 0 };
    if (improves) {
        residual_at_trial(rs);
        improves = rs[1] == 0 && rs[0] < 0.5 * iter.gmax;
    }
    phase_end(t, result.line_search_time);
    if (!improves) {
        result.roundoff_limited = true;
        return DeviceStepStatus::CONVERGED;
    }
    m.accept_trial();
    m.active_current = contact != nullptr; // built at the trial, now x
    energy = trial_energy;
    result.newton_step = iter.pmax / step_scale;
    end_iteration();
    result.iterations = iter.index + 1;
    if (result.iterations >= settings.max_iterations && rs[0] / force_scale > settings.residual_tolerance) {
        // Out of iterations inside the round-off regime: converged as far as it gets.
        result.residual = rs[0] / force_scale;
        result.roundoff_limited = true;
        return DeviceStepStatus::CONVERGED;
    }
    return std::nullopt;
}

void DeviceNewton::Impl::NewtonLoop::ensure_descent(Iteration& iter)
{
    if (!iter.lifting && !(iter.slope < 0)) {
        // Not a descent direction (PCG on a nearly singular matrix): the negative gradient, scaled to
        // the rejected step's length (under load control g - lambda a, orthogonal to a: the step stays
        // on the hyperplane, and its slope is g's).
        const double scale = iter.gmax > 0 && iter.pmax > 0 ? iter.pmax / iter.gmax : 1.0;
        gradient_direction<<<Gu, THREADS>>>(nu, fixed, m.u_g().data(), scale, m.u_p().data());
        check_launch("launch of the gradient direction");
        m.direction_scalars(iter.ds);
        iter.slope = iter.ds[0];
        iter.pmax = iter.ds[1];
        ++result.gradient_steps;
    }
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::bound_step(Iteration& iter)
{
    m.step_to_positions();
    iter.t_ls = Clock::now();
    bool unresolved = false;
    iter.length = iter.ds[2]; // of the free dofs' step: lifting moves prescribed dofs as far as it must
    if (settings.max_displacement > 0 && iter.length > settings.max_displacement) {
        const double cap = settings.max_displacement / iter.length;
        iter.alpha = cap * m.max_step(cap, settings.inversion_keep, unresolved); // from the capped step
    } else {
        iter.alpha = m.max_step(1.0, settings.inversion_keep, unresolved);
    }
    if (!(iter.alpha > 0) && unresolved) {
        phase_end(iter.t_ls, result.line_search_time);
        return DeviceStepStatus::CCD_UNRESOLVED;
    }
    return std::nullopt;
}

std::optional<DeviceStepStatus> DeviceNewton::Impl::NewtonLoop::line_search(Iteration& iter)
{
    bool accepted = false;
    iter.active_at_trial = false;
    iter.new_energy = energy;
    // Differences below this are round-off in the energy sum.
    iter.roundoff = std::max(1e-13 * std::abs(energy), 16 * EPS * magnitude);
    // Near the solution the predicted decrease can drop below what the energy sum resolves; there a
    // full step is judged by the free-dof gradient instead.
    iter.unresolvable = !iter.lifting
        && std::abs(iter.alpha * iter.slope) < std::max(ENERGY_RESOLUTION * std::abs(energy), 1e3 * EPS * magnitude);
    for (int h = 0; h <= settings.line_search_max_halvings && iter.alpha > 0; ++h, iter.alpha *= 0.5) {
        m.make_trial(iter.alpha, m.u_trial(), m.trial);
        iter.new_energy = m.energy(mesh, m.trial.data(), w, true).total;
        if (!std::isfinite(iter.new_energy))
            continue;
        if (iter.lifting || iter.new_energy <= energy + settings.armijo * iter.alpha * iter.slope + iter.roundoff) {
            accepted = true;
            result.line_search_cuts += h;
            break;
        }
        if (iter.unresolvable && h == 0) {
            double rs[2];
            residual_at_trial(rs);
            if (rs[1] == 0 && rs[0] < 0.5 * iter.gmax) {
                accepted = true;
                iter.active_at_trial = contact != nullptr;
                result.line_search_cuts += h;
                result.roundoff_limited = true;
                break;
            }
        }
    }
    if (!accepted) {
        phase_end(iter.t_ls, result.line_search_time);
        return DeviceStepStatus::LINE_SEARCH_EXHAUSTED;
    }
    return std::nullopt;
}

void DeviceNewton::Impl::NewtonLoop::extend_step(Iteration& iter)
{
    // NewtonSolver's rule. It compares the energy's decrease with -g.p, which equals p^T A p for the
    // exact step of the search matrix A; PCG's inexact step, started from zero, keeps that identity (its
    // residual is orthogonal to the Krylov space that holds p). Not where the predicted decrease is below
    // the energy's resolution: there the decrease is round-off (a last step of the 2D falling box in
    // AdaptiveTimeSteppingOfDynamicScenes was extended 4x on such noise).
    if (settings.step_extension && iter.alpha == 1.0 && !iter.lifting && !control && !iter.unresolvable
        && !result.roundoff_limited && energy - iter.new_energy > EXTENSION_RATIO * -iter.slope)
        iter.alpha = m.extend(mesh, w, iter.length, settings, energy, iter.slope, iter.new_energy, result);
}

void DeviceNewton::Impl::NewtonLoop::commit(const Iteration& iter)
{
    full_step_taken = iter.alpha >= 1.0;
    result.newton_step = iter.alpha * iter.pmax / step_scale;
    last_drop = energy - iter.new_energy;
    last_roundoff = iter.roundoff;
    m.accept_trial(); // x = the accepted trial; trial = the old x, no longer needed
    m.active_current = iter.active_at_trial;
    if (iter.lifting && iter.alpha >= 1.0)
        snap_lifted(iter);
    else
        energy = iter.new_energy;
    end_iteration();
    phase_end(iter.t_ls, result.line_search_time);
    result.iterations = iter.index + 1;
    trace_iteration(iter);
}

void DeviceNewton::Impl::NewtonLoop::snap_lifted(const Iteration& iter)
{
    // x_D + (target - x_D) need not round to target: snap so lifting ends exactly, unless the
    // snapped state is invalid (then the rounding stays for one more iteration).
    detail::copy_device_to_device(m.trial.data(), m.x.data(), m.n * sizeof(double));
    if (m.periodic)
        detail::copy_device_to_device(m.trial_q.data(), m.q.data(), nu * sizeof(double));
    if (m.surface)
        detail::copy_device_to_device(m.ys_trial.data(), m.ys.data(), m.ys.size() * sizeof(double));
    snap_to_target<<<Gu, THREADS>>>(nu, fixed, m.u_target().data(), m.u().data());
    check_launch("launch of the lifting snap");
    if (m.periodic)
        m.expand_state(m.q, m.x);
    m.active_current = false;
    energy = m.energy(mesh, m.x.data(), w).total;
    if (!std::isfinite(energy)) {
        m.accept_trial(); // back to the unsnapped state
        energy = iter.new_energy;
    }
}

void DeviceNewton::Impl::NewtonLoop::residual_at_trial(double* rs)
{
    if (contact) {
        contact->update_active(m.contact_positions(m.trial.data()));
        m.active_current = false;
    }
    m.gradient(mesh, m.trial.data(), w, m.g_trial.data());
    m.residual_of_trial(rs);
}

void DeviceNewton::Impl::NewtonLoop::end_iteration()
{
    if (!contact || !hook)
        return;
    m.activate_at_x();
    if (hook()) {
        ++result.kappa_updates;
        energy = m.energy(mesh, m.x.data(), w).total;
    }
}

void DeviceNewton::Impl::NewtonLoop::trace_iteration(const Iteration& iter) const
{
    if (trace)
        std::fprintf(stderr,
            "  device newton %3d: residual %.3e forcing %.1e alpha %.3e energy %.15e step %.2e; totals: pcg %d, "
            "true-Hessian steps %d, cuts %d, kappa updates %d%s\n",
            iter.index, iter.gmax / force_scale, iter.forcing, iter.alpha, energy, result.newton_step,
            result.pcg_iterations, result.true_hessian_steps, result.line_search_cuts, result.kappa_updates,
            last_true ? ", true Hessian" : "");
}

} // namespace diffipc::gpu

namespace diffipc::gpu {

void DeviceNewton::set_periodic(DevicePeriodicMap* map, const std::vector<char>& fixed_q)
{
    Impl& m = *m_impl;
    if (!map)
        throw std::invalid_argument("DeviceNewton::set_periodic: no map");
    if (m_contact)
        throw std::logic_error("DeviceNewton::set_periodic: a contact is set; a periodic cell's contact (on its image "
                               "surface) comes after set_periodic(), by set_periodic_contact()");
    if (map->dim() != m_mesh.dim() || size_t(map->num_vertices()) * size_t(map->dim()) != m.n)
        throw std::invalid_argument("DeviceNewton::set_periodic: the map has " + std::to_string(map->num_vertices())
            + " vertices in " + std::to_string(map->dim()) + "D, the mesh " + std::to_string(m.n) + " dofs");
    const size_t nq = size_t(map->num_reduced());
    if (fixed_q.size() != nq)
        throw std::invalid_argument("DeviceNewton::set_periodic: " + std::to_string(fixed_q.size())
            + " flags, expected the cell's " + std::to_string(nq) + " reduced unknowns");
    m.periodic = map;
    m.nq = nq;
    std::vector<unsigned char> flags(nq);
    for (size_t k = 0; k < nq; ++k)
        flags[k] = fixed_q[k] ? 1 : 0;
    m.fixed_q.upload(flags);
    m.pcg_q.set_fixed_dofs(fixed_q);
    for (auto* v :
        { &m.q, &m.trial_q, &m.longer_q, &m.target_q, &m.g_q, &m.g_trial_q, &m.p_q, &m.pD_q, &m.rhs_q, &m.coupling_q })
        v->resize(nq);
}

void DeviceNewton::set_periodic_contact(DeviceContact* contact, DevicePeriodicMap* surface)
{
    Impl& m = *m_impl;
    if (!m.periodic)
        throw std::logic_error("DeviceNewton::set_periodic_contact: set_periodic() first");
    if (!contact || !surface)
        throw std::invalid_argument("DeviceNewton::set_periodic_contact: no contact or no surface map");
    if (surface->dim() != m.periodic->dim() || surface->num_classes() != m.periodic->num_classes())
        throw std::invalid_argument("DeviceNewton::set_periodic_contact: the surface map has "
            + std::to_string(surface->num_classes()) + " classes in " + std::to_string(surface->dim()) + "D, the cell "
            + std::to_string(m.periodic->num_classes()));
    const size_t ns = size_t(surface->num_vertices()) * size_t(surface->dim());
    if (size_t(contact->num_dofs()) != ns)
        throw std::invalid_argument("DeviceNewton::set_periodic_contact: the contact has "
            + std::to_string(contact->num_dofs()) + " dofs, the surface map " + std::to_string(ns));
    if (m_friction)
        throw std::logic_error("DeviceNewton::set_periodic_contact: no friction across a cell's boundary yet");
    m.surface = surface;
    for (auto* v : { &m.ys, &m.ys_trial, &m.ys_longer, &m.gc, &m.ps })
        v->resize(ns);
    m.gc.set_zero();
    m.gc_q.resize(m.nq);
    m.p_q_scaled.resize(m.nq);
    m_contact = contact;
    m.contact = contact;
    m.active_current = false;
}

ContactBalance DeviceNewton::balance_at_periodic(const std::vector<double>& q_host,
    const std::vector<double>& inertial_target, double weight, const std::vector<double>& force)
{
    Impl& m = *m_impl;
    if (!m.periodic || !m.surface)
        throw std::logic_error("DeviceNewton::balance_at_periodic: set_periodic_contact() first");
    if (q_host.size() != m.nq || force.size() != m.n || (m.dynamic && inertial_target.size() != m.n))
        throw std::invalid_argument("DeviceNewton::balance_at_periodic: q needs the cell's " + std::to_string(m.nq)
            + " unknowns, force and inertial_target #dofs = " + std::to_string(m.n));
    m.q.upload(q_host);
    m.expand_state(m.q, m.x);
    m.take_terms(m_contact, inertial_target, weight, force);
    m.activate_at_x();
    return m.balance(m_mesh, weight);
}

void DeviceNewton::set_contact(DeviceContact* contact)
{
    if (contact && m_impl->periodic)
        throw std::logic_error("DeviceNewton::set_contact: a periodic cell's contact runs on its image surface: "
                               "set_periodic_contact()");
    if (contact && size_t(contact->num_dofs()) != m_impl->n)
        throw std::invalid_argument("DeviceNewton::set_contact: the contact has " + std::to_string(contact->num_dofs())
            + " dofs, the mesh " + std::to_string(m_impl->n));
    m_contact = contact;
    m_impl->contact = contact;
    m_impl->active_current = false;
}

void DeviceNewton::set_friction(DeviceFriction* friction)
{
    if (friction && m_impl->periodic)
        throw std::logic_error("DeviceNewton::set_friction: no friction in a periodic cell on the device yet");
    if (friction && size_t(friction->num_dofs()) != m_impl->n)
        throw std::invalid_argument("DeviceNewton::set_friction: the friction has "
            + std::to_string(friction->num_dofs()) + " dofs, the mesh " + std::to_string(m_impl->n));
    if (friction && !m_contact)
        throw std::logic_error("DeviceNewton::set_friction: friction needs the contact (set_contact() first)");
    m_friction = friction;
    m_impl->friction = friction;
}

double DeviceNewton::residual_at(const std::vector<double>& x, const std::vector<double>& inertial_target,
    double weight, const std::vector<double>& force)
{
    Impl& m = *m_impl;
    m.load_state("residual_at", m_contact, x, inertial_target, weight, force);
    m.gradient(m_mesh, m.x.data(), weight, m.g_trial.data());
    double rs[2];
    m.residual_of_trial(rs);
    return rs[1] != 0 ? std::numeric_limits<double>::quiet_NaN() : rs[0];
}

ContactBalance DeviceNewton::current_balance() { return m_impl->balance(m_mesh, m_impl->w); }

ContactBalance DeviceNewton::balance_at(const std::vector<double>& x, const std::vector<double>& inertial_target,
    double weight, const std::vector<double>& force)
{
    Impl& m = *m_impl;
    m.load_state("balance_at", m_contact, x, inertial_target, weight, force);
    return m.balance(m_mesh, weight);
}

} // namespace diffipc::gpu
