"""Study 503 (studies/503_stability_atlas): every cell of the stability atlas runs through the CLI
with IPC and with the penalty baseline (without the fix verification runs, about 12 s). IPC must
have no intersecting, inverted or passed-through state and no vertex behind a plane in any
committed step of any cell, checked by `diffipc check` and by the study's own position checks;
a cell that stops says why with its status and writes no NaN. The penalty baseline's invalid
cells show that the checks can fail."""
import math
import os

import h5py
import numpy as np
import pytest

from conftest import ROOT, load_script

STUDY = ROOT / "studies" / "503_stability_atlas"


study = load_script(STUDY / "run.py")


@pytest.fixture(scope="module")
def atlas(tmp_path_factory):
    cli = os.environ.get("DIFFIPC_CLI", str(ROOT / "build" / "cli" / "diffipc"))
    return study.main(["--cli", cli, "-o", str(tmp_path_factory.mktemp("s503"))])


def test_every_committed_ipc_state_is_valid(atlas):
    ipc = [r for r in atlas if r["model"] == "IPC"]
    assert len(ipc) == sum(len(f[2]) for f in study.FAMILIES)
    for r in ipc:
        where = (r["family"], r["value"], r["status"], r["failure"])
        assert r["steps"] > 0, where
        assert r["intersecting_states"] == 0 and r["inverted_states"] == 0 and r["passed_through"] == 0, where
        assert math.isnan(r["plane_gap"]) or r["plane_gap"] > 0, where
        assert r["min_volume_ratio"] > 0, where


def test_cells_that_stop_say_why_and_write_no_nan(atlas):
    for r in atlas:
        assert r["exit"] in (0, 2), r
        if r["status"] != "CONVERGED":
            assert r["exit"] == 2 and r["failure"].startswith(f"step {r['steps'] + 1} "), r
            assert r["status"] in r["failure"], r
        with h5py.File(ROOT / r["folder"] / "trajectory.h5", "r") as f:
            assert np.isfinite(f["positions"][:]).all() and np.isfinite(f["velocities"][:]).all(), r["folder"]
            assert len(f["time"]) == r["steps"] + 1


def test_the_checks_catch_the_penalty_baselines_failures(atlas):
    pen = [r for r in atlas if r["model"].startswith("penalty")]
    invalid = [r for r in pen if study.verdict(r) == "invalid"]
    # Intersections found by `diffipc check`, bodies passed through a plate, vertices behind a plane.
    assert any(r["intersecting_states"] > 0 for r in invalid)
    assert any(r["passed_through"] > 0 for r in invalid)
    assert any(r["plane_gap"] < 0 for r in invalid)
    for r in invalid:
        why, remedy, fixes = study.note_for(r)
        assert why and remedy and fixes
