"""A problem's "checkpointing" (docs/problem_format.md): the gradient by the
checkpointed adjoint equals the full-memory one to round-off while fewer step
records than steps hold their state, the statistics reach Python and
`diffipc gradcheck`, and bad settings raise naming the field."""
import copy
import json
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT

STUDIES = {
    "302": ROOT / "studies" / "302_bar_youngs_markers" / "problem.json",
    "304": ROOT / "studies" / "304_ring_wall_velocity" / "problem.json",
}


def study(name, steps=None):
    """The study's problem as a dict without "checkpointing" and "gradcheck", optionally with more steps."""
    problem = json.loads(STUDIES[name].read_text())
    problem.pop("checkpointing", None)
    problem.pop("gradcheck", None)
    if steps is not None:
        problem["scene"]["time"]["steps"] = steps
    return problem


def with_checkpointing(problem, settings):
    problem = copy.deepcopy(problem)
    problem["checkpointing"] = settings
    return problem


def relative(a, b):
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b)


# 302: 3D bar, per-element E, markers at states 2 and 4 (12 steps here); 304: a ring
# thrown against a wall (contact), initial velocity, markers at the final state.
CASES = [("302", 12, 3, 2), ("304", None, 3, 1), ("304", None, 0, 1)]


@pytest.mark.parametrize("name,steps,stride,objective_states", CASES)
def test_checkpointed_gradient_equals_full_memory(name, steps, stride, objective_states):
    plain = diffipc.ReducedFunctional(study(name, steps))
    J = diffipc.ReducedFunctional(with_checkpointing(study(name, steps), {"stride": stride}))
    p = J.initial * 1.01  # away from the scene's own values
    reference = plain.evaluation(p)
    e = J.evaluation(p)
    assert reference.checkpoints == []
    assert abs(e.value - reference.value) <= 1e-10 * abs(reference.value)
    assert relative(e.gradient, reference.gradient) <= 1e-10
    assert len(e.checkpoints) == 1
    c = e.checkpoints[0]
    T = c["steps"]
    assert T == (steps or 16)
    assert c["stride"] == (stride or int(np.ceil(np.sqrt(T))))  # implicit Euler: h = 1
    assert 0 < c["peak_stored_states"] <= c["bound_stored_states"] < T
    assert c["peak_stored_bytes"] > 0
    assert c["recomputed_steps"] > 0 and c["cost_ratio"] > 1
    assert c["objective_stored_states"] == objective_states
    assert e.adjoint_time >= c["recompute_time"]
    # Without a gradient the forward runs as without checkpointing.
    value, none = J.evaluate(p, gradient=False)
    assert none is None and value == reference.value
    assert J.evaluation(p, gradient=False).checkpoints == []


def test_mode_none_is_the_full_memory_adjoint():
    problem = study("304")
    J = diffipc.ReducedFunctional(with_checkpointing(problem, {"mode": "none", "stride": 3}))
    assert J.checkpointing == {"mode": "none", "stride": 3}
    e = J.evaluation(J.initial)
    assert e.checkpoints == []
    np.testing.assert_array_equal(e.gradient, diffipc.ReducedFunctional(problem).evaluation(J.initial).gradient)
    J = diffipc.ReducedFunctional(with_checkpointing(problem, {}))
    assert J.checkpointing == {"mode": "stride", "stride": 0}
    assert diffipc.ReducedFunctional(problem).checkpointing == {"mode": "none", "stride": 0}


def test_every_load_case_reports_its_checkpoints():
    case = study("304")
    problem = {"scenes": [{"scene": case["scene"], "objective": case["objective"], "weight": w} for w in (1.0, 0.5)],
               "parameters": case["parameters"]}
    reference = diffipc.ReducedFunctional(problem).evaluation(np.array([2.9, 0.6]))
    e = diffipc.ReducedFunctional(with_checkpointing(problem, {"stride": 4})).evaluation(np.array([2.9, 0.6]))
    assert abs(e.value - reference.value) <= 1e-10 * abs(reference.value)
    assert relative(e.gradient, reference.gradient) <= 1e-10
    assert [c["stride"] for c in e.checkpoints] == [4, 4]


@pytest.mark.parametrize(
    "settings,field,words",
    [
        ({"stride": -1}, "checkpointing.stride", "at least 0"),
        ({"stride": 2.5}, "checkpointing.stride", "expected an integer"),
        ({"stride": "3"}, "checkpointing.stride", "expected an integer"),
        ({"mode": "sqrt"}, "checkpointing.mode", "expected \"stride\" or \"none\""),
        ({"mode": 1}, "checkpointing.mode", "expected a string"),
        ({"strides": 3}, "checkpointing.strides", "unknown field"),
        (3, "checkpointing", "expected an object"),
    ],
)
def test_bad_checkpointing_names_the_field(settings, field, words):
    with pytest.raises(ValueError) as error:
        diffipc.ReducedFunctional(with_checkpointing(study("304"), settings))
    assert str(error.value).startswith(field + ":"), str(error.value)
    assert words in str(error.value)


def test_gradcheck_prints_the_checkpoint_statistics(cli, tmp_path):
    problem = with_checkpointing(study("304"), {"stride": 4})
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(problem))
    r = subprocess.run([cli, "gradcheck", path], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[1].startswith("J = ")
    assert lines[2].startswith("checkpointing: stride 4, peak 7 of 16 step records held (bound 7,")
    assert "the objective holds 1 of 17 states" in lines[2]
    path.write_text(json.dumps(study("304")))
    r = subprocess.run([cli, "gradcheck", path], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and "checkpointing" not in r.stdout
