"""scripts/compare_trajectories.py on two real runs of one scene: the same run against itself is
0 apart, a run with another material is not, and a different scene is refused."""
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
