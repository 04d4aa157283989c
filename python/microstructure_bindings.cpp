// pybind11 bindings of the microstructure cells (shape_opt/microstructure/, issue 15):
// _diffipc.CellFamily (a family file's variables, its level set and meshes as numpy arrays) and
// _diffipc.CellDesign (the plateau objective of a cell's compression, its gradient, and the
// cell's optimization), _diffipc.DropDesign (a drop test's peak stress on a pad of the cell, the
// same). python/diffipc/microstructure.py documents them for users.
// Heavy calls release the GIL; the optimization's progress callback takes it back.

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"
#include "shape_opt/microstructure/cell_design.hpp"
#include "shape_opt/microstructure/cell_optimization.hpp"
#include "shape_opt/microstructure/drop_design.hpp"

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace py = pybind11;
using namespace diffipc;

namespace {

VectorXd design_vector(
    const CellFamily& family, const py::array_t<double, py::array::c_style | py::array::forcecast>& p)
{
    if (p.ndim() != 1 || p.shape(0) != py::ssize_t(family.size()))
        throw InputError(
            "design", "expected a vector of the family's " + std::to_string(family.size()) + " design variables");
    VectorXd x = Eigen::Map<const VectorXd>(p.data(), family.size());
    family.check(x, "design");
    return x;
}

py::dict value_dict(const DesignValue& e)
{
    py::dict d;
    d["ok"] = e.ok;
    d["message"] = e.message;
    d["J"] = e.J;
    d["gradient"] = e.gradient.size() ? py::cast(e.gradient) : py::none();
    return d;
}

py::dict evaluation_dict(const CellEvaluation& e)
{
    py::dict d = value_dict(e);
    d["strain"] = e.strain;
    d["stress"] = e.stress;
    d["shear"] = e.shear;
    d["lateral"] = e.lateral;
    d["contacts"] = e.contacts;
    d["vertices"] = e.vertices;
    d["elements"] = e.elements;
    d["newton_iterations"] = e.newton_iterations;
    d["seconds"] = e.seconds;
    return d;
}

nlohmann::json json_of(const py::dict& settings)
{
    const std::string text = py::module_::import("json").attr("dumps")(settings).cast<std::string>();
    return parse_json_text(text, "settings");
}

const char* const optimize_doc = "Minimize J from x0 (docs/microstructures.md, \"Optimization\"), the variables named "
                                 "in `fixed` held: dict of x, final (J, gradient on a new mesh), history, remeshes, "
                                 "evaluations, rejected, rejections (x and reason of each rejected design), reason, "
                                 "message";

py::dict optimize_dict(const CellObjective& d, const py::array_t<double, py::array::c_style | py::array::forcecast>& x0,
    const std::string& algorithm, int max_iterations, double remesh_quality, const std::vector<std::string>& fixed,
    const std::function<void(py::dict)>& callback)
{
    const VectorXd x = design_vector(d.family(), x0);
    CellOptimizationSettings o;
    o.optimizer.algorithm = parse_optimizer_algorithm(algorithm, "algorithm");
    o.optimizer.max_iterations = max_iterations;
    o.remesh_quality = remesh_quality;
    o.fixed = fixed;
    auto record = [](const CellIteration& it) {
        py::dict r;
        r["iteration"] = it.iteration;
        r["mesh"] = it.mesh;
        r["J"] = it.J;
        r["gradient_norm"] = it.gradient_norm;
        r["quality"] = it.quality;
        r["seconds"] = it.seconds;
        r["x"] = it.x;
        return r;
    };
    CellOptimizationResult r;
    {
        py::gil_scoped_release release;
        r = optimize_cell(d, x, o, [&](const CellIteration& it) {
            if (!callback)
                return;
            py::gil_scoped_acquire acquire;
            callback(record(it));
        });
    }
    py::dict out;
    out["x"] = r.x;
    out["final"] = value_dict(r.final);
    py::list history;
    for (const CellIteration& it : r.history)
        history.append(record(it));
    out["history"] = history;
    out["remeshes"] = r.remeshes;
    out["evaluations"] = r.evaluations;
    out["rejected"] = r.rejected();
    py::list rejections;
    for (const CellRejection& j : r.rejections) {
        py::dict d;
        d["x"] = j.x;
        d["reason"] = j.reason;
        rejections.append(d);
    }
    out["rejections"] = rejections;
    out["reason"] = to_string(r.reason);
    out["message"] = r.message;
    return out;
}

} // namespace

void bind_microstructure(py::module_& m)
{
    py::class_<CellFamily>(m, "CellFamily", "A microstructure cell family (a family file: graph, symmetry, bounds).")
        .def(py::init([](const std::string& path) { return read_cell_family(path); }), py::arg("path"))
        .def_property_readonly("names", &CellFamily::names)
        .def_property_readonly("lower", &CellFamily::lower)
        .def_property_readonly("upper", &CellFamily::upper)
        .def_property_readonly("initial", &CellFamily::initial)
        .def_property_readonly("width_index", &CellFamily::width_index)
        .def_property_readonly("symmetry", [](const CellFamily& f) { return to_string(f.symmetry()); })
        .def_property_readonly("nodes", [](const CellFamily& f) { return MatrixXd(f.graph().nodes); })
        .def_property_readonly("edges", [](const CellFamily& f) { return Eigen::MatrixXi(f.graph().edges); })
        .def(
            "sdf",
            [](const CellFamily& f, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                const Eigen::Ref<const MatrixXd>& points) {
                if (points.cols() != 2)
                    throw InputError("points", "expected an (N, 2) array of graph coordinates");
                const CellSDF sdf(f.graph(), f.cell_parameters(design_vector(f, p)));
                VectorXd phi(points.rows());
                for (Index i = 0; i < points.rows(); ++i)
                    phi[i] = sdf.value(points.row(i).transpose());
                return phi;
            },
            py::arg("p"), py::arg("points"),
            "The level set phi at (N, 2) points in graph coordinates ([-1, 1]^2 is the cell): solid where < 0.")
        .def(
            "mesh",
            [](const CellFamily& f, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                double size, double height) {
                const VectorXd x = design_vector(f, p);
                CellMeshSettings s;
                s.size = size;
                s.height = height;
                Mesh mesh;
                {
                    py::gil_scoped_release release;
                    mesh = mesh_design(f, x, s);
                }
                return py::make_tuple(MatrixXd(mesh.rest_positions), Eigen::MatrixXi(mesh.elements));
            },
            py::arg("p"), py::arg("size") = 0.025, py::arg("height") = 1.0,
            "(vertices (V, 2), triangles (E, 3)): the periodic mesh of design p, box [-w h/2, w h/2] x [-h/2, h/2].");

    py::class_<CellObjective>(
        m, "CellObjective", "A function of a cell family's design (the base of CellDesign and DropDesign).");

    py::class_<CellDesign, CellObjective>(
        m, "CellDesign", "A cell's plateau objective over its compression (docs/microstructures.md).")
        .def(py::init([](const CellFamily& family, const py::dict& settings) {
            return CellDesign(family, parse_cell_design_settings(JsonField(json_of(settings), "settings")));
        }),
            py::arg("family"), py::arg("settings"))
        .def_property_readonly("family", &CellDesign::family)
        .def(
            "scene",
            [](const CellDesign& d, const std::string& mesh_file, double width) {
                return d.scene(mesh_file, width).dump();
            },
            py::arg("mesh_file"), py::arg("width"), "The periodic compression scene of a cell mesh file (JSON text).")
        .def(
            "write_scene",
            [](const CellDesign& d, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                const std::string& directory) { return d.write_scene(design_vector(d.family(), p), directory); },
            py::arg("p"), py::arg("directory"),
            "Write design p's cell (cell.msh) and compression (scene.json) into `directory`; returns the scene's path.")
        .def(
            "evaluate",
            [](const CellDesign& d, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                bool gradient) {
                const VectorXd x = design_vector(d.family(), p);
                CellEvaluation e;
                {
                    py::gil_scoped_release release;
                    e = d.evaluate(x, gradient);
                }
                return evaluation_dict(e);
            },
            py::arg("p"), py::arg("gradient") = false,
            "Compress design p's cell (a new mesh): dict of J, gradient, strain, stress, shear, lateral, contacts, ...")
        .def("optimize", &optimize_dict, py::arg("x0"), py::arg("algorithm") = "lbfgsb", py::arg("max_iterations") = 50,
            py::arg("remesh_quality") = 0.3, py::arg("fixed") = std::vector<std::string> {},
            py::arg("callback") = nullptr, optimize_doc);

    py::class_<DropDesign, CellObjective>(m, "DropDesign",
        "A block dropped on a pad tiled from a cell: the smooth maximum of the stress it feels "
        "(docs/microstructures.md).")
        .def(py::init([](const CellFamily& family, const py::dict& settings) {
            return DropDesign(family, parse_drop_settings(JsonField(json_of(settings), "settings")));
        }),
            py::arg("family"), py::arg("settings"))
        .def_property_readonly("family", &DropDesign::family)
        .def(
            "scene",
            [](const DropDesign& d, const std::string& pad_file, double width) {
                return d.scene(pad_file, width).dump();
            },
            py::arg("pad_file"), py::arg("width"), "The drop's scene for a pad mesh file of cell width w (JSON text).")
        .def(
            "write_scene",
            [](const DropDesign& d, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                const std::string& directory) { return d.write_scene(design_vector(d.family(), p), directory); },
            py::arg("p"), py::arg("directory"),
            "Write design p's pad (pad.msh) and the drop (scene.json) into `directory`; returns the scene's path.")
        .def(
            "evaluate",
            [](const DropDesign& d, const py::array_t<double, py::array::c_style | py::array::forcecast>& p,
                bool gradient) {
                const VectorXd x = design_vector(d.family(), p);
                DropEvaluation e;
                {
                    py::gil_scoped_release release;
                    e = d.evaluate(x, gradient);
                }
                py::dict r = value_dict(e);
                r["time"] = e.time;
                r["stress"] = e.stress;
                r["deceleration"] = e.deceleration;
                r["peak"] = e.peak;
                r["width"] = e.width;
                r["vertices"] = e.vertices;
                r["elements"] = e.elements;
                r["newton_iterations"] = e.newton_iterations;
                r["seconds"] = e.seconds;
                return r;
            },
            py::arg("p"), py::arg("gradient") = false,
            "Drop the block on design p's pad (a new mesh): dict of J, gradient, time, stress (Pa), deceleration, "
            "peak, ...")
        .def("optimize", &optimize_dict, py::arg("x0"), py::arg("algorithm") = "lbfgsb", py::arg("max_iterations") = 50,
            py::arg("remesh_quality") = 0.3, py::arg("fixed") = std::vector<std::string> {},
            py::arg("callback") = nullptr, optimize_doc);
}
