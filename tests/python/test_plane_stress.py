"""2D "plane": "stress" materials (forward/materials/material.hpp): a bar pulled uniaxially
with free sides holds a homogeneous uniaxial stress, so its elastic energy is known in closed
form: 1/2 E_eff eps^2 A with E_eff = E in plane stress and E / (1 - nu^2) in plane strain.
The adjoint's dJ/dE and dJ/dnu are checked against the derivatives of that formula."""
import pytest

import diffipc

L, H, DELTA = 1.0, 0.2, 1e-3


def problem(plane):
    material = {"model": "linear", "E": 2e5, "nu": 0.3, "density": 1000}
    if plane:
        material["plane"] = plane
    scene = {
        "dimension": 2,
        "bodies": [{"name": "bar", "mesh": {"box": {"min": [0, 0], "max": [L, H], "cells": [10, 3]}},
                    "material": material}],
        "dirichlet": [
            {"body": "bar", "region": {"min": [-1, -1], "max": [1e-9, 2]}, "displacement": [0, None]},
            {"body": "bar", "region": {"min": [-1, -1], "max": [1e-9, 1e-9]}, "displacement": [0, 0]},
            {"body": "bar", "region": {"min": [L - 1e-9, -1], "max": [2, 2]}, "displacement": [f"{DELTA}*t", None]},
        ],
        "time": {"integrator": "static", "dt": 1.0, "steps": 1},
        "solver": {"residual_tolerance": 1e-12},
    }
    return {"scene": scene, "objective": {"type": "elastic_energy", "time": "final"},
            "parameters": [{"type": "E"}, {"type": "nu"}]}


@pytest.mark.parametrize("plane", [None, "strain", "stress"])
def test_uniaxial_tension_energy_and_its_gradient(plane):
    J = diffipc.ReducedFunctional(problem(plane))
    E, nu = J.initial
    value, gradient = J.evaluate(J.initial)
    eps, area = DELTA / L, L * H
    if plane == "stress":
        expected = 0.5 * E * eps ** 2 * area
        dE, dnu = 0.5 * eps ** 2 * area, 0.0
    else:
        expected = 0.5 * E / (1 - nu ** 2) * eps ** 2 * area
        dE = 0.5 / (1 - nu ** 2) * eps ** 2 * area
        dnu = 0.5 * E * eps ** 2 * area * 2 * nu / (1 - nu ** 2) ** 2
    assert value == pytest.approx(expected, rel=1e-9)
    assert gradient[0] == pytest.approx(dE, rel=1e-7)
    assert gradient[1] == pytest.approx(dnu, abs=1e-7 * abs(dE) * E)


def test_plane_stress_lame_parameters():
    mu, lam = diffipc.lame_parameters(1e6, 0.3, plane_stress=True)
    mu3, lam3 = diffipc.lame_parameters(1e6, 0.3)
    assert mu == mu3
    assert lam == pytest.approx(2 * lam3 * mu3 / (lam3 + 2 * mu3), rel=1e-14)
    assert lam == pytest.approx(1e6 * 0.3 / (1 - 0.09), rel=1e-14)


def test_plane_is_2d_only_and_named():
    p = problem("stress")
    p["scene"]["bodies"][0]["material"]["plane"] = "membrane"
    with pytest.raises(ValueError, match="scene.bodies\\[0\\].material.plane"):
        diffipc.ReducedFunctional(p)
    s = {"dimension": 3, "bodies": [{"name": "b", "mesh": {"box": {"min": [0, 0, 0], "max": [1, 1, 1],
                                                                   "cells": [1, 1, 1]}},
                                     "material": {"model": "linear", "E": 1e5, "nu": 0.3, "density": 1,
                                                  "plane": "stress"}}],
         "time": {"dt": 0.1, "steps": 1}}
    with pytest.raises(ValueError, match="bodies\\[0\\].material.plane: plane stress or strain is a 2D option"):
        diffipc.scene(s)
