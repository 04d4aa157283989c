"""summary.json of diffipc optimize (docs/optimization.md, "Results and non-smooth objectives";
docs/output_format.md): the result is the optimizer's own last iterate, the best point seen is
reported beside it with a warning when they differ, steps and a final Taylor check that show a
non-smooth J are recorded, last_rejection is always there, and settings the optimizer refuses
are refused before any output (issue 46)."""
import csv
import json
import os
import subprocess

import h5py
import numpy as np
import pytest

from conftest import ROOT


def run(cli, *args, timeout=600):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout)


# A ring dropped onto a rigid ridge (a polyline with its peak at the origin): it lands on the peak
# and slides down the slope on the side its horizontal offset x puts it, then over the ridge's
# next vertex; J is the misfit of one vertex to a target down the right slope. The contact pairs
# flip from one slope's edges to the other's and from edge to edge along x, so J jumps between
# designs a millimetre apart (J(0) = 0.036, J(0.002) = 0.016, with small gradients on either
# side). Ipopt from x = -0.015 crosses the peak, sees J = 2.6e-5 at a trial point near the upper
# bound that its barrier line search does not accept, and stops with Solve_Succeeded at a
# local minimum with J = 1.05e-3.
RIDGE_OBJ = "v -0.6 -0.3 0\nv -0.3 -0.15 0\nv 0 0 0\nv 0.3 -0.15 0\nv 0.6 -0.3 0\nl 1 2 3 4 5\n"


def ridge_problem(tmp_path, start=-0.015, algorithm="ipopt"):
    (tmp_path / "ridge.obj").write_text(RIDGE_OBJ)
    scene = {
        "dimension": 2,
        "bodies": [{"name": "ring",
                    "mesh": {"annulus": {"center": [0.0, 0.06], "inner_radius": 0.035, "outer_radius": 0.05,
                                         "segments": 24, "layers": 1}},
                    "material": {"model": "neo_hookean", "E": 3e5, "nu": 0.4, "density": 1000}}],
        "obstacles": [{"name": "ridge", "mesh": {"file": "ridge.obj"}}],
        "gravity": [0, -9.81],
        "contact": {"dhat": 1e-3, "kappa": 1e8},
        "time": {"integrator": "implicit_euler", "dt": 0.01, "steps": 30},
        "solver": {"residual_tolerance": 1e-9},
    }
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    problem = {
        "scene": "scene.json",
        "objective": {"type": "markers", "vertices": [0], "targets": [[[0.25, -0.05]]], "steps": [30]},
        "parameters": [{"type": "initial_displacement", "per": "body", "body": "ring",
                        "lower": [-0.04, 0], "upper": [0.04, 0], "initial": [start, 0]}],
        "optimizer": {"algorithm": algorithm, "max_iterations": 20},
    }
    path = tmp_path / "ridge.json"
    path.write_text(json.dumps(problem))
    return path


@pytest.fixture(scope="module")
def ridge_run(tmp_path_factory):
    cli = os.environ.get("DIFFIPC_CLI", str(ROOT / "build" / "cli" / "diffipc"))
    tmp_path = tmp_path_factory.mktemp("ridge")
    out = tmp_path / "out"
    r = run(cli, "optimize", ridge_problem(tmp_path), "-o", out)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr
    return r, out, json.loads((out / "summary.json").read_text())


def initial_design(problem_path):
    doc = json.loads(problem_path.read_text())
    return [v for entry in doc["parameters"] for v in entry["initial"]]


def test_result_is_the_last_iterate_and_its_stop_reason_the_optimizers(ridge_run):
    r, out, summary = ridge_run
    assert summary["algorithm"] == "ipopt"
    assert summary["stop_reason"] == "gradient_tolerance" and "Solve_Succeeded" in summary["message"], summary
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert int(rows[-1]["iteration"]) == summary["iterations"]
    assert float(rows[-1]["J"]) == summary["final_J"]
    with h5py.File(out / "history.h5", "r") as f:
        assert f["x"][-1].tolist() == summary["design"]
    assert initial_design(out / "optimal_problem.json") == summary["design"]
    # The CLI's last line reports the last iterate's J.
    assert f"-> {summary['final_J']:.6e}; wrote" in r.stdout


def test_best_point_is_reported_as_such_with_a_warning(ridge_run):
    r, out, summary = ridge_run
    best = summary["best_point"]
    # A trial point Ipopt did not accept, far better than where it stopped.
    assert best["iteration"] is None and best["evaluation"] >= 2
    assert best["J"] < 0.1 * summary["final_J"]
    assert best["design"] != summary["design"] and best["max_violation"] == 0
    assert initial_design(out / "best_problem.json") == best["design"]
    warnings = [w for w in summary["warnings"] if w.startswith("the last iterate is not the best point seen")]
    assert len(warnings) == 1, summary["warnings"]
    assert "diffipc: warning: the last iterate is not the best point seen" in r.stderr


def test_best_point_is_evaluated_independently(ridge_run):
    diffipc = pytest.importorskip("diffipc")
    _, out, summary = ridge_run
    for name, J in (("best_problem.json", summary["best_point"]["J"]), ("optimal_problem.json", summary["final_J"])):
        f = diffipc.ReducedFunctional(str(out / name))
        assert f(f.parameters_of(f.design_initial)) == pytest.approx(J, rel=1e-9), name


def test_jumps_of_the_objective_are_recorded_and_warned_about(ridge_run):
    r, _, summary = ridge_run
    check = summary["step_check"]
    assert check["steps_checked"] == summary["iterations"]
    assert check["jumps"], summary
    assert check["jumps_found"] == len(check["jumps"])  # fewer than the 20 kept
    for j in check["jumps"]:
        assert abs(j["J_change"] - j["predicted_change"]) > 2 * j["first_order_scale"]
        assert 1 <= j["iteration"] <= summary["iterations"]
    # Iteration 2 moved x by 1e-3 and J fell by 5.6e-3 where its gradients predict 1e-5: a jump.
    worst = max(check["jumps"], key=lambda j: abs(j["J_change"]) / max(j["first_order_scale"], 1e-300))
    assert abs(worst["J_change"]) > 30 * worst["first_order_scale"]
    warning = [w for w in summary["warnings"] if "accepted steps changed J by far more than its gradients predict" in w]
    assert len(warning) == 1 and warning[0].startswith(f"{check['jumps_found']} of {check['steps_checked']} "), warning
    # Both causes named: a jump of J, or a step beyond its first-order model.
    assert "J is not smooth along the run" in warning[0] and "first-order model" in warning[0]
    assert "diffipc: warning: " in r.stderr and "gradients predict" in r.stderr
    # The final Taylor check ran at the last iterate, a smooth spot of this J, and says so: R/h^2
    # settles there, after one halving more than the 3 planned (the rate of R(h) - 4 R(h/2) at
    # the two smallest planned steps disagree).
    taylor = summary["final_taylor_check"]
    assert taylor["verdict"] == "smooth", taylor
    assert taylor["evaluations"] == len(taylor["rows"]) == 5 and taylor["rejected"] == 0
    assert "final Taylor check at the last iterate: smooth" in r.stdout
    assert not any("Taylor" in w for w in summary["warnings"])


def test_a_final_taylor_check_across_a_jump_is_warned_about_and_recorded(cli, tmp_path):
    """The ridge run again, its final check's first step 100 times the default (10 times the ring
    offset's gradcheck scale): J jumps between the checked points (the contact flips from edge to
    edge), the remainder does not fall and the verdict is non_smooth."""
    path = ridge_problem(tmp_path)
    problem = json.loads(path.read_text())
    problem["optimizer"]["final_taylor_check"] = {"step": 10}
    path.write_text(json.dumps(problem))
    out = tmp_path / "out"
    r = run(cli, "optimize", path, "-o", out)
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    taylor = summary["final_taylor_check"]
    assert taylor["verdict"] == "non_smooth", taylor
    assert [row["step"] for row in taylor["rows"]][:4] == [10, 5, 2.5, 1.25]
    assert all(row["remainder"] is not None and row["J_change"] is not None for row in taylor["rows"])
    warning = "final Taylor check at the last iterate: " + taylor["reason"]
    assert warning in summary["warnings"], summary["warnings"]
    assert "diffipc: warning: " + warning in r.stderr
    # The table, for a verdict that needs reading.
    assert "final Taylor check at the last iterate: non_smooth" in r.stdout and "R/h^2" in r.stdout


def test_a_shape_problem_gets_a_taylor_verdict(cli, tmp_path):
    """Study 301's rest positions: the direction is at gradcheck's scale (1e-3 of the mesh's size),
    not 1 m, and every checked design is valid."""
    out = tmp_path / "out"
    r = run(cli, "optimize", ROOT / "studies" / "301_beam_shape_stress" / "problem.json", "-o", out,
            "--max-iterations", 3)
    assert r.returncode == 0, r.stderr
    taylor = json.loads((out / "summary.json").read_text())["final_taylor_check"]
    assert taylor["verdict"] == "smooth", taylor
    assert taylor["rejected"] == 0


def test_flagged_step_is_a_jump_of_J_on_a_finer_scan(ridge_run):
    """Independently of the step check: J along the flagged step, at 17 points, changes between two
    neighbours by far more than the gradients along the whole step can account for."""
    diffipc = pytest.importorskip("diffipc")
    _, out, summary = ridge_run
    k = max(summary["step_check"]["jumps"], key=lambda j: abs(j["J_change"]) / j["first_order_scale"])["iteration"]
    with h5py.File(out / "history.h5", "r") as f:
        x0, x1 = f["x"][k - 1], f["x"][k]
    J = diffipc.ReducedFunctional(str(out / "optimal_problem.json"))
    values, slopes = [], []
    for t in np.linspace(0, 1, 17):
        p = J.parameters_of(x0 + t * (x1 - x0))
        value, gradient = J.value_and_gradient(p)
        values.append(value)
        slopes.append(abs(J.design_gradient(x0 + t * (x1 - x0), gradient) @ (x1 - x0)))
    largest_step = np.max(np.abs(np.diff(values)))
    assert largest_step > 10 * max(slopes) / 16, (values, slopes)


def test_last_rejection_is_null_when_nothing_was_rejected(ridge_run):
    _, _, summary = ridge_run
    assert summary["rejected"] == 0
    assert "last_rejection" in summary and summary["last_rejection"] is None


def test_a_smooth_shipped_problem_is_not_flagged(cli, tmp_path):
    out = tmp_path / "out"
    r = run(cli, "optimize", ROOT / "studies" / "401_cantilever_area" / "problem.json", "-o", out,
            "--max-iterations", "6")
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["step_check"]["steps_checked"] == 6 and summary["step_check"]["jumps"] == []
    assert summary["final_taylor_check"]["verdict"] == "smooth", summary["final_taylor_check"]
    # At least two resolved rates (the smallest step's remainder may fall below 100 x the round-off
    # floor: None), each 2.
    rates = [row["rate"] for row in summary["final_taylor_check"]["rows"][1:] if row["rate"] is not None]
    assert len(rates) >= 2 and all(abs(rate - 2) < 0.1 for rate in rates), rates
    assert not any("smooth" in w or "gradients predict" in w for w in summary["warnings"]), summary["warnings"]
    assert summary["last_rejection"] is None


def test_final_taylor_check_can_be_turned_off_or_tuned(cli, tmp_path):
    problem = json.loads((ROOT / "studies" / "401_cantilever_area" / "problem.json").read_text())
    problem["optimizer"]["max_iterations"] = 1
    path = tmp_path / "p.json"
    problem["optimizer"]["final_taylor_check"] = False
    path.write_text(json.dumps(problem))
    r = run(cli, "optimize", path, "-o", tmp_path / "off")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "off" / "summary.json").read_text())["final_taylor_check"] is None
    assert "final Taylor check" not in r.stdout
    problem["optimizer"]["final_taylor_check"] = {"step": 0.005, "halvings": 2, "seed": 3}
    path.write_text(json.dumps(problem))
    r = run(cli, "optimize", path, "-o", tmp_path / "tuned", "-q")
    assert r.returncode == 0, r.stderr
    taylor = json.loads((tmp_path / "tuned" / "summary.json").read_text())["final_taylor_check"]
    assert [row["step"] for row in taylor["rows"]] == [0.005, 0.0025, 0.00125]
    assert taylor["seed"] == 3 and taylor["evaluations"] == 3


@pytest.mark.parametrize("value, field", [
    ({"step": -1}, "optimizer.final_taylor_check.step"),
    ({"halvings": 0}, "optimizer.final_taylor_check.halvings"),
    ({"halvings": 1}, "optimizer.final_taylor_check.halvings"),  # a verdict needs three steps
    ({"steps": 3}, "optimizer.final_taylor_check"),
    ("yes", "optimizer.final_taylor_check"),
])
def test_bad_final_taylor_check_names_the_field(cli, tmp_path, value, field):
    problem = json.loads((ROOT / "studies" / "401_cantilever_area" / "problem.json").read_text())
    problem["optimizer"]["final_taylor_check"] = value
    path = tmp_path / "p.json"
    path.write_text(json.dumps(problem))
    r = run(cli, "optimize", path, "-o", tmp_path / "out")
    assert r.returncode == 1 and field in r.stderr, r.stderr
    assert r.stdout == ""


def test_lbfgsb_with_a_constraint_is_refused_before_any_output(cli, tmp_path):
    problem = json.loads((ROOT / "studies" / "401_cantilever_area" / "problem.json").read_text())
    problem["optimizer"] = {"algorithm": "lbfgsb"}  # 401 has a true area constraint
    path = tmp_path / "p.json"
    path.write_text(json.dumps(problem))
    out = tmp_path / "out"
    r = run(cli, "optimize", path, "-o", out)
    assert r.returncode == 1
    assert r.stdout == "", r.stdout  # no iteration table header, no banner
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "optimizer.algorithm" in lines[0] and "takes no constraints" in lines[0], r.stderr
    assert not out.exists()


def test_a_signal_during_the_final_taylor_check_keeps_the_summary(cli, tmp_path):
    """summary.json is on disk before the final check's evaluations, and a SIGINT among them ends
    the check (inconclusive, saying so) and the run with 130, the summary written again."""
    import signal
    import time
    path = ridge_problem(tmp_path)
    problem = json.loads(path.read_text())
    problem["optimizer"]["final_taylor_check"] = {"halvings": 60}  # 61 evaluations: time to signal
    path.write_text(json.dumps(problem))
    out = tmp_path / "out"
    proc = subprocess.Popen([cli, "optimize", str(path), "-o", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    while not (out / "summary.json").exists() and proc.poll() is None:
        time.sleep(0.002)
    early = json.loads((out / "summary.json").read_text())
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout[-2000:] + stderr
    assert early["final_taylor_check"] is None and early["stop_reason"] == "gradient_tolerance"
    assert "wall_time" in early and early["warnings"]  # complete, but for the check
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == "gradient_tolerance" and summary["final_J"] == early["final_J"]
    taylor = summary["final_taylor_check"]
    assert taylor["verdict"] == "inconclusive" and "stopped by a signal" in taylor["reason"], taylor
    assert 0 < taylor["evaluations"] < 61
