// pybind11 bindings: scenes from files or dicts, simulation with numpy
// trajectories, element-level energy/gradient/Hessian for testing, and the
// reduced functional of a problem file (value and adjoint gradient).
// InputError becomes ValueError with the message naming the field;
// AdjointError (no gradient can be computed) becomes diffipc.AdjointError, a RuntimeError.

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/io/output.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/scene/json_input.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "shape_opt/reduced_functional.hpp"

#include <nlohmann/json.hpp>
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <limits>
#include <mutex>
#include <unordered_set>

namespace py = pybind11;
using namespace diffipc;

namespace {

/// [T+1, N, d] array from the initial state and a per-step member.
py::array_t<double> stack(const Trajectory& tr, const VectorXd& initial, VectorXd StepRecord::*member, int dim)
{
    const ssize_t T = ssize_t(tr.steps.size()), N = ssize_t(initial.size() / dim);
    py::array_t<double> out({ T + 1, N, ssize_t(dim) });
    double* p = out.mutable_data();
    std::copy(initial.data(), initial.data() + initial.size(), p);
    for (ssize_t k = 0; k < T; ++k) {
        const VectorXd& v = tr.steps[size_t(k)].*member;
        if (v.size() == initial.size())
            std::copy(v.data(), v.data() + v.size(), p + (k + 1) * N * dim);
        else
            std::fill(p + (k + 1) * N * dim, p + (k + 2) * N * dim, 0.0);
    }
    return out;
}

template <typename T, typename F> py::array_t<T> per_step(const Trajectory& tr, F f)
{
    py::array_t<T> out(ssize_t(tr.steps.size()));
    for (size_t k = 0; k < tr.steps.size(); ++k)
        out.mutable_data()[k] = f(tr.steps[k]);
    return out;
}

py::dict trajectory_dict(const Simulator& sim)
{
    const Trajectory& tr = sim.trajectory();
    const int d = sim.mesh().dim;
    py::dict out;
    std::vector<double> time { tr.initial_time };
    for (const auto& s : tr.steps)
        time.push_back(s.time);
    out["time"] = py::array_t<double>(ssize_t(time.size()), time.data());
    out["positions"] = stack(tr, tr.initial_positions, &StepRecord::positions, d);
    out["velocities"] = stack(tr, tr.initial_velocities, &StepRecord::velocities, d);
    out["accelerations"] = stack(tr, tr.initial_accelerations, &StepRecord::accelerations, d);
    out["status"] = per_step<int>(tr, [](const StepRecord& s) { return int(s.status); });
    out["newton_iterations"] = per_step<int>(tr, [](const StepRecord& s) { return s.newton_iterations; });
    out["residual"] = per_step<double>(tr, [](const StepRecord& s) { return s.residual; });
    out["newton_step"] = per_step<double>(tr, [](const StepRecord& s) { return s.newton_step; });
    out["min_volume_ratio"] = per_step<double>(tr, [](const StepRecord& s) { return s.min_volume_ratio; });
    out["wall_time"] = per_step<double>(tr, [](const StepRecord& s) { return s.wall_time; });
    if (sim.contact()) {
        out["min_distance"] = per_step<double>(tr, [](const StepRecord& s) { return s.min_distance; });
        out["active_contacts"] = per_step<int>(tr, [](const StepRecord& s) { return s.active_contacts; });
        out["kappa"] = per_step<double>(tr, [](const StepRecord& s) { return s.kappa; });
        out["ccd_time"] = per_step<double>(tr, [](const StepRecord& s) { return s.phases.ccd; });
        out["broad_phase_time"] = per_step<double>(tr, [](const StepRecord& s) { return s.phases.broad_phase; });
        out["friction_residual"] = per_step<double>(tr, [](const StepRecord& s) { return s.friction_residual; });
    }
    if (tr.macro_dim > 0) {
        // [T, d, d] with [k, i, j] = G_ij (resp. P_ij) after step k + 1: the records hold them
        // row-major, as trajectory.h5's macro_gradient and macro_stress do.
        const ssize_t T = ssize_t(tr.steps.size()), dm = tr.macro_dim;
        auto macro = [&](const VectorXd StepRecord::*member) {
            py::array_t<double> a({ T, dm, dm });
            double* p = a.mutable_data();
            for (ssize_t k = 0; k < T; ++k) {
                const VectorXd& v = tr.steps[size_t(k)].*member;
                if (v.size() == dm * dm)
                    std::copy(v.data(), v.data() + v.size(), p + k * dm * dm);
                else
                    std::fill(p + k * dm * dm, p + (k + 1) * dm * dm, std::numeric_limits<double>::quiet_NaN());
            }
            return a;
        };
        out["macro_gradient"] = macro(&StepRecord::macro_gradient);
        out["macro_stress"] = macro(&StepRecord::macro_stress);
    }
    out["final_status"] = to_string(tr.final_status);
    out["failed_step"] = tr.failed_step;
    out["failure_message"] = tr.failure_message;
    return out;
}

Scene scene_from_json_text(const std::string& text, const std::string& base_directory)
{
    return parse_scene_text(text, base_directory, "<dict>");
}

/// A problem given as a Python dict: through Python's json (no NaN, only JSON types).
ReducedFunctional reduced_functional_from_dict(
    const py::dict& document, const py::object& base_directory, const std::string& device)
{
    std::string text;
    try {
        text = py::module_::import("json").attr("dumps")(document, py::arg("allow_nan") = false).cast<std::string>();
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_ValueError) && !e.matches(PyExc_TypeError))
            throw;
        throw InputError("<dict>",
            std::string("the problem is not plain JSON (no NaN, infinity or other types): ")
                + py::str(e.value()).cast<std::string>());
    }
    const std::string base = base_directory.is_none()
        ? std::filesystem::current_path().string()
        : py::str(py::module_::import("os").attr("fspath")(base_directory)).cast<std::string>();
    return ReducedFunctional(parse_json_text(text, "<dict>"), base, "<dict>", device);
}

/// A #V by dim array of finite values, else an InputError (ValueError) naming `what`.
void check_shape(const MatrixXd& x, const Simulator& s, const std::string& what)
{
    if (x.rows() != s.mesh().num_vertices() || x.cols() != s.mesh().dim)
        throw InputError(what,
            "expected an array of shape (" + std::to_string(s.mesh().num_vertices()) + ", "
                + std::to_string(s.mesh().dim) + "), got (" + std::to_string(x.rows()) + ", " + std::to_string(x.cols())
                + ")");
    if (!x.allFinite())
        throw InputError(what, "non-finite value");
}

/// One Python thread at a time per Simulator: run() releases the GIL while it steps, and a
/// second thread calling into the same Simulator meanwhile would race with it.
class Exclusive {
public:
    explicit Exclusive(const Simulator& s)
        : m_simulator(&s)
    {
        std::lock_guard<std::mutex> lock(mutex());
        if (!busy().insert(m_simulator).second)
            throw std::runtime_error("this Simulator is in use by another thread (a run() in progress); use one "
                                     "Simulator per thread");
    }
    ~Exclusive()
    {
        std::lock_guard<std::mutex> lock(mutex());
        busy().erase(m_simulator);
    }
    Exclusive(const Exclusive&) = delete;
    Exclusive& operator=(const Exclusive&) = delete;

private:
    static std::mutex& mutex()
    {
        static std::mutex m;
        return m;
    }
    static std::unordered_set<const Simulator*>& busy()
    {
        static std::unordered_set<const Simulator*> b;
        return b;
    }
    const Simulator* m_simulator;
};

/// p as a copied vector; a wrong shape is an InputError like a wrong size.
VectorXd parameter_vector(const py::array_t<double, py::array::c_style | py::array::forcecast>& p, Index size)
{
    if (p.ndim() != 1)
        throw InputError("parameters",
            "expected a 1D array of " + std::to_string(size) + " values, got " + std::to_string(p.ndim())
                + " dimensions");
    return Eigen::Map<const VectorXd>(p.data(), p.shape(0));
}

Evaluation evaluate_without_gil(const ReducedFunctional& rf, const VectorXd& p, bool gradient, bool constraints = false)
{
    py::gil_scoped_release release;
    return rf.evaluate(p, gradient, constraints);
}

void bind_errors(py::module_& m)
{
    py::register_exception<InputError>(m, "InputError", PyExc_ValueError);
    py::register_exception<AdjointError>(m, "AdjointError", PyExc_RuntimeError);
}

void bind_scene(py::module_& m)
{
    py::class_<Scene>(m, "Scene", "A validated scene (see docs/scene_format.md)")
        .def_readonly("dimension", &Scene::dim)
        .def_property_readonly("num_vertices", [](const Scene& s) { return s.mesh.num_vertices(); })
        .def_property_readonly("num_elements", [](const Scene& s) { return s.mesh.num_elements(); })
        .def_property_readonly("rest_positions", [](const Scene& s) { return MatrixXd(s.mesh.rest_positions); })
        .def_property_readonly("elements", [](const Scene& s) { return Eigen::MatrixXi(s.mesh.elements); })
        .def_property_readonly(
            "boundary_facets", [](const Scene& s) { return Eigen::MatrixXi(s.mesh.boundary_facets); })
        .def_property_readonly("vertex_body", [](const Scene& s) { return Eigen::VectorXi(s.mesh.vertex_body); })
        .def_property_readonly("steps", [](const Scene& s) { return s.time.steps; })
        .def_property_readonly("dt", [](const Scene& s) { return s.time.dt; })
        .def_property_readonly("integrator", [](const Scene& s) { return to_string(s.time.integrator); });
}

void bind_threads(py::module_& m)
{
    m.def(
        "set_threads",
        [](int count) { return to_json(set_threads(count, ThreadSource::EXPLICIT, "diffipc.set_threads")).dump(); },
        py::arg("count"),
        "Set the threads of TBB, OpenBLAS and OpenMP (0: the cores this process may use); returns the configuration "
        "as JSON text.");
    m.def(
        "_thread_info",
        [] {
            ensure_threads_configured();
            return to_json(thread_config()).dump();
        },
        "The effective thread configuration as JSON text.");
}

void bind_scene_loading(py::module_& m)
{
    m.def("load_scene", static_cast<Scene (*)(const std::string&)>(&load_scene), py::arg("path"),
        "Read and validate a JSON scene file.");
    m.def("_scene_from_json_text", &scene_from_json_text, py::arg("text"), py::arg("base_directory"));
}

void bind_simulator(py::module_& m)
{
    py::class_<Simulator>(m, "Simulator", "Transactional time stepping of a scene.")
        .def(py::init<Scene>(), py::arg("scene"))
        .def(
            "step",
            [](Simulator& s) {
                const Exclusive exclusive(s);
                return to_string(s.step());
            },
            "Attempt one time step; returns the status name (only CONVERGED commits).")
        .def(
            "run",
            [](Simulator& s, const std::function<void(int, double)>& progress) {
                const Exclusive exclusive(s);
                {
                    // The GIL is released while stepping and taken back between steps for the
                    // progress callback and for Ctrl-C: a KeyboardInterrupt stops the run after
                    // the current step, with every committed step kept.
                    py::gil_scoped_release release;
                    if (s.current_step() < s.steps_done())
                        s.recompute_steps(s.steps_done());
                    while (s.steps_done() < s.scene().time.steps) {
                        if (s.step() != StepStatus::CONVERGED)
                            break;
                        py::gil_scoped_acquire acquire;
                        if (progress)
                            progress(s.trajectory().steps.back().index, s.trajectory().steps.back().time);
                        if (PyErr_CheckSignals() != 0)
                            throw py::error_already_set();
                    }
                }
                return trajectory_dict(s);
            },
            py::arg("progress") = std::function<void(int, double)>(),
            "Run the remaining steps; returns the trajectory as a dict of numpy arrays. Ctrl-C stops it after "
            "the current step (KeyboardInterrupt; the committed steps stay).")
        .def(
            "trajectory",
            [](const Simulator& s) {
                const Exclusive exclusive(s);
                return trajectory_dict(s);
            },
            "The committed trajectory as a dict of numpy arrays.")
        .def_property_readonly("steps_done", &Simulator::steps_done)
        .def_property_readonly("time", &Simulator::time)
        .def_property_readonly("positions",
            [](const Simulator& s) {
                const Exclusive exclusive(s);
                return MatrixXd(unflatten(s.positions(), s.mesh().dim));
            })
        .def_property_readonly("velocities",
            [](const Simulator& s) {
                const Exclusive exclusive(s);
                return MatrixXd(unflatten(s.velocities(), s.mesh().dim));
            })
        .def_property_readonly(
            "contact_forces",
            [](const Simulator& s) {
                const Exclusive exclusive(s);
                return MatrixXd(unflatten(s.contact_forces(), s.mesh().dim));
            },
            "#V by dim contact forces (N), -dB/dx at the committed state; zero without contact.")
        .def_property_readonly(
            "friction_forces",
            [](const Simulator& s) {
                const Exclusive exclusive(s);
                return MatrixXd(unflatten(s.friction_forces(), s.mesh().dim));
            },
            "#V by dim friction forces (N), -dD/dx at the committed state with the lagged data of the last "
            "step; zero without friction and before the first step.")
        .def_property_readonly("force_scale", &Simulator::force_scale)
        .def(
            "energy",
            [](const Simulator& s, const MatrixXd& x) {
                const Exclusive exclusive(s);
                check_shape(x, s, "positions");
                const Positions p = x;
                return s.problem().energy(flatten(p));
            },
            py::arg("positions"), "Incremental potential of the last prepared step at #V by dim positions.")
        .def(
            "set_element_materials",
            [](Simulator& s, const VectorXd& E, const VectorXd& nu) {
                const Exclusive exclusive(s);
                s.set_element_materials(E, nu);
            },
            py::arg("E"), py::arg("nu"), "Per-element Young's modulus and Poisson's ratio (before the first step).")
        .def(
            "set_initial_state",
            [](Simulator& s, const MatrixXd& x, const MatrixXd& v) {
                const Exclusive exclusive(s);
                check_shape(x, s, "positions");
                check_shape(v, s, "velocities");
                const Positions xc = x, vc = v;
                s.set_initial_state(flatten(xc), flatten(vc));
            },
            py::arg("positions"), py::arg("velocities"),
            "Initial #V by dim positions and velocities (before the first step); prescribed dofs keep theirs.")
        .def("write_hdf5",
            [](const Simulator& s, const std::string& path) {
                const Exclusive exclusive(s);
                write_hdf5(path, s.mesh(), s.trajectory(), s.contact() != nullptr, s.scene().time.adaptive.enabled);
            })
        .def("summary", [](const Simulator& s) {
            const Exclusive exclusive(s);
            return summary_json(s).dump();
        });
}

void bind_elastic_elements(py::module_& m)
{
    auto model = [](const std::string& name) { return parse_material_model(name, "model"); };
    m.def(
        "lame_parameters",
        [](double E, double nu, bool plane_stress) {
            return std::make_pair(lame_mu(E, nu), lame_lambda(E, nu, plane_stress));
        },
        py::arg("E"), py::arg("nu"), py::arg("plane_stress") = false,
        "(mu, lambda) from Young's modulus and Poisson's ratio (3D and plane strain; plane_stress=True: the 2D "
        "lambda of a thin sheet, E nu / (1 - nu^2)).");
    m.def(
        "element_energy",
        [model](const std::string& name, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda) {
            return element_energy(model(name), rest, deformed, mu, lambda);
        },
        py::arg("model"), py::arg("rest"), py::arg("deformed"), py::arg("mu"), py::arg("lam"),
        "Elastic energy (J) of one P1 element; rest/deformed are (dim+1) by dim.");
    m.def(
        "element_gradient",
        [model](const std::string& name, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda) {
            return element_gradient(model(name), rest, deformed, mu, lambda);
        },
        py::arg("model"), py::arg("rest"), py::arg("deformed"), py::arg("mu"), py::arg("lam"),
        "Gradient w.r.t. deformed positions flattened vertex-major.");
    m.def(
        "element_hessian",
        [model](const std::string& name, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda,
            bool project) { return element_hessian(model(name), rest, deformed, mu, lambda, project); },
        py::arg("model"), py::arg("rest"), py::arg("deformed"), py::arg("mu"), py::arg("lam"),
        py::arg("project_to_psd") = false,
        "Hessian w.r.t. deformed positions flattened vertex-major (optionally PSD-projected).");
}

void bind_evaluation(py::module_& m)
{
    py::class_<Evaluation>(m, "Evaluation", "One evaluation of a reduced functional.")
        .def_readonly("value", &Evaluation::value, "J")
        .def_property_readonly(
            "gradient",
            [](const Evaluation& e) -> py::object {
                if (e.gradient.size() == 0)
                    return py::none();
                return py::cast(e.gradient);
            },
            "dJ/dp (numpy), or None if not requested")
        .def_property_readonly(
            "constraint_values", [](const Evaluation& e) { return VectorXd(e.constraint_values); },
            "g_i(p) of every constraint (numpy; empty unless evaluation(..., constraints=True))")
        .def_property_readonly(
            "constraint_gradients",
            [](const Evaluation& e) -> py::object {
                if (e.constraint_gradients.size() == 0 && e.constraint_values.size() > 0)
                    return py::none();
                return py::cast(MatrixXd(e.constraint_gradients));
            },
            "dg_i/dp as row i (numpy, #constraints by size), or None if the gradient was not requested")
        .def_readonly("forward_time", &Evaluation::forward_time, "s, summed over load cases")
        .def_readonly("adjoint_blocks", &Evaluation::adjoint_blocks,
            "with the gradient: the parameter blocks the adjoint computed (rest_positions, lame, density, "
            "friction, initial_displacement, initial_velocity, prescribed, macro)")
        .def_readonly("adjoint_time", &Evaluation::adjoint_time,
            "s, summed over load cases (with checkpointing: the recomputed steps included)")
        .def_property_readonly(
            "checkpoints",
            [](const Evaluation& e) {
                py::list out;
                for (const LoadCaseCheckpoint& c : e.checkpoints) {
                    const CheckpointStatistics& r = c.records;
                    py::dict d;
                    d["steps"] = r.steps;
                    d["stride"] = r.stride;
                    d["checkpoints"] = r.checkpoints;
                    d["peak_stored_states"] = r.peak_stored_states;
                    d["peak_stored_bytes"] = r.peak_stored_bytes;
                    d["bound_stored_states"] = r.bound_stored_states;
                    d["recomputed_steps"] = r.recomputed_steps;
                    d["forward_time"] = r.forward_time;
                    d["recompute_time"] = r.recompute_time;
                    d["adjoint_time"] = r.adjoint_time;
                    d["cost_ratio"] = r.cost_ratio;
                    d["objective_stored_states"] = c.objective_stored_states;
                    d["objective_stored_bytes"] = c.objective_stored_bytes;
                    out.append(d);
                }
                return out;
            },
            "With the problem's \"checkpointing\" and a gradient: one dict per load case (steps, stride, "
            "checkpoints, peak_stored_states, peak_stored_bytes, bound_stored_states, recomputed_steps, "
            "forward_time, recompute_time, adjoint_time, cost_ratio, objective_stored_states, "
            "objective_stored_bytes); else an empty list.");
}

void bind_reduced_functional(py::module_& m)
{
    py::class_<ReducedFunctional>(
        m, "ReducedFunctional", "p -> J(p) and its adjoint gradient dJ/dp for a problem file (docs/problem_format.md).")
        .def(py::init([](const std::filesystem::path& path, const std::string& device) {
            return ReducedFunctional::load(path.string(), device);
        }),
            py::arg("path"), py::arg("device") = "",
            "Load and validate a problem file; scene paths are relative to it. device: \"cpu\" or \"gpu\" runs "
            "every load case's simulations and adjoint solves there, replacing the scenes' \"device\" (\"\": "
            "theirs).")
        .def(py::init(&reduced_functional_from_dict), py::arg("problem"), py::arg("base_directory") = py::none(),
            py::arg("device") = "",
            "A problem as a dict; scene and mesh paths are relative to base_directory (default: the current "
            "directory); device as for a problem file.")
        .def_property_readonly("size", &ReducedFunctional::size, "Number of optimization variables.")
        .def_property_readonly(
            "initial", [](const ReducedFunctional& rf) { return VectorXd(rf.initial()); },
            "The scenes' own parameter values (the starting point).")
        .def_property_readonly(
            "scales", [](const ReducedFunctional& rf) { return VectorXd(rf.scales()); },
            "A typical magnitude per variable (gradcheck's direction scale).")
        .def_property_readonly(
            "layout", &ReducedFunctional::layout, "[(type, size)] per entry of the problem's parameter list.")
        .def_property_readonly("design_size", &ReducedFunctional::design_size,
            "Number of design variables x (the inputs of the entries' maps; docs/parametrizations.md).")
        .def_property_readonly(
            "design_initial", [](const ReducedFunctional& rf) { return VectorXd(rf.design_initial()); },
            "x at the start (the entries' \"initial\", else the maps' inverse of the scenes' values).")
        .def_property_readonly(
            "design_lower", [](const ReducedFunctional& rf) { return VectorXd(rf.design_lower()); },
            "Lower bounds of x (the entries' \"lower\"; -inf without).")
        .def_property_readonly(
            "design_upper", [](const ReducedFunctional& rf) { return VectorXd(rf.design_upper()); },
            "Upper bounds of x (the entries' \"upper\"; +inf without).")
        .def_property_readonly("design_layout", &ReducedFunctional::design_layout,
            "[(type, design size)] per entry of the problem's parameter list.")
        .def(
            "parameters_of",
            [](const ReducedFunctional& rf, const py::array_t<double, py::array::c_style | py::array::forcecast>& x) {
                return rf.parameters_of(parameter_vector(x, rf.design_size()));
            },
            py::arg("x"), "p = P(x): the parameters the design variables give.")
        .def(
            "design_gradient",
            [](const ReducedFunctional& rf, const py::array_t<double, py::array::c_style | py::array::forcecast>& x,
                const py::array_t<double, py::array::c_style | py::array::forcecast>& dJ_dp) {
                return rf.design_gradient(parameter_vector(x, rf.design_size()), parameter_vector(dJ_dp, rf.size()));
            },
            py::arg("x"), py::arg("dJ_dp"), "dJ/dx = P'(x)^T dJ/dp (the maps' vector-Jacobian products in reverse).")
        .def_property_readonly(
            "check_settings",
            [](const ReducedFunctional& rf) {
                const auto& c = rf.check_settings();
                py::dict d;
                d["directions"] = c.directions;
                d["seed"] = c.seed;
                d["step"] = c.step;
                d["halvings"] = c.halvings;
                return d;
            },
            "The problem file's \"gradcheck\" settings (defaults where absent).")
        .def_property_readonly(
            "checkpointing",
            [](const ReducedFunctional& rf) {
                const CheckpointSettings& c = rf.checkpointing();
                py::dict d;
                d["mode"] = c.mode == CheckpointSettings::Mode::NONE ? "none" : "stride";
                d["stride"] = c.stride;
                return d;
            },
            "The problem file's \"checkpointing\" as a dict (mode \"stride\" or \"none\", stride; 0: the "
            "default ceil(sqrt(h T))); mode \"none\" without it.")
        .def(
            "evaluation",
            [](const ReducedFunctional& rf, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                bool gradient, bool constraints) {
                return evaluate_without_gil(rf, parameter_vector(p, rf.size()), gradient, constraints);
            },
            py::arg("p"), py::arg("gradient") = true, py::arg("constraints") = false,
            "An Evaluation (value, gradient, forward and adjoint seconds; with constraints=True also every "
            "constraint's functional and its gradient, from the same forward runs). Raises ValueError for a p of the "
            "wrong size or with a non-finite entry, AdjointError if a forward step fails or no gradient can be "
            "computed.")
        .def(
            "evaluation_of_case",
            [](const ReducedFunctional& rf, size_t c,
                const py::array_t<double, py::array::c_style | py::array::forcecast>& p, bool gradient,
                bool constraints) {
                if (c >= rf.load_cases())
                    throw py::index_error("load case " + std::to_string(c) + " of " + std::to_string(rf.load_cases()));
                const VectorXd pv = parameter_vector(p, rf.size());
                py::gil_scoped_release release;
                return rf.evaluate_case(c, pv, gradient, constraints);
            },
            py::arg("case"), py::arg("p"), py::arg("gradient") = true, py::arg("constraints") = false,
            "Load case `case`'s share of evaluation(p): its weighted objective and gradient, the rows of the "
            "constraints on it (the others zero), its times. evaluation() is the sum of the shares in case order "
            "(sum_shares), wherever they were computed; the checks on the sum are sum_shares' caller's.")
        .def_static(
            "sum_shares",
            [](const std::vector<Evaluation>& shares) {
                Evaluation total;
                for (const Evaluation& e : shares)
                    ReducedFunctional::add_share(total, e);
                return total;
            },
            py::arg("shares"),
            "The Evaluation whose parts are the sums of the shares' (evaluation_of_case), added in list order: in "
            "case order, the same bits as evaluation().")
        .def_property_readonly("load_cases", &ReducedFunctional::load_cases, "Number of load cases (scenes).")
        .def_property_readonly(
            "constraints",
            [](const ReducedFunctional& rf) {
                py::list out;
                for (const ConstraintSpec& c : rf.constraints()) {
                    py::dict d;
                    d["name"] = c.name;
                    d["kind"] = c.kind == ConstraintSpec::Kind::UPPER ? "upper"
                        : c.kind == ConstraintSpec::Kind::LOWER       ? "lower"
                                                                      : "equals";
                    d["bound"] = c.bound;
                    d["case"] = c.load_case;
                    out.append(d);
                }
                return out;
            },
            "The problem's constraints: [{name, kind (\"upper\", \"lower\", \"equals\"), bound, case}].")
        .def(
            "evaluate",
            [](const ReducedFunctional& rf, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                bool gradient) {
                const Evaluation e = evaluate_without_gil(rf, parameter_vector(p, rf.size()), gradient);
                return py::make_tuple(e.value, gradient ? py::cast(e.gradient) : py::none());
            },
            py::arg("p"), py::arg("gradient") = true,
            "(J, dJ/dp) with dJ/dp a numpy array, or None if gradient=False; raises like evaluation().");
}

} // namespace

// Defined in the other *_bindings.cpp files of this module.
void bind_minimize(py::module_&); // _minimize (minimize_bindings.cpp)
void bind_microstructure(py::module_&); // CellFamily, CellDesign (microstructure_bindings.cpp)
void bind_distribution(py::module_&); // Communicator, _distribute (distribution_bindings.cpp)
void bind_gradient_check(py::module_&); // _check_direction, _richardson_one_sided (gradient_check_bindings.cpp)
void bind_stress(py::module_&); // Simulator.element_von_mises, young_poisson_of_lame (stress_bindings.cpp)

PYBIND11_MODULE(_diffipc, m)
{
    m.doc() = "diffipc: differentiable IPC elastodynamics (forward solver)";
    // In this order: a class is registered before any later signature or default argument names it,
    // and bind_stress adds a method to Simulator.
    bind_errors(m);
    bind_scene(m);
    bind_threads(m);
    bind_scene_loading(m);
    bind_simulator(m);
    bind_elastic_elements(m);
    bind_evaluation(m);
    bind_reduced_functional(m);
    bind_minimize(m);
    bind_microstructure(m);
    bind_distribution(m);
    bind_gradient_check(m);
    bind_stress(m);
}
