"""Study 403 (studies/403_friction_fit): a block's friction coefficient fitted to its final
centre of mass on a slope, with L-BFGS-B, Ipopt and SLSQP, and with a noisy measurement.
Short runs through the CLI and their outputs, the optimum re-evaluated through Python, the
full runs' recovery of the true coefficient, and the noisy fit's error against its
first-order prediction."""
import csv
import importlib.util
import json
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT

STUDY = ROOT / "studies" / "403_friction_fit"
FILES = ["problem", "problem_ipopt", "problem_slsqp"]


def load_generate():
    spec = importlib.util.spec_from_file_location("study_403_generate", STUDY / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen = load_generate()


def optimize(cli, tmp_path, name, iterations=None):
    p = json.loads((STUDY / f"{name}.json").read_text())
    if iterations is not None:
        p["optimizer"]["max_iterations"] = iterations
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "o"
    r = subprocess.run([cli, "optimize", str(problem), "-o", str(out), "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, (r.returncode, r.stdout[-2000:], r.stderr)
    return out, json.loads((out / "summary.json").read_text())


def test_measurement_comes_from_the_true_coefficient():
    J = diffipc.ReducedFunctional(STUDY / "problem.json")
    assert J.layout == [("friction", 1)]
    assert J([gen.TRUE_MU]) < 1e-20
    assert J([gen.START_MU]) > 1e-2
    # The same measurement in every exact file; the noisy one differs by about the noise level.
    targets = {n: np.array(json.loads((STUDY / f"{n}.json").read_text())["objective"]["targets"][0])
               for n in FILES + ["problem_noisy"]}
    for n in FILES:
        assert np.array_equal(targets[n], targets["problem"])
    assert 1e-4 < np.linalg.norm(targets["problem_noisy"] - targets["problem"]) < 1e-2


@pytest.mark.parametrize("name", FILES)
def test_study_403_short(cli, tmp_path, name):
    out, s = optimize(cli, tmp_path, name, iterations=3)
    for f in ("history.csv", "summary.json", "optimal_problem.json", "design_final.vtu"):
        assert (out / f).is_file(), f
    assert s["iterations"] <= 3 and s["rejected"] == 0
    assert s["max_violation"] == 0
    # Three iterations take J down by more than two orders of magnitude (measured on the 8 x 4
    # block: 3.84e-2 to 6.3e-5 with Ipopt, 1.2e-13 with L-BFGS-B, 7.2e-13 with SLSQP).
    assert s["final_J"] < 1e-2 * s["initial_J"], s
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == s["iterations"] + 1
    assert float(rows[-1]["J"]) == pytest.approx(s["final_J"], rel=1e-12)
    mu = s["design"][0]
    assert gen.LOWER <= mu <= gen.UPPER
    # 10 times closer to the truth than the start (measured: Ipopt's third iterate 0.2836, 0.0164 off
    # against the bound 0.058; the others within 2e-6).
    assert abs(mu - gen.TRUE_MU) < 0.1 * abs(gen.START_MU - gen.TRUE_MU)
    # optimal_problem.json holds the design and evaluates to final_J; the block's centre there
    # is final_J's distance from the measurement.
    optimal = json.loads((out / "optimal_problem.json").read_text())
    assert optimal["parameters"][0]["initial"] == pytest.approx([mu], rel=1e-15)
    assert diffipc.ReducedFunctional(optimal)([mu]) == pytest.approx(s["final_J"], rel=1e-8)
    measured = np.array(optimal["objective"]["targets"][0])
    center = gen.final_center(mu)
    assert 0.5 * np.sum((center - measured) ** 2) == pytest.approx(s["final_J"], rel=1e-6, abs=1e-24)


@pytest.mark.parametrize("name", FILES)
def test_study_403_full_run_recovers_mu(cli, tmp_path, name):
    _, s = optimize(cli, tmp_path, name)
    assert s["stop_reason"] == "gradient_tolerance", s
    # Measured: final J 2.9e-18 (Ipopt), 6.3e-22 (SLSQP), 2.0e-24 (L-BFGS-B); mu within 3.6e-9.
    assert s["final_J"] < 1e-16
    assert abs(s["design"][0] - gen.TRUE_MU) < 1e-6, s["design"]


def test_noisy_fit_error_matches_the_first_order_prediction(cli, tmp_path):
    _, s = optimize(cli, tmp_path, "problem_noisy")
    assert s["stop_reason"] == "gradient_tolerance", s
    exact = np.array(json.loads((STUDY / "problem.json").read_text())["objective"]["targets"][0])
    noisy = np.array(json.loads((STUDY / "problem_noisy.json").read_text())["objective"]["targets"][0])
    h = 1e-4
    dc = (gen.final_center(gen.TRUE_MU + h) - gen.final_center(gen.TRUE_MU - h)) / (2 * h)
    predicted = float(dc @ (noisy - exact)) / float(dc @ dc)
    error = s["design"][0] - gen.TRUE_MU
    # While the block slides (mu < tan 30 deg) its centre is affine in mu, so the least-squares
    # fit of the noisy centre is off by exactly the projection of the noise (measured: both -2.921e-4).
    assert abs(predicted) > 1e-5
    assert error == pytest.approx(predicted, rel=1e-3)
