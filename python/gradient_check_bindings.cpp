// diffipc.gradcheck's verdict on one direction: the C++ check that `diffipc gradcheck` runs
// (shape_opt/gradient_check.hpp), so that Python and the CLI judge with one piece of code.

#include "shape_opt/gradient_check.hpp"

#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

namespace py = pybind11;
using namespace diffipc;

namespace {

py::dict check_dict(const DirectionCheck& c)
{
    py::dict d;
    d["verdict"] = verdict_name(c.verdict);
    d["passed"] = passed(c.verdict);
    d["slope"] = c.slope;
    d["central"] = c.central;
    d["central_error"] = c.central_error;
    py::list taylor;
    for (const auto& row : c.taylor)
        taylor.append(py::make_tuple(row.h, row.first, row.second));
    d["taylor"] = taylor;
    d["floor"] = c.floor;
    d["last_rate"] = c.last_rate;
    d["resolved"] = c.resolved;
    d["one_sided"] = c.one_sided;
    // Only measured when the central difference disagreed.
    if (c.one_sided) {
        d["forward"] = c.forward;
        d["backward"] = c.backward;
        d["forward_error"] = c.forward_error;
        d["backward_error"] = c.backward_error;
    }
    return d;
}

} // namespace

void bind_gradient_check(py::module_& m)
{
    m.attr("GRADIENT_CHECK_TOLERANCE") = GRADIENT_CHECK_TOLERANCE;
    m.attr("KINK_SLOPE_GAP") = KINK_SLOPE_GAP;
    m.def(
        "_check_direction",
        [](const std::function<double(double)>& j, double j0, double slope, double step, int halvings) {
            if (!(step > 0))
                throw py::value_error("check_direction: step must be > 0, got " + std::to_string(step));
            if (halvings < 0)
                throw py::value_error("check_direction: halvings must be >= 0, got " + std::to_string(halvings));
            return check_dict(check_direction(j, j0, slope, step, halvings));
        },
        py::arg("j"), py::arg("j0"), py::arg("slope"), py::arg("step"), py::arg("halvings"),
        "shape_opt/gradient_check.hpp's check_direction: j(h) = J(p + h dp), j0 = j(0), slope = g.dp. Returns a "
        "dict: verdict (\"PASS\", \"PASS (kink)\", \"FAIL\", \"NOT DIFFERENTIABLE\", \"INCONCLUSIVE\"), passed, "
        "slope, central, central_error, taylor [(h, |j(h)-j0|, |j(h)-j0-h slope|)], floor, last_rate, resolved, "
        "one_sided and, if one_sided, forward, backward, forward_error, backward_error.");
    m.def(
        "_richardson_one_sided",
        [](const std::vector<double>& quotients) {
            if (quotients.size() < 3)
                throw py::value_error(
                    "richardson_one_sided needs at least three quotients, got " + std::to_string(quotients.size()));
            return richardson_one_sided(quotients);
        },
        py::arg("quotients"),
        "shape_opt/gradient_check.hpp's richardson_one_sided: of one-sided quotients D(h_i), h_i = h_0 / 2^i.");
}
