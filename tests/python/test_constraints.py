"""A problem's "constraints": functionals with bounds, evaluated with their adjoint gradients
from the objective's forward run (shape_opt/reduced_functional.hpp)."""
import json

import numpy as np
import pytest

import diffipc
from conftest import ROOT


def beam_problem(checkpointing=False):
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    p["constraints"] = [
        {"name": "volume", "objective": {"type": "volume"}, "upper": 0.19},
        {"name": "energy", "objective": {"type": "elastic_energy", "time": "final"}, "lower": 1e-3},
        {"name": "material", "objective": {"type": "volume", "configuration": "rest"}, "upper": 0.2},
    ]
    if checkpointing:
        p["checkpointing"] = {"mode": "stride", "stride": 1}
    return p


@pytest.mark.parametrize("checkpointing", [False, True])
def test_constraint_values_and_gradients(checkpointing):
    problem = beam_problem(checkpointing)
    J = diffipc.ReducedFunctional(problem)
    assert [c["name"] for c in J.constraints] == ["volume", "energy", "material"]
    assert J.constraints[0]["kind"] == "upper" and J.constraints[1]["bound"] == 1e-3
    p = J.initial
    e = J.evaluation(p, gradient=True, constraints=True)
    assert e.constraint_values.shape == (3,) and e.constraint_gradients.shape == (3, J.size)
    # Independently: each constraint's functional as the objective of its own problem.
    for i, c in enumerate(problem["constraints"]):
        alone = dict(problem, objective=c["objective"])
        del alone["constraints"]
        Ji = diffipc.ReducedFunctional(alone)
        value, gradient = Ji.evaluate(p)
        assert e.constraint_values[i] == pytest.approx(value, rel=1e-12)
        np.testing.assert_allclose(e.constraint_gradients[i], gradient, rtol=1e-10, atol=1e-12 * abs(gradient).max())
    # The deformed area at the final state, near the rest area 0.2; the gradients against
    # central differences.
    assert e.constraint_values[0] == pytest.approx(0.2, rel=0.05)
    assert e.constraint_values[2] == pytest.approx(0.2, rel=1e-14)  # the rest area of the 1 x 0.2 beam
    rng = np.random.default_rng(4)
    d = rng.uniform(-1, 1, J.size) * J.scales
    h = 1e-3  # truncation O(h^2): about 1e-8 relative here
    plus = J.evaluation(p + h * d, gradient=False, constraints=True).constraint_values
    minus = J.evaluation(p - h * d, gradient=False, constraints=True).constraint_values
    fd = (plus - minus) / (2 * h)
    np.testing.assert_allclose(e.constraint_gradients @ d, fd, rtol=1e-6)
    # The objective is the same with or without constraints.
    assert e.value == pytest.approx(J.evaluation(p, gradient=False).value, rel=1e-14)


BAD = [
    (lambda c: c[0].update(lower=1.0) or c, "constraints[0]", "exactly one"),
    (lambda c: c[0].pop("upper") and c, "constraints[0]", "exactly one"),
    (lambda c: c[0].update(objective={"type": "nope"}) or c, "constraints[0].objective", ""),
    (lambda c: c[0].pop("objective") and c, "constraints[0].objective", "missing"),
    (lambda c: c[1].update(name="volume") or c, "constraints[1].name", "duplicate"),
    (lambda c: c[0].update(case=1) or c, "constraints[0].case", "no load case"),
    (lambda c: c[0].update(uper=2) or c, "constraints[0].uper", "unknown"),
    (lambda c: c[0].update(upper="big") or c, "constraints[0].upper", ""),
]


@pytest.mark.parametrize("mutate,field,words", BAD)
def test_bad_constraints_name_the_field(mutate, field, words):
    problem = beam_problem()
    problem["constraints"] = mutate(problem["constraints"])
    with pytest.raises(ValueError) as info:
        diffipc.ReducedFunctional(problem)
    assert str(info.value).startswith(field), str(info.value)
    assert words in str(info.value), str(info.value)
