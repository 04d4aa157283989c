#include "forward/simulation/device_solver.hpp"

#include "forward/common/error.hpp"

#ifdef DIFFIPC_HAVE_CUDA
#include "cuda/common/device.hpp"
#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/solver/device_newton.hpp"
#endif

namespace diffipc {

#ifdef DIFFIPC_HAVE_CUDA

namespace {
    std::vector<double> to_std(const VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }

    // DeviceStepStatus has StepStatus's numbers (device_newton.hpp).
    StepStatus to_status(gpu::DeviceStepStatus s) { return StepStatus(int(s)); }
} // namespace

struct DeviceSolver::Impl {
    gpu::DeviceElasticMesh mesh;
    std::unique_ptr<gpu::DeviceNewton> newton;
    std::vector<double> x, target, inertial_target, force;
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

DeviceSolver::DeviceSolver(
    const ElasticPotential& elastic, const InertiaPotential* inertia, const std::vector<char>& constrained)
    : m_impl(std::make_unique<Impl>())
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
    std::vector<int> models;
    models.reserve(elastic.models().size());
    for (MaterialModel m : elastic.models())
        models.push_back(int(m));
    m_impl->mesh.upload(dim, rest, elements, models, to_std(elastic.mu()), to_std(elastic.lambda()));
    std::vector<double> mass;
    if (inertia) {
        const VectorXd& lumped = inertia->lumped_masses();
        mass.resize(size_t(mesh.num_dofs()));
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            for (int a = 0; a < dim; ++a)
                mass[size_t(v * dim + a)] = lumped[v];
    }
    m_impl->newton = std::make_unique<gpu::DeviceNewton>(m_impl->mesh, mass);
    m_impl->newton->set_constrained(constrained);
    // The CPU's energy measures the external work from the rest positions and its round-off
    // allowance counts the neo-Hookean models' cancelling terms: the same here.
    m_impl->newton->set_force_reference(rest);
    m_impl->newton->set_material_scale(models, to_std(elastic.mu()));
}

DeviceSolver::~DeviceSolver() = default;

NewtonResult DeviceSolver::solve(VectorXd& x, const VectorXd& inertial_target, double weight, const VectorXd& force,
    const VectorXd& target, double force_scale, double step_scale, const NewtonSettings& settings)
{
    gpu::DeviceNewtonSettings s;
    s.residual_tolerance = settings.residual_tolerance;
    s.max_iterations = settings.max_iterations;
    s.line_search_max_halvings = settings.line_search_max_halvings;
    s.armijo = settings.armijo;
    Impl& d = *m_impl;
    d.x.assign(x.data(), x.data() + x.size());
    d.target.assign(target.data(), target.data() + target.size());
    d.force.assign(force.data(), force.data() + force.size());
    if (inertial_target.size() == x.size())
        d.inertial_target.assign(inertial_target.data(), inertial_target.data() + inertial_target.size());
    else
        d.inertial_target.assign(size_t(x.size()), 0.0);
    const gpu::DeviceNewtonResult r
        = d.newton->solve(d.x, d.inertial_target, weight, d.force, d.target, force_scale, step_scale, s);
    NewtonResult result;
    result.status = to_status(r.status);
    result.iterations = r.iterations;
    result.residual = r.residual;
    result.newton_step = r.newton_step;
    result.line_search_cuts = r.line_search_cuts;
    result.roundoff_limited = r.roundoff_limited;
    result.gradient_steps = r.gradient_steps;
    result.times.assembly = r.assembly_time;
    result.times.solve = r.solve_time;
    result.times.line_search = r.line_search_time;
    m_last_pcg_iterations = r.pcg_iterations;
    if (result.status == StepStatus::CONVERGED)
        x = Eigen::Map<const VectorXd>(d.x.data(), Index(d.x.size()));
    return result;
}

bool DeviceSolver::solve_adjoint(const VectorXd& x, double weight, const VectorXd& b, VectorXd& y, int* iterations)
{
    // The adjoint of the tests' gradient checks needs 1e-6 relative agreement with the CPU's direct
    // solve: 1e-12 relative residual leaves the solution's error far below that on conditioned steps.
    constexpr double TOLERANCE = 1e-12;
    std::vector<double> out;
    const gpu::PcgResult r
        = m_impl->newton->solve_true_hessian(to_std(x), weight, to_std(b), out, TOLERANCE, 50 * int(x.size()) + 100);
    if (iterations)
        *iterations = r.iterations;
    if (!r.converged || r.breakdown)
        return false;
    y = Eigen::Map<const VectorXd>(out.data(), Index(out.size()));
    return y.allFinite();
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

DeviceSolver::DeviceSolver(const ElasticPotential&, const InertiaPotential*, const std::vector<char>&)
{
    std::string why;
    available(&why);
    throw InputError("device", "\"gpu\" is not available: " + why);
}

DeviceSolver::~DeviceSolver() = default;

NewtonResult DeviceSolver::solve(
    VectorXd&, const VectorXd&, double, const VectorXd&, const VectorXd&, double, double, const NewtonSettings&)
{
    return {};
}

bool DeviceSolver::solve_adjoint(const VectorXd&, double, const VectorXd&, VectorXd&, int*) { return false; }

#endif

} // namespace diffipc
