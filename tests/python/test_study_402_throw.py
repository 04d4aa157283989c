"""Study 402 (studies/402_throw_target): the initial velocity of a ring thrown against a wall,
fitted so that its centre of mass is at a target at the final step. A short run through the
CLI and its outputs, the optimum re-evaluated through Python, the bounce checked on the
re-simulated throw, and the full run's recovery of the true velocity."""
import csv
import importlib.util
import json
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT

STUDY = ROOT / "studies" / "402_throw_target"


def load_generate():
    spec = importlib.util.spec_from_file_location("study_402_generate", STUDY / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen = load_generate()


def optimize(cli, tmp_path, iterations=None):
    p = json.loads((STUDY / "problem.json").read_text())
    if iterations is not None:
        p["optimizer"]["max_iterations"] = iterations
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "o"
    r = subprocess.run([cli, "optimize", str(problem), "-o", str(out), "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, (r.returncode, r.stdout[-2000:], r.stderr)
    return out, json.loads((out / "summary.json").read_text())


def throw(velocity):
    """The study's throw with the given initial velocity: centre and centre velocity at the
    final step, and the steps with an active contact pair."""
    scene = diffipc.scene(gen.scene_dict(list(velocity)))
    _, tr = diffipc.simulate(scene)
    assert tr["final_status"] == "CONVERGED", tr["failure_message"]
    T = gen.STEPS
    return (gen.lumped_center(scene, tr["positions"][T]), gen.lumped_center(scene, tr["velocities"][T]),
            gen.contact_steps(tr))


def test_target_is_reachable_from_the_true_velocity():
    # The target is the centre of the true throw: J vanishes there (up to the 12 digits written).
    J = diffipc.ReducedFunctional(STUDY / "problem.json")
    assert J(np.array(gen.TRUE_VELOCITY)) < 1e-20
    assert J(np.array(gen.START_VELOCITY)) > 0.1
    # The start lies inside the bounds and both it and the truth bounce off the wall.
    entry = json.loads((STUDY / "problem.json").read_text())["parameters"][0]
    assert np.all(np.array(entry["lower"]) <= gen.START_VELOCITY)
    assert np.all(np.array(gen.START_VELOCITY) <= entry["upper"])
    for v in (gen.START_VELOCITY, gen.TRUE_VELOCITY):
        _, velocity, steps = throw(v)
        assert steps, f"no wall contact with v = {v}"
        assert velocity[0] < 0, f"v = {v}: the ring does not come back from the wall"


def test_study_402_short(cli, tmp_path):
    out, s = optimize(cli, tmp_path, iterations=10)
    for name in ("history.csv", "summary.json", "optimal_problem.json", "design_final.vtu"):
        assert (out / name).is_file(), name
    assert s["stop_reason"] in ("iteration_budget", "gradient_tolerance"), s
    assert s["iterations"] <= 10 and s["rejected"] == 0
    # Ten iterations bring J down by more than three orders of magnitude (measured: 0.405 -> 5.7e-6).
    assert s["final_J"] < 1e-3 * s["initial_J"], s
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == s["iterations"] + 1
    J_history = [float(r["J"]) for r in rows]
    assert J_history[0] == pytest.approx(s["initial_J"], rel=1e-12)
    assert J_history[-1] == pytest.approx(s["final_J"], rel=1e-12)
    assert all(b <= a for a, b in zip(J_history, J_history[1:])), J_history   # L-BFGS-B's Armijo steps
    # The design is in its box and closer to the truth than the start by a factor 10.
    v = np.array(s["design"])
    assert np.all(v >= gen.LOWER) and np.all(v <= gen.UPPER)
    start_gap = np.linalg.norm(np.array(gen.START_VELOCITY) - gen.TRUE_VELOCITY)
    assert np.linalg.norm(v - gen.TRUE_VELOCITY) < 0.1 * start_gap
    # optimal_problem.json holds the design and evaluates to final_J.
    optimal = json.loads((out / "optimal_problem.json").read_text())
    assert optimal["parameters"][0]["initial"] == pytest.approx(list(v), rel=1e-15)
    J = diffipc.ReducedFunctional(optimal)
    assert J(v) == pytest.approx(s["final_J"], rel=1e-8)
    # The centre there is J's distance from the target, and the ring did bounce.
    center, velocity, steps = throw(v)
    target = np.array(optimal["objective"]["targets"][0])
    assert 0.5 * np.sum((center - target) ** 2) == pytest.approx(s["final_J"], rel=1e-6)
    assert steps and velocity[0] < 0


def test_study_402_full_run_recovers_the_velocity(cli, tmp_path):
    _, s = optimize(cli, tmp_path)
    assert s["stop_reason"] == "gradient_tolerance", s
    assert s["final_J"] < 1e-10
    # The ring's centre at 0.3 s pins the throw: the fit finds the true velocity (measured error 6e-6 m/s).
    assert np.abs(np.array(s["design"]) - gen.TRUE_VELOCITY).max() < 1e-4, s["design"]
