"""The problem-file forms of `gather` and `concatenate` (docs/parametrizations.md): a beam whose
bottom edge mirrors its top edge (one design variable per pair of vertices), and one entry split
into parts with chains of their own; `diffipc gradcheck` on them, and dJ/dx against central
differences of J(P(x)). Before: both were refused ("unknown map type 'gather'")."""
import json
import math
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT


def beam(parameters):
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    p["parameters"] = parameters
    return p


def edges():
    """The beam's bottom (y = 0) and top (y = 0.2) vertices at x >= 0.1, by x: the rest positions
    from the problem itself (a shape entry over every vertex)."""
    X = diffipc.ReducedFunctional(beam([{"type": "shape"}])).initial.reshape(-1, 2)
    bottom = [int(v) for v in np.argsort(X[:, 0]) if abs(X[v, 1]) < 1e-12 and X[v, 0] > 0.05]
    top = [int(v) for v in np.argsort(X[:, 0]) if abs(X[v, 1] - 0.2) < 1e-12 and X[v, 0] > 0.05]
    assert len(bottom) == len(top) == 10
    np.testing.assert_array_equal(X[bottom, 0], X[top, 0])  # pairs one above the other
    return X, bottom, top


def mirrored(bottom, top):
    n = len(bottom)
    return beam([{"type": "shape", "maps": [
        {"type": "gather", "index": list(range(n)) * 2},
        {"type": "scale", "scale": [-1.0] * n + [1.0] * n},
        {"type": "boundary_extension", "vertices": bottom + top, "axes": [1]}]}])


def check_design_gradient(J, x, seed=1, h=1e-5, rtol=1e-6):
    _, dJ_dp = J.evaluate(J.parameters_of(x))
    g = J.design_gradient(x, dJ_dp)
    d = np.random.default_rng(seed).uniform(-1, 1, J.design_size)
    plus = J.evaluate(J.parameters_of(x + h * d), gradient=False)[0]
    minus = J.evaluate(J.parameters_of(x - h * d), gradient=False)[0]
    assert g @ d == pytest.approx((plus - minus) / (2 * h), rel=rtol)


def test_mirrored_edges_move_together(cli, tmp_path):
    X, bottom, top = edges()
    problem = mirrored(bottom, top)
    path = tmp_path / "mirrored.json"
    path.write_text(json.dumps(problem))
    r = subprocess.run([cli, "gradcheck", path], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "gradcheck passed" in r.stdout

    J = diffipc.ReducedFunctional(problem)
    assert J.design_size == 10
    np.testing.assert_array_equal(J.design_initial, 0)  # the maps' inverse at the rest shape
    x = np.random.default_rng(3).uniform(-0.01, 0.01, 10)
    u = (J.parameters_of(x) - X.ravel()).reshape(-1, 2)
    np.testing.assert_allclose(u[top, 1], x, atol=1e-15)
    np.testing.assert_allclose(u[bottom, 1], -x, atol=1e-15)  # each mirrored pair moves together
    np.testing.assert_array_equal(u[:, 0], 0)  # axes [1]: nothing moves along x
    # A variable moves its pair and nothing else on the edges.
    one = np.zeros(10)
    one[4] = 0.02
    v = (J.parameters_of(one) - X.ravel()).reshape(-1, 2)
    moved = [k for k in bottom + top if v[k, 1] != 0]
    assert moved == [bottom[4], top[4]]
    check_design_gradient(J, x)


def test_concatenate_splits_a_per_element_modulus(cli, tmp_path):
    E0 = 1e6
    problem = beam([{"type": "E", "per": "element", "maps": [{"type": "concatenate", "parts": [
        {"size": 20, "maps": [{"type": "exp"}, {"type": "per_body"}]},
        {"maps": [{"type": "exp"}]}]}]}])
    path = tmp_path / "split.json"
    path.write_text(json.dumps(problem))
    r = subprocess.run([cli, "gradcheck", path], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr

    J = diffipc.ReducedFunctional(problem)
    assert J.size == 40 and J.design_size == 1 + 20
    np.testing.assert_allclose(J.design_initial, math.log(E0), rtol=1e-14)
    x = J.design_initial + np.random.default_rng(4).uniform(-0.2, 0.2, 21)
    p = J.parameters_of(x)
    np.testing.assert_allclose(p[:20], math.exp(x[0]), rtol=1e-14)  # one value for the first part
    np.testing.assert_allclose(p[20:], np.exp(x[1:]), rtol=1e-14)
    check_design_gradient(J, x, h=1e-4)


@pytest.mark.parametrize("maps,field,text", [
    ([{"type": "gather", "index": [0] * 20 + [2] * 20}], "parameters[0].maps[0].index", "design variable 1"),
    ([{"type": "gather", "index": [0, 1]}], "parameters[0].maps[0].index", "gives 2 values where 40"),
    ([{"type": "concatenate", "parts": [{"size": 30}, {"size": 30}]}], "parameters[0].maps[0].parts[1].size",
     "give 60 values where 40"),
    ([{"type": "mirror"}], "parameters[0].maps[0].type", "known: exp, scale, insert, gather, concatenate"),
])
def test_bad_maps_name_the_field(maps, field, text):
    with pytest.raises(ValueError) as e:
        diffipc.ReducedFunctional(beam([{"type": "E", "per": "element", "maps": maps}]))
    assert field in str(e.value) and text in str(e.value), str(e.value)
