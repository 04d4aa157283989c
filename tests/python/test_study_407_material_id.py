"""Study 407 (studies/407_material_id_cube): the real cube's Lame parameters fitted to its 24
scanned markers. A short check of what the README reports: from a far-off start L-BFGS-B
converges to the README's Poisson's ratio and marker residual, while the modulus stays where the
start put it (the data do not determine it), and the Fisher matrix there says so."""
import json
import math
import os
import re
import subprocess
import sys

import pytest

from conftest import ROOT

STUDY = ROOT / "studies" / "407_material_id_cube"


def test_study_407_fit_from_a_far_off_start(cli, tmp_path):
    p = json.loads((STUDY / "problem.json").read_text())
    p["scene"]["bodies"][0]["mesh"]["file"] = str(STUDY / "data" / "cube.msh")
    p["objective"]["file"] = str(STUDY / "data" / "markers.txt")
    p["parameters"][0]["initial"], p["parameters"][1]["initial"] = 13.0, 10.0
    problem = tmp_path / "problem.json"
    problem.write_text(json.dumps(p))
    r = subprocess.run([cli, "optimize", problem, "-o", tmp_path / "out", "-q"], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["stop_reason"] == "gradient_tolerance", s
    log_mu, log_lambda = s["design"]
    mu, lam = math.exp(log_mu), math.exp(log_lambda)
    nu = lam / (2 * (lam + mu))
    # README: nu = 0.46870 from every start, RMS 0.806 mm (sqrt(2 J / 24)), start RMS 1.937 mm.
    assert nu == pytest.approx(0.4687, abs=5e-4)
    assert 1e3 * math.sqrt(2 * s["final_J"] / 24) == pytest.approx(0.806, abs=0.005)
    assert 1e3 * math.sqrt(2 * s["initial_J"] / 24) > 1.9
    # The modulus is not determined: it ends far from the fit that started at (10, 10) (E = 1.67e4 Pa).
    E = mu * (3 * lam + 2 * mu) / (lam + mu)
    assert E > 3e4

    # The Fisher matrix at this fit (fisher.py): one eigenvalue at round-off, along E at fixed nu.
    r = subprocess.run([sys.executable, str(STUDY / "fisher.py"), "--run", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=600, env=os.environ)
    assert r.returncode == 0, r.stderr
    lines = [line for line in r.stdout.splitlines() if "eigenvalue" in line]
    assert len(lines) == 2, r.stdout
    assert "eigenvector (-0.707107, 0.707107): identifiable" in lines[0]
    assert "eigenvector (0.707107, 0.707107): NOT identifiable from this data" in lines[1]
    ratio = float(re.search(r"ratio to the largest (\S+)\)", lines[1]).group(1))
    assert abs(ratio) < 1e-10
    se = float(re.search(r"nu = \S+, standard error (\S+)", r.stdout).group(1))
    assert 0.001 < se < 0.05  # README: 0.0128


def eigen_ratio(text):
    """The smaller eigenvalue's ratio to the larger, from a report's two eigenvalue lines."""
    lines = [line for line in text.splitlines() if "eigenvalue" in line]
    assert len(lines) == 2 and all(": identifiable" in line for line in lines), text
    return float(re.search(r"ratio to the largest (\S+)\)", lines[1]).group(1))


def test_study_407_a_load_cell_makes_E_identifiable(tmp_path):
    """force.py's problem (markers and the top plate's force) at its truth: both directions of the
    Fisher matrix identifiable, far above round-off (README: ratio 7.6e-4)."""
    sys.path.insert(0, str(STUDY))
    try:
        import force
        from confidence import e_nu_to_design
        from run_study import absolute
    finally:
        sys.path.remove(str(STUDY))
    from diffipc.identifiability import fisher_matrix, identifiability
    base = absolute(json.loads((STUDY / "problem.json").read_text()))
    truth = e_nu_to_design(force.E_ASSUMED, force.NU_FIT)
    reading = force.top_force(base, truth)
    assert reading == pytest.approx(-7.544, abs=2e-3)  # README: -7.54427 N before the noise
    labels = []
    R, F, J = fisher_matrix(force.force_problem(base, reading), truth, labels=labels)
    assert R.shape == (73, 2) and labels[-1] == "reaction force of dirichlet[0] along z at step 4"
    (l1, _, ok1), (l2, _, ok2) = identifiability(F)
    assert ok1 and ok2 and l2 / l1 > 1e-4


def test_study_407_a_drop_test_makes_E_identifiable(tmp_path):
    """drop.py --no-fit: the synthetic transient markers (72 rows with a time column) and the
    Fisher matrix at the truth with both directions identifiable (README: ratio 3.4e-4)."""
    r = subprocess.run([sys.executable, str(STUDY / "drop.py"), "--no-fit", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600, env=os.environ)
    assert r.returncode == 0, r.stderr
    rows = [line.split() for line in (tmp_path / "drop_markers.txt").read_text().splitlines()
            if not line.startswith("#")]
    assert len(rows) == 72 and all(len(row) == 7 for row in rows)
    assert sorted({float(row[3]) for row in rows}) == pytest.approx([0.01, 0.02, 0.028])
    assert "216 weighted residuals" in r.stdout
    assert eigen_ratio(r.stdout) > 1e-4
