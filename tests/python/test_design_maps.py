"""Parameter entries with "maps" (docs/parametrizations.md): design variables x -> p = P(x),
and dJ/dx = P'(x)^T dJ/dp against central differences of J(P(x)) along random directions."""
import json
import math

import numpy as np
import pytest

import diffipc
from conftest import ROOT


def beam(parameters):
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    p["parameters"] = parameters
    return p


def check_design_gradient(J, x, seed=1, h=1e-4, rtol=1e-6):
    value, dJ_dp = J.evaluate(J.parameters_of(x))
    g = J.design_gradient(x, dJ_dp)
    rng = np.random.default_rng(seed)
    d = rng.uniform(-1, 1, J.design_size)
    plus = J.evaluate(J.parameters_of(x + h * d), gradient=False)[0]
    minus = J.evaluate(J.parameters_of(x - h * d), gradient=False)[0]
    fd = (plus - minus) / (2 * h)
    assert g @ d == pytest.approx(fd, rel=rtol), (g @ d, fd)


def test_log_space_modulus_with_a_smoothing_filter():
    E0 = 1e6
    J = diffipc.ReducedFunctional(beam([{"type": "E", "per": "element", "initial": math.log(E0),
                                         "maps": [{"type": "exp"}, {"type": "filter", "radius": 0.25}]}]))
    n = J.size
    assert J.design_size == n and J.design_layout == [("E", n)]
    x0 = J.design_initial
    np.testing.assert_allclose(x0, math.log(E0))
    np.testing.assert_allclose(J.parameters_of(x0), E0, rtol=1e-14)  # a filtered constant is the constant
    x = x0 + np.random.default_rng(2).uniform(-0.3, 0.3, n)
    check_design_gradient(J, x)


def test_one_modulus_per_body_in_log_space():
    J = diffipc.ReducedFunctional(beam([{"type": "E", "per": "element",
                                         "maps": [{"type": "exp"}, {"type": "per_body"}]}]))
    assert J.design_size == 1
    assert J.design_initial[0] == pytest.approx(math.log(1e6), rel=1e-14)  # the maps' inverse
    np.testing.assert_allclose(J.parameters_of(J.design_initial), 1e6, rtol=1e-14)
    check_design_gradient(J, J.design_initial + 0.1)


def test_free_form_deformation_of_the_beam():
    J = diffipc.ReducedFunctional(beam([{"type": "shape", "maps": [
        {"type": "ffd", "box": {"min": [0.3, -0.05], "max": [0.9, 0.25]}, "degree": [3, 2], "axes": [1],
         "fixed_border": True}]}]))
    assert J.design_size == (3 - 1) * (2 - 1)  # interior control points, one axis
    np.testing.assert_array_equal(J.design_initial, 0)
    np.testing.assert_array_equal(J.parameters_of(J.design_initial), J.initial)
    check_design_gradient(J, np.array([0.01, -0.02]), h=1e-5)


def test_boundary_extension_of_the_top_edge():
    J = diffipc.ReducedFunctional(beam([{"type": "shape", "maps": [
        {"type": "boundary_extension", "vertices": {"region": {"min": [0.05, 0.19], "max": [0.95, 1]}},
         "axes": [1]}]}]))
    assert J.design_size == 9  # the top edge's vertices at x = 0.1 .. 0.9
    np.testing.assert_array_equal(J.parameters_of(J.design_initial), J.initial)
    x = np.random.default_rng(5).uniform(-0.01, 0.01, 9)
    check_design_gradient(J, x, h=1e-5)


BAD = [
    ([{"type": "E", "per": "body", "maps": [{"type": "filter", "radius": 0.1}]}], "parameters[0].maps[0]",
     "one value per element"),
    ([{"type": "shape", "vertices": [3, 4], "maps": [{"type": "ffd", "box": {"min": [0, 0], "max": [1, 1]},
                                                     "degree": [2, 2]}]}], "parameters[0].maps[0]", "every rest-position"),
    ([{"type": "E", "per": "element", "maps": [{"type": "nope"}]}], "parameters[0].maps[0].type", "unknown map"),
    ([{"type": "E", "per": "element", "maps": [{"type": "exp", "radius": 2}]}], "parameters[0].maps[0].radius",
     "unknown field"),
    ([{"type": "E", "per": "element", "maps": [{"type": "filter", "radius": 0.1}, {"type": "per_body"}]}],
     "parameters[0].maps[0]", "only exp and scale"),
    ([{"type": "E", "per": "element", "maps": [{"type": "exp"}, {"type": "filter", "radius": 0.1}]}],
     "parameters[0].maps", "give \"initial\""),
    ([{"type": "E", "per": "element", "maps": [{"type": "filter", "radius": -1}]}], "parameters[0].maps[0].radius",
     "positive"),
    ([{"type": "shape", "maps": [{"type": "boundary_extension", "vertices": [0, 0]}]}], "parameters[0].maps[0]",
     "twice"),
    ([{"type": "E", "per": "element", "initial": [1, 2], "maps": [{"type": "exp"}]}], "parameters[0].initial", ""),
]


@pytest.mark.parametrize("parameters,field,words", BAD)
def test_bad_maps_name_the_field(parameters, field, words):
    with pytest.raises(ValueError) as info:
        diffipc.ReducedFunctional(beam(parameters))
    assert str(info.value).startswith(field), str(info.value)
    assert words in str(info.value), str(info.value)
