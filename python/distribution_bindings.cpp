// diffipc.ReducedFunctional over processes (issue 18): a Communicator written in Python (diffipc.mpi wraps an
// mpi4py communicator in one) and the collective distribution of a problem's load cases over it.

#include "shape_opt/case_distribution.hpp"

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdlib>

namespace py = pybind11;
using namespace diffipc;

namespace {

/// The Python subclass's methods: rank(), size(), broadcast(bytes) -> bytes, gather(bytes) -> [bytes] or None,
/// abort(message, code). Called with the GIL taken (evaluations run without it).
class PyCommunicator : public Communicator {
public:
    int rank() const override { PYBIND11_OVERRIDE_PURE(int, Communicator, rank, ); }
    int size() const override { PYBIND11_OVERRIDE_PURE(int, Communicator, size, ); }
    void broadcast(std::string& bytes) override
    {
        py::gil_scoped_acquire gil;
        const py::object result = method("broadcast")(py::bytes(bytes));
        bytes = result.cast<std::string>();
    }
    std::vector<std::string> gather(const std::string& mine) override
    {
        py::gil_scoped_acquire gil;
        const py::object result = method("gather")(py::bytes(mine));
        std::vector<std::string> out;
        if (result.is_none())
            return out;
        for (const py::handle item : result)
            out.push_back(item.cast<std::string>());
        return out;
    }
    [[noreturn]] void abort(const std::string& message, int code) override
    {
        {
            py::gil_scoped_acquire gil;
            method("abort")(message, code);
        }
        std::_Exit(code);
    }

private:
    py::function method(const char* name) const
    {
        py::function f = py::get_override(static_cast<const Communicator*>(this), name);
        if (!f)
            throw std::logic_error(std::string("diffipc.Communicator: the subclass defines no ") + name + "()");
        return f;
    }
};

} // namespace

void bind_distribution(py::module_& m)
{
    py::class_<Communicator, PyCommunicator, std::shared_ptr<Communicator>>(m, "Communicator",
        "Processes that evaluate a problem's load cases together: subclass it with rank(), size(), "
        "broadcast(bytes) -> bytes (rank 0's to every rank), gather(bytes) -> list of bytes in rank order on rank "
        "0 (None elsewhere) and abort(message, code). diffipc.mpi.MpiCommunicator is one over mpi4py.")
        .def(py::init<>())
        .def("rank", &Communicator::rank)
        .def("size", &Communicator::size);

    m.def(
        "_distribute",
        [](ReducedFunctional& rf, std::shared_ptr<Communicator> communicator) {
            rf.set_distribution(communicator
                    ? std::make_shared<CaseDistribution>(communicator, CaseDistribution::Mode::COLLECTIVE)
                    : nullptr);
        },
        py::arg("functional"), py::arg("communicator"),
        "From now on functional.evaluation() is collective over the communicator's processes (every one calls "
        "it, with the same p); None: this process alone.");
    m.def(
        "_distribution_times",
        [](const ReducedFunctional& rf) -> py::object {
            if (!rf.distribution())
                return py::none();
            const CaseDistribution& d = *rf.distribution();
            py::dict out;
            out["ranks"] = d.size();
            out["rank"] = d.rank();
            out["evaluations"] = d.times().evaluations;
            out["wall"] = d.times().wall;
            out["compute"] = d.times().compute;
            out["loading"] = d.times().loading;
            out["cases"] = d.times().cases;
            out["assignment"] = d.last_assignment();
            out["assignment_costs"] = d.last_assignment_costs();
            return std::move(out);
        },
        py::arg("functional"));
}
