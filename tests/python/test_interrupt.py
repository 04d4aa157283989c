"""Interrupted runs keep their committed steps (docs/output_format.md, "Interrupted runs").

A long simulation is started, followed live through trajectory.h5 (h5py in SWMR mode,
as a user watching a run would), then stopped by SIGINT, SIGTERM or SIGKILL. What was
committed and flushed must be readable afterwards, consistent between trajectory.h5 and
summary.json, finite, and in order.
"""
import json
import signal
import subprocess
import time

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")


def long_scene(tmp_path):
    scene = {
        "dimension": 2,
        "bodies": [{"name": "b", "mesh": {"box": {"min": [0, 0], "max": [0.5, 0.2], "cells": [20, 8]}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000.0}}],
        "gravity": [0, -9.81],
        "time": {"integrator": "implicit_euler", "dt": 1e-3, "steps": 1000000},
        "solver": {"residual_tolerance": 1e-10},
    }
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    return path


def start_and_watch(cli, tmp_path, min_steps):
    """Starts the run and waits until trajectory.h5 shows at least `min_steps` flushed steps."""
    out = tmp_path / "out"
    proc = subprocess.Popen([cli, "simulate", str(long_scene(tmp_path)), "-o", str(out), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    seen = 0
    while time.time() < deadline and proc.poll() is None:
        try:
            with h5py.File(out / "trajectory.h5", "r", swmr=True) as f:
                seen = f["status"].shape[0]
                # A live file: the datasets are written one after the other, so a reader may find
                # the state datasets (written first) up to a batch ahead, never behind.
                assert f["time"].shape[0] >= seen + 1
        except (OSError, KeyError, RuntimeError, ValueError):
            seen = 0
        if seen >= min_steps:
            return proc, out, seen
        time.sleep(0.1)
    proc.kill()
    pytest.fail(f"the run did not show {min_steps} steps in time (saw {seen}, exit {proc.poll()})")


def check_trajectory(path, at_least, swmr=False):
    """swmr: the writer was killed; it may have stopped between the datasets of a batch, so
    the steps are those every dataset has (as `simulate --restart` reads them)."""
    with h5py.File(path, "r", swmr=swmr) as f:
        step_sets = ("status", "newton_iterations", "residual", "min_volume_ratio", "wall_time")
        state_sets = ("time", "positions", "velocities")
        T = min(f[n].shape[0] for n in step_sets)
        assert T >= at_least
        N = f["mesh/rest_positions"].shape[0]
        for name in step_sets:
            assert f[name].shape[0] >= T if swmr else f[name].shape == (T,)
        for name in state_sets:
            assert f[name].shape[0] >= T + 1 if swmr else f[name].shape[0] == T + 1
        assert f["positions"].shape[1:] == (N, 2)
        assert (f["status"][:T] == 0).all()
        t = f["time"][:T + 1]
        np.testing.assert_allclose(np.diff(t), 1e-3, rtol=1e-9)
        x = f["positions"][:T + 1]
        assert np.isfinite(x).all() and np.isfinite(f["velocities"][:T + 1]).all()
        np.testing.assert_array_equal(x[0], f["mesh/rest_positions"][:])
        # The body falls under gravity: every committed state is a real step, not a copy.
        assert (np.diff(x[:, :, 1].mean(axis=1)) < 0).all()
        assert f.attrs["diffipc_version"]
        return T


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_stops_after_the_step_and_writes_everything(cli, tmp_path, sig, code):
    proc, out, seen = start_and_watch(cli, tmp_path, 20)
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == code, stderr
    assert "interrupted by" in stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "INTERRUPTED"
    T = check_trajectory(out / "trajectory.h5", seen)
    assert summary["steps_committed"] == T
    assert not (out / "summary.json.tmp").exists()


def test_sigkill_keeps_every_flushed_step(cli, tmp_path):
    proc, out, seen = start_and_watch(cli, tmp_path, 20)
    # Each second the writer flushes trajectory.h5 and then replaces summary.json: a kill between
    # the two (seen on a loaded machine) leaves the summary of the flush before. Wait for a
    # summary that counts steps, so that the check below is about what a kill keeps.
    deadline = time.time() + 60
    while time.time() < deadline and json.loads((out / "summary.json").read_text())["steps_committed"] == 0:
        time.sleep(0.05)
    proc.kill()
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    # Everything that a reader saw before the kill is still there. The writer could not
    # close the file, so HDF5 still marks it open for writing: it opens in SWMR mode.
    check_trajectory(out / "trajectory.h5", seen, swmr=True)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "RUNNING"
    assert 0 < summary["steps_committed"] <= 1000000


def restart_scene(tmp_path, integrator, steps=600):
    scene = {
        "dimension": 2,
        "bodies": [{"name": "b", "mesh": {"box": {"min": [0, 0], "max": [0.5, 0.2], "cells": [40, 16]}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000.0},
                    "initial_velocity": [0.3, 0.1]}],
        "gravity": [0, -9.81],
        "time": {"integrator": integrator, "dt": 1e-3, "steps": steps},
        "solver": {"residual_tolerance": 1e-10},
        "output": {"flush_interval": 0.01},
    }
    path = tmp_path / f"{integrator}.json"
    path.write_text(json.dumps(scene))
    return path


@pytest.mark.parametrize("integrator", ["implicit_euler", "bdf2", "newmark"])
def test_restart_after_sigkill_matches_an_uninterrupted_run(cli, tmp_path, integrator):
    scene = restart_scene(tmp_path, integrator)
    full = tmp_path / "full"
    r = subprocess.run([cli, "simulate", str(scene), "-o", str(full), "-q"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    part = tmp_path / "part"
    proc = subprocess.Popen([cli, "simulate", str(scene), "-o", str(part), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, seen = time.time() + 60, 0
    while time.time() < deadline and proc.poll() is None and seen < 10:
        try:
            with h5py.File(part / "trajectory.h5", "r", swmr=True) as f:
                seen = f["status"].shape[0]
        except (OSError, KeyError, RuntimeError, ValueError):
            pass
        time.sleep(0.05)
    proc.kill()
    proc.communicate(timeout=60)
    with h5py.File(part / "trajectory.h5", "r", swmr=True) as f:
        killed_at = f["status"].shape[0]
    assert 0 < killed_at < 600, "the kill should land inside the run"
    r = subprocess.run([cli, "simulate", "--restart", str(part), str(scene), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with h5py.File(full / "trajectory.h5", "r") as a, h5py.File(part / "trajectory.h5", "r") as b:
        assert b["status"].shape == (600,)
        for name in ("time", "positions", "velocities", "accelerations", "newton_iterations"):
            # The same operations from the same stored bits: the same bits.
            np.testing.assert_array_equal(a[name][:], b[name][:], err_msg=name)
    summary = json.loads((part / "summary.json").read_text())
    assert summary["status"] == "CONVERGED" and summary["steps_committed"] == 600


def test_restart_refuses_another_scene(cli, tmp_path):
    a = restart_scene(tmp_path, "implicit_euler", steps=5)
    out = tmp_path / "out"
    assert subprocess.run([cli, "simulate", str(a), "-o", str(out), "-q"], timeout=120).returncode == 0
    other = json.loads(a.read_text())
    other["bodies"][0]["mesh"]["box"]["cells"] = [20, 8]
    b = tmp_path / "other.json"
    b.write_text(json.dumps(other))
    r = subprocess.run([cli, "simulate", "--restart", str(out), str(b), "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 1 and "restart:" in r.stderr.strip().splitlines()[-1]
    r = subprocess.run([cli, "simulate", "--restart", str(tmp_path / "nothing"), str(a), "-q"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and "trajectory.h5" in r.stderr
