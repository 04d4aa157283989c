"""scripts/compare_trajectories.py on real runs: the same run against itself is 0 apart, a run with
another material is not, a different scene is refused, runs of different lengths are compared over
their common steps with exit status 2, and contact runs report the barrier stiffness."""
import json
import pathlib
import subprocess
import sys

import pytest

from conftest import box_scene

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "compare_trajectories.py"


def simulate(cli, tmp_path, name, scene):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / name
    r = subprocess.run([cli, "simulate", path, "-o", out, "-q"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return out / "trajectory.h5"


def compare(a, b):
    return subprocess.run([sys.executable, SCRIPT, a, b, "--quiet"], capture_output=True, text=True, timeout=60)


def test_compare_trajectories(cli, tmp_path):
    pytest.importorskip("h5py")
    s = box_scene(dim=2, steps=3)
    s["gravity"] = [0, -9.81]  # a cantilever: clamped at x = 0, bending under its weight
    s["dirichlet"] = [{"body": "b", "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [0, 0]}]
    a = simulate(cli, tmp_path, "a", s)
    again = simulate(cli, tmp_path, "again", s)
    s["bodies"][0]["material"]["E"] *= 2
    stiffer = simulate(cli, tmp_path, "stiffer", s)

    same = compare(a, again)
    assert same.returncode == 0, same.stderr
    assert "3 steps: states within 0.0e+00 of the size" in same.stdout, same.stdout
    differ = compare(a, stiffer)
    assert differ.returncode == 0, differ.stderr
    worst = float(differ.stdout.split("states within ")[1].split(" ")[0])
    assert worst > 1e-6, differ.stdout

    t = box_scene(dim=2, steps=3)
    t["bodies"][0]["mesh"]["box"]["cells"] = [3, 3]
    other = simulate(cli, tmp_path, "other", t)
    refused = compare(a, other)
    assert refused.returncode == 2 and "not the same scene" in refused.stderr, refused.stderr

    s["time"]["steps"] = 2
    shorter = simulate(cli, tmp_path, "shorter", s)
    partial = compare(stiffer, shorter)
    assert partial.returncode == 2, partial.stderr
    assert "comparing the first 2" in partial.stderr and "2 steps: states within" in partial.stdout, partial

    # A box resting on a plane 1 mm below it (dhat 1 cm): contact from the start.
    c = box_scene(dim=2, steps=2)
    c["gravity"] = [0, -9.81]
    c["obstacles"] = [{"plane": {"point": [0, -0.001], "normal": [0, 1]}}]
    c["contact"] = {"dhat": 0.01, "kappa": 1e5}
    first = simulate(cli, tmp_path, "contact_a", c)
    second = simulate(cli, tmp_path, "contact_b", c)
    contact = compare(first, second)
    assert contact.returncode == 0, contact.stderr
    assert "kappa differs in 0 steps" in contact.stdout, contact.stdout
