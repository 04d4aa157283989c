"""diffipc optimize (docs/optimization.md): short runs of a shape and a material problem,
their outputs, independent checks that every written rest design is valid, and bad input."""
import csv
import json
import math
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT
from design_checks import boundary_edges, crossing, triangle_areas


def run(cli, *args, timeout=600):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def beam_shape_problem(algorithm="ipopt", iterations=6):
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    p["parameters"] = [{"type": "shape", "lower": -0.05, "upper": 0.05, "maps": [
        {"type": "ffd", "box": {"min": [0.2, -0.05], "max": [0.95, 0.25]}, "degree": [3, 2], "axes": [1],
         "fixed_border": True}]}]
    p["constraints"] = [{"name": "material", "objective": {"type": "volume", "configuration": "rest"},
                         "upper": 0.2}]
    p["optimizer"] = {"algorithm": algorithm, "max_iterations": iterations}
    del p["gradcheck"]
    return p


@pytest.mark.parametrize("algorithm", ["ipopt", "slsqp"])
def test_beam_shape_under_a_material_constraint(cli, tmp_path, algorithm):
    meshio = pytest.importorskip("meshio")
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam_shape_problem(algorithm)))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] in ("gradient_tolerance", "iteration_budget", "f_tolerance", "x_tolerance",
                                      "line_search_stalled"), summary
    assert summary["final_J"] < summary["initial_J"]
    assert summary["max_violation"] <= 1e-6
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == summary["iterations"] + 1 and rows[0]["iteration"] == "0"
    assert float(rows[0]["J"]) == pytest.approx(summary["initial_J"], rel=1e-12)
    for row in rows:
        assert float(row["material"]) <= 0.2 * (1 + 1e-6) or row["iteration"] == "0"
    # Every written rest design is valid, checked here on the VTU's points and cells.
    designs = sorted(out.glob("design_*.vtu"))
    assert len(designs) >= 2
    for path in designs:
        m = meshio.read(path)
        cells = m.cells_dict["triangle"]
        assert (triangle_areas(m.points, cells) > 0).all(), path
        assert not crossing(m.points, boundary_edges(cells)), path
    # The optimal problem starts from the optimum: its J is the final J.
    J = diffipc.ReducedFunctional(str(out / "optimal_problem.json"))
    np.testing.assert_allclose(J.design_initial, summary["design"], rtol=0, atol=0)
    value, _ = J.evaluate(J.parameters_of(J.design_initial), gradient=False)
    assert value == pytest.approx(summary["final_J"], rel=1e-10)


@pytest.mark.parametrize("algorithm", ["mma", "ccsaq", "slsqp"])
def test_nlopt_starts_on_an_active_constraint(cli, tmp_path, algorithm):
    # The beam starts with its rest area on the bound up to round-off (0.2 + 1e-14): NLopt's CCSA
    # methods used to shrink their steps to 1e-17 there and stop where they began (the driver
    # now hands them the inequalities a tenth of the tolerance looser).
    p = beam_shape_problem(algorithm, iterations=30)
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["final_J"] < (1 - 5e-3) * s["initial_J"], s  # measured with MMA: 2.15441e5 -> 2.12831e5
    assert s["max_violation"] <= 1e-6


def modulus_fit_problem(iterations):
    """Synthetic markers: the bar of study 302 simulated at its own E; a log-space, filtered
    per-element fit that starts at half of it."""
    p = json.loads((ROOT / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())
    E0 = p["scene"]["bodies"][0]["material"]["E"]
    _, tr = diffipc.simulate(p["scene"])
    objective = p["objective"]
    objective["targets"] = [[list(tr["positions"][k][v]) for v in objective["vertices"]] for k in objective["steps"]]
    p["parameters"] = [{"type": "E", "per": "element", "initial": math.log(0.5 * E0),
                        "lower": math.log(1e-2 * E0), "upper": math.log(1e2 * E0),
                        "maps": [{"type": "exp"}, {"type": "filter", "radius": 0.05}]}]
    p["optimizer"] = {"algorithm": "lbfgsb", "max_iterations": iterations}
    p.pop("gradcheck", None)
    return p


def test_log_space_modulus_with_lbfgsb(cli, tmp_path):
    p = modulus_fit_problem(15)
    problem = tmp_path / "bar.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["final_J"] < 1e-2 * summary["initial_J"], summary


def test_objective_target_stops_the_run_at_the_first_iterate_below_it(cli, tmp_path):
    # The log-space fit above, with a target at 1e-3 of its start (a discrepancy-principle stop).
    p = modulus_fit_problem(30)
    problem = tmp_path / "bar.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "full", "-q")
    assert r.returncode == 0, r.stderr
    full = [float(row["J"]) for row in csv.DictReader((tmp_path / "full" / "history.csv").open())]
    target = 1e-3 * full[0]
    first = next(k for k, J in enumerate(full) if J <= target)  # the run without a target passes it here
    p["optimizer"]["objective_target"] = target
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["stop_reason"] == "objective_target", summary
    assert summary["iterations"] == first
    rows = [float(row["J"]) for row in csv.DictReader((tmp_path / "o" / "history.csv").open())]
    assert rows == pytest.approx(full[:first + 1], rel=1e-12)
    assert summary["final_J"] <= target
    # A finished run is not resumed.
    r = run(cli, "optimize", "--resume", tmp_path / "o")
    assert r.returncode == 0 and "nothing to resume" in r.stdout


def test_a_failing_forward_solve_is_a_rejected_point_and_the_run_goes_on(cli, tmp_path):
    # Newton gets 9 iterations per step: the beam of study 301 converges for E >= 2e6 and fails
    # (NEWTON_EXHAUSTED) at its own E = 1e6. The tip's targets come from a run at E = 1e6, so
    # the fit, started at E = 3e6 in log space, steps towards designs whose forward fails:
    # those are rejected points, the line search cuts the step, and the run ends normally.
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    scene = p["scene"]
    _, tr = diffipc.simulate(scene)
    tip = [10, 32]  # (1, 0) and (1, 0.2) of the 11 x 3 vertex grid
    p["objective"] = {"type": "markers", "vertices": tip, "steps": [2],
                      "targets": [[list(tr["positions"][2][v]) for v in tip]]}
    scene["solver"]["max_iterations"] = 9
    p["parameters"] = [{"type": "E", "initial": math.log(3e6), "lower": math.log(1e5), "upper": math.log(1e7),
                        "maps": [{"type": "exp"}]}]
    p["optimizer"] = {"algorithm": "lbfgsb", "max_iterations": 10}
    p.pop("gradcheck", None)
    problem = tmp_path / "tip.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["rejected"] >= 1 and "NEWTON_EXHAUSTED" in summary["last_rejection"], summary
    assert summary["final_J"] < summary["initial_J"], summary
    assert math.exp(summary["design"][0]) > 1e6  # it stayed where the forward converges


def test_sigint_stops_after_the_iteration_and_writes_everything(cli, tmp_path):
    import signal
    p = beam_shape_problem("ipopt", iterations=200)
    p["scene"]["bodies"][0]["mesh"]["box"]["cells"] = [80, 16]
    p["optimizer"]["gradient_tolerance"] = 0
    p["optimizer"]["relative_gradient_tolerance"] = 0
    problem = tmp_path / "long.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "o"
    proc = subprocess.Popen([cli, "optimize", str(problem), "-o", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.split()[:1] == ["1"]:  # iteration 1 is done
            proc.send_signal(signal.SIGINT)
            break
    proc.stdout.read()
    assert proc.wait(timeout=120) == 130, proc.stderr.read()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] == "user_stop", summary
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == summary["iterations"] + 1 >= 2
    assert (out / "optimal_problem.json").exists() and (out / "design_final.vtu").exists()


@pytest.mark.parametrize("name", ["problem", "problem_penalty"])
def test_study_401_short(cli, tmp_path, name):
    p = json.loads((ROOT / "studies" / "401_cantilever_area" / f"{name}.json").read_text())
    p["optimizer"]["max_iterations"] = 4
    p["output"]["design_every"] = 0
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["final_J"] < summary["initial_J"]
    if name == "problem":
        assert summary["max_violation"] <= 1e-6


BAD = [
    (lambda p: p["optimizer"].update(algorithm="bfgs") or p, "optimizer.algorithm"),
    (lambda p: p["optimizer"].update(max_iterations=-1) or p, "optimizer.max_iterations"),
    (lambda p: p["optimizer"].update(gradient_tol=1) or p, "optimizer.gradient_tol"),
    (lambda p: p["parameters"][0].update(lower=0.1, upper=0.0) or p, "parameters[0].lower"),
    (lambda p: p["parameters"][0].update(lower=0.01) or p, "parameters[0].lower"),
    (lambda p: p["constraints"][0].update(objective={"type": "nope"}) or p, "constraints[0].objective"),
    (lambda p: p.update(optimizer=[1]) or p, "optimizer"),
]


@pytest.mark.parametrize("mutate,field", BAD)
def test_bad_optimization_input_names_the_field(cli, tmp_path, mutate, field):
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps(mutate(beam_shape_problem())))
    r = run(cli, "optimize", problem, "-o", tmp_path / "o", "-q")
    assert r.returncode == 1, (r.returncode, r.stdout[-500:], r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], r.stderr


@pytest.mark.parametrize("command", ["optimize", "gradcheck"])
def test_device_flag_is_checked_naming_it(cli, tmp_path, command):
    """--device replaces the scenes' "device": an unknown one is an error naming it, before any work."""
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps(beam_shape_problem()))
    args = ["-o", tmp_path / "o", "-q"] if command == "optimize" else []
    r = run(cli, command, problem, "--device", "tpu", *args)
    assert r.returncode == 1, (r.returncode, r.stdout[-500:], r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and 'device: expected "cpu" or "gpu", got "tpu"' in lines[0], r.stderr
