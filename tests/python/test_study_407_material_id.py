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
