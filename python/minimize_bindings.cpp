// pybind11 binding of minimize() (shape_opt/optimizer/optimizer.hpp) as
// _diffipc._minimize(fun, x0, method, lower, upper, n_ineq, n_eq, options, callback, valid_step);
// python/diffipc/optimize.py wraps it as diffipc.minimize with scipy's conventions.
// The GIL is held throughout: every callable is Python. An exception raised by one of them
// (KeyboardInterrupt included) ends the run and is raised again from _minimize.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <string>

namespace py = pybind11;
using namespace diffipc;

namespace {

/// `value` as a `rows` by `cols` matrix of doubles (a vector: cols == 0); None is an empty
/// one, accepted only when rows == 0. A wrong shape is an InputError (ValueError) naming `what`.
MatrixXd to_matrix(const py::handle& value, Index rows, Index cols, const std::string& what)
{
    const std::string shape = cols == 0 ? "(" + std::to_string(rows) + ",)"
                                        : "(" + std::to_string(rows) + ", " + std::to_string(cols) + ")";
    if (value.is_none()) {
        if (rows == 0)
            return MatrixXd(0, std::max<Index>(cols, 1));
        throw InputError("minimize", what + " is None, expected shape " + shape);
    }
    py::array_t<double, py::array::c_style | py::array::forcecast> a;
    try {
        a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
    } catch (const py::error_already_set&) {
        a = py::array_t<double, py::array::c_style | py::array::forcecast>();
    }
    if (!a)
        throw InputError("minimize", what + " is not an array of numbers");
    const Index size = Index(a.size());
    // A (1, n) Jacobian may come as a vector of n; a vector may come as (m, 1) or (1, m).
    const bool fits = cols == 0
        ? (size == rows && (a.ndim() <= 1 || (a.ndim() == 2 && (a.shape(0) == 1 || a.shape(1) == 1))))
        : ((a.ndim() == 2 && a.shape(0) == rows && a.shape(1) == cols) || (a.ndim() == 1 && rows == 1 && size == cols)
            || (rows == 0 && size == 0));
    if (!fits) {
        std::string got = "(";
        for (py::ssize_t d = 0; d < a.ndim(); ++d)
            got += (d ? ", " : "") + std::to_string(a.shape(d));
        got += a.ndim() == 1 ? ",)" : ")";
        throw InputError("minimize", what + " has shape " + got + ", expected " + shape);
    }
    MatrixXd m(rows, std::max<Index>(cols, 1));
    const double* p = a.data();
    for (Index i = 0; i < rows; ++i)
        for (Index j = 0; j < std::max<Index>(cols, 1); ++j)
            m(i, j) = p[i * std::max<Index>(cols, 1) + j];
    return m;
}

VectorXd to_vector(const py::handle& value, Index size, const std::string& what)
{
    return to_matrix(value, size, 0, what).col(0);
}

/// The problem as Python callables: fun(x) -> (f, grad, c, dc, h, dh) or None (invalid point).
class PythonProblem : public OptimizationProblem {
public:
    PythonProblem(
        py::function fun, Index n, int inequalities, int equalities, py::object callback, py::object valid_step)
        : m_fun(std::move(fun))
        , m_n(n)
        , m_inequalities(inequalities)
        , m_equalities(equalities)
        , m_callback(std::move(callback))
        , m_valid_step(std::move(valid_step))
    {
    }
    Index size() const override { return m_n; }
    int inequalities() const override { return m_inequalities; }
    int equalities() const override { return m_equalities; }

    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        const py::object r = m_fun(py::array_t<double>(py::ssize_t(x.size()), x.data()));
        if (r.is_none())
            return false;
        if (!py::isinstance<py::tuple>(r) || py::len(r) != 6)
            throw InputError("minimize", "fun(x) must return (f, grad, c, dc, h, dh) or None");
        const py::tuple t = r;
        try {
            out.f = t[0].cast<double>();
        } catch (const py::cast_error&) {
            throw InputError("minimize", "f, returned by fun(x), is not a number");
        }
        out.gradient = to_vector(t[1], m_n, "the gradient returned by fun(x)");
        out.inequality = to_vector(t[2], m_inequalities, "c returned by fun(x)");
        out.inequality_jacobian = to_matrix(t[3], m_inequalities, m_n, "dc returned by fun(x)");
        out.equality = to_vector(t[4], m_equalities, "h returned by fun(x)");
        out.equality_jacobian = to_matrix(t[5], m_equalities, m_n, "dh returned by fun(x)");
        return true;
    }

    double max_valid_step(const VectorXd& x, const VectorXd& dx) override
    {
        if (m_valid_step.is_none())
            return 1.0;
        const py::object t = m_valid_step(py::array_t<double>(py::ssize_t(x.size()), x.data()),
            py::array_t<double>(py::ssize_t(dx.size()), dx.data()));
        return t.is_none() ? 1.0 : t.cast<double>();
    }

    bool iteration(const IterationInfo& info) override
    {
        if (m_callback.is_none())
            return true;
        py::dict d;
        d["iteration"] = info.iteration;
        d["x"] = py::array_t<double>(py::ssize_t(info.x->size()), info.x->data());
        d["fun"] = info.values->f;
        d["jac"] = py::array_t<double>(py::ssize_t(info.values->gradient.size()), info.values->gradient.data());
        d["gradient_norm"] = info.gradient_norm;
        d["step_norm"] = info.step_norm;
        d["nfev"] = info.evaluations;
        d["nrejected"] = info.rejected;
        d["evaluation_seconds"] = info.evaluation_seconds;
        d["optimizer_seconds"] = info.optimizer_seconds;
        const py::object r = m_callback(d);
        return r.is_none() || r.cast<bool>();
    }

private:
    py::function m_fun;
    Index m_n;
    int m_inequalities, m_equalities;
    py::object m_callback, m_valid_step;
};

/// A bound vector from None (empty: no bounds) or an array of n.
VectorXd bound(const py::object& value, Index n, const std::string& field)
{
    if (value.is_none())
        return VectorXd();
    try {
        return to_vector(value, n, field);
    } catch (const InputError& e) {
        throw InputError(field, e.message());
    }
}

/// An option value as the text OptimizerSettings::options holds: str as is, bool as yes/no
/// (Ipopt's convention), int and float as Python prints them (repr round-trips a float).
std::string option_text(const std::string& key, const py::handle& value)
{
    if (py::isinstance<py::str>(value))
        return value.cast<std::string>();
    if (py::isinstance<py::bool_>(value))
        return value.cast<bool>() ? "yes" : "no";
    if (py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value))
        return py::repr(value).cast<std::string>();
    throw InputError("optimizer.options." + key, "must be a str, bool, int or float");
}

OptimizerSettings settings_from(
    const std::string& method, const py::object& lower, const py::object& upper, Index n, const py::dict& options)
{
    OptimizerSettings s;
    s.algorithm = parse_optimizer_algorithm(method, "method");
    s.lower = bound(lower, n, "optimizer.lower");
    s.upper = bound(upper, n, "optimizer.upper");
    for (const auto& [key_handle, value] : options) {
        const std::string key = py::str(key_handle);
        const auto number = [&, &value = value]() {
            try {
                return value.cast<double>();
            } catch (const py::cast_error&) {
                throw InputError("optimizer." + key, "must be a number");
            }
        };
        const auto integer = [&, &value = value]() {
            // int or numpy's integers (anything with __index__), not bool or float
            if (!PyIndex_Check(value.ptr()) || py::isinstance<py::bool_>(value))
                throw InputError("optimizer." + key, "must be an integer");
            return py::int_(py::reinterpret_borrow<py::object>(value)).cast<int>();
        };
        if (key == "gradient_tolerance")
            s.gradient_tolerance = number();
        else if (key == "relative_gradient_tolerance")
            s.relative_gradient_tolerance = number();
        else if (key == "x_tolerance")
            s.x_tolerance = number();
        else if (key == "f_tolerance")
            s.f_tolerance = number();
        else if (key == "max_iterations")
            s.max_iterations = integer();
        else if (key == "max_seconds")
            s.max_seconds = number();
        else if (key == "constraint_tolerance")
            s.constraint_tolerance = number();
        else if (key == "lbfgs_memory")
            s.lbfgs_memory = integer();
        else
            s.options[key] = option_text(key, value);
    }
    return s;
}

} // namespace

void bind_minimize(py::module_& m)
{
    m.def(
        "_minimize",
        [](py::function fun, const py::object& x0_object, const std::string& method, const py::object& lower,
            const py::object& upper, int n_ineq, int n_eq, const py::dict& options, const py::object& callback,
            const py::object& valid_step) {
            py::array_t<double, py::array::c_style | py::array::forcecast> x0_array;
            try {
                x0_array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(x0_object);
            } catch (const py::error_already_set&) {
            }
            if (!x0_array || x0_array.ndim() != 1)
                throw InputError("optimizer.x0", "must be a 1-D array of numbers");
            const VectorXd x0 = Eigen::Map<const VectorXd>(x0_array.data(), x0_array.size());
            if (n_ineq < 0 || n_eq < 0)
                throw InputError("minimize", "negative number of constraints");
            const OptimizerSettings settings = settings_from(method, lower, upper, x0.size(), options);
            PythonProblem problem(std::move(fun), x0.size(), n_ineq, n_eq, callback, valid_step);
            const OptimizerResult r = minimize(problem, x0, settings);
            py::dict d;
            d["x"] = py::array_t<double>(py::ssize_t(r.x.size()), r.x.data());
            d["fun"] = r.values.gradient.size() ? py::object(py::float_(r.values.f)) : py::object(py::none());
            d["jac"] = py::array_t<double>(py::ssize_t(r.values.gradient.size()), r.values.gradient.data());
            d["reason"] = to_string(r.reason);
            d["status"] = int(r.reason);
            d["message"] = r.message;
            d["nit"] = r.iterations;
            d["nfev"] = r.evaluations;
            d["nrejected"] = r.rejected;
            d["maxcv"] = r.max_violation;
            d["evaluation_seconds"] = r.evaluation_seconds;
            d["optimizer_seconds"] = r.optimizer_seconds;
            return d;
        },
        py::arg("fun"), py::arg("x0"), py::arg("method"), py::arg("lower"), py::arg("upper"), py::arg("n_ineq"),
        py::arg("n_eq"), py::arg("options"), py::arg("callback"), py::arg("valid_step"),
        "Low-level minimize(): fun(x) -> (f, grad, c, dc, h, dh) or None; c <= 0, h == 0. Use diffipc.minimize.");
    m.def(
        "registered_optimizer_algorithms",
        [] {
            py::list algorithms;
            for (const OptimizerAlgorithmInfo& info : registered_optimizer_algorithms()) {
                py::dict d;
                d["name"] = info.name;
                d["bounds"] = info.bounds;
                d["inequalities"] = info.inequalities;
                d["equalities"] = info.equalities;
                d["library_options"] = info.library_options;
                d["library"] = info.library;
                algorithms.append(d);
            }
            return algorithms;
        },
        "The optimizers, from the one table that problem files, diffipc.minimize and the docs follow: "
        "[{name, bounds, inequalities, equalities, library_options, library}].");
}
