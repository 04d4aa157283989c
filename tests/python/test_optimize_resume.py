"""diffipc optimize: history.h5 (read with h5py, against history.csv and an independent
evaluation of J) and --resume DIR (docs/optimization.md). An L-BFGS-B run stopped after some
iterations (by its iteration budget, SIGINT, SIGKILL) and resumed must repeat the uninterrupted
run's iterates; an Ipopt run resumed from its last iterate must converge; a run that cannot be
resumed is refused with one line naming the file or field."""
import csv
import json
import math
import shutil
import signal
import subprocess

import numpy as np
import pytest

import diffipc
from conftest import ROOT

h5py = pytest.importorskip("h5py")

# Per-iteration datasets of history.h5 that do not depend on timing.
EXACT = ["iteration", "x", "J", "constraints", "gradient_norm", "step_norm", "evaluations", "rejected"]
TIMES = ["evaluation_seconds", "optimizer_seconds", "wall_seconds"]


def run(cli, *args, timeout=300):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def bar_problem(tmp_path, steps=4, iterations=12):
    """Study 302's bar: 30 per-element log-moduli (exp, then a filter) fitted by L-BFGS-B to
    markers simulated at the bar's own E, from half of it. `steps` time steps (the markers are
    at steps 2 and 4; more steps only make each evaluation longer)."""
    p = json.loads((ROOT / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())
    E0 = p["scene"]["bodies"][0]["material"]["E"]
    _, tr = diffipc.simulate(p["scene"])
    objective = p["objective"]
    objective["targets"] = [[list(tr["positions"][k][v]) for v in objective["vertices"]] for k in objective["steps"]]
    p["scene"]["time"]["steps"] = steps
    p["parameters"] = [{"type": "E", "per": "element", "initial": math.log(0.5 * E0),
                        "lower": math.log(1e-2 * E0), "upper": math.log(1e2 * E0),
                        "maps": [{"type": "exp"}, {"type": "filter", "radius": 0.05}]}]
    p["optimizer"] = {"algorithm": "lbfgsb", "max_iterations": iterations}
    p.pop("gradcheck", None)
    path = tmp_path / f"bar{steps}.json"
    path.write_text(json.dumps(p))
    return path


def beam_problem(tmp_path, name="material", algorithm="ipopt"):
    """Study 301's beam: the shape of its top through 2 FFD variables under a rest-area limit."""
    p = json.loads((ROOT / "studies" / "301_beam_shape_stress" / "problem.json").read_text())
    p["parameters"] = [{"type": "shape", "lower": -0.05, "upper": 0.05, "maps": [
        {"type": "ffd", "box": {"min": [0.2, -0.05], "max": [0.95, 0.25]}, "degree": [3, 2], "axes": [1],
         "fixed_border": True}]}]
    p["constraints"] = [{"name": name, "objective": {"type": "volume", "configuration": "rest"}, "upper": 0.2}]
    p["optimizer"] = {"algorithm": algorithm, "max_iterations": 40}
    p.pop("gradcheck", None)
    path = tmp_path / f"beam_{name}_{algorithm}.json"
    path.write_text(json.dumps(p))
    return path


def history(out):
    with h5py.File(out / "history.h5", "r") as f:
        return {k: f[k][()] for k in f.keys()}, dict(f.attrs)


def summary(out):
    return json.loads((out / "summary.json").read_text())


def assert_same_run(resumed, whole):
    """The resumed run's history and summary are the uninterrupted run's, but for times."""
    a, _ = history(resumed)
    b, _ = history(whole)
    for name in EXACT:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    sa, sb = summary(resumed), summary(whole)
    for key in ("stop_reason", "iterations", "evaluations", "rejected", "initial_J", "final_J", "design",
                "max_violation"):
        assert sa[key] == sb[key], key
    rows_a = list(csv.reader((resumed / "history.csv").open()))
    rows_b = list(csv.reader((whole / "history.csv").open()))
    assert len(rows_a) == len(rows_b)
    for ra, rb in zip(rows_a, rows_b):
        assert ra[:-3] == rb[:-3]  # every column but the three times, as text


def test_history_h5_agrees_with_the_csv_and_with_J_evaluated_again(cli, tmp_path):
    problem = beam_problem(tmp_path)
    out = tmp_path / "o"
    r = run(cli, "optimize", problem, "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    h, attrs = history(out)
    s = summary(out)
    K = s["iterations"] + 1
    assert attrs["algorithm"] == "ipopt" and attrs["design_size"] == 2
    assert list(attrs["constraint_names"]) == ["material"]
    assert attrs["problem"] == str(problem)
    assert h["x"].shape == (K, 2) and h["constraints"].shape == (K, 1)
    np.testing.assert_array_equal(h["iteration"], np.arange(K))
    assert (np.diff(h["evaluations"]) >= 0).all() and (np.diff(h["wall_seconds"]) > 0).all()
    # history.csv holds the same numbers (%.17g: every bit).
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == K
    for k, row in enumerate(rows):
        assert int(row["iteration"]) == h["iteration"][k]
        assert float(row["J"]) == h["J"][k]
        assert float(row["material"]) == h["constraints"][k, 0]
        for name in ["gradient_norm", "step_norm"] + TIMES:
            assert float(row[name]) == h[name][k], name
        assert int(row["evaluations"]) == h["evaluations"][k] and int(row["rejected"]) == h["rejected"][k]
    # x of each row is the design of that row's J and constraint: evaluated again here.
    J = diffipc.ReducedFunctional(str(problem))
    np.testing.assert_array_equal(h["x"][0], J.design_initial)
    for k in (0, K - 1):
        value, _ = J.evaluate(J.parameters_of(h["x"][k]), gradient=False)
        assert value == pytest.approx(h["J"][k], rel=1e-12)
    # The rest area of the first and last design (the constraint), from the VTU's triangles.
    meshio = pytest.importorskip("meshio")
    for k in (0, K - 1):
        m = meshio.read(out / f"design_{k}.vtu")
        p, t = m.points, m.cells_dict["triangle"]
        u, v = p[t[:, 1], :2] - p[t[:, 0], :2], p[t[:, 2], :2] - p[t[:, 0], :2]
        area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
        assert area == pytest.approx(h["constraints"][k, 0], rel=1e-12)
    assert s["design"] == list(h["x"][-1])


def test_lbfgsb_resumed_after_its_iteration_budget_repeats_the_uninterrupted_run(cli, tmp_path):
    problem = bar_problem(tmp_path)
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert run(cli, "optimize", problem, "-o", whole, "-q").returncode == 0
    assert summary(whole)["stop_reason"] == "iteration_budget" and summary(whole)["iterations"] == 12
    r = run(cli, "optimize", problem, "-o", part, "-q", "--max-iterations", 5)
    assert r.returncode == 0, r.stderr
    assert summary(part)["iterations"] == 5 and len(history(part)[0]["J"]) == 6
    # The same budget again: nothing left to do, refused (exit 1) naming the field.
    r = run(cli, "optimize", "--resume", part, "-q", "--max-iterations", 5)
    assert r.returncode == 1 and "optimizer.max_iterations" in r.stderr, r.stderr
    # The problem's budget (12) counts the whole run: 7 more iterations.
    r = run(cli, "optimize", "--resume", part)
    assert r.returncode == 0, r.stderr
    assert "resuming" in r.stdout and "at iteration 5" in r.stdout
    assert summary(part)["resumed_at_iteration"] == 5
    assert_same_run(part, whole)
    # The rest designs of the whole run are all there and listed.
    assert sorted(p.name for p in part.glob("design_*.vtu")) == sorted(p.name for p in whole.glob("design_*.vtu"))
    assert (part / "designs.pvd").read_text().count("<DataSet") == 13


def test_lbfgsb_resumed_after_sigint_repeats_the_uninterrupted_run(cli, tmp_path):
    # 100 time steps: an evaluation takes long enough for the signal to arrive mid-run.
    problem = bar_problem(tmp_path, steps=100)
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert run(cli, "optimize", problem, "-o", whole, "-q").returncode == 0
    proc = subprocess.Popen([cli, "optimize", str(problem), "-o", str(part)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.split()[:1] == ["2"]:
            proc.send_signal(signal.SIGINT)
            break
    proc.stdout.read()
    assert proc.wait(timeout=120) == 130, proc.stderr.read()
    s = summary(part)
    assert s["stop_reason"] == "user_stop" and 2 <= s["iterations"] < 12, s
    r = run(cli, "optimize", "--resume", part, "-q")
    assert r.returncode == 0, r.stderr
    assert summary(part)["resumed_at_iteration"] == s["iterations"]
    assert_same_run(part, whole)


def test_lbfgsb_resumed_after_sigkill_and_with_rows_beyond_the_state(cli, tmp_path):
    problem = bar_problem(tmp_path, steps=100)
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert run(cli, "optimize", problem, "-o", whole, "-q").returncode == 0
    proc = subprocess.Popen([cli, "optimize", str(problem), "-o", str(part)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    for line in proc.stdout:
        if line.split()[:1] == ["3"]:
            proc.kill()  # SIGKILL: no summary, history.h5 still marked as open for writing
            break
    proc.wait(timeout=60)
    assert not (part / "summary.json").exists()
    with h5py.File(part / "history.h5", "r", swmr=True) as f:
        done = f["J"].shape[0]
    assert done >= 4
    r = run(cli, "optimize", "--resume", part, "-q")
    assert r.returncode == 0, r.stderr
    assert_same_run(part, whole)

    # A run killed after it wrote an iteration's row but before its state: the rows after the
    # state's iteration are dropped and done again. Made here by putting back iteration 5's state
    # after the run went on to iteration 7.
    again = tmp_path / "again"
    assert run(cli, "optimize", problem, "-o", again, "-q", "--max-iterations", 5).returncode == 0
    shutil.copy(again / "optimizer_state.h5", tmp_path / "state5.h5")
    assert run(cli, "optimize", "--resume", again, "-q", "--max-iterations", 7).returncode == 0
    assert len(history(again)[0]["J"]) == 8
    shutil.copy(tmp_path / "state5.h5", again / "optimizer_state.h5")
    r = run(cli, "optimize", "--resume", again)
    assert r.returncode == 0, r.stderr
    assert "at iteration 5" in r.stdout
    assert_same_run(again, whole)


def test_a_resumed_run_keeps_its_step_check_and_best_point(cli, tmp_path):
    """The ridge of test_optimize_summary.py: Ipopt's steps to iterations 1 and 2 jump, and its best
    point is a trial point at evaluation 2. Stopped after 3 iterations and resumed for one more,
    the run's summary still lists those jumps, counts every step of both parts and keeps that best
    point (the resumed part, at J near 1e-3, does not beat it)."""
    from test_optimize_summary import ridge_problem
    problem = ridge_problem(tmp_path)
    out = tmp_path / "out"
    assert run(cli, "optimize", problem, "-o", out, "-q", "--max-iterations", 3).returncode == 0
    before = summary(out)
    assert [j["iteration"] for j in before["step_check"]["jumps"]] == [1, 2], before["step_check"]
    assert before["best_point"]["evaluation"] == 2 and before["best_point"]["iteration"] is None
    r = run(cli, "optimize", "--resume", out, "-q", "--max-iterations", 4)
    assert r.returncode == 0, r.stderr
    after = summary(out)
    assert after["resumed_at_iteration"] == 3 and after["iterations"] == 4
    assert after["step_check"]["steps_checked"] == 4
    for jump in before["step_check"]["jumps"]:
        assert jump in after["step_check"]["jumps"], after["step_check"]
    assert after["step_check"]["jumps_found"] == len(after["step_check"]["jumps"]) >= 2
    assert after["best_point"] == before["best_point"]
    assert any(w.startswith(f"{after['step_check']['jumps_found']} of 4 accepted steps") for w in after["warnings"])


def test_ipopt_resumed_from_its_last_iterate_converges(cli, tmp_path):
    problem = beam_problem(tmp_path)
    whole, part = tmp_path / "whole", tmp_path / "part"
    assert run(cli, "optimize", problem, "-o", whole, "-q").returncode == 0
    sw = summary(whole)
    assert sw["stop_reason"] == "gradient_tolerance", sw
    assert run(cli, "optimize", problem, "-o", part, "-q", "--max-iterations", 2).returncode == 0
    first, _ = history(part)
    r = run(cli, "optimize", "--resume", part, "-q")
    assert r.returncode == 0, r.stderr
    s = summary(part)
    assert s["stop_reason"] == "gradient_tolerance", s
    assert s["max_violation"] <= 1e-6
    assert s["final_J"] == pytest.approx(sw["final_J"], rel=1e-7)
    np.testing.assert_allclose(s["design"], sw["design"], rtol=0, atol=1e-6)
    h, _ = history(part)
    # The first part's rows are kept as they were; the iterations go on from 3.
    for name in EXACT:
        np.testing.assert_array_equal(h[name][:3], first[name], err_msg=name)
    np.testing.assert_array_equal(h["iteration"], np.arange(s["iterations"] + 1))
    assert s["evaluations"] == h["evaluations"][-1] and s["initial_J"] == h["J"][0]
    # A converged run: nothing to resume, exit 0, the outputs untouched.
    before = (part / "history.csv").read_text()
    r = run(cli, "optimize", "--resume", part)
    assert r.returncode == 0 and "nothing to resume" in r.stdout, r.stdout + r.stderr
    assert (part / "history.csv").read_text() == before


def test_a_resume_with_the_problem_file_given_and_a_larger_budget(cli, tmp_path):
    problem = bar_problem(tmp_path, iterations=4)
    out = tmp_path / "o"
    assert run(cli, "optimize", problem, "-o", out, "-q").returncode == 0
    p = json.loads(problem.read_text())
    p["optimizer"]["max_iterations"] = 6
    longer = tmp_path / "longer.json"
    longer.write_text(json.dumps(p))
    r = run(cli, "optimize", longer, "--resume", out, "-q")
    assert r.returncode == 0, r.stderr
    s = summary(out)
    assert s["iterations"] == 6 and s["problem"] == str(problem)  # the run's problem, not the file given


def changed(problem, tmp_path, mutate):
    p = json.loads(problem.read_text())
    mutate(p)
    path = tmp_path / "changed.json"
    path.write_text(json.dumps(p))
    return path


def test_a_run_that_cannot_be_resumed_is_refused_naming_why(cli, tmp_path):
    bar, beam = bar_problem(tmp_path, iterations=3), beam_problem(tmp_path)
    runs = {}
    for name, problem in (("bar", bar), ("beam", beam)):
        runs[name] = tmp_path / name
        assert run(cli, "optimize", problem, "-o", runs[name], "-q", "--max-iterations", 2).returncode == 0

    def refused(args, expect):
        r = run(cli, "optimize", *args, "-q")
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 1 and len(lines) == 1 and expect in lines[0], (r.returncode, r.stdout, r.stderr)

    refused(["--resume", tmp_path / "nowhere"], "nowhere: no such directory")
    (tmp_path / "empty").mkdir()
    refused(["--resume", tmp_path / "empty"], "history.h5: missing")
    refused(["--resume", runs["bar"], "-o", tmp_path / "elsewhere"], "--resume excludes --output")
    refused([], "a problem file is required")
    # Another problem: other design variables, other constraint names, another algorithm.
    per_body = changed(bar, tmp_path, lambda p: p["parameters"][0].update(per="body", maps=[{"type": "exp"}]))
    refused([per_body, "--resume", runs["bar"]], "has 1 design variables, the run in")
    refused([beam_problem(tmp_path, name="area"), "--resume", runs["beam"]], 'constraints ["area"]')
    refused([beam_problem(tmp_path, algorithm="slsqp"), "--resume", runs["beam"]], "optimizer.algorithm")
    # A time budget already spent.
    refused(["--resume", runs["bar"], "--max-seconds", 1e-9], "optimizer.max_seconds")
    # A run the optimizer ended (here: its summary says so).
    stalled = tmp_path / "stalled"
    shutil.copytree(runs["bar"], stalled)
    s = summary(stalled)
    s["stop_reason"] = "line_search_stalled"
    (stalled / "summary.json").write_text(json.dumps(s))
    refused(["--resume", stalled], "stop_reason line_search_stalled")
    # Files that do not belong together, or are not ours.
    for name, damage, expect in (
            ("nostate", lambda d: (d / "optimizer_state.h5").unlink(), "optimizer_state.h5: missing"),
            ("otherstate", lambda d: shutil.copy(runs["beam"] / "optimizer_state.h5", d), "optimizer_state.h5"),
            ("garbage", lambda d: (d / "history.h5").write_text("garbage"), "history.h5: cannot open")):
        d = tmp_path / name
        shutil.copytree(runs["bar"], d)
        damage(d)
        refused(["--resume", d], expect)
