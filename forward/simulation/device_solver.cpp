#include "forward/simulation/device_solver.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/contact/barrier.hpp"

#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#ifdef DIFFIPC_HAVE_CUDA
#include "forward/simulation/device_conversion.hpp"

#include "cuda/common/device.hpp"
#include "cuda/contact/device_contact.hpp"
#include "cuda/contact/device_friction.hpp"
#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/periodic/device_periodic_map.hpp"
#include "cuda/solver/device_newton.hpp"
#endif

#include <algorithm>
#include <cstring>
#include <limits>
#include <tuple>

namespace diffipc {

#ifdef DIFFIPC_HAVE_CUDA

namespace {
    std::vector<double> to_std(const VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

    // DeviceStepStatus has StepStatus's numbers (device_newton.hpp).
    StepStatus to_status(gpu::DeviceStepStatus s) { return StepStatus(int(s)); }

    /// ContactPotential::end_iteration's state of the adaptive stiffness.
    struct AdaptiveState {
        DeviceSolver::AdaptiveKappa params;
        bool rule_applied = false;
        double previous_gap2 = -1;
    };
} // namespace

gpu::CollisionMeshData to_device(const CollisionMesh& m)
{
    gpu::CollisionMeshData d;
    d.dim = m.dim;
    d.num_vertices = int(m.num_vertices);
    d.vertices.assign(m.vertices.data(), m.vertices.data() + m.vertices.size());
    // MatrixXi is row-major: edge e is (data[2e], data[2e + 1]).
    d.edges.assign(m.edges.data(), m.edges.data() + m.edges.size());
    if (m.dim == 3)
        d.faces.assign(m.faces.data(), m.faces.data() + m.faces.size());
    d.vertex_group = m.vertex_group;
    d.group_self_contact = m.group_self_contact;
    d.group_kinematic = m.group_kinematic;
    d.point = m.point;
    d.edge_source.assign(m.edge_source.begin(), m.edge_source.end());
    d.edge_shift_positive = m.edge_shift_positive;
    return d;
}

std::vector<gpu::PlaneObstacle> to_device(const std::vector<ContactPlane>& planes)
{
    std::vector<gpu::PlaneObstacle> out;
    for (const ContactPlane& p : planes) {
        gpu::PlaneObstacle g;
        g.vertex = int(p.vertex);
        for (int k = 0; k < 3; ++k)
            g.normal[k] = p.normal[k];
        out.push_back(g);
    }
    return out;
}

gpu::DeviceContactSettings to_device(const ContactSettings& cs)
{
    gpu::DeviceContactSettings s;
    s.kappa = cs.kappa;
    s.dhat = cs.dhat;
    s.min_distance = cs.min_distance;
    s.ccd_max_iterations = cs.ccd_max_iterations;
    s.ccd_rescaling = cs.ccd_rescaling;
    s.penalty = cs.penalty;
    return s;
}

std::pair<gpu::BarrierPair, gpu::FrictionPair> to_device(const FrictionContact& c)
{
    gpu::BarrierPair pair;
    pair.kind = int(c.kind);
    for (int a = 0; a < 4; ++a)
        pair.vertices[a] = a < c.num_vertices ? int(c.vertices[size_t(a)]) : -1;
    pair.plane = c.kind == ContactKind::VERTEX_PLANE ? c.source.plane : -1;
    return { pair, friction_pair(c) };
}

struct DeviceSolver::Impl {
    gpu::DeviceElasticMesh mesh;
    std::unique_ptr<gpu::DeviceContact> contact;
    std::unique_ptr<gpu::DeviceFriction> friction; // made by the first set_friction()
    std::unique_ptr<gpu::DeviceNewton> newton;
    std::unique_ptr<gpu::DevicePeriodicMap> periodic; // set_periodic()
    std::unique_ptr<gpu::DevicePeriodicMap> surface; // with contact across the cell's boundary
    bool proximal = false; // in solve_proximal
    std::vector<double> surface_rest; // T X: the image surface's rest positions (empty without images)
    std::vector<double> rest;
    std::vector<double> x, target, inertial_target, force;
    AdaptiveState adaptive;
    double weight = 1;
    bool dynamic = false; // made with an inertia (its masses are the integrator's)
    gpu::DeviceContactTimes profiled; // the contact's times already added to the profile
    mutable gpu::DeviceArray<double> scratch; // a host state uploaded for contacts() / min_distance()
    // The last contacts(x): the lagging at a step's end, its record and the next step's lagging ask for
    // the same x (the active set depends on x alone).
    mutable VectorXd contacts_x;
    mutable ContactSet contacts_at_x;

    /// IPC's balancing rule at the solve's current iterate (Simulator::balancing_kappa).
    double balancing_kappa(const gpu::ContactBalance& b) const
    {
        return initial_barrier_stiffness(b.gb_ge / weight, b.gb_gb, adaptive.params.kappa_min);
    }

    /// ContactPotential::end_iteration with the device's active set: true if kappa changed.
    bool end_iteration()
    {
        if (!adaptive.params.enabled)
            return false;
        const double kappa = contact->kappa();
        if (!adaptive.rule_applied && contact->num_active() > 0) {
            // Contact appeared during this step: balance the barrier now.
            adaptive.rule_applied = true;
            adaptive.previous_gap2 = -1;
            const double k
                = std::min(std::max(kappa, balancing_kappa(newton->current_balance())), adaptive.params.kappa_max);
            if (k != kappa) {
                contact->set_kappa(k);
                return true;
            }
            return false;
        }
        const double gap2 = contact->min_active_gap_squared();
        const double previous = adaptive.previous_gap2;
        adaptive.previous_gap2 = gap2;
        if (previous < 0)
            return false;
        const double k = update_barrier_stiffness(
            previous, gap2, kappa, adaptive.params.kappa_max, adaptive.params.bbox_diagonal, /*dmin=*/0.0);
        if (k == kappa)
            return false;
        contact->set_kappa(k);
        return true;
    }

    /// A solve's terms as the device Newton takes them: the weight, the force and the inertial target
    /// (zeros when static: the Newton ignores it then).
    void set_terms(double w, const VectorXd& inertial_target, const VectorXd& f)
    {
        weight = w;
        force.assign(f.data(), f.data() + f.size());
        if (inertial_target.size() == f.size())
            this->inertial_target.assign(inertial_target.data(), inertial_target.data() + inertial_target.size());
        else
            this->inertial_target.assign(size_t(f.size()), 0.0);
    }

    const double* upload(const VectorXd& x) const
    {
        scratch.upload(x.data(), size_t(x.size()));
        return scratch.data();
    }
};

bool DeviceSolver::available(std::string* why)
{
    if (gpu::cuda_device_available())
        return true;
    if (why)
        *why = gpu::cuda_device_description();
    return false;
}

std::string DeviceSolver::describe_device() { return gpu::cuda_device_description(); }

DeviceSolver::DeviceSolver(const ElasticPotential& elastic, const InertiaPotential* inertia,
    const std::vector<char>& constrained, const ContactPotential* contact)
    : m_impl(std::make_unique<Impl>())
    , m_cpu_contact(contact)
{
    std::string why;
    if (!available(&why))
        throw InputError("device", "\"gpu\" needs a CUDA device, and none is usable here (" + why + ")");
    const Mesh& mesh = elastic.space().mesh();
    const int dim = mesh.dim;
    std::vector<double> rest(size_t(mesh.num_dofs()));
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        for (int a = 0; a < dim; ++a)
            rest[size_t(v * dim + a)] = mesh.rest_positions(v, a);
    std::vector<int> elements(size_t(mesh.num_elements() * (dim + 1)));
    for (Index e = 0; e < mesh.num_elements(); ++e)
        for (int a = 0; a <= dim; ++a)
            elements[size_t(e * (dim + 1) + a)] = int(mesh.elements(e, a));
    m_impl->mesh.upload(dim, rest, elements, elastic.models(), to_std(elastic.mu()), to_std(elastic.lambda()));
    m_impl->rest = rest;
    std::vector<double> mass;
    if (inertia) {
        const VectorXd& lumped = inertia->lumped_masses();
        mass.resize(size_t(mesh.num_dofs()));
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            for (int a = 0; a < dim; ++a)
                mass[size_t(v * dim + a)] = lumped[v];
    }
    m_impl->newton = std::make_unique<gpu::DeviceNewton>(m_impl->mesh, mass);
    m_impl->dynamic = inertia != nullptr;
    if (inertia && inertia->consistent()) {
        // The consistent mass matrix (#dofs square, the mesh's element couplings) in place of the lumped one.
        const SparseMatrixd& M = inertia->consistent_matrix();
        std::vector<int> rows, cols;
        std::vector<double> values;
        for (Index j = 0; j < M.outerSize(); ++j)
            for (SparseMatrixd::InnerIterator it(M, j); it; ++it) {
                rows.push_back(int(it.row()));
                cols.push_back(int(it.col()));
                values.push_back(it.value());
            }
        m_impl->newton->set_consistent_mass(rows, cols, values);
    }
    m_impl->newton->set_constrained(constrained);
    // The CPU's energy measures the external work from the rest positions and its round-off
    // allowance counts the neo-Hookean models' cancelling terms: the same here.
    m_impl->newton->set_force_reference(rest);
    m_impl->newton->set_material_scale(elastic.models(), to_std(elastic.mu()));
    if (contact) {
        // With periodic images the contact runs on the image surface (rest positions T X); set_periodic()
        // hands it to the Newton with the surface's map.
        if (contact->has_images()) {
            const VectorXd surface_rest
                = contact->images() * Eigen::Map<const VectorXd>(rest.data(), Index(rest.size()));
            m_impl->surface_rest = to_std(surface_rest);
        }
        m_impl->contact = std::make_unique<gpu::DeviceContact>(to_device(contact->collision_mesh()),
            contact->has_images() ? m_impl->surface_rest : rest, to_device(contact->planes()),
            to_device(contact->settings()));
        if (!contact->has_images())
            m_impl->newton->set_contact(m_impl->contact.get());
        m_impl->newton->set_end_iteration([impl = m_impl.get()]() { return impl->end_iteration(); });
    }
}

void DeviceSolver::begin_step(double kappa, const AdaptiveKappa& adaptive, const VectorXd& x,
    const VectorXd& inertial_target, double weight, const VectorXd& force, const VectorXd* q)
{
    Impl& d = *m_impl;
    if (!d.contact)
        return;
    d.contact->reset_times();
    d.profiled = {};
    d.contact->set_kappa(kappa);
    d.adaptive = AdaptiveState {};
    d.adaptive.params = adaptive;
    d.weight = weight;
    if (!adaptive.enabled)
        return;
    if (d.surface && !q)
        throw std::logic_error("DeviceSolver::begin_step: a periodic cell with contact balances at its unknowns q");
    const std::vector<double> xt
        = inertial_target.size() == x.size() ? to_std(inertial_target) : std::vector<double>(size_t(x.size()), 0.0);
    const gpu::ContactBalance b = d.surface ? d.newton->balance_at_periodic(to_std(*q), xt, weight, to_std(force))
                                            : d.newton->balance_at(to_std(x), xt, weight, to_std(force));
    const bool active = b.active > 0;
    if (active)
        d.contact->set_kappa(std::max(kappa, d.balancing_kappa(b)));
    d.adaptive.rule_applied = active;
}

double DeviceSolver::kappa() const { return m_impl->contact ? m_impl->contact->kappa() : 0.0; }

void DeviceSolver::set_kappa(double kappa)
{
    if (m_impl->contact)
        m_impl->contact->set_kappa(kappa);
}

bool DeviceSolver::adaptive_rule_applied() const { return m_impl->adaptive.rule_applied; }

ContactSet DeviceSolver::contacts(const VectorXd& x) const
{
    ContactSet out;
    if (!m_impl->contact)
        return out;
    Impl& d = *m_impl;
    if (d.contacts_x.size() == x.size()
        && std::memcmp(d.contacts_x.data(), x.data(), size_t(x.size()) * sizeof(double)) == 0)
        return d.contacts_at_x;
    const Timer timer;
    const VectorXd y = m_cpu_contact->surface_positions(x); // the positions the pairs index
    m_impl->contact->update_active(m_impl->upload(y));
    const std::vector<gpu::BarrierPair>& pairs = m_impl->contact->active_pairs();
    out.resize(pairs.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, pairs.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k < r.end(); ++k) {
            const gpu::BarrierPair& p = pairs[k];
            out[k] = m_cpu_contact->classify(
                ContactKind(p.kind), { p.vertices[0], p.vertices[1], p.vertices[2], p.vertices[3] }, p.plane, y);
        }
    });
    d.contacts_x = x;
    d.contacts_at_x = out;
    timer.add_to(m_profile.contact_sets);
    ++m_profile.contact_set_count;
    return out;
}

void DeviceSolver::set_friction(const FrictionPotential& friction)
{
    Impl& d = *m_impl;
    if (!d.contact)
        throw std::logic_error("DeviceSolver::set_friction: friction needs the scene's contact");
    const Timer timer;
    if (friction.has_images())
        throw InputError("device", "\"gpu\" has no friction across periodic images; use \"cpu\"");
    if (!d.friction) {
        d.friction = std::make_unique<gpu::DeviceFriction>();
        d.friction->upload(d.mesh.dim(), d.rest, int(m_cpu_contact->planes().size()));
        d.newton->set_friction(d.friction.get());
    }
    const std::vector<FrictionContact>& lagged = friction.lagged();
    std::vector<gpu::BarrierPair> pairs(lagged.size());
    std::vector<gpu::FrictionPair> data(lagged.size());
    for (size_t k = 0; k < lagged.size(); ++k)
        std::tie(pairs[k], data[k]) = to_device(lagged[k]);
    d.friction->set_pairs(pairs, data);
    d.friction->set_step_start(to_std(friction.step_start()), friction.eps());
    timer.add_to(m_profile.friction_uploads);
    ++m_profile.friction_upload_count;
}

double DeviceSolver::residual(const VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force)
{
    const std::vector<double> xt
        = inertial_target.size() == x.size() ? to_std(inertial_target) : std::vector<double>(size_t(x.size()), 0.0);
    m_impl->weight = weight;
    return m_impl->newton->residual_at(to_std(x), xt, weight, to_std(force));
}

double DeviceSolver::min_distance(const VectorXd& x, double radius) const
{
    if (!m_impl->contact)
        return std::numeric_limits<double>::infinity();
    return m_impl->contact->min_distance(m_impl->upload(m_cpu_contact->surface_positions(x)), radius);
}

ContactTimes DeviceSolver::contact_times() const
{
    ContactTimes t;
    if (m_impl->contact) {
        const gpu::DeviceContactTimes& d = m_impl->contact->times();
        t.broad_phase = d.broad_phase;
        t.ccd = d.ccd;
        t.barrier = d.barrier;
    }
    return t;
}

DeviceSolver::~DeviceSolver() = default;

namespace {

    /// NewtonSettings as the device Newton takes them, with the linear solves' forcing capped where the
    /// scene's terms need it (friction, the penalty: the comments say why).
    gpu::DeviceNewtonSettings device_settings(
        const NewtonSettings& settings, const gpu::DeviceFriction* friction, const gpu::DeviceContact* contact)
    {
        gpu::DeviceNewtonSettings s;
        s.residual_tolerance = settings.residual_tolerance;
        s.max_iterations = settings.max_iterations;
        s.line_search_max_halvings = settings.line_search_max_halvings;
        s.armijo = settings.armijo;
        s.max_displacement = settings.max_displacement;
        s.adaptive_projection = settings.adaptive_projection;
        s.step_extension = settings.step_extension;
        // Sticking friction's tangential stiffness (mu lambda 2 / (eps_v h)) is orders above the elastic one,
        // and block-Jacobi PCG solved to the elastic scenes' loose forcing leaves its modes' error in the
        // direction: 202's head-on boxes with friction stall at NEWTON_EXHAUSTED with forcing_max 0.5 and
        // converge with 0.1 or 0.01; the 53k-tet friction slabs take 7.0 Newton iterations per step with 0.5,
        // 5.0 with 0.1 and 4.5 with 0.01, the fastest (docs/performance.md).
        constexpr double FRICTION_FORCING_MAX = 0.01;
        if (friction && friction->num_pairs() > 0)
            s.forcing_max = std::min(s.forcing_max, FRICTION_FORCING_MAX);
        // The penalty has no CCD to bound a step: a loose direction that leaves the stiff penalty modes
        // unresolved steps vertices through the surfaces they press on, where the penalty on the unsigned
        // distance then holds them on the wrong side. Rings settling onto each other (PenaltyContact) pass
        // through in 4 of 10 GPU steps with forcing_max 0.5 and in none with 0.01, as on the CPU, whose
        // trajectory the GPU's then follows to 4e-11 (with fewer Newton iterations: 52 against 86).
        constexpr double PENALTY_FORCING_MAX = 0.01;
        if (contact && contact->settings().penalty)
            s.forcing_max = std::min(s.forcing_max, PENALTY_FORCING_MAX);
        return s;
    }

    /// The lifting's relative tolerance where a lifted step passes only with the free unknowns' accurate
    /// response in the same iteration (DeviceNewtonSettings::lifting_forcing_max). A Dirichlet boundary's
    /// lifting in a plain solve moves boundary vertices that the rest follows over the next iterations.
    /// But a periodic cell's step of G moves the whole tiling and presses its posts on the next cell's
    /// at once: with the loose forcing (0.5: one block-Jacobi iteration) the fluctuation's response stayed
    /// local, the CCD cut every lifting step (alpha 1e-3 .. 1e-11) and the post cell under compression
    /// ended CCD_UNRESOLVED with its residual grown to 2.5e7 (test PeriodicCellWithContactAcrossTheBoundary;
    /// study 210 stalled at its step 19). And a proximal solve of load stepping's relaxation holds every
    /// free vertex near its last position with an element's stiffness while the boundary is lifted to the
    /// step's end (study 209's step 20: every proximal solve failed, from the start's weight to 1e6 times
    /// it, where the CPU's exact solves relaxed).
    constexpr double TIGHT_LIFTING_FORCING = 1e-6;

    /// The device solve's result as NewtonResult (NewtonSolver::solve's meaning of every field).
    NewtonResult host_result(const gpu::DeviceNewtonResult& r)
    {
        NewtonResult result;
        result.status = to_status(r.status);
        result.iterations = r.iterations;
        result.residual = r.residual;
        result.newton_step = r.newton_step;
        result.line_search_cuts = r.line_search_cuts;
        result.roundoff_limited = r.roundoff_limited;
        result.gradient_steps = r.gradient_steps;
        result.extended_steps = r.extended_steps;
        result.true_hessian_steps = r.true_hessian_steps;
        result.times.assembly = r.assembly_time;
        result.times.solve = r.solve_time;
        result.times.line_search = r.line_search_time;
        return result;
    }

} // namespace

void DeviceSolver::set_periodic(const PeriodicCell& cell, const std::vector<int>& image_classes)
{
    Impl& d = *m_impl;
    const PeriodicMap& map = cell.map();
    const VectorXi& classes = cell.pairing().vertex_class;
    const std::vector<double> origin(map.origin().data(), map.origin().data() + map.dim());
    d.periodic = std::make_unique<gpu::DevicePeriodicMap>(
        map.dim(), std::vector<int>(classes.data(), classes.data() + classes.size()), d.rest, origin, map.length());
    d.newton->set_periodic(d.periodic.get(), cell.constrained());
    if (d.contact) {
        if (d.surface_rest.empty() || image_classes.size() * size_t(map.dim()) != d.surface_rest.size())
            throw std::logic_error("DeviceSolver::set_periodic: the contact needs its image surface's classes");
        // The image surface's positions T (X + P q) = X_s + P_s q: a periodic map of its own
        // (cuda/README.md, "Periodic cells on the device").
        d.surface
            = std::make_unique<gpu::DevicePeriodicMap>(map.dim(), image_classes, d.surface_rest, origin, map.length());
        d.newton->set_periodic_contact(d.contact.get(), d.surface.get());
    }
}

NewtonResult DeviceSolver::solve_periodic(VectorXd& q, const VectorXd& target, const VectorXd& inertial_target,
    double weight, const VectorXd& force, double force_scale, double step_scale, const NewtonSettings& settings)
{
    Impl& d = *m_impl;
    gpu::DeviceNewtonSettings s = device_settings(settings, d.friction.get(), d.contact.get());
    if (d.surface) // contact across the cell's boundary
        s.lifting_forcing_max = TIGHT_LIFTING_FORCING;
    d.set_terms(weight, inertial_target, force);
    std::vector<double> q_host(q.data(), q.data() + q.size());
    const gpu::DeviceNewtonResult r
        = d.newton->solve_periodic(q_host, std::vector<double>(target.data(), target.data() + target.size()),
            d.inertial_target, weight, d.force, force_scale, step_scale, s);
    NewtonResult result = host_result(r);
    account(r);
    if (result.status == StepStatus::CONVERGED)
        q = Eigen::Map<const VectorXd>(q_host.data(), q.size());
    return result;
}

NewtonResult DeviceSolver::solve(VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force,
    const VectorXd& target, double force_scale, double step_scale, const NewtonSettings& settings, LoadControl* control)
{
    Impl& d = *m_impl;
    if (!d.surface_rest.empty())
        throw std::logic_error("DeviceSolver::solve: a periodic cell's contact (on its image surface) solves through "
                               "set_periodic() and solve_periodic()");
    gpu::DeviceNewtonSettings s = device_settings(settings, d.friction.get(), d.contact.get());
    if (d.proximal)
        s.lifting_forcing_max = TIGHT_LIFTING_FORCING;
    d.set_terms(weight, inertial_target, force);
    d.x.assign(x.data(), x.data() + x.size());
    d.target.assign(target.data(), target.data() + target.size());
    std::optional<gpu::DeviceLoadControl> device_control;
    if (control) {
        device_control.emplace();
        device_control->direction.assign(
            control->direction.data(), control->direction.data() + control->direction.size());
        device_control->level = control->level;
        device_control->tolerance = control->tolerance;
        ++m_control_solves;
    }
    const gpu::DeviceNewtonResult r = d.newton->solve(d.x, d.inertial_target, weight, d.force, d.target, force_scale,
        step_scale, s, device_control ? &*device_control : nullptr);
    if (control)
        control->multiplier = device_control->multiplier;
    NewtonResult result = host_result(r);
    account(r);
    if (result.status == StepStatus::CONVERGED)
        x = Eigen::Map<const VectorXd>(d.x.data(), Index(d.x.size()));
    return result;
}

void DeviceSolver::account(const gpu::DeviceNewtonResult& r)
{
    Impl& d = *m_impl;
    m_last_pcg_iterations = r.pcg_iterations;
    m_total_pcg_iterations += r.pcg_iterations;
    if (!d.contact)
        return;
    // Times since begin_step() (which resets them), added after each solve.
    const gpu::DeviceContactTimes& t = d.contact->times();
    m_profile.active_sets += t.active_sets - d.profiled.active_sets;
    m_profile.energies += t.energies - d.profiled.energies;
    m_profile.active_set_count += t.active_set_count - d.profiled.active_set_count;
    m_profile.energy_count += t.energy_count - d.profiled.energy_count;
    m_profile.max_active = std::max(m_profile.max_active, d.contact->num_active());
    d.profiled = t;
}

NewtonResult DeviceSolver::solve_proximal(VectorXd& x, const VectorXd& center, double proximal_weight,
    const VectorXd& lumped_masses, double weight, const VectorXd& force, const VectorXd& target, double force_scale,
    double step_scale, const NewtonSettings& settings)
{
    Impl& d = *m_impl;
    if (d.dynamic)
        throw std::logic_error("DeviceSolver::solve_proximal: a dynamic scene's inertia is its integrator's");
    const int dim = d.mesh.dim();
    if (lumped_masses.size() * Index(dim) != x.size() || center.size() != x.size())
        throw std::invalid_argument("DeviceSolver::solve_proximal: " + std::to_string(lumped_masses.size())
            + " masses and a centre of " + std::to_string(center.size()) + " entries for " + std::to_string(x.size())
            + " dofs in " + std::to_string(dim) + "D");
    if (!(proximal_weight > 0) || !std::isfinite(proximal_weight))
        throw std::invalid_argument("DeviceSolver::solve_proximal: the proximal weight must be positive and finite");
    std::vector<double> mass(size_t(x.size()));
    for (Index i = 0; i < x.size(); ++i)
        mass[size_t(i)] = proximal_weight * lumped_masses[i / dim];
    struct Static { // the device is static again however the solve ends
        Impl& d;
        ~Static()
        {
            d.newton->set_lumped_mass({});
            d.proximal = false;
        }
    } restore { d };
    d.newton->set_lumped_mass(mass);
    d.proximal = true;
    ++m_proximal_solves;
    return solve(x, center, weight, force, target, force_scale, step_scale, settings);
}

void DeviceSolver::set_adjoint_multigrid(bool on)
{
    // The plan's threads follow the process's configuration (docs/threads.md).
    m_impl->newton->set_adjoint_multigrid(on, std::max(1, thread_config().threads));
}

bool DeviceSolver::solve_adjoint(
    const VectorXd& x, double weight, const VectorXd& b, VectorXd& y, int* iterations, double kappa, VectorXd* coupling)
{
    if (m_impl->contact)
        m_impl->contact->set_kappa(kappa);
    // The adjoint of the tests' gradient checks needs 1e-6 relative agreement with the CPU's direct
    // solve: 1e-12 relative residual leaves the solution's error far below that on conditioned steps.
    constexpr double TOLERANCE = 1e-12;
    std::vector<double> out, product;
    const gpu::PcgResult r = m_impl->newton->solve_true_hessian(
        to_std(x), weight, to_std(b), out, TOLERANCE, 50 * int(x.size()) + 100, coupling ? &product : nullptr);
    if (iterations)
        *iterations = r.iterations;
    if (!r.converged || r.breakdown)
        return false;
    y = Eigen::Map<const VectorXd>(out.data(), Index(out.size()));
    if (coupling)
        *coupling = Eigen::Map<const VectorXd>(product.data(), Index(product.size()));
    return y.allFinite() && (!coupling || coupling->allFinite());
}

#else // no CUDA in this build

struct DeviceSolver::Impl { };

bool DeviceSolver::available(std::string* why)
{
    if (why)
        *why = "this build has no CUDA (configure with nvcc present, or -DDIFFIPC_CUDA=ON)";
    return false;
}

std::string DeviceSolver::describe_device()
{
    std::string why;
    available(&why);
    return why;
}

DeviceSolver::DeviceSolver(
    const ElasticPotential&, const InertiaPotential*, const std::vector<char>&, const ContactPotential*)
{
    std::string why;
    available(&why);
    throw InputError("device", "\"gpu\" is not available: " + why);
}

DeviceSolver::~DeviceSolver() = default;

NewtonResult DeviceSolver::solve(VectorXd&, const VectorXd&, double, const VectorXd&, const VectorXd&, double, double,
    const NewtonSettings&, LoadControl*)
{
    return {};
}

NewtonResult DeviceSolver::solve_proximal(VectorXd&, const VectorXd&, double, const VectorXd&, double, const VectorXd&,
    const VectorXd&, double, double, const NewtonSettings&)
{
    return {};
}

bool DeviceSolver::solve_adjoint(const VectorXd&, double, const VectorXd&, VectorXd&, int*, double, VectorXd*)
{
    return false;
}

void DeviceSolver::set_adjoint_multigrid(bool) { }

void DeviceSolver::set_periodic(const PeriodicCell&, const std::vector<int>&) { }

NewtonResult DeviceSolver::solve_periodic(
    VectorXd&, const VectorXd&, const VectorXd&, double, const VectorXd&, double, double, const NewtonSettings&)
{
    return {};
}

void DeviceSolver::begin_step(
    double, const AdaptiveKappa&, const VectorXd&, const VectorXd&, double, const VectorXd&, const VectorXd*)
{
}

double DeviceSolver::kappa() const { return 0.0; }

void DeviceSolver::set_kappa(double) { }

bool DeviceSolver::adaptive_rule_applied() const { return false; }

ContactSet DeviceSolver::contacts(const VectorXd&) const { return {}; }

void DeviceSolver::set_friction(const FrictionPotential&) { }

double DeviceSolver::residual(const VectorXd&, const VectorXd&, double, const VectorXd&) { return 0.0; }

double DeviceSolver::min_distance(const VectorXd&, double) const { return 0.0; }

ContactTimes DeviceSolver::contact_times() const { return {}; }

#endif

} // namespace diffipc
