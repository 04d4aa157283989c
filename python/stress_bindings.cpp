// Element stresses of a Simulator as the VTU frames write them (forward/io/vtu_frame.cpp's
// von_mises), and the Lame parameters' inverse, so that diffipc.plot draws the C++ physics
// rather than a copy of it.

#include "forward/common/error.hpp"
#include "forward/materials/material.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "shape_opt/parametrization/lame_map.hpp"

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Dense>

namespace py = pybind11;
using namespace diffipc;

void bind_stress(py::module_& m)
{
    // Simulator is registered in bindings.cpp; the method is added to that class.
    auto simulator = py::reinterpret_borrow<py::class_<Simulator>>(py::type::of<Simulator>());
    simulator.def(
        "element_von_mises",
        [](const Simulator& s, const MatrixXd& x) {
            const Mesh& mesh = s.mesh();
            if (x.rows() != mesh.num_vertices() || x.cols() != mesh.dim)
                throw InputError("positions",
                    "expected an array of shape (" + std::to_string(mesh.num_vertices()) + ", "
                        + std::to_string(mesh.dim) + "), got (" + std::to_string(x.rows()) + ", "
                        + std::to_string(x.cols()) + ")");
            if (!x.allFinite())
                throw InputError("positions", "non-finite value");
            const Positions p = x;
            const MatrixXd sigma = s.elastic().element_cauchy_stresses(flatten(p));
            VectorXd out(sigma.rows());
            for (Index e = 0; e < sigma.rows(); ++e) {
                Eigen::Matrix3d S;
                for (int k = 0; k < 9; ++k)
                    S(k / 3, k % 3) = sigma(e, k);
                out[e] = von_mises_stress(S);
            }
            return out;
        },
        py::arg("positions"),
        "#E von Mises stresses (Pa) of the elements' Cauchy stress at #V by dim positions (in 2D of the in-plane "
        "stress), with the simulator's per-element materials: the VTU frames' von_mises.");

    m.def(
        "young_poisson_of_lame",
        [](const VectorXd& mu, const VectorXd& lambda, bool plane_stress) {
            if (mu.size() != lambda.size())
                throw InputError("lam",
                    "expected " + std::to_string(mu.size()) + " values (one per mu), got "
                        + std::to_string(lambda.size()));
            VectorXd y(2 * mu.size());
            y << mu, lambda;
            // Plane strain and 3D share one formula; only plane stress differs.
            const LameMap map(mu.size(), plane_stress ? ElasticityPlane::STRESS : ElasticityPlane::STRAIN);
            const VectorXd x = map.inverse(y, "lame");
            return std::make_pair(VectorXd(x.head(mu.size())), VectorXd(x.tail(mu.size())));
        },
        py::arg("mu"), py::arg("lam"), py::arg("plane_stress") = false,
        "(E, nu) arrays from arrays of Lame mu and lambda (Pa): the inverse of lame_parameters (plane_stress=True: "
        "lambda is a 2D thin sheet's in-plane one). ValueError for mu <= 0 or a pair with no E > 0, nu in "
        "(-1, 0.5).");
}
