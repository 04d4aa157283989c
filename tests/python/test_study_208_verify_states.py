"""studies/208_lattice_block/verify_states.py on a real static run: every committed state of a CPU run is
an equilibrium by the CPU's residual (0 Newton iterations from it), a state moved off its equilibrium is
reported and makes the exit status 1, and a dynamic scene is refused."""
import json
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT, box_scene

SCRIPT = ROOT / "studies" / "208_lattice_block" / "verify_states.py"


def verify(scene, trajectory):
    return subprocess.run([sys.executable, SCRIPT, scene, trajectory], capture_output=True, text=True, timeout=300)


def test_verify_states(cli, tmp_path):
    h5py = pytest.importorskip("h5py")
    s = box_scene(dim=2, steps=3, integrator="static", dt=0.1)
    # Clamped at x = 0, its free end pulled down by a traction that grows with t.
    s["dirichlet"] = [{"body": "b", "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [0, 0]}]
    s["neumann"] = [{"body": "b", "region": {"min": [0.5 - 1e-6, -1], "max": [1, 1]}, "traction": [0, "-2000*t"]}]
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(s))
    out = tmp_path / "run"
    r = subprocess.run([cli, "simulate", scene, "-o", out, "-q"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    trajectory = out / "trajectory.h5"

    ok = verify(scene, trajectory)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "3 of 3 states are equilibria" in ok.stdout, ok.stdout
    assert ok.stdout.count("0 Newton iterations") == 3, ok.stdout

    # Step 2's free vertices moved by 1 mm: not an equilibrium at t_2 (the CPU needs iterations from it).
    moved = tmp_path / "moved.h5"
    shutil.copy(trajectory, moved)
    with h5py.File(moved, "r+") as f:
        x = f["positions"][2]
        rest = f["positions"][0]
        x[rest[:, 0] > 1e-6, 1] += 1e-3
        f["positions"][2] = x
    off = verify(scene, moved)
    assert off.returncode == 1, off.stdout + off.stderr
    assert "2 of 3 states are equilibria" in off.stdout, off.stdout
    line = [l for l in off.stdout.splitlines() if l.startswith("step   2")][0]
    assert "not within the tolerance" in line, off.stdout

    dynamic = dict(s, time={"integrator": "implicit_euler", "dt": 0.1, "steps": 3})
    scene_dynamic = tmp_path / "dynamic.json"
    scene_dynamic.write_text(json.dumps(dynamic))
    refused = verify(scene_dynamic, trajectory)
    assert refused.returncode != 0 and "static" in refused.stderr, refused.stderr
