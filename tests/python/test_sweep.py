"""diffipc sweep (cli/sweep.cpp, docs/sweep.md): a problem or scene at every point of a grid or list, one folder
per run and one table. The values in the table are checked against the same documents evaluated here through
the Python module; a stopped sweep goes on where it stopped; a bad path stops it before any run. The sweep over
MPI ranks is in test_mpi_runs.py."""
import copy
import csv
import json
import os
import subprocess

import diffipc
import numpy as np
import pytest

from conftest import ROOT, box_scene

RING = ROOT / "studies" / "304_ring_wall_velocity" / "problem.json"


def sweep(cli, path, *args):
    return subprocess.run([cli, "sweep", str(path), *args], capture_output=True, text=True, timeout=600)


def table(directory):
    with open(directory / "sweep.csv") as f:
        return list(csv.DictReader(f))


def ring_with(E, steps):
    problem = json.loads(RING.read_text())
    problem["scene"]["bodies"][0]["material"]["E"] = E
    problem["scene"]["time"]["steps"] = steps
    problem["objective"]["steps"] = [steps]
    return problem


def test_a_grid_of_evaluations_is_the_problems_evaluated_one_by_one(cli, tmp_path):
    # objective.steps must follow time.steps: points, not a grid.
    spec = {"problem": str(RING), "run": "evaluate",
            "points": [{"scene.bodies[0].material.E": E, "scene.time.steps": n, "objective.steps": [n]}
                       for E in (8e4, 1.2e5) for n in (8, 12)]}
    path = tmp_path / "sweep.json"
    path.write_text(json.dumps(spec))
    out = tmp_path / "out"
    result = sweep(cli, path, "-o", str(out))
    assert result.returncode == 0, result.stdout + result.stderr
    rows = table(out)
    assert [int(r["run"]) for r in rows] == [0, 1, 2, 3]
    assert all(r["status"] == "ok" and r["exit_code"] == "0" and r["rank"] == "0" for r in rows)
    values = []
    for row, (E, n) in zip(rows, [(E, n) for E in (8e4, 1.2e5) for n in (8, 12)]):
        assert float(row["scene.bodies[0].material.E"]) == E and int(row["scene.time.steps"]) == n
        J = diffipc.ReducedFunctional(ring_with(E, n), base_directory=RING.parent)
        e = J.evaluation(J.parameters_of(J.design_initial), gradient=True)
        assert float(row["J"]) == pytest.approx(e.value, rel=1e-12)
        assert float(row["gradient_norm"]) == pytest.approx(np.linalg.norm(e.gradient), rel=1e-12)
        stored = json.loads((out / f"run_{row['run']}" / "evaluation.json").read_text())
        assert stored["J"] == float(row["J"])
        values.append(e.value)
    assert len(set(values)) == 4  # the points differ


def test_optimize_and_simulate_runs_and_their_folders(cli, tmp_path):
    spec = {"problem": str(RING), "points": [{"optimizer": {"algorithm": "lbfgsb", "max_iterations": 2}},
                                             {"optimizer": {"algorithm": "lbfgsb", "max_iterations": 3}}]}
    path = tmp_path / "opt.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "opt"), "-q")
    assert result.returncode == 0, result.stderr
    rows = table(tmp_path / "opt")
    for row, budget in zip(rows, (2, 3)):
        summary = json.loads((tmp_path / "opt" / f"run_{row['run']}" / "summary.json").read_text())
        assert int(row["iterations"]) == summary["iterations"] == budget
        assert float(row["final_J"]) == summary["final_J"] < float(row["initial_J"])
    scene = box_scene(steps=4)
    spec = {"scene": scene, "grid": {"time.dt": [0.01, 0.02]}, "repeat": 2}
    path = tmp_path / "sim.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "sim"), "-q")
    assert result.returncode == 0, result.stderr
    rows = table(tmp_path / "sim")
    assert [(r["point"], r["repetition"], r["time.dt"]) for r in rows] == \
        [("0", "0", "0.01"), ("0", "1", "0.01"), ("1", "0", "0.02"), ("1", "1", "0.02")]
    assert all(r["status_of_run"] == "CONVERGED" and r["steps_committed"] == "4" for r in rows)
    run_scene = json.loads((tmp_path / "sim" / "run_2" / "scene.json").read_text())
    assert run_scene["time"]["dt"] == 0.02


def test_a_failing_run_is_a_row_and_the_sweep_goes_on(cli, tmp_path):
    spec = {"problem": str(RING), "run": "evaluate",
            "points": [{"scene.solver.max_iterations": 1}, {"scene.solver.max_iterations": 100}]}
    path = tmp_path / "fail.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "fail"), "-q")
    assert result.returncode == 2
    rows = table(tmp_path / "fail")
    assert rows[0]["status"] == "failed" and "NEWTON_EXHAUSTED" in rows[0]["message"]
    assert rows[1]["status"] == "ok" and float(rows[1]["J"]) > 0


def test_a_stopped_sweep_goes_on_where_it_stopped(cli, tmp_path):
    spec = {"problem": str(RING), "run": "evaluate", "grid": {"scene.bodies[0].material.E": [8e4, 1e5, 1.2e5]}}
    path = tmp_path / "s.json"
    path.write_text(json.dumps(spec))
    out = tmp_path / "out"
    assert sweep(cli, path, "-o", str(out), "-q").returncode == 0
    first = table(out)
    # As if killed during run 1: its row never written; the others are kept, not run again.
    os.remove(out / "run_1" / "row.json")
    (out / "run_1" / "evaluation.json").unlink()
    stamp = {k: os.stat(out / f"run_{k}" / "row.json").st_mtime_ns for k in (0, 2)}
    assert sweep(cli, path, "-o", str(out), "-q").returncode == 0
    assert {k: os.stat(out / f"run_{k}" / "row.json").st_mtime_ns for k in (0, 2)} == stamp
    assert (out / "run_1" / "evaluation.json").exists()
    again = table(out)
    assert [r["J"] for r in again] == [r["J"] for r in first]
    # A changed sweep (another value at run 2) runs run 2 again.
    spec["grid"]["scene.bodies[0].material.E"][2] = 1.3e5
    path.write_text(json.dumps(spec))
    assert sweep(cli, path, "-o", str(out), "-q").returncode == 0
    assert table(out)[2]["J"] != first[2]["J"]
    assert os.stat(out / "run_0" / "row.json").st_mtime_ns == stamp[0]


@pytest.mark.parametrize("change, field", [
    (lambda s: s.update(points=[{"scene.bodies[3].material.E": 1}]), "points[0].scene.bodies[3].material.E"),
    (lambda s: s.update(points=[{"scene.time.dtt": 0.1}]), "points[0]"),
    (lambda s: s.update(points=[{"scene.time.dt[0]": 0.1}]), "points[0].scene.time.dt[0]"),
    (lambda s: s.update(grid={"scene.time.dt": []}), "grid.scene.time.dt"),
    (lambda s: s.update(run="simulate"), "run"),
    (lambda s: s.update(repeat=0), "repeat"),
    (lambda s: s.update(scene={}), ""),
    (lambda s: s.update(colour=1), "colour"),
])
def test_a_bad_sweep_file_stops_before_any_run(cli, tmp_path, change, field):
    spec = {"problem": str(RING), "run": "evaluate", "points": [{"scene.time.dt": 0.004}]}
    change(spec)
    if "grid" in spec:
        del spec["points"]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "out"))
    assert result.returncode == 1, result.stdout + result.stderr
    assert result.stderr.startswith("diffipc: error: " + field), result.stderr
    assert not (tmp_path / "out").exists()  # nothing ran


def test_a_missing_sweep_file_is_named(cli, tmp_path):
    result = sweep(cli, tmp_path / "none.json")
    assert result.returncode == 1 and "none.json" in result.stderr


def test_the_empty_path_makes_each_point_a_document_of_its_own(cli, tmp_path):
    """{"": scene}: the point is that scene (study 502 runs its cases so); no column for it in the table."""
    scenes = [box_scene(steps=2), box_scene(dim=3, steps=3)]
    spec = {"scene": scenes[0], "points": [{"": s} for s in scenes]}
    path = tmp_path / "docs.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "out"), "-q")
    assert result.returncode == 0, result.stderr
    rows = table(tmp_path / "out")
    assert [r["steps_committed"] for r in rows] == ["2", "3"] and "" not in rows[0]
    assert json.loads((tmp_path / "out" / rows[1]["folder"] / "scene.json").read_text())["dimension"] == 3
    bad = {"scene": scenes[0], "points": [{"": 3}]}
    path.write_text(json.dumps(bad))
    result = sweep(cli, path, "-o", str(tmp_path / "bad"))
    assert result.returncode == 1 and "points[0]." in result.stderr and "whole document" in result.stderr


def test_relative_paths_in_points_are_relative_to_the_sweep_file(cli, tmp_path):
    """A point that names a scene file by a relative path: checked against the sweep file's folder before the
    runs, and found by the run in its own folder."""
    (tmp_path / "scenes").mkdir()
    ring = json.loads(RING.read_text())
    faster = copy.deepcopy(ring["scene"])
    faster["bodies"][0]["initial_velocity"] = [3.5, 0.5]
    (tmp_path / "scenes" / "faster.json").write_text(json.dumps(faster))
    spec = {"problem": str(RING), "run": "evaluate", "points": [{"scene": "scenes/faster.json"}]}
    path = tmp_path / "rel.json"
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "out"), "-q")
    assert result.returncode == 0, result.stdout + result.stderr
    row = table(tmp_path / "out")[0]
    assert row["status"] == "ok", row
    J = diffipc.ReducedFunctional(dict(ring, scene="scenes/faster.json"), base_directory=tmp_path)
    assert float(row["J"]) == pytest.approx(J(J.parameters_of(J.design_initial)), rel=1e-12)
    # A file that is not there is named with the sweep file's folder before any run.
    spec["points"] = [{"scene": "scenes/none.json"}]
    path.write_text(json.dumps(spec))
    result = sweep(cli, path, "-o", str(tmp_path / "bad"), "-q")
    assert result.returncode == 1 and str(tmp_path / "scenes" / "none.json") in result.stderr, result.stderr
    assert not (tmp_path / "bad").exists()
