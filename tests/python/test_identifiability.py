"""diffipc.identifiability (issue 13) on synthetic 2D experiments with known parameters: markers
produced by the simulator plus seeded noise, written as a marker file, fitted in log-space with
`diffipc optimize`. Displacement-controlled compression: the Fisher matrix has a zero eigenvalue
along (1, 1) in (log mu, log lambda) and the fit recovers nu within 3 standard errors. The same
block under a traction (force-controlled): both directions are identifiable and the fit recovers
mu and lambda within 3 standard errors each. The Fisher matrix's residual Jacobian is also checked
against finite differences of the markers' simulated positions. In 2D and 3D."""
import json
import math
import re
import subprocess

import numpy as np
import pytest

import diffipc
from diffipc.identifiability import fisher_matrix, identifiability, standard_errors

MU, LAM = 6e4, 1.4e5  # E = 1.62e5 Pa, nu = 0.35
SIGMA = 2e-5  # m, the markers' noise


def scene(load, dim=2):
    """A 4 cm block on its bottom face (y = 0), its top face pushed down: by a prescribed
    displacement, or by a traction."""
    zeros = [0] * dim
    top = [-1] * dim
    top[1] = 0.04 - 1e-6
    down = ["0"] * dim
    s = {
        "dimension": dim,
        "bodies": [{"name": "block", "mesh": {"box": {"min": zeros, "max": [0.04] * dim,
                                                      "cells": [8, 8] if dim == 2 else [4, 4, 4]}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
        "dirichlet": [{"body": "block", "region": {"min": [-1] * dim, "max": [1, 1e-6] + [1] * (dim - 2)},
                       "displacement": zeros}],
        "time": {"integrator": "static", "dt": 0.5, "steps": 2},
        "solver": {"residual_tolerance": 1e-11},
    }
    if load == "displacement":
        down[1] = "-0.004*t"
        s["dirichlet"].append({"body": "block", "region": {"min": top, "max": [1] * dim}, "displacement": down})
    else:
        down[1] = "-1.5e4*t"
        s["neumann"] = [{"body": "block", "region": {"min": top, "max": [1] * dim}, "traction": down}]
    return s


def lame_to_E_nu(mu, lam):
    return mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu))


def synthetic(tmp_path, load, dim=2):
    s = scene(load, dim)
    E, nu = lame_to_E_nu(MU, LAM)
    s["bodies"][0]["material"].update(E=E, nu=nu)
    _, tr = diffipc.simulate(s)
    rest, final = tr["positions"][0], tr["positions"][-1]
    right = np.where(rest[:, 0] > 0.04 - 1e-9)[0]  # the vertices of the right face
    rng = np.random.default_rng(13)
    measured = final[right] + rng.normal(0, SIGMA, size=final[right].shape)
    path = tmp_path / f"markers_{load}.txt"
    assert len(right) == (9 if dim == 2 else 25)
    path.write_text("\n".join(" ".join("%.17g" % v for v in (*r, *m)) for r, m in zip(rest[right], measured)) + "\n")
    problem = {
        "scene": scene(load, dim),
        "objective": {"type": "markers", "file": path.name},
        "parameters": [{"type": "mu", "per": "body", "maps": [{"type": "exp"}], "initial": math.log(MU / 4),
                        "lower": 5, "upper": 20},
                       {"type": "lambda", "per": "body", "maps": [{"type": "exp"}], "initial": math.log(LAM / 10),
                        "lower": 5, "upper": 20}],
        "optimizer": {"algorithm": "lbfgsb", "max_iterations": 100, "relative_gradient_tolerance": 1e-9},
    }
    (tmp_path / f"problem_{load}.json").write_text(json.dumps(problem))
    return problem


def fit(cli, tmp_path, load):
    r = subprocess.run([cli, "optimize", tmp_path / f"problem_{load}.json", "-o", tmp_path / f"out_{load}", "-q"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return np.array(json.loads((tmp_path / f"out_{load}" / "summary.json").read_text())["design"])


@pytest.mark.parametrize("dim", [2, 3])
def test_displacement_control_leaves_E_unidentified_and_recovers_nu(cli, tmp_path, dim):
    problem = synthetic(tmp_path, "displacement", dim)
    x = fit(cli, tmp_path, "displacement")
    R, F, J = fisher_matrix(problem, x, base_directory=tmp_path)
    assert R.shape == ((9 if dim == 2 else 25) * dim, 2)
    (l1, v1, ok1), (l2, v2, ok2) = identifiability(F)
    assert ok1 and not ok2
    assert abs(l2) < 1e-8 * l1
    assert np.allclose(v2, [math.sqrt(0.5)] * 2, atol=1e-6)  # E at fixed nu
    # nu's direction: t = log lambda - log mu; its standard error from F along (-1, 1)/sqrt(2).
    d = np.array([-1.0, 1.0]) / math.sqrt(2)
    s2 = 2 * J / (R.shape[0] - 2)
    se_t = math.sqrt(2) * math.sqrt(s2 / (d @ F @ d))
    t_fit, t_true = x[1] - x[0], math.log(LAM / MU)
    assert abs(t_fit - t_true) < 3 * se_t, (t_fit, t_true, se_t)
    assert se_t < 0.2


@pytest.mark.parametrize("dim", [2, 3])
def test_a_traction_makes_both_identifiable_and_recovers_them(cli, tmp_path, dim):
    problem = synthetic(tmp_path, "traction", dim)
    x = fit(cli, tmp_path, "traction")
    R, F, J = fisher_matrix(problem, x, base_directory=tmp_path)
    (l1, _, ok1), (l2, _, ok2) = identifiability(F)
    assert ok1 and ok2 and l2 > 1e-4 * l1
    se = standard_errors(R, F, J)
    truth = np.log([MU, LAM])
    assert np.all(np.abs(x - truth) < 3 * se), (x, truth, se)
    assert np.all(se < 0.3)


def markers_at(x, rest, load, scene_json=None, steps=(-1,)):
    """The simulated positions of the vertices at `rest` (2D) for the design x, at the listed
    states, flattened state by state."""
    s = json.loads(json.dumps(scene_json or scene(load)))
    E, nu = lame_to_E_nu(*np.exp(x))
    s["bodies"][0]["material"].update(E=E, nu=nu)
    _, tr = diffipc.simulate(s)
    idx = [int(np.argmin(np.linalg.norm(tr["positions"][0] - X, axis=1))) for X in rest]
    return np.concatenate([tr["positions"][k][idx].reshape(-1) for k in steps])


def test_the_residual_jacobian_matches_finite_differences(cli, tmp_path):
    problem = synthetic(tmp_path, "traction")
    x = np.log([MU, LAM])
    R, _, _ = fisher_matrix(problem, x, base_directory=tmp_path)
    rest = np.loadtxt(tmp_path / "markers_traction.txt")[:, :2]
    h = 1e-4
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (markers_at(x + e, rest, "traction") - markers_at(x - e, rest, "traction")) / (2 * h)
        assert np.allclose(R[:, k], fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max()), k


def test_timed_markers_rows_match_finite_differences(tmp_path):
    """A transient run (implicit Euler, the traction block released from rest) with markers
    measured at steps 1 and 3 (a marker file with a time column) and per-marker sigma: each row
    of R is the marker coordinate's derivative at its time over its sigma."""
    s = scene("traction")
    s["time"] = {"integrator": "implicit_euler", "dt": 0.002, "steps": 3}
    truth = np.log([MU, LAM])
    rest = np.array([[0.04, 0.01], [0.04, 0.03], [0.02, 0.04]])
    measured = markers_at(truth, rest, None, s, steps=(1, 3)).reshape(2, 3, 2) + 1e-5
    lines = ["%.17g %.17g %.17g %.17g %.17g" % (*X, k * 0.002, *measured[i, m])
             for i, k in enumerate((1, 3)) for m, X in enumerate(rest)]
    (tmp_path / "timed.txt").write_text("\n".join(lines) + "\n")
    sigma = [1e-5, 2e-5, 4e-5]
    problem = {"scene": s, "objective": {"type": "markers", "file": "timed.txt", "sigma": sigma},
               "parameters": [{"type": t, "per": "body", "maps": [{"type": "exp"}], "initial": 10}
                              for t in ("mu", "lambda")]}
    labels = []
    R, _, _ = fisher_matrix(problem, truth, base_directory=tmp_path, labels=labels)
    assert R.shape == (12, 2) and labels[0] == "marker 0 at t = 0.002, x" and labels[-1] == "marker 2 at t = 0.006, y"
    scale = np.tile(np.repeat(1 / np.array(sigma), 2), 2)
    h = 1e-4
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (markers_at(truth + e, rest, None, s, (1, 3)) - markers_at(truth - e, rest, None, s, (1, 3))) / (2 * h)
        assert np.allclose(R[:, k], fd * scale, rtol=1e-5, atol=1e-9 * np.abs(fd * scale).max()), k


def test_plane_stress_young_poisson_matches_the_delta_method():
    from diffipc.identifiability import young_poisson
    x = np.array([9.0, 10.5])
    cov = np.array([[0.02, -0.004], [-0.004, 0.05]])

    def plane_stress(x):
        mu, lam = np.exp(x)
        return 4 * mu * (lam + mu) / (lam + 2 * mu), lam / (lam + 2 * mu)

    (E, nu), (se_log_e, se_nu) = young_poisson(x, cov, plane_stress=True)
    assert (E, nu) == pytest.approx(plane_stress(x), rel=1e-14)
    jac = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = 1e-6
        (Ep, nup), (Em, num) = plane_stress(x + e), plane_stress(x - e)
        jac[:, j] = [(math.log(Ep) - math.log(Em)) / 2e-6, (nup - num) / 2e-6]
    c = jac @ cov @ jac.T
    assert se_log_e == pytest.approx(math.sqrt(c[0, 0]), rel=1e-7)
    assert se_nu == pytest.approx(math.sqrt(c[1, 1]), rel=1e-7)


def test_a_problem_whose_scene_is_a_file(tmp_path):
    problem = synthetic(tmp_path, "traction")
    (tmp_path / "scene.json").write_text(json.dumps(problem["scene"]))
    by_file = dict(problem, scene="scene.json")
    x = np.log([MU, LAM])
    R1, _, J1 = fisher_matrix(problem, x, base_directory=tmp_path)
    R2, _, J2 = fisher_matrix(by_file, x, base_directory=tmp_path)
    assert np.array_equal(R1, R2) and J1 == J2
    with pytest.raises(ValueError, match="scenes"):
        fisher_matrix({"scenes": [], "objective": problem["objective"]}, x, base_directory=tmp_path)


def force_at(problem, x):
    """The top plate's y force (N) at the last step for the design x (reaction_force, no targets)."""
    p = json.loads(json.dumps(problem))
    p["objective"] = {"type": "reaction_force", "dirichlet": 1, "axis": "y", "time": "final"}
    p.pop("optimizer", None)
    rf = diffipc.ReducedFunctional(p)
    return rf(rf.parameters_of(np.asarray(x, dtype=float)))


def test_a_force_term_weights_its_row_and_identifies_E(cli, tmp_path):
    """Markers (sigma) and the top plate's force (sigma_F) together: each row of R is sqrt(w) times
    the residual's derivative (checked by finite differences of the markers' and the force's
    simulated values), the Fisher matrix is regular, and the fit recovers mu and lambda."""
    problem = synthetic(tmp_path, "displacement")
    truth = np.log([MU, LAM])
    reading = force_at(problem, truth) * (1 + 0.01 * np.random.default_rng(5).normal())
    sigma_f = 0.01 * abs(reading)
    problem["objective"] = {"type": "sum", "terms": [
        {"objective": dict(problem["objective"], sigma=SIGMA)},
        {"weight": 2.0, "objective": {"type": "reaction_force", "dirichlet": 1, "axis": "y", "targets": [reading],
                                      "steps": [2], "sigma": sigma_f}}]}
    labels, misfits = [], []
    R, F, J = fisher_matrix(problem, truth, base_directory=tmp_path, labels=labels, misfits=misfits)
    assert R.shape == (9 * 2 + 1, 2) and len(labels) == 19
    assert labels[0] == "marker 0, x" and labels[-1] == "reaction force of dirichlet[1] along y at step 2"
    rest = np.loadtxt(tmp_path / "markers_displacement.txt")[:, :2]
    h = 1e-4
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (force_at(problem, truth + e) - force_at(problem, truth - e)) / (2 * h)
        assert R[-1, k] == pytest.approx(math.sqrt(2.0) / sigma_f * fd, rel=1e-5), k
        fd = (markers_at(truth + e, rest, "displacement") - markers_at(truth - e, rest, "displacement")) / (2 * h)
        assert np.allclose(R[:-1, k], fd / SIGMA, rtol=1e-5, atol=1e-9 * np.abs(fd).max() / SIGMA), k
    # J = 1/2 sum of the weighted misfits squared: the weights of R are those of J
    assert len(misfits) == 10
    weights = [1 / SIGMA**2] * 9 + [2.0 / sigma_f**2]
    assert J == pytest.approx(0.5 * sum(w * m**2 for w, (_, m) in zip(weights, misfits)), rel=1e-9)
    assert misfits[-1][1] == pytest.approx(abs(reading - force_at(problem, truth)), rel=1e-6)
    (l1, _, ok1), (l2, _, ok2) = identifiability(F)
    assert ok1 and ok2 and l2 > 1e-4 * l1
    (tmp_path / "problem_displacement.json").write_text(json.dumps(problem))
    x = fit(cli, tmp_path, "displacement")
    R, F, J = fisher_matrix(problem, x, base_directory=tmp_path)
    se = standard_errors(R, F, J)
    assert np.all(np.abs(x - truth) < 3 * se), (x, truth, se)


def test_young_poisson_standard_errors_match_the_delta_method():
    from diffipc.identifiability import young_poisson
    x = np.array([8.6, 11.3])
    cov = np.array([[0.01, 0.002], [0.002, 0.03]])
    (E, nu), (se_log_e, se_nu) = young_poisson(x, cov)
    assert (E, nu) == pytest.approx(lame_to_E_nu(*np.exp(x)), rel=1e-14)
    jac = np.zeros((2, 2))
    for j in range(2):
        e = np.zeros(2)
        e[j] = 1e-6
        (Ep, nup), (Em, num) = lame_to_E_nu(*np.exp(x + e)), lame_to_E_nu(*np.exp(x - e))
        jac[:, j] = [(math.log(Ep) - math.log(Em)) / 2e-6, (nup - num) / 2e-6]
    c = jac @ cov @ jac.T
    assert se_log_e == pytest.approx(math.sqrt(c[0, 0]), rel=1e-7)
    assert se_nu == pytest.approx(math.sqrt(c[1, 1]), rel=1e-7)


def test_the_report_of_a_run_says_what_the_data_determine(cli, tmp_path):
    """python3 -m diffipc.identifiability RUN: E not determined under displacement control, both
    with standard errors under a traction."""
    import sys
    for load in ("displacement", "traction"):
        synthetic(tmp_path, load)
        fit(cli, tmp_path, load)
        r = subprocess.run([sys.executable, "-m", "diffipc.identifiability", str(tmp_path / f"out_{load}")],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        lines = r.stdout.splitlines()
        assert lines[0].startswith("fit: J = ") and "from 18 weighted residuals, 2 design variables" in lines[0]
        # the markers' distances, from single-marker functionals; J = 1/2 sum of their squares here
        J = float(re.match(r"fit: J = (\S+) ", lines[0]).group(1))
        rms = float(re.match(r"  markers: 9 positions, distance to the measured ones RMS (\S+) mm", lines[1]).group(1))
        assert rms == pytest.approx(1e3 * math.sqrt(2 * J / 9), rel=1e-3)
        if load == "displacement":
            assert "NOT identifiable" in lines[3] and "identifiable" in lines[2]
            assert "E is NOT determined by these data" in lines[-1] and lines[-1].startswith("  nu = 0.3")
        else:
            assert "NOT" not in r.stdout
            assert re.match(r"  E = [0-9.e+]+ Pa \+- [0-9.]+%, nu = 0\.3\d* \+- 0\.0", lines[-1]), lines[-1]
    r = subprocess.run([sys.executable, "-m", "diffipc.identifiability", str(tmp_path / "nothing")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "optimal_problem.json: missing" in r.stderr


def test_active_bounds_within_the_tolerance():
    from diffipc.identifiability import active_bounds
    lo, hi = np.array([5.0, 5.0, -np.inf, 0.0]), np.array([20.0, 20.0, np.inf, np.inf])
    # 15 * 1e-6 of the range is the tolerance: on, just inside it, well inside; a one-sided bound
    assert active_bounds([5.0, 20.0 - 1e-5, 7.0, 1e-7], lo, hi) == ["lo", "hi", None, "lo"]
    assert active_bounds([5.0 + 1e-3, 19.9, 0.0, 1e-3], lo, hi) == [None, None, None, None]


def test_the_report_marks_a_variable_ended_on_its_bound(tmp_path):
    """A fit that ended with log lambda on its lower bound (nu near 0): the report says that the
    bound is active where it prints that variable's and nu's standard errors; a fit inside its
    bounds carries no such mark. The run folder is written by hand (the problem at the design,
    as optimal_problem.json), so no optimization is run."""
    import sys
    problem = synthetic(tmp_path, "traction")
    for name, lam_lower, marked in (("on_bound", math.log(LAM / 100), True), ("inside", 5.0, False)):
        run = tmp_path / name
        run.mkdir()
        (run / "markers_traction.txt").write_text((tmp_path / "markers_traction.txt").read_text())
        p = json.loads(json.dumps(problem))
        p["parameters"][0]["initial"] = math.log(MU)
        p["parameters"][1]["initial"] = lam_lower if marked else math.log(LAM)
        p["parameters"][1]["lower"] = lam_lower
        (run / "optimal_problem.json").write_text(json.dumps(p))
        r = subprocess.run([sys.executable, "-m", "diffipc.identifiability", str(run)],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        design = next(line for line in r.stdout.splitlines() if line.startswith("  design "))
        last = r.stdout.splitlines()[-1]
        if marked:
            first, second = design[len("  design "):].split(", ", 1)
            assert "at bound" not in first
            assert second.endswith("(at bound lo: standard error not meaningful)"), design
            assert last.startswith("  E = ") and "nu = 0.0" in last, last
            assert last.endswith("(log lambda at bound lo: standard error not meaningful)"), last
        else:
            assert "at bound" not in r.stdout, r.stdout
