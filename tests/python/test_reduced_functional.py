"""diffipc.ReducedFunctional: J(p) and its adjoint gradient from Python, the
Taylor and finite-difference checks, the mu/lambda parameters of problem files,
and the errors on bad input and failed forward steps."""
import json

import numpy as np
import pytest

import diffipc
from diffipc.gradcheck import random_directions
from conftest import ROOT, box_scene

STUDIES = {
    "301": ROOT / "studies" / "301_beam_shape_stress" / "problem.json",
    "302": ROOT / "studies" / "302_bar_youngs_markers" / "problem.json",
    "303": ROOT / "studies" / "303_block_slope_friction" / "problem.json",
}


def study_problem(name, parameters):
    """The study's problem as a dict, with other parameters."""
    problem = json.loads(STUDIES[name].read_text())
    problem["parameters"] = parameters
    problem.pop("gradcheck", None)
    return problem


def check_gradient(J, seed):
    p = J.initial
    errors = diffipc.finite_difference_check(J, p, directions=2, seed=seed)
    assert errors.shape == (2,)
    assert (errors < 1e-6).all(), errors
    dp = random_directions(J.size, 1, seed=seed + 100, scales=J.scales)[0]
    rate = diffipc.taylor_test(J, p, dp)
    assert rate >= 1.9, rate


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_study_gradient_matches_finite_differences(name):
    J = diffipc.ReducedFunctional(STUDIES[name])
    assert J.size == sum(n for _, n in J.layout)
    assert J.initial.shape == (J.size,) and J.scales.shape == (J.size,)
    check_gradient(J, seed=J.check_settings["seed"])


def test_layout_and_initial_values():
    J = diffipc.ReducedFunctional(STUDIES["302"])
    assert J.layout == [("E", 30)]
    np.testing.assert_array_equal(J.initial, np.full(30, 2e5))
    J = diffipc.ReducedFunctional(STUDIES["301"])
    assert J.layout == [("shape", 66)]  # 11 x 3 vertices, 2 components


def test_evaluate_returns_numpy_and_no_gradient_on_request():
    J = diffipc.ReducedFunctional(STUDIES["302"])
    value, g = J.evaluate(J.initial)
    assert isinstance(value, float) and isinstance(g, np.ndarray) and g.shape == (J.size,)
    value2, none = J.evaluate(J.initial, gradient=False)
    assert none is None and value2 == value
    e = J.evaluation(list(J.initial))  # any sequence of numbers is accepted
    assert e.value == value and e.forward_time > 0 and e.adjoint_time > 0
    np.testing.assert_array_equal(e.gradient, g)


def test_cache_and_timings():
    J = diffipc.ReducedFunctional(STUDIES["302"])
    p = J.initial
    value = J(p)
    assert J.timings["evaluations"] == 1 and J.timings["gradients"] == 0
    assert J(p.copy()) == value and J.timings["evaluations"] == 1
    g = J.gradient(p)  # needs the adjoint: evaluated again
    assert J.timings["evaluations"] == 2 and J.timings["gradients"] == 1
    v2, g2 = J.value_and_gradient(p)
    assert J.timings["evaluations"] == 2 and v2 == value
    np.testing.assert_array_equal(g, g2)
    g2[0] = 123.0  # the cached gradient is not handed out
    np.testing.assert_array_equal(J.gradient(p), g)
    q = p * 1.01
    assert J(q) != value and J.timings["evaluations"] == 3
    assert J.timings["forward"] > 0 and J.timings["adjoint"] > 0


def test_dict_matches_file():
    problem = json.loads(STUDIES["302"].read_text())
    from_dict = diffipc.ReducedFunctional(problem, base_directory=STUDIES["302"].parent)
    from_file = diffipc.ReducedFunctional(str(STUDIES["302"]))
    p = from_file.initial * 1.05
    assert from_dict(p) == from_file(p)
    np.testing.assert_array_equal(from_dict.gradient(p), from_file.gradient(p))
    assert from_dict.check_settings == from_file.check_settings == {
        "directions": 2, "seed": 2, "step": 0.1, "halvings": 4}


def test_checks_detect_a_wrong_gradient():
    J = diffipc.ReducedFunctional(STUDIES["302"])
    p = J.initial
    value, g = J.value_and_gradient(p)
    wrong = g * 1.01
    assert (diffipc.finite_difference_check(J, p, directions=2, seed=3, dJdp=wrong) > 1e-3).all()
    dp = random_directions(J.size, 1, seed=4, scales=J.scales)[0]
    assert diffipc.taylor_test(J, p, dp, dJdp=wrong) < 1.2
    assert diffipc.taylor_test(J, p, dp, dJdp=g) >= 1.9


# mu and lambda (Lame parameters) in problem files


def test_lame_gradient_matches_finite_differences():
    J = diffipc.ReducedFunctional(
        study_problem("302", [{"type": "mu", "per": "element"}, {"type": "lambda"}]), base_directory=ROOT)
    assert J.layout == [("mu", 30), ("lambda", 1)]
    mu, lam = diffipc.lame_parameters(2e5, 0.35)
    np.testing.assert_allclose(J.initial, np.r_[np.full(30, mu), lam], rtol=1e-12)
    check_gradient(J, seed=5)


def test_lame_gradient_is_the_chain_rule_of_young_poisson():
    nu = 0.35  # the study's
    lame = diffipc.ReducedFunctional(study_problem("302", [{"type": "mu"}, {"type": "lambda"}]))
    young = diffipc.ReducedFunctional(study_problem("302", [{"type": "E"}]))
    J_lame, (d_mu, d_lambda) = lame.value_and_gradient(lame.initial)
    J_young, (d_E,) = young.value_and_gradient(young.initial)
    assert J_lame == pytest.approx(J_young, rel=1e-10)
    # mu = E / (2 (1 + nu)), lambda = E nu / ((1 + nu)(1 - 2 nu))
    expected = d_mu / (2 * (1 + nu)) + d_lambda * nu / ((1 + nu) * (1 - 2 * nu))
    assert d_E == pytest.approx(expected, rel=1e-8)


def test_lame_only_mu_keeps_the_scene_lambda():
    J = diffipc.ReducedFunctional(study_problem("302", [{"type": "mu"}]))
    young = diffipc.ReducedFunctional(study_problem("302", [{"type": "E"}]))
    assert J(J.initial) == pytest.approx(young(young.initial), rel=1e-10)
    # Doubling mu alone is not doubling E (lambda stays): the values differ.
    assert J(2 * J.initial) != pytest.approx(young(2 * young.initial), rel=1e-6)


def test_mixing_young_poisson_and_lame_names_the_field():
    with pytest.raises(ValueError, match=r"parameters\[1\]\.type.*'lambda'.*'E'"):
        diffipc.ReducedFunctional(study_problem("302", [{"type": "E"}, {"type": "lambda"}]))
    with pytest.raises(ValueError, match=r"parameters\[2\]\.type.*'nu'.*'mu'"):
        diffipc.ReducedFunctional(study_problem("302", [{"type": "mu"}, {"type": "density"}, {"type": "nu"}]))
    with pytest.raises(ValueError, match=r"parameters\[0\]\.per"):
        diffipc.ReducedFunctional(study_problem("302", [{"type": "mu", "per": "vertex"}]))


def test_nonpositive_mu_is_an_input_error():
    J = diffipc.ReducedFunctional(study_problem("302", [{"type": "mu"}]))
    with pytest.raises(ValueError, match=r"mu\[0\].*positive"):
        J(-J.initial)


# Bad input


def test_wrong_size_and_nan_raise_naming_the_field():
    J = diffipc.ReducedFunctional(STUDIES["302"])
    with pytest.raises(ValueError, match=r"parameters: expected 30 values, got 29"):
        J(J.initial[:-1])
    with pytest.raises(ValueError, match=r"parameters: expected 30 values, got 31"):
        J.gradient(np.r_[J.initial, 1.0])
    with pytest.raises(ValueError, match=r"parameters: expected a 1D array"):
        J.evaluate(J.initial.reshape(5, 6))
    p = J.initial.copy()
    p[7] = np.nan
    with pytest.raises(ValueError, match=r"parameters\[7\]: non-finite"):
        J(p)
    p[7] = np.inf
    with pytest.raises(ValueError, match=r"parameters\[7\]: non-finite"):
        J.value_and_gradient(p)
    assert J.timings["evaluations"] == 0
    with pytest.raises(diffipc.InputError):  # the module's own class, a ValueError
        J.evaluate(p)


def write_problem(tmp_path, scene, parameters):
    path = tmp_path / "problem.json"
    path.write_text(json.dumps({"scene": scene, "objective": {"type": "elastic_energy"}, "parameters": parameters}))
    return path


def test_parameters_the_scene_lacks_raise_naming_the_field(tmp_path):
    with pytest.raises(ValueError, match=r"parameters\[0\].*no friction"):
        diffipc.ReducedFunctional(write_problem(tmp_path, box_scene(), [{"type": "friction"}]))
    with pytest.raises(ValueError, match=r"parameters\[1\].*no prescribed dofs"):
        diffipc.ReducedFunctional(write_problem(tmp_path, box_scene(), [{"type": "E"}, {"type": "prescribed"}]))
    with pytest.raises(ValueError, match=r"parameters\[0\]\.body.*no body named 'nope'"):
        diffipc.ReducedFunctional(write_problem(tmp_path, box_scene(), [{"type": "mu", "body": "nope"}]))
    with pytest.raises(ValueError, match=r"parameters\[0\]\.type.*unknown parameter type 'young'"):
        diffipc.ReducedFunctional(write_problem(tmp_path, box_scene(), [{"type": "young"}]))


def test_bad_problem_dict_raises():
    problem = study_problem("302", [{"type": "E"}])
    problem["objective"]["targets"][0][0][0] = float("nan")
    with pytest.raises(ValueError, match=r"<dict>.*NaN"):
        diffipc.ReducedFunctional(problem)
    with pytest.raises(TypeError):
        diffipc.ReducedFunctional(42)


# A failed forward step


def failing_scene():
    # As in test_gradcheck.py: one Newton iteration allowed, so the first (nonlinear) step
    # cannot converge; here a clamped 3D bar sagging under heavy gravity.
    s = box_scene(dim=3)
    s["dirichlet"] = [{"body": "b", "region": {"min": [-1] * 3, "max": [1e-6, 1, 1]}, "displacement": [0] * 3}]
    s["gravity"] = [0.0, -2000.0, 0.0]
    s["solver"]["max_iterations"] = 1
    return s


def test_failed_forward_step_raises_adjoint_error_and_returns_nothing():
    problem = {"scene": failing_scene(), "objective": {"type": "elastic_energy"}, "parameters": [{"type": "E"}]}
    J = diffipc.ReducedFunctional(problem)
    assert issubclass(diffipc.AdjointError, RuntimeError)
    assert not issubclass(diffipc.AdjointError, ValueError)
    result = None
    with pytest.raises(diffipc.AdjointError, match="no value and no gradient"):
        result = J.gradient(J.initial)
    assert result is None
    with pytest.raises(diffipc.AdjointError, match="no value and no gradient"):
        result = J.evaluate(J.initial)
    with pytest.raises(diffipc.AdjointError, match="no value and no gradient"):
        result = J(J.initial)
    assert result is None and J._last is None and J.timings["evaluations"] == 0
    # With the default Newton iterations the same problem converges: the error was the failed step.
    del problem["scene"]["solver"]["max_iterations"]
    value, g = diffipc.ReducedFunctional(problem).value_and_gradient(J.initial)
    assert np.isfinite(value) and np.isfinite(g).all()


def test_friction_selection_global_and_one_group():
    """per "group" (default): one coefficient per body and obstacle; per "global": one value
    for all of them, whose derivative is the sum; "group": NAME selects one."""
    base = study_problem("303", [{"type": "friction"}])
    per_group = diffipc.ReducedFunctional(base, base_directory=str(STUDIES["303"].parent))
    assert per_group.layout == [("friction", 2)]
    value, g = per_group.evaluate(per_group.initial)

    glob = study_problem("303", [{"type": "friction", "per": "global"}])
    J = diffipc.ReducedFunctional(glob, base_directory=str(STUDIES["303"].parent))
    assert J.layout == [("friction", 1)]
    np.testing.assert_array_equal(J.initial, [0.2])
    value_global, g_global = J.evaluate(J.initial)
    assert value_global == value
    assert g_global[0] == pytest.approx(g.sum(), rel=1e-12)
    check_gradient(J, seed=5)

    slope = study_problem("303", [{"type": "friction", "group": "slope"}])
    J = diffipc.ReducedFunctional(slope, base_directory=str(STUDIES["303"].parent))
    assert J.size == 1
    assert J.evaluate(J.initial)[1][0] == pytest.approx(g[1], rel=1e-12)

    for bad, field in [({"type": "friction", "per": "body"}, "parameters[0].per"),
                       ({"type": "friction", "group": "wall"}, "parameters[0].group")]:
        problem = study_problem("303", [bad])
        with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
            diffipc.ReducedFunctional(problem, base_directory=str(STUDIES["303"].parent))


def test_global_friction_needs_equal_group_coefficients():
    problem = study_problem("303", [{"type": "friction", "per": "global"}])
    problem["scene"]["obstacles"][0]["friction"] = {"coefficient": 0.4}
    with pytest.raises(ValueError, match="share one coefficient"):
        diffipc.ReducedFunctional(problem, base_directory=str(STUDIES["303"].parent))


def test_friction_parameter_errors_name_the_field():
    problem = study_problem("303", [{"type": "friction", "groups": 1}])  # a typo of "group"
    with pytest.raises(ValueError, match=r"parameters\[0\]\.groups"):
        diffipc.ReducedFunctional(problem, base_directory=str(STUDIES["303"].parent))
    problem = study_problem("303", [{"type": "friction", "per": 3}])
    with pytest.raises(ValueError, match=r"parameters\[0\]\.per"):
        diffipc.ReducedFunctional(problem, base_directory=str(STUDIES["303"].parent))
    # A selected group with coefficient 0: sqrt(mu_a mu_b) has no derivative there.
    problem = study_problem("303", [{"type": "friction", "group": "slope"}])
    problem["scene"]["obstacles"][0]["friction"] = {"coefficient": 0.0}
    with pytest.raises(ValueError, match="coefficient 0"):
        diffipc.ReducedFunctional(problem, base_directory=str(STUDIES["303"].parent))


def test_device_replaces_the_scenes_device():
    """device="cpu" is the scenes' own path (the same numbers); a device that is not "cpu" or "gpu",
    or a scene the GPU path refuses, is an error naming "device" at load; device="gpu" runs there
    (checked against the CPU on a GPU machine; elsewhere it is the error that says no GPU is usable)."""
    J = diffipc.ReducedFunctional(STUDIES["302"])
    value, g = J.evaluate(J.initial)
    J_cpu = diffipc.ReducedFunctional(STUDIES["302"], device="cpu")
    value_cpu, g_cpu = J_cpu.evaluate(J_cpu.initial)
    assert value_cpu == value and np.array_equal(g_cpu, g)
    with pytest.raises(ValueError, match=r'device: expected "cpu" or "gpu", got "tpu"'):
        diffipc.ReducedFunctional(STUDIES["302"], device="tpu")
    problem = json.loads(STUDIES["302"].read_text())
    problem["scene"] = {"dimension": 2, "bodies": [{"mesh": {"box": {"min": [0, 0], "max": [1, 0.8], "cells": [4, 3]}},
                                                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3,
                                                                 "density": 1000}}],
                        "periodic": {"gradient": [["-0.2*t", 0], [0, None]]}, "contact": {"dhat": 0.003},
                        "friction": {"coefficient": 0.3},
                        "time": {"integrator": "static", "dt": 0.05, "steps": 3}}
    with pytest.raises(ValueError, match=r"device: \"gpu\" does not support friction across a periodic cell's boundary"):
        diffipc.ReducedFunctional(problem, base_directory=STUDIES["302"].parent, device="gpu")
    try:
        J_gpu = diffipc.ReducedFunctional(STUDIES["302"], device="gpu")
    except ValueError as e:
        assert "device" in str(e) and "CUDA" in str(e), str(e)
        return
    value_gpu, g_gpu = J_gpu.evaluate(J_gpu.initial)
    assert abs(value_gpu - value) <= 1e-6 * abs(value)
    assert np.linalg.norm(g_gpu - g) <= 1e-6 * np.linalg.norm(g)
