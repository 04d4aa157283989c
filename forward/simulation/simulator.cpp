#include "forward/simulation/simulator.hpp"

#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"

#include "forward/contact/barrier.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/periodic/contact_images.hpp"
#include "forward/solver/newton.hpp"
#include <Eigen/Geometry>

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

Simulator::Simulator(Scene scene)
    : Simulator(std::move(scene), SimulationParameters {})
{
}

namespace {

    void check_size(const VectorXd& v, Index n, const std::string& field, const std::string& what)
    {
        if (v.size() != 0 && v.size() != n)
            throw InputError(
                field, "expected " + std::to_string(n) + " values (" + what + "), got " + std::to_string(v.size()));
        if (!v.allFinite())
            throw InputError(field, "non-finite value");
    }

    /// The sizes and values of the parameter overrides that do not depend on the built problem.
    void check_parameters(const SimulationParameters& P, Index n, Index ne, int groups)
    {
        check_size(P.rest_positions, n, "rest_positions", "#V*dim");
        check_size(P.mu, ne, "mu", "one per element");
        check_size(P.lambda, ne, "lambda", "one per element");
        check_size(P.youngs_modulus, ne, "E", "one per element");
        check_size(P.poisson_ratio, ne, "nu", "one per element");
        check_size(P.density, ne, "density", "one per element");
        check_size(P.friction, Index(groups), "friction", "one per body and obstacle");
        check_size(P.initial_displacement, n, "initial_displacement", "#V*dim");
        check_size(P.initial_velocity, n, "initial_velocity", "#V*dim");
        if (!P.prescribed.allFinite())
            throw InputError("prescribed", "non-finite value");
        if (!(P.kappa >= 0) || !std::isfinite(P.kappa))
            throw InputError("kappa", "must be a positive finite barrier stiffness (or 0 for the scene's)");
    }

    double element_det(const Positions& X, const MatrixXi& elements, Index e, int d)
    {
        Eigen::MatrixXd Dm(d, d);
        for (int a = 0; a < d; ++a)
            Dm.col(a) = (X.row(elements(e, a + 1)) - X.row(elements(e, 0))).transpose();
        return Dm.determinant();
    }

    /// Each element's law and parameters: its body's material, or the overrides where given.
    struct ElementMaterials {
        std::vector<MaterialModel> models;
        std::vector<char> plane_stress;
        VectorXd mu, lambda, density;
        double mean_youngs_modulus = 0;
    };

    ElementMaterials element_materials(const Scene& scene, const SimulationParameters& P)
    {
        const Mesh& mesh = scene.mesh;
        const int d = mesh.dim;
        const Index ne = mesh.num_elements();
        ElementMaterials out;
        out.models.resize(size_t(ne));
        out.plane_stress.assign(size_t(ne), 0);
        out.mu.resize(ne);
        out.lambda.resize(ne);
        out.density.resize(ne);
        VectorXd &mu = out.mu, &lambda = out.lambda, &density = out.density;
        for (Index e = 0; e < ne; ++e) {
            const MaterialSpec& m = scene.bodies[size_t(mesh.element_body[e])].material;
            out.models[size_t(e)] = m.model;
            out.plane_stress[size_t(e)] = m.plane_stress;
            const double E = P.youngs_modulus.size() ? P.youngs_modulus[e] : m.youngs_modulus;
            const double nu = P.poisson_ratio.size() ? P.poisson_ratio[e] : m.poisson_ratio;
            if (!(E > 0))
                throw InputError("E[" + std::to_string(e) + "]", "Young's modulus must be positive");
            if (!(nu > -1 && nu < 0.5))
                throw InputError("nu[" + std::to_string(e) + "]", "Poisson's ratio must lie in (-1, 0.5)");
            mu[e] = P.mu.size() ? P.mu[e] : lame_mu(E, nu);
            lambda[e] = P.lambda.size() ? P.lambda[e] : lame_lambda(E, nu, m.plane_stress);
            if (!(mu[e] > 0))
                throw InputError("mu[" + std::to_string(e) + "]", "the shear modulus must be positive");
            if (!(lambda[e] > -2.0 / d * mu[e]))
                throw InputError(
                    "lambda[" + std::to_string(e) + "]", "the bulk modulus lambda + 2 mu / dim must be positive");
            density[e] = P.density.size() ? P.density[e] : m.density;
            if (!(density[e] > 0))
                throw InputError("density[" + std::to_string(e) + "]", "must be positive");
            out.mean_youngs_modulus += E / double(ne);
        }
        return out;
    }

} // namespace

Simulator::Simulator(Scene scene, const SimulationParameters& parameters)
    : m_scene(std::move(scene))
    , m_overrides(parameters)
{
    ensure_threads_configured();
    if (m_scene.solver.threads > 0)
        set_threads(m_scene.solver.threads, ThreadSource::SCENE_FILE, "solver.threads of " + m_scene.source);
    check_parameters(m_overrides, m_scene.mesh.num_dofs(), m_scene.mesh.num_elements(), num_groups());
    // Regions and boundary expressions stay tied to the scene's own rest positions.
    const Positions reference = m_scene.mesh.rest_positions;
    apply_rest_positions(reference);
    if (m_overrides.kappa > 0 && m_scene.contact.enabled) {
        m_scene.contact.kappa = m_overrides.kappa;
        m_scene.contact.adaptive_kappa = false;
    }
    m_space = std::make_unique<FESpace>(m_scene.mesh);
    setup_potentials();
    if (m_scene.contact.enabled) {
        setup_contact();
        setup_friction();
    }
    m_linear = std::make_unique<LinearSolver>(m_scene.solver.linear_solver);
    if (m_scene.periodic.enabled) {
        // forward/periodic/periodic_cell.hpp: each step solves for the fluctuation and G.
        m_periodic = std::make_unique<PeriodicCell>(m_scene, m_problem, m_assembler);
        m_macro = VectorXd::Zero(m_scene.dim * m_scene.dim);
        m_trajectory.macro_dim = m_scene.dim;
    }
    const double tol = 1e-9 * m_bbox_diagonal;
    setup_dirichlet(reference, tol);
    setup_obstacle_motion(reference);
    setup_neumann(reference, tol);
    setup_gravity();
    setup_initial_state();
    if (m_scene.device == DeviceType::GPU)
        setup_device();
}

void Simulator::apply_rest_positions(const Positions& reference)
{
    if (!m_overrides.rest_positions.size())
        return;
    const Mesh& mesh = m_scene.mesh;
    const Positions X = unflatten(m_overrides.rest_positions, mesh.dim);
    for (Index e = 0; e < mesh.num_elements(); ++e) {
        const double before = element_det(reference, mesh.elements, e, mesh.dim),
                     after = element_det(X, mesh.elements, e, mesh.dim);
        if (!(after * before > 0) || !(std::abs(after) > 1e-12 * std::abs(before)))
            throw InputError("rest_positions", "element " + std::to_string(e) + " degenerates or inverts");
    }
    m_scene.mesh.rest_positions = X;
}

void Simulator::setup_potentials()
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    const Index ne = mesh.num_elements();
    const ElementMaterials materials = element_materials(m_scene, m_overrides);
    m_plane_stress = materials.plane_stress;
    double mean_volume = 0;
    for (double v : m_space->rest_volumes())
        mean_volume += v / double(ne);
    m_force_scale = materials.mean_youngs_modulus * std::pow(mean_volume, double(d - 1) / d);
    // The bodies' bounding box: obstacles (a plane's point, a large floor) must not change the scales.
    const auto bodies = mesh.rest_positions.topRows(m_scene.body_vertices);
    const Eigen::RowVectorXd extent = bodies.colwise().maxCoeff() - bodies.colwise().minCoeff();
    m_bbox_diagonal = extent.norm();
    m_elastic = std::make_unique<ElasticPotential>(*m_space, materials.models, materials.mu, materials.lambda);
    m_inertia = std::make_unique<InertiaPotential>(*m_space, materials.density, m_scene.mass == MassType::CONSISTENT);
    m_external = std::make_unique<ExternalForcePotential>(flatten(mesh.rest_positions));
    m_integrator = TimeIntegrator::create(m_scene.time.integrator, m_scene.time.dt);
    const double w = m_integrator->potential_weight();
    if (m_integrator->dynamic())
        m_problem.add(m_inertia.get(), 1.0);
    m_problem.add(m_elastic.get(), w);
    m_problem.add(m_external.get(), w);
    m_assembler.build(d, mesh.num_vertices(), mesh.elements);
}

void Simulator::setup_dirichlet(const Positions& reference, double tol)
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    const Index n = mesh.num_dofs();
    // Later entries override earlier ones on the same dof.
    std::vector<int> owner(size_t(n), -1);
    for (size_t k = 0; k < m_scene.dirichlet.size(); ++k) {
        const DirichletSpec& spec = m_scene.dirichlet[k];
        for (Index v = 0; v < mesh.num_vertices(); ++v) {
            if (mesh.vertex_body[v] != spec.body || !spec.region.contains(reference.row(v).transpose(), tol))
                continue;
            for (int a = 0; a < d; ++a)
                if (spec.displacement[size_t(a)])
                    owner[size_t(v * d + a)] = int(k);
        }
    }
    m_constrained.assign(size_t(n), 0);
    m_prescribing_condition = owner;
    for (Index i = 0; i < n; ++i) {
        if (owner[size_t(i)] < 0)
            continue;
        m_constrained[size_t(i)] = 1;
        Eigen::Vector3d rest = Eigen::Vector3d::Zero(), ref = Eigen::Vector3d::Zero();
        rest.head(d) = mesh.rest_positions.row(i / d).transpose();
        ref.head(d) = reference.row(i / d).transpose();
        m_dirichlet.push_back(
            { i, &*m_scene.dirichlet[size_t(owner[size_t(i)])].displacement[size_t(i % d)], rest, ref });
    }
}

void Simulator::setup_obstacle_motion(const Positions& reference)
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    for (size_t k = 0; k < m_scene.obstacles.size(); ++k) {
        const ObstacleSpec& o = m_scene.obstacles[k];
        for (Index v = o.first_vertex; v < o.first_vertex + o.num_vertices; ++v)
            for (int a = 0; a < d; ++a) {
                const Index i = v * d + a;
                m_constrained[size_t(i)] = 1;
                m_prescribing_condition[size_t(i)] = int(m_scene.dirichlet.size() + k);
                Eigen::Vector3d rest = Eigen::Vector3d::Zero(), ref = Eigen::Vector3d::Zero();
                rest.head(d) = mesh.rest_positions.row(v).transpose();
                ref.head(d) = reference.row(v).transpose();
                m_dirichlet.push_back({ i, &o.motion[size_t(a)], rest, ref });
            }
    }
}

void Simulator::setup_neumann(const Positions& reference, double tol)
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    for (size_t k = 0; k < m_scene.neumann.size(); ++k) {
        const NeumannSpec& spec = m_scene.neumann[k];
        for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
            if (mesh.facet_body[f] != spec.body)
                continue;
            bool inside = true;
            Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
            Eigen::Matrix3d corners = Eigen::Matrix3d::Zero();
            for (int a = 0; a < d; ++a) {
                const Index v = mesh.boundary_facets(f, a);
                inside = inside && spec.region.contains(reference.row(v).transpose(), tol);
                corners.col(a).head(d) = mesh.rest_positions.row(v).transpose();
                Eigen::Vector3d r = Eigen::Vector3d::Zero();
                r.head(d) = reference.row(v).transpose();
                centroid += r / d;
            }
            if (!inside)
                continue;
            const double area = d == 2
                ? (corners.col(1) - corners.col(0)).norm()
                : 0.5 * (corners.col(1) - corners.col(0)).cross(corners.col(2) - corners.col(0)).norm();
            m_loaded_facets.push_back({ f, int(k), area, centroid });
        }
    }
}

void Simulator::setup_gravity()
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    m_gravity_forces = VectorXd::Zero(mesh.num_dofs());
    const VectorXd& masses = m_inertia->lumped_masses();
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        for (int a = 0; a < d; ++a)
            m_gravity_forces[v * d + a] = masses[v] * m_scene.gravity[a];
}

void Simulator::setup_initial_state()
{
    const VectorXd x0 = initial_positions();
    check_step_parameters();
    const VectorXd v0 = initial_velocities(x0);
    const VectorXd a0 = initial_accelerations(x0);
    m_integrator->initialize(x0, v0, a0);
    m_trajectory.initial_time = 0;
    m_trajectory.initial_positions = x0;
    m_trajectory.initial_velocities = v0;
    m_trajectory.initial_accelerations = a0;
}

VectorXd Simulator::initial_positions() const
{
    const SimulationParameters& P = m_overrides;
    VectorXd x0 = flatten(m_scene.mesh.rest_positions);
    if (P.initial_displacement.size() && m_periodic && !P.initial_displacement.isZero(0.0))
        throw InputError("initial_displacement", "a periodic cell starts from its rest positions (G = 0, w = 0)");
    if (P.initial_displacement.size())
        x0 += P.initial_displacement;
    dirichlet_targets(0.0, x0);
    return x0;
}

void Simulator::check_step_parameters() const
{
    const SimulationParameters& P = m_overrides;
    const int d = m_scene.dim;
    if (P.prescribed.size()
        && (P.prescribed.rows() != m_scene.time.steps || P.prescribed.cols() != Index(m_dirichlet.size())))
        throw InputError("prescribed",
            "expected " + std::to_string(m_scene.time.steps) + " by " + std::to_string(m_dirichlet.size())
                + " values (steps by prescribed dofs)");
    if (const std::string bad = check_substep_plan(P.substeps); !bad.empty())
        throw InputError("substeps", bad);
    if (P.macro_gradient.size()
        && (!m_periodic || P.macro_gradient.rows() != m_scene.time.steps || P.macro_gradient.cols() != d * d))
        throw InputError("macro_gradient",
            m_periodic ? "expected " + std::to_string(m_scene.time.steps) + " by " + std::to_string(d * d)
                    + " values (steps by G's components, row-major)"
                       : std::string("only a periodic cell has a macro gradient"));
    if (m_periodic && !P.substeps.empty())
        throw InputError("substeps", "a periodic cell's steps cannot be given sub-steps (not built yet)");
}

VectorXd Simulator::initial_velocities(const VectorXd& x0) const
{
    // Body velocities, with the prescribed rate on Dirichlet dofs.
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    const Index n = mesh.num_dofs();
    VectorXd v0(n);
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        v0.segment(v * d, d) = v < m_scene.body_vertices
            ? VectorXd(m_scene.bodies[size_t(mesh.vertex_body[v])].initial_velocity)
            : VectorXd::Zero(d);
    if (m_overrides.initial_velocity.size())
        for (Index i = 0; i < n; ++i)
            if (!m_constrained[size_t(i)])
                v0[i] = m_overrides.initial_velocity[i];
    const double dt = m_scene.time.dt * 1e-3;
    VectorXd x1 = x0;
    dirichlet_targets(dt, x1);
    for (const auto& dd : m_dirichlet)
        v0[dd.dof] = (x1[dd.dof] - x0[dd.dof]) / dt;
    return v0;
}

VectorXd Simulator::initial_accelerations(const VectorXd& x0) const
{
    const Index n = m_scene.mesh.num_dofs();
    VectorXd a0 = VectorXd::Zero(n);
    if (m_scene.time.integrator != IntegratorType::NEWMARK || !std::isfinite(m_elastic->value(x0)))
        return a0;
    // a0 = M^-1 (f_ext(0) - grad Psi(x0)) on free dofs, 0 on Dirichlet dofs.
    VectorXd f = external_forces(0.0);
    VectorXd grad = VectorXd::Zero(n);
    m_elastic->add_gradient(x0, 1.0, grad);
    f -= grad;
    if (!m_inertia->consistent()) {
        const VectorXd& masses = m_inertia->lumped_masses();
        for (Index i = 0; i < n; ++i)
            a0[i] = m_constrained[size_t(i)] ? 0.0 : f[i] / masses[i / m_scene.dim];
        return a0;
    }
    SparseMatrixd M = m_inertia->consistent_matrix();
    for (Index k = 0; k < M.outerSize(); ++k)
        for (SparseMatrixd::InnerIterator it(M, k); it; ++it)
            if (m_constrained[size_t(it.row())] || m_constrained[size_t(it.col())])
                it.valueRef() = it.row() == it.col() ? 1.0 : 0.0;
    for (Index i = 0; i < n; ++i)
        if (m_constrained[size_t(i)])
            f[i] = 0;
    Eigen::SimplicialLDLT<SparseMatrixd> ldlt(M);
    return ldlt.solve(f);
}

void Simulator::setup_device()
{
    // parse_scene refuses the scene's own friction across the boundary; this catches coefficients
    // given as parameters (SimulationParameters::friction).
    if (m_periodic && m_friction)
        throw InputError("device",
            "\"gpu\" does not support friction across a periodic cell's boundary yet; "
            "use \"cpu\"");
    m_device = std::make_unique<DeviceSolver>(
        *m_elastic, m_integrator->dynamic() ? m_inertia.get() : nullptr, m_constrained, m_contact.get());
    if (m_periodic)
        m_device->set_periodic(*m_periodic, m_image_classes);
    m_device->set_adjoint_multigrid(m_scene.solver.gpu_adjoint_multigrid);
}

Simulator::~Simulator() = default;

void Simulator::setup_contact()
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    const size_t nb = m_scene.bodies.size(), groups = nb + m_scene.obstacles.size();
    std::vector<char> self_contact(groups, 0), kinematic(groups, 0);
    for (size_t b = 0; b < nb; ++b)
        self_contact[b] = m_scene.bodies[b].self_contact;
    for (size_t k = nb; k < groups; ++k)
        kinematic[k] = 1;
    std::vector<ContactPlane> planes;
    for (const ObstacleSpec& o : m_scene.obstacles)
        if (o.type == ObstacleType::PLANE) {
            Eigen::Vector3d n = Eigen::Vector3d::Zero();
            n.head(d) = o.normal;
            planes.push_back({ o.first_vertex, n });
        }
    const ContactSpec& spec = m_scene.contact;
    ContactSettings settings;
    settings.dhat = spec.dhat;
    settings.min_distance = spec.min_distance;
    settings.ccd_max_iterations = spec.ccd_max_iterations;
    settings.ccd_rescaling = spec.ccd_rescaling;
    settings.kappa = spec.kappa;
    settings.penalty = spec.penalty;
    {
        // Per-vertex stiffness reference (docs/math.md): m_avg / (c h^2) in dynamics,
        // a nodal elastic stiffness E l in static solves. With a fixed kappa the adaptive
        // rule's minimum only explains a failed step (barrier_hint).
        double reference;
        if (m_integrator->dynamic()) {
            const VectorXd& masses = m_inertia->lumped_masses();
            double sum = 0;
            Index count = 0;
            for (Index v = 0; v < m_scene.body_vertices; ++v)
                if (masses[v] > 0) {
                    sum += masses[v];
                    ++count;
                }
            reference = sum / double(std::max<Index>(count, 1)) / m_integrator->potential_weight();
        } else {
            double mean_volume = 0;
            for (double v : m_space->rest_volumes())
                mean_volume += v / double(m_space->num_elements());
            const double length = std::pow(mean_volume, 1.0 / d);
            reference = m_force_scale / std::pow(length, d - 2);
        }
        m_kappa_min = barrier_stiffness_min(m_bbox_diagonal, reference, spec.dhat, spec.min_distance);
        if (spec.adaptive_kappa && (!(m_kappa_min > 0) || !std::isfinite(m_kappa_min)))
            throw InputError("contact.dhat",
                "too small for the adaptive barrier stiffness (it must exceed 1e-8 of the bodies' bounding-box "
                "diagonal, "
                    + format_number(1e-8 * m_bbox_diagonal) + " m); give a fixed \"kappa\" or a larger dhat");
        if (spec.adaptive_kappa)
            settings.kappa = m_kappa_min;
    }
    m_kappa_initial = settings.kappa;
    if (m_scene.periodic.enabled) {
        // Contact across the cell's boundary: the surface with its periodic images.
        ContactImages images
            = build_contact_images(mesh, m_scene.periodic.box, m_scene.periodic.pairing, self_contact, kinematic);
        m_image_classes.resize(images.source.size());
        for (size_t t = 0; t < images.source.size(); ++t)
            m_image_classes[t] = m_scene.periodic.pairing.vertex_class[images.source[t]];
        m_contact
            = std::make_unique<ContactPotential>(std::move(images.mesh), images.rest, std::move(planes), settings);
        m_contact->set_images(std::move(images.map));
    } else
        m_contact = std::make_unique<ContactPotential>(
            build_collision_mesh(mesh, self_contact, kinematic), mesh.rest_positions, std::move(planes), settings);
    m_problem.add(m_contact.get(), m_integrator->potential_weight());
}

VectorXd Simulator::macro_stress(const VectorXd& x) const
{
    if (!m_periodic)
        throw std::logic_error("Simulator::macro_stress: the scene is not a periodic cell");
    VectorXd stress = m_periodic->average_stress(*m_elastic, x);
    if (m_contact)
        stress += m_periodic->average_stress(*m_contact, x);
    return stress;
}

double Simulator::balancing_kappa(const VectorXd& x) const
{
    const double w = m_problem.weight(m_contact.get());
    VectorXd grad_energy;
    m_problem.gradient(x, grad_energy);
    VectorXd grad_barrier = m_contact->barrier_gradient(x);
    grad_energy -= w * m_contact->kappa() * grad_barrier;
    if (m_friction) // IPC's rule balances the barrier against the rest without friction
        m_friction->add_gradient(x, -m_problem.weight(m_friction.get()), grad_energy);
    const std::vector<char>* constrained = &m_constrained;
    if (m_periodic) { // balanced in the cell's unknowns q
        grad_energy = m_periodic->map().reduce(grad_energy);
        grad_barrier = m_periodic->map().reduce(grad_barrier);
        constrained = &m_periodic->constrained();
    }
    for (size_t i = 0; i < constrained->size(); ++i)
        if ((*constrained)[i])
            grad_energy[Index(i)] = grad_barrier[Index(i)] = 0;
    // The barrier enters with weight w kappa: kappa balances w^-1 grad E against grad B.
    return initial_barrier_stiffness(grad_barrier.dot(grad_energy) / w, grad_barrier.squaredNorm(), m_kappa_min);
}

void Simulator::setup_friction()
{
    const FrictionSpec& spec = m_scene.friction;
    std::vector<double> mu;
    bool any = false;
    for (const BodySpec& b : m_scene.bodies)
        mu.push_back(b.friction_coefficient >= 0 ? b.friction_coefficient : spec.coefficient);
    for (const ObstacleSpec& o : m_scene.obstacles)
        mu.push_back(o.friction_coefficient >= 0 ? o.friction_coefficient : spec.coefficient);
    if (m_overrides.friction.size())
        for (size_t k = 0; k < mu.size(); ++k) {
            mu[k] = m_overrides.friction[Index(k)];
            if (!(mu[k] >= 0))
                throw InputError("friction[" + std::to_string(k) + "]", "friction coefficients must be >= 0");
        }
    for (double m : mu)
        any = any || m > 0;
    if (!any)
        return; // zero coefficients: no friction work at all
    m_friction = std::make_unique<FrictionPotential>(m_scene.dim, mu, m_scene.mesh.vertex_body, spec.eps_v);
    if (m_contact->has_images()) // a periodic cell: friction across its boundary too
        m_friction->set_images(m_contact->images(),
            Eigen::Map<const VectorXi>(m_contact->collision_mesh().vertex_group.data(),
                Index(m_contact->collision_mesh().vertex_group.size())));
    m_problem.add(m_friction.get(), m_integrator->potential_weight());
}

void Simulator::lag_friction_at(const VectorXd& x)
{
    if (!m_device || m_fallback_on_cpu) {
        m_friction->lag(*m_contact, x);
        return;
    }
    // The device's active set at x (the CPU's pairs) and its current kappa give the normal forces.
    m_contact->set_kappa(m_device->kappa());
    m_friction->lag(*m_contact, m_device->contacts(x), x);
    m_device->set_friction(*m_friction);
}

double Simulator::force_residual(const VectorXd& x, double w) const
{
    VectorXd g;
    m_problem.gradient(x, g);
    double gmax = 0;
    for (Index i = 0; i < g.size(); ++i)
        if (!m_constrained[size_t(i)])
            gmax = std::max(gmax, std::abs(g[i]));
    return gmax / (w * m_force_scale);
}

void Simulator::update_kappa_for_step(const VectorXd& x)
{
    if (!m_scene.contact.adaptive_kappa)
        return;
    const bool active = !m_contact->contacts(x).empty();
    if (active)
        m_contact->set_kappa(std::max(m_contact->kappa(), balancing_kappa(x)));
    m_contact->set_adaptive(
        100 * m_kappa_min, m_bbox_diagonal, [this](const VectorXd& y) { return balancing_kappa(y); }, active);
}

std::string Simulator::check_contact_state(const VectorXd& x) const
{
    const Positions X = unflatten(m_contact->surface_positions(x), m_scene.dim);
    const std::string hit = find_intersection(m_contact->collision_mesh(), X, false);
    if (!hit.empty())
        return hit;
    const std::string inside = find_containment(m_contact->collision_mesh(), X);
    if (!inside.empty())
        return inside + " (group k is body k, then obstacles in order)";
    if (!std::isfinite(m_contact->value(x)))
        return "a contact pair is at or below the minimum distance, or a vertex lies behind a plane obstacle";
    return "";
}

std::string Simulator::state_problem() const
{
    const VectorXd& x = positions();
    if (m_contact) {
        const std::string problem = check_contact_state(x);
        if (!problem.empty())
            return problem;
    }
    const double ratio = m_space->min_volume_ratio(x);
    if (!(ratio > 0))
        return "an element is inverted or degenerate (minimum volume ratio " + format_number(ratio) + ")";
    return "";
}

double Simulator::time() const { return steps_done() * m_scene.time.dt; }

void Simulator::dirichlet_targets(double t, VectorXd& x) const
{
    for (const auto& dd : m_dirichlet)
        x[dd.dof]
            = dd.rest[dd.dof % m_scene.dim] + (*dd.expression)(t, dd.reference[0], dd.reference[1], dd.reference[2]);
}

void Simulator::prescribed_targets_at(int k, double t, VectorXd& x) const
{
    if (m_overrides.prescribed.size() == 0 || k < 1 || k > m_overrides.prescribed.rows()) {
        dirichlet_targets(t, x);
        return;
    }
    const double s = (t - (k - 1) * m_scene.time.dt) / m_scene.time.dt;
    const VectorXd& committed = m_integrator->positions();
    for (size_t j = 0; j < m_dirichlet.size(); ++j) {
        const auto& dd = m_dirichlet[j];
        const double g_k = dd.rest[dd.dof % m_scene.dim] + m_overrides.prescribed(k - 1, Index(j));
        x[dd.dof] = committed[dd.dof] + s * (g_k - committed[dd.dof]);
    }
}

void Simulator::prescribed_targets(int k, VectorXd& x) const
{
    if (m_overrides.prescribed.size() == 0 || k < 1 || k > m_overrides.prescribed.rows()) {
        dirichlet_targets(k * m_scene.time.dt, x);
        return;
    }
    for (size_t j = 0; j < m_dirichlet.size(); ++j) {
        const auto& dd = m_dirichlet[j];
        x[dd.dof] = dd.rest[dd.dof % m_scene.dim] + m_overrides.prescribed(k - 1, Index(j));
    }
}

VectorXd Simulator::external_forces(double t) const
{
    const int d = m_scene.dim;
    VectorXd f = m_gravity_forces;
    for (const auto& lf : m_loaded_facets) {
        const NeumannSpec& spec = m_scene.neumann[size_t(lf.spec)];
        for (int c = 0; c < d; ++c) {
            const double traction = spec.traction[size_t(c)](t, lf.centroid[0], lf.centroid[1], lf.centroid[2]);
            for (int a = 0; a < d; ++a)
                f[m_scene.mesh.boundary_facets(lf.facet, a) * d + c] += traction * lf.area / d;
        }
    }
    return f;
}

VectorXd Simulator::contact_forces() const
{
    if (!m_contact)
        return VectorXd::Zero(m_scene.mesh.num_dofs());
    return -m_contact->kappa() * m_contact->barrier_gradient(positions());
}

VectorXd Simulator::friction_forces() const
{
    VectorXd f = VectorXd::Zero(m_scene.mesh.num_dofs());
    // m_friction has the last step's start positions, but has been re-lagged at its converged
    // state since; the lagged data its final solve used is in the step's record.
    if (!m_friction || !m_friction_at_last_step)
        return f;
    const int k = steps_done();
    const std::vector<FrictionContact>* lagged = nullptr;
    if (m_trajectory.has_record(k) && m_trajectory.step(k).holds_state())
        lagged = &m_trajectory.step(k).friction;
    else if (m_last_attempt.index == k && m_last_attempt.status == StepStatus::CONVERGED)
        lagged = &m_last_attempt.friction; // the record was forgotten or released
    if (!lagged)
        return f;
    FrictionPotential used = *m_friction;
    used.set_lagged(*lagged);
    used.add_gradient(positions(), -1.0, f);
    return f;
}

void Simulator::set_initial_state(const VectorXd& positions, const VectorXd& velocities)
{
    const Index n = m_scene.mesh.num_dofs();
    if (steps_done() > 0)
        throw InputError("initial_state", "the initial state can only be set before the first step");
    if (positions.size() != n || velocities.size() != n)
        throw InputError("initial_state", "expected " + std::to_string(n) + " positions and velocities (#V*dim)");
    if (!positions.allFinite() || !velocities.allFinite())
        throw InputError("initial_state", "non-finite value");
    if (m_periodic && positions != m_integrator->positions())
        throw InputError("initial_state", "a periodic cell starts from its rest positions (G = 0, w = 0)");
    VectorXd x = positions, v = velocities;
    for (Index i = 0; i < n; ++i)
        if (m_constrained[size_t(i)]) {
            x[i] = m_integrator->positions()[i];
            v[i] = m_integrator->velocities()[i];
        }
    const VectorXd a = m_integrator->accelerations();
    m_integrator->initialize(x, v, a);
    m_trajectory.initial_positions = x;
    m_trajectory.initial_velocities = v;
}

void Simulator::set_element_materials(const VectorXd& youngs_modulus, const VectorXd& poisson_ratio)
{
    const Index ne = m_space->num_elements();
    if (steps_done() > 0)
        throw InputError("materials", "per-element materials can only be set before the first step");
    if (youngs_modulus.size() != ne || poisson_ratio.size() != ne)
        throw InputError("materials", "expected " + std::to_string(ne) + " values (one per element)");
    VectorXd mu(ne), lambda(ne);
    for (Index e = 0; e < ne; ++e) {
        if (!(youngs_modulus[e] > 0) || !std::isfinite(youngs_modulus[e]))
            throw InputError("materials.E[" + std::to_string(e) + "]", "Young's modulus must be positive and finite");
        if (!(poisson_ratio[e] > -1 && poisson_ratio[e] < 0.5))
            throw InputError("materials.nu[" + std::to_string(e) + "]", "Poisson's ratio must lie in (-1, 0.5)");
        mu[e] = lame_mu(youngs_modulus[e], poisson_ratio[e]);
        lambda[e] = lame_lambda(youngs_modulus[e], poisson_ratio[e], m_plane_stress[size_t(e)]);
    }
    m_elastic->set_lame_parameters(mu, lambda);
}

/// One call of step(): what its steps hand to each other.
struct Simulator::StepContext {
    int index = 0; ///< the step's number (1-based)
    /// After restore_state(): a step committed before, recomputed to refill its record.
    bool recompute = false;
    double t_next = 0; ///< the step's end time
    double w = 0; ///< the weight of the non-inertial potentials
    VectorXd inertial_target;
    VectorXd target; ///< the committed positions with the prescribed dofs at t_next
    VectorXd x; ///< the solve's iterate, from the committed positions
    double kappa_before = 0; ///< what a failed step restores
    double step_scale = 0; ///< the Newton step is measured in this unit
    /// Sub-steps given (a recomputed step repeats its own, SimulationParameters::substeps), else null.
    const std::vector<double>* plan = nullptr;
    std::string substep_note; ///< how far sub-stepping got, for a failure's message
    StepRecord record;
};

StepStatus Simulator::step()
{
    m_friction_at_last_step = false;
    Timer wall;
    StepContext s = begin_step();
    if (!set_step_loads(s))
        return s.record.status;
    const NewtonSolver newton(m_problem, m_assembler, *m_linear, step_settings(s.inertial_target));
    s.x = m_integrator->positions();
    s.kappa_before = m_contact ? m_contact->kappa() : 0.0;
    if (!check_run_start(s))
        return s.record.status;
    begin_contact_step(s);
    s.step_scale = m_integrator->dynamic() ? m_scene.time.dt : m_bbox_diagonal;
    s.plan = substep_plan(s.index, s.recompute);
    NewtonResult result = solve_step(s, newton);
    if (m_friction && result.status == StepStatus::CONVERGED && !s.plan)
        iterate_friction_lagging(s, newton, result);
    if (result.status != StepStatus::CONVERGED && m_scene.time.adaptive.enabled && !s.plan)
        result = solve_step_in_substeps(s, newton, result);
    record_solve(s, result);
    if (result.status == StepStatus::CONVERGED)
        commit_step(s);
    else {
        if (m_contact)
            m_contact->set_kappa(s.kappa_before); // a failed step leaves no trace, kappa included
        s.record.min_volume_ratio = m_space->min_volume_ratio(m_integrator->positions());
        if (s.recompute)
            return result.status;
        record_failure(s, result);
    }
    s.record.wall_time = wall.seconds();
    if (s.recompute)
        refill_record(s, result.status);
    else
        store_record(s, result.status);
    return result.status;
}

Simulator::StepContext Simulator::begin_step()
{
    StepContext s;
    s.index = current_step() + 1;
    s.recompute = s.index <= steps_done();
    s.t_next = s.index * m_scene.time.dt;
    s.w = m_integrator->potential_weight();
    set_potential_weights(s.w); // a sub-stepped step leaves its last sub-step's
    s.inertial_target = m_integrator->inertial_target();
    m_inertia->set_target(s.inertial_target);
    if (m_contact)
        m_contact->reset_times();
    s.record.index = s.index;
    s.record.time = s.t_next;
    return s;
}

void Simulator::refuse_step(StepContext& s, StepStatus status, const std::string& message)
{
    s.record.status = status;
    if (s.recompute)
        return;
    m_last_attempt = s.record;
    m_trajectory.final_status = status;
    m_trajectory.failed_step = s.index;
    m_trajectory.failure_message = message;
}

bool Simulator::set_step_loads(StepContext& s)
{
    s.target = m_integrator->positions();
    try {
        m_external->set_force(external_forces(s.t_next));
        prescribed_targets(s.index, s.target);
    } catch (const InputError& e) {
        // A boundary expression that is not finite at this time: not committable.
        refuse_step(s, StepStatus::NON_FINITE, e.what());
        return false;
    }
    return true;
}

NewtonSettings Simulator::step_settings(const VectorXd& inertial_target) const
{
    NewtonSettings settings;
    settings.residual_tolerance = m_scene.solver.residual_tolerance;
    settings.step_tolerance = m_scene.solver.step_tolerance;
    settings.max_iterations = m_scene.solver.max_iterations;
    settings.line_search_max_halvings = m_scene.solver.line_search_max_halvings;
    settings.armijo = m_scene.solver.armijo;
    settings.adaptive_projection = m_scene.solver.adaptive_projection;
    settings.step_extension = m_scene.solver.step_extension;
    if (m_contact) {
        // A free dof's Newton step longer than the bodies' size plus the inertial drift
        // |x~ - x_n| is not a step a converging solve takes (docs/math.md, "Newton").
        double largest = 0;
        if (m_integrator->dynamic()) {
            const VectorXd& x_n = m_integrator->positions();
            for (Index i = 0; i < x_n.size(); ++i)
                if (!m_constrained[size_t(i)])
                    largest = std::max(largest, std::abs(inertial_target[i] - x_n[i]));
        }
        settings.max_displacement = m_bbox_diagonal + largest;
    }
    return settings;
}

bool Simulator::check_run_start(StepContext& s)
{
    // The start of the run is checked as validate checks it: intersecting or too close contact
    // pairs, and inverted elements (whose energy is finite for linear elasticity and StVK, so
    // that Newton alone would fail later with a status that does not say why).
    if (s.index != 1)
        return true;
    const std::string problem = state_problem();
    if (problem.empty())
        return true;
    refuse_step(s, StepStatus::INVALID_INITIAL_STATE,
        "step 1 (t = 0) failed: INVALID_INITIAL_STATE: the initial state is invalid: " + problem);
    return false;
}

void Simulator::begin_contact_step(const StepContext& s)
{
    if (!m_contact)
        return;
    if (m_device) {
        DeviceSolver::AdaptiveKappa adaptive;
        adaptive.enabled = m_scene.contact.adaptive_kappa;
        adaptive.kappa_min = m_kappa_min;
        adaptive.kappa_max = 100 * m_kappa_min;
        adaptive.bbox_diagonal = m_bbox_diagonal;
        VectorXd q; // a periodic cell's contact balances in its unknowns
        if (m_periodic)
            q = m_periodic->map().reduced(s.x, m_macro);
        m_device->begin_step(
            m_contact->kappa(), adaptive, s.x, s.inertial_target, s.w, m_external->force(), m_periodic ? &q : nullptr);
    } else
        update_kappa_for_step(s.x);
    if (m_friction) {
        m_problem.set_weight(m_friction.get(), s.w);
        m_friction->set_step(s.x, m_scene.time.dt);
        if (m_device)
            lag_friction_at(s.x);
        else
            m_friction->lag(*m_contact, s.x);
    }
}

const std::vector<double>* Simulator::substep_plan(int index, bool recompute) const
{
    // Taken as they are, without a full solve first.
    if (recompute && m_trajectory.has_record(index) && !m_trajectory.step(index).substep_times.empty())
        return &m_trajectory.step(index).substep_times;
    if (size_t(index) <= m_overrides.substeps.size() && !m_overrides.substeps[size_t(index - 1)].empty())
        return &m_overrides.substeps[size_t(index - 1)];
    return nullptr;
}

NewtonResult Simulator::solve_step(StepContext& s, const NewtonSolver& newton)
{
    const NewtonSettings& settings = newton.settings();
    const double force_scale = s.w * m_force_scale;
    if (s.plan)
        return solve_dynamic_substeps(s.index, newton, s.plan, s.kappa_before, s.x, s.record, s.substep_note);
    if (!m_periodic) {
        if (m_device)
            return m_device->solve(
                s.x, s.inertial_target, s.w, m_external->force(), s.target, force_scale, s.step_scale, settings);
        return newton.solve(s.x, s.target, m_constrained, force_scale, s.step_scale);
    }
    s.record.macro_gradient = m_macro;
    VectorXd given;
    if (m_overrides.macro_gradient.rows() >= s.index)
        given = m_overrides.macro_gradient.row(s.index - 1).transpose();
    if (!m_device)
        return m_periodic->solve(s.x, s.record.macro_gradient, s.t_next, settings, force_scale, s.step_scale,
            given.size() ? &given : nullptr);
    VectorXd q, target_q;
    m_periodic->step_unknowns(s.x, s.record.macro_gradient, s.t_next, given.size() ? &given : nullptr, q, target_q);
    const NewtonResult result = m_device->solve_periodic(
        q, target_q, s.inertial_target, s.w, m_external->force(), force_scale, s.step_scale, settings);
    if (result.status == StepStatus::CONVERGED) {
        s.x = m_periodic->map().positions(q);
        s.record.macro_gradient = m_periodic->map().macro_gradient(q);
    }
    return result;
}

void Simulator::iterate_friction_lagging(StepContext& s, const NewtonSolver& newton, NewtonResult& r)
{
    // Refresh normal forces, tangents and weights at the converged state and solve again, up to
    // `iterations` solves; the residual of the re-lagged problem at the converged state says
    // whether the lagged data describes it. With automatic load stepping a failed re-solve fails
    // the step, which is then sub-stepped.
    StepRecord& record = s.record;
    const double force_scale = s.w * m_force_scale;
    record.friction_iterations = 1;
    for (;;) {
        std::vector<FrictionContact> used = m_friction->lagged();
        lag_friction_at(s.x);
        record.friction_residual = m_device
            ? m_device->residual(s.x, s.inertial_target, s.w, m_external->force()) / force_scale
            : force_residual(s.x);
        record.friction_converged = record.friction_residual <= newton.settings().residual_tolerance;
        if (record.friction_converged || record.friction_iterations >= m_scene.friction.iterations) {
            record.friction = std::move(used);
            break;
        }
        // Solve a copy: if this re-solve fails, the last converged state (with the
        // data it satisfies) is still there for the permissive policy.
        VectorXd y = s.x;
        NewtonResult again = m_device ? m_device->solve(y, s.inertial_target, s.w, m_external->force(), s.target,
                                 force_scale, s.step_scale, newton.settings())
                                      : newton.solve(y, s.target, m_constrained, force_scale, s.step_scale);
        ++record.friction_iterations;
        r.add_costs(again);
        if (again.status != StepStatus::CONVERGED) {
            m_friction->set_lagged(used);
            record.friction = std::move(used);
            record.friction_converged = false;
            if (m_scene.friction.strict || m_scene.time.adaptive.enabled)
                r.status = again.status;
            break;
        }
        r.residual = again.residual;
        r.newton_step = again.newton_step;
        r.roundoff_limited = again.roundoff_limited;
        s.x = std::move(y);
    }
    if (r.status == StepStatus::CONVERGED && !record.friction_converged && m_scene.friction.strict)
        r.status = StepStatus::FRICTION_EXHAUSTED;
}

NewtonResult Simulator::solve_step_in_substeps(StepContext& s, const NewtonSolver& newton, const NewtonResult& first)
{
    NewtonResult result;
    if (m_integrator->dynamic()) {
        result = solve_dynamic_substeps(s.index, newton, nullptr, s.kappa_before, s.x, s.record, s.substep_note);
    } else {
        result = solve_in_substeps(s.index, newton, s.step_scale, s.kappa_before, s.x, s.record, s.substep_note);
        if (m_friction && result.status == StepStatus::CONVERGED)
            iterate_friction_lagging(s, newton, result); // the last sub-step's friction, as lagged by the sub-stepping
    }
    result.add_costs(first);
    return result;
}

void Simulator::record_solve(StepContext& s, const NewtonResult& result)
{
    StepRecord& record = s.record;
    record.status = result.status;
    record.newton_iterations = result.iterations;
    record.residual = result.residual;
    record.newton_step = result.newton_step;
    record.linear_fallbacks = result.linear_fallbacks;
    record.line_search_cuts = result.line_search_cuts;
    record.roundoff_limited = result.roundoff_limited;
    record.phases = result.times;
    if (m_contact && m_device) {
        m_contact->set_kappa(m_device->kappa()); // the CPU contact carries kappa between steps
        const ContactTimes times = m_device->contact_times();
        record.phases.broad_phase = times.broad_phase;
        record.phases.ccd = times.ccd;
        record.phases.barrier = times.barrier;
        record.kappa = m_contact->kappa();
        if (result.status == StepStatus::CCD_UNRESOLVED)
            record.min_distance = m_device->min_distance(m_integrator->positions(), 1e-2 * m_bbox_diagonal);
    } else if (m_contact) {
        record.phases.broad_phase = m_contact->times().broad_phase;
        record.phases.ccd = m_contact->times().ccd;
        record.phases.barrier = m_contact->times().barrier;
        record.kappa = m_contact->kappa();
        if (result.status == StepStatus::CCD_UNRESOLVED)
            record.min_distance = m_contact->min_distance(m_integrator->positions(), 1e-2 * m_bbox_diagonal);
    }
    if (!s.recompute) {
        m_trajectory.phases += record.phases;
        m_trajectory.newton_iterations += result.iterations;
    }
}

void Simulator::commit_step(StepContext& s)
{
    StepRecord& record = s.record;
    const VectorXd& x = s.x;
    record.positions = x;
    // A dynamic sub-stepped step has its velocities and accelerations from its last sub-step.
    if (record.substep_times.empty())
        m_integrator->update(x, record.velocities, record.accelerations);
    record.min_volume_ratio = m_space->min_volume_ratio(x);
    if (m_periodic) {
        m_macro = record.macro_gradient;
        record.macro_stress = macro_stress(x);
    }
    if (m_contact) {
        record.contacts = m_device ? m_device->contacts(x) : m_contact->contacts(x);
        record.active_contacts = int(record.contacts.size());
        record.min_distance = m_device ? m_device->min_distance(x, 1e-2 * m_bbox_diagonal)
                                       : m_contact->min_distance(x, 1e-2 * m_bbox_diagonal);
    }
    m_integrator->commit(record.positions, record.velocities, record.accelerations);
}

void Simulator::record_failure(const StepContext& s, const NewtonResult& result)
{
    m_trajectory.final_status = result.status;
    m_trajectory.failed_step = s.index;
    std::string& message = m_trajectory.failure_message;
    message = "step " + std::to_string(s.index) + " (t = " + format_number(s.t_next)
        + " s) failed: " + to_string(result.status) + " after " + std::to_string(result.iterations)
        + " Newton iterations, residual " + format_number(result.residual) + s.substep_note;
    // x: the solve's last iterate; the hint only where it is in contact
    if (result.status == StepStatus::NEWTON_EXHAUSTED && m_contact && !m_scene.contact.adaptive_kappa
        && !m_scene.contact.penalty && m_scene.contact.kappa < 1e-2 * m_kappa_min && s.x.allFinite()
        && m_contact->min_distance(s.x, m_scene.contact.dhat) < m_scene.contact.dhat)
        message += "; the fixed contact.kappa " + format_number(m_scene.contact.kappa)
            + " is below 1/100 of the adaptive rule's minimum " + format_number(m_kappa_min)
            + " for this scene (docs/math.md): a barrier too soft for the contact stalls Newton; try a larger "
              "kappa or \"adaptive\"";
    if (result.status == StepStatus::INVALID_INITIAL_STATE) {
        const std::string problem = state_problem();
        message += ": the incremental potential is not finite at the step's start"
            + (problem.empty() ? std::string(" (an energy term overflows: check E, density and loads)")
                               : " (" + problem + ")");
    }
}

void Simulator::refill_record(StepContext& s, StepStatus status)
{
    // Only the state is refilled: the record keeps the first run's diagnostics.
    if (!m_trajectory.has_record(s.index))
        throw std::logic_error(
            "Simulator::step: recomputing step " + std::to_string(s.index) + ", whose record was forgotten");
    StepRecord& kept = m_trajectory.step(s.index);
    kept.positions = std::move(s.record.positions);
    kept.velocities = std::move(s.record.velocities);
    kept.accelerations = std::move(s.record.accelerations);
    kept.contacts = std::move(s.record.contacts);
    kept.friction = std::move(s.record.friction);
    kept.path = std::move(s.record.path);
    m_friction_at_last_step = status == StepStatus::CONVERGED && s.index == steps_done();
}

void Simulator::store_record(StepContext& s, StepStatus status)
{
    m_trajectory.wall_time += s.record.wall_time;
    m_last_attempt = s.record;
    if (status == StepStatus::CONVERGED) {
        m_trajectory.totals.add(s.record);
        m_trajectory.steps.push_back(std::move(s.record));
        m_friction_at_last_step = true;
    }
}

void Simulator::resume(const Trajectory& stored, bool stored_contact)
{
    if (steps_done() > 0 || current_step() > 0)
        throw InputError("restart", "a run can only be resumed before its first step");
    const Index n = m_scene.mesh.num_dofs();
    if (stored.initial_positions.size() != n)
        throw InputError("restart",
            "the stored trajectory has " + std::to_string(stored.initial_positions.size())
                + " position values, this scene " + std::to_string(n));
    if (stored_contact != (m_contact != nullptr))
        throw InputError("restart",
            stored_contact ? "the stored run has contact, this scene has none"
                           : "this scene has contact, the stored run has none");
    const double scale = std::max(1.0, m_trajectory.initial_positions.lpNorm<Eigen::Infinity>());
    if ((stored.initial_positions - m_trajectory.initial_positions).lpNorm<Eigen::Infinity>() > 1e-12 * scale
        || (stored.initial_velocities - m_trajectory.initial_velocities).lpNorm<Eigen::Infinity>() > 1e-12 * scale)
        throw InputError("restart", "the stored trajectory does not start from this scene's initial state");
    const int k = stored.committed();
    if (k > m_scene.time.steps)
        throw InputError("restart",
            "the stored run has " + std::to_string(k) + " steps, this scene asks for "
                + std::to_string(m_scene.time.steps));
    if (k == 0)
        return;
    for (int j = std::max(1, k - 1); j <= k; ++j) {
        const StepRecord& r = stored.step(j);
        if (r.positions.size() != n || r.velocities.size() != n || r.accelerations.size() != n)
            throw InputError("restart", "step " + std::to_string(j) + " of the stored trajectory has the wrong size");
        if (std::abs(r.time - j * m_scene.time.dt) > 1e-9 * std::max(1.0, r.time))
            throw InputError("restart",
                "step " + std::to_string(j) + " of the stored trajectory is at t = " + std::to_string(r.time)
                    + " s, not at step * dt of this scene");
    }
    const StepRecord& last = stored.step(k);
    const VectorXd& x_prev = k == 1 ? stored.initial_positions : stored.step(k - 1).positions;
    const VectorXd& v_prev = k == 1 ? stored.initial_velocities : stored.step(k - 1).velocities;
    m_integrator->restore(k, last.positions, last.velocities, last.accelerations, x_prev, v_prev);
    if (m_contact)
        m_contact->set_kappa(last.kappa);
    if (m_periodic) {
        if (last.macro_gradient.size() != m_scene.dim * m_scene.dim)
            throw InputError("restart",
                "the stored trajectory has no macro_gradient (the periodic cell's G at step " + std::to_string(k)
                    + "): it was not written by this periodic scene");
        m_macro = last.macro_gradient;
    }
    m_trajectory.steps.clear();
    m_trajectory.first_index = k + 1;
    m_trajectory.totals = stored.totals;
    m_trajectory.newton_iterations = stored.newton_iterations;
    m_trajectory.wall_time = stored.wall_time;
}

StepRecord& Simulator::record_of(int k, const char* caller)
{
    if (!m_trajectory.has_record(k))
        throw std::logic_error(std::string("Simulator::") + caller + ": the record of step " + std::to_string(k)
            + " was forgotten (forget_records)");
    return m_trajectory.step(k);
}

void Simulator::forget_records()
{
    if (current_step() != steps_done())
        throw std::logic_error("Simulator::forget_records while steps are being recomputed");
    m_trajectory.first_index += int(m_trajectory.steps.size());
    m_trajectory.steps.clear();
}

void Simulator::release_state(int k)
{
    if (k < 1 || k > steps_done())
        throw std::out_of_range("Simulator::release_state: step " + std::to_string(k) + " was not committed");
    record_of(k, "release_state").release_state();
}

void Simulator::restore_state(int k)
{
    m_friction_at_last_step = false;
    if (k < 0 || k > steps_done())
        throw std::out_of_range("Simulator::restore_state: step " + std::to_string(k) + " was not committed");
    const auto held = [this](int j) {
        if (j >= 1 && !record_of(j, "restore_state").holds_state())
            throw std::logic_error("Simulator::restore_state: the record of step " + std::to_string(j)
                + " does not hold its state (it was released)");
        return j;
    };
    const Trajectory& tr = m_trajectory;
    if (k == 0) {
        m_integrator->restore(0, tr.initial_positions, tr.initial_velocities, tr.initial_accelerations,
            tr.initial_positions, tr.initial_velocities);
    } else {
        const StepRecord& r = tr.step(held(k));
        const int j = m_integrator->history() == 2 ? held(k - 1) : k;
        const VectorXd& x_prev = j == 0 ? tr.initial_positions : tr.step(j).positions;
        const VectorXd& v_prev = j == 0 ? tr.initial_velocities : tr.step(j).velocities;
        m_integrator->restore(k, r.positions, r.velocities, r.accelerations, x_prev, v_prev);
    }
    if (m_periodic)
        m_macro = k == 0 ? VectorXd::Zero(m_scene.dim * m_scene.dim) : tr.step(k).macro_gradient;
    // step_problem() and adaptive steps change kappa; step k + 1 started from the value step k ended with.
    if (m_contact)
        m_contact->set_kappa(k == 0 ? m_kappa_initial : tr.step(k).kappa);
}

void Simulator::recompute_steps(int last)
{
    if (last > steps_done())
        throw std::out_of_range("Simulator::recompute_steps: step " + std::to_string(last) + " was not committed");
    while (current_step() < last) {
        const StepStatus status = step();
        if (status != StepStatus::CONVERGED)
            throw std::runtime_error("recomputing step " + std::to_string(current_step() + 1) + " from a checkpoint: "
                + to_string(status) + " (the first run converged; the forward is not deterministic)");
    }
}

const Trajectory& Simulator::run(const std::function<void(const StepRecord&)>& progress)
{
    if (current_step() < steps_done())
        recompute_steps(steps_done());
    while (steps_done() < m_scene.time.steps) {
        if (step() != StepStatus::CONVERGED)
            break;
        if (progress)
            progress(m_trajectory.steps.back());
    }
    return m_trajectory;
}

std::vector<Index> Simulator::prescribed_dofs() const
{
    std::vector<Index> dofs;
    dofs.reserve(m_dirichlet.size());
    for (const auto& dd : m_dirichlet)
        dofs.push_back(dd.dof);
    return dofs;
}

SimulationParameters Simulator::parameters() const
{
    SimulationParameters p;
    const int d = m_scene.dim;
    p.rest_positions = flatten(m_scene.mesh.rest_positions);
    p.mu = m_elastic->mu();
    p.lambda = m_elastic->lambda();
    const Index ne = p.mu.size();
    p.youngs_modulus.resize(ne);
    p.poisson_ratio.resize(ne);
    for (Index e = 0; e < ne; ++e) {
        p.youngs_modulus[e] = youngs_modulus_of(p.mu[e], p.lambda[e], m_plane_stress[size_t(e)]);
        p.poisson_ratio[e] = poisson_ratio_of(p.mu[e], p.lambda[e], m_plane_stress[size_t(e)]);
    }
    p.density = m_inertia->density();
    p.friction = VectorXd::Zero(num_groups());
    if (m_friction)
        for (int k = 0; k < num_groups(); ++k)
            p.friction[k] = m_friction->group_coefficients()[size_t(k)];
    p.initial_displacement = m_trajectory.initial_positions - p.rest_positions;
    p.initial_velocity = m_trajectory.initial_velocities;
    const int T = m_scene.time.steps;
    // Every step's prescribed values (and a periodic cell's G): refused, naming the field, when
    // they cannot fit, where time.steps = 2e9 ended in std::bad_alloc (exit 3).
    const double values = double(T) * double(m_dirichlet.size() + (m_periodic ? size_t(d * d) : 0));
    if (const double have = usable_memory_bytes(); values * sizeof(double) > have)
        throw InputError("time.steps",
            std::to_string(T) + " steps of " + format_number(values / T)
                + " prescribed values each (the parameters of a differentiated run) need about "
                + format_number(values * sizeof(double) * 1e-9) + " GB, more than the " + format_number(have * 1e-9)
                + " GB this process may use");
    p.prescribed.resize(T, Index(m_dirichlet.size()));
    VectorXd x = p.rest_positions;
    for (int k = 1; k <= T && !m_dirichlet.empty(); ++k) {
        prescribed_targets(k, x);
        for (size_t j = 0; j < m_dirichlet.size(); ++j)
            p.prescribed(k - 1, Index(j)) = x[m_dirichlet[j].dof] - m_dirichlet[j].rest[m_dirichlet[j].dof % d];
    }
    p.kappa = m_contact ? m_contact->kappa() : 0.0;
    // The sub-steps the run took (dynamic steps): a run from these parameters repeats them.
    for (int k = m_trajectory.first_index; k <= steps_done(); ++k)
        if (!m_trajectory.step(k).substep_times.empty()) {
            p.substeps.resize(size_t(T));
            p.substeps[size_t(k - 1)] = m_trajectory.step(k).substep_times;
        }
    if (p.substeps.empty() && !m_overrides.substeps.empty())
        p.substeps = m_overrides.substeps;
    if (m_periodic) {
        // G's prescribed values at t_1..t_T (the free components: 0, ignored).
        p.macro_gradient = MatrixXd::Zero(T, d * d);
        for (int k = 1; k <= T; ++k)
            p.macro_gradient.row(k - 1)
                = m_periodic
                      ->prescribed_values(k * m_scene.time.dt,
                          m_overrides.macro_gradient.rows() >= k ? &m_overrides.macro_gradient : nullptr, k)
                      .transpose();
    }
    return p;
}

const Problem& Simulator::step_problem(int k)
{
    m_friction_at_last_step = false;
    if (k < 1 || k > steps_done())
        throw std::out_of_range("Simulator::step_problem: step " + std::to_string(k) + " was not committed");
    const StepScheme s = m_integrator->scheme(k);
    for (int j = std::max(1, k - m_integrator->history()); j <= k; ++j)
        if (!record_of(j, "step_problem").holds_state())
            throw std::logic_error("Simulator::step_problem: step " + std::to_string(k) + " reads the record of step "
                + std::to_string(j) + ", which does not hold its state (it was released)");
    const auto state = [this](int j, int which) -> const VectorXd& {
        if (j == 0)
            return which == 0 ? m_trajectory.initial_positions
                : which == 1  ? m_trajectory.initial_velocities
                              : m_trajectory.initial_accelerations;
        const StepRecord& r = m_trajectory.step(j);
        return which == 0 ? r.positions : which == 1 ? r.velocities : r.accelerations;
    };
    VectorXd target = VectorXd::Zero(m_scene.mesh.num_dofs());
    for (int j = 1; j <= 2 && k - j >= 0; ++j) {
        if (s.tx[j] != 0)
            target += s.tx[j] * state(k - j, 0);
        if (s.tv[j] != 0)
            target += s.tv[j] * state(k - j, 1);
        if (s.ta[j] != 0)
            target += s.ta[j] * state(k - j, 2);
    }
    m_inertia->set_target(target);
    m_problem.set_weight(m_elastic.get(), s.weight);
    m_problem.set_weight(m_external.get(), s.weight);
    m_external->set_force(external_forces(k * m_scene.time.dt));
    const StepRecord& record = m_trajectory.step(k);
    if (m_contact) {
        m_problem.set_weight(m_contact.get(), s.weight);
        m_contact->set_kappa(record.kappa);
    }
    if (m_friction) {
        m_problem.set_weight(m_friction.get(), s.weight);
        m_friction->set_step(state(k - 1, 0), m_scene.time.dt);
        m_friction->set_lagged(record.friction);
    }
    return m_problem;
}

void Simulator::external_force_derivatives(
    double t, const VectorXd& direction, VectorXd* d_rest_positions, VectorXd* d_density) const
{
    const Mesh& mesh = m_scene.mesh;
    const int d = mesh.dim;
    const VectorXd& density = m_inertia->density();
    Eigen::VectorXd g = Eigen::VectorXd::Zero(d);
    for (int a = 0; a < d; ++a)
        g[a] = m_scene.gravity[a];
    if (g.squaredNorm() > 0) {
        // direction^T f_gravity = sum_e rho_e |e| / (d+1) sum_{a in e} direction_a . g
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            double s = 0;
            for (int a = 0; a <= d; ++a)
                s += direction.segment(mesh.elements(e, a) * d, d).dot(g);
            const double vol = m_space->rest_volume(e);
            if (d_density)
                (*d_density)[e] += vol / (d + 1) * s;
            if (d_rest_positions) {
                // d|e|/dX_a = |e| G_a
                const double* G = m_space->shape_gradients(e);
                const double c = density[e] / (d + 1) * s * vol;
                for (int a = 0; a <= d; ++a)
                    for (int j = 0; j < d; ++j)
                        (*d_rest_positions)[mesh.elements(e, a) * d + j] += c * G[a * d + j];
            }
        }
    }
    if (!d_rest_positions)
        return;
    for (const auto& lf : m_loaded_facets) {
        const NeumannSpec& spec = m_scene.neumann[size_t(lf.spec)];
        // direction^T f = area / d * sum_a sum_c direction_(a,c) t_c
        double s = 0;
        for (int c = 0; c < d; ++c) {
            const double traction = spec.traction[size_t(c)](t, lf.centroid[0], lf.centroid[1], lf.centroid[2]);
            for (int a = 0; a < d; ++a)
                s += direction[mesh.boundary_facets(lf.facet, a) * d + c] * traction;
        }
        s /= d;
        Eigen::Vector3d X[3];
        for (int a = 0; a < d; ++a) {
            X[a].setZero();
            X[a].head(d) = mesh.rest_positions.row(mesh.boundary_facets(lf.facet, a)).transpose();
        }
        Eigen::Vector3d grad[3];
        if (d == 2) {
            const Eigen::Vector3d u = (X[1] - X[0]).normalized();
            grad[0] = -u;
            grad[1] = u;
        } else {
            // dA/dX_i = 1/2 n^ x (X_{i+2} - X_{i+1})
            const Eigen::Vector3d n = (X[1] - X[0]).cross(X[2] - X[0]).normalized();
            for (int i = 0; i < 3; ++i)
                grad[i] = 0.5 * n.cross(X[(i + 2) % 3] - X[(i + 1) % 3]);
        }
        for (int a = 0; a < d; ++a)
            d_rest_positions->segment(mesh.boundary_facets(lf.facet, a) * d, d) += s * grad[a].head(d);
    }
}

} // namespace diffipc
