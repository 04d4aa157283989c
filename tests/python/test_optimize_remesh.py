"""Remeshing inside `diffipc optimize` (docs/remeshing.md): a 2D cantilever whose free-form
deformation stretches the mesh until it is remeshed; the run keeps its design variables and
iteration count, J and the area change across the remesh by a discretization amount only, every
written design is valid (areas and boundary crossings checked here, not by the code under test),
and the run converges afterwards. Also: a remesher that cannot run leaves the run going, a resume
after a remesh reads the problem on the new mesh, and problems that cannot be remeshed are refused."""
import csv
import json
import os
import subprocess

import numpy as np
import pytest

import diffipc
from design_checks import boundary_edges, crossing, triangle_areas


def run(cli, *args, env=None, timeout=600):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **(env or {})})


def beam(cells=(50, 10), quality=0.7, size=0.02, iterations=40, algorithm="ipopt"):
    lower = [-0.3] * 4 + [-0.05] * 4
    upper = [0.05] * 4 + [0.3] * 4
    return {
        "scene": {
            "dimension": 2,
            "bodies": [{"name": "beam", "mesh": {"box": {"min": [0, 0], "max": [1.0, 0.2], "cells": list(cells)}},
                        "material": {"model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": 1000}}],
            "dirichlet": [{"body": "beam", "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [0, 0]}],
            "neumann": [{"body": "beam", "region": {"min": [0.999, -1], "max": [2, 2]}, "traction": [0, "-4e4*t"]}],
            "time": {"integrator": "static", "dt": 0.5, "steps": 2},
            "solver": {"residual_tolerance": 1e-10},
        },
        "objective": {"type": "compliance", "time": "final"},
        # Bottom (first four) and top (last four) control heights of a lattice over the beam's
        # root part; the root moves, the tip stays.
        "parameters": [{"type": "shape", "lower": lower, "upper": upper, "maps": [
            {"type": "ffd", "box": {"min": [-0.5, -0.01], "max": [0.9, 0.21]}, "degree": [5, 1], "axes": [1],
             "fixed_border": [0]}]}],
        "constraints": [{"name": "area", "objective": {"type": "volume", "configuration": "rest"}, "upper": 0.22}],
        "remesh": {"quality": quality, "size": size},
        "optimizer": {"algorithm": algorithm, "max_iterations": iterations},
        "output": {"design_every": 1},
    }


def penalty(p):
    """The area limit as a quadratic penalty (for L-BFGS-B, which takes bounds only)."""
    limit = p.pop("constraints")[0]
    p["objective"] = {"type": "sum", "terms": [
        {"objective": p["objective"]},
        {"weight": 1e8, "objective": {"type": "constraint", "upper": limit["upper"], "objective": limit["objective"]}}]}
    return p


def check_design(path):
    meshio = pytest.importorskip("meshio")
    m = meshio.read(path)
    cells = m.cells_dict["triangle"]
    assert triangle_areas(m.points, cells).min() > 0, path
    assert not crossing(m.points[:, :2], boundary_edges(cells)), path
    return m


@pytest.mark.parametrize("algorithm", ["ipopt", "lbfgsb"])
def test_a_run_remeshes_and_goes_on_converging(cli, tmp_path, algorithm):
    problem = tmp_path / "beam.json"
    # L-BFGS-B on the penalty needs more iterations (measured: 76 against Ipopt's 12).
    p = beam(algorithm=algorithm, iterations=40 if algorithm == "ipopt" else 150)
    if algorithm == "lbfgsb":
        p = penalty(p)
    problem.write_text(json.dumps(p))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    remeshes = summary["remeshes"]
    assert len(remeshes) >= 1, r.stdout
    assert "remeshed after iteration" in r.stdout
    rows = list(csv.DictReader((out / "history.csv").open()))
    # One row per iteration, numbered without a gap or a restart across the remesh.
    assert [int(row["iteration"]) for row in rows] == list(range(summary["iterations"] + 1))
    for rm in remeshes:
        assert rm["quality_after"] > rm["quality_before"]
        assert rm["elements_after"] != rm["elements_before"]
        # The same domain at the remesh's design: the polygon's area exactly, the compliance
        # within the discretization tolerance (P1, h = 0.02 structured against gmsh's).
        if algorithm == "ipopt":
            assert rm["constraints_after"][0] == pytest.approx(rm["constraints_before"][0], rel=1e-10)
        assert rm["J_after"] == pytest.approx(rm["J_before"], rel=0.01)
        for f in rm["files"]:
            assert os.path.exists(f)
        # The history's row at the remesh iteration holds J on the old mesh.
        assert float(rows[rm["iteration"]]["J"]) == pytest.approx(rm["J_before"], rel=1e-12)
    # It converges after the remesh: a tolerance stop, J below its value at the last remesh.
    assert summary["stop_reason"] in ("gradient_tolerance", "f_tolerance", "x_tolerance"), summary
    assert summary["final_J"] < remeshes[-1]["J_after"]
    assert summary["final_J"] < 0.8 * summary["initial_J"]
    assert summary["max_violation"] <= 1e-6
    # Every written design is valid, and the designs after the remesh are on the new mesh.
    sizes = set()
    for row in rows:
        m = check_design(out / f"design_{row['iteration']}.vtu")
        sizes.add(len(m.cells_dict["triangle"]))
    assert len(sizes) == len(remeshes) + 1
    m = check_design(out / "design_final.vtu")
    area = triangle_areas(m.points, m.cells_dict["triangle"]).sum()
    assert area <= 0.22 * (1 + (1e-6 if algorithm == "ipopt" else 1e-3))  # the penalty's 1e8 allows a little more
    # The optimal problem (on the new mesh) evaluates to the final J with the final design.
    rf = diffipc.ReducedFunctional(str(out / "optimal_problem.json"))
    x = np.array(summary["design"])
    assert rf(rf.parameters_of(x)) == pytest.approx(summary["final_J"], rel=1e-10)
    assert (out / "current_problem.json").exists()


def test_a_remesher_that_cannot_run_leaves_the_run_going(cli, tmp_path):
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam(iterations=12)))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out, env={"DIFFIPC_GMSH_REMESHER": str(tmp_path / "missing")})
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["remeshes"] == []
    assert "cannot run the remesher" in summary["remesh_failure"]
    assert summary["final_J"] < summary["initial_J"]


def test_resume_after_a_remesh_uses_the_new_mesh(cli, tmp_path):
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam(iterations=8)))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    first = json.loads((out / "summary.json").read_text())
    assert first["stop_reason"] == "iteration_budget" and len(first["remeshes"]) >= 1
    r = run(cli, "optimize", "--resume", out, "--max-iterations", 40)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["resumed_at_iteration"] == 8
    assert summary["stop_reason"] in ("gradient_tolerance", "f_tolerance", "x_tolerance"), summary
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert [int(row["iteration"]) for row in rows] == list(range(summary["iterations"] + 1))
    # The resumed part ran on the remeshed problem: its first design has the new mesh's size.
    meshio = pytest.importorskip("meshio")
    n8 = len(meshio.read(out / "design_8.vtu").cells_dict["triangle"])
    n9 = len(meshio.read(out / "design_9.vtu").cells_dict["triangle"])
    assert n9 == n8
    assert n8 != 1000  # not the initial 50 x 10 box


def test_problems_that_cannot_be_remeshed_are_refused(cli, tmp_path):
    p = beam()
    p["parameters"][0] = {"type": "shape", "maps": [{"type": "boundary_extension", "vertices": {"region": {
        "min": [0.01, 0.199], "max": [2, 1]}}, "axes": [1]}]}
    problem = tmp_path / "bad.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "out")
    assert r.returncode == 1
    assert "remesh" in r.stderr and "ffd" in r.stderr
    p = beam()
    p["remesh"]["quality"] = 0
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "out")
    assert r.returncode == 1 and "remesh.quality" in r.stderr


def test_resume_at_the_remesh_iteration_and_a_remesh_after_the_resume(cli, tmp_path):
    # The Ipopt run remeshes after iteration 5 (test above). Stopped there, the state saved is
    # the one on the new mesh; resumed, it goes on as the uninterrupted run does.
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam(iterations=40)))
    full = tmp_path / "full"
    r = run(cli, "optimize", problem, "-o", full)
    assert r.returncode == 0, r.stderr
    uninterrupted = json.loads((full / "summary.json").read_text())
    k = uninterrupted["remeshes"][0]["iteration"]
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out, "--max-iterations", k)
    assert r.returncode == 0, r.stderr
    assert len(json.loads((out / "summary.json").read_text())["remeshes"]) == 1
    mesh_file = out / "remesh_1_body0.msh"
    before = mesh_file.read_bytes()
    # Resuming with a problem file that is not the remeshed one is refused.
    r = run(cli, "optimize", problem, "--resume", out, "--max-iterations", 40)
    assert r.returncode == 1 and "current_problem.json" in r.stderr
    r = run(cli, "optimize", "--resume", out, "--max-iterations", 40)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["stop_reason"] == uninterrupted["stop_reason"] == "gradient_tolerance"
    assert s["final_J"] == pytest.approx(uninterrupted["final_J"], rel=1e-6)
    # The first run's remesh is still the run's, and its mesh file is untouched.
    assert s["remeshes"][0]["files"] == [str(mesh_file)]
    assert mesh_file.read_bytes() == before


def test_a_second_remesh_in_a_resumed_run_gets_new_files(cli, tmp_path):
    p = beam(iterations=40, quality=0.7)
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out, "--max-iterations", 7)
    assert r.returncode == 0, r.stderr
    first = json.loads((out / "summary.json").read_text())["remeshes"]
    assert len(first) == 1
    # Resume with a remesh forced at once: the threshold and the saved trigger above any quality.
    current = json.loads((out / "current_problem.json").read_text())
    current["remesh"]["quality"] = 0.99
    (out / "current_problem.json").write_text(json.dumps(current))
    state = json.loads((out / "remeshes.json").read_text())
    assert state["attempts"] == 1 and len(state["records"]) == 1
    state["trigger"] = 0.99
    (out / "remeshes.json").write_text(json.dumps(state))
    r = run(cli, "optimize", "--resume", out, "--max-iterations", 9)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert [rm["files"][0].split("/")[-1] for rm in s["remeshes"][:2]] == ["remesh_1_body0.msh", "remesh_2_body0.msh"]


def fake_remesher(tmp_path, text):
    script = tmp_path / "fake_remesher.sh"
    script.write_text("#!/bin/sh\nprintf '%s\\n' > \"$2\"\n" % text)
    script.chmod(0o755)
    return str(script)


@pytest.mark.parametrize("output", ["ok -1 2", "ok 18446744073709551615 3", "ok 3 1\n0 0\n1 0", "garbage"])
def test_garbage_from_the_remesher_is_a_failed_remesh(cli, tmp_path, output):
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam(iterations=12)))
    out = tmp_path / "out"
    temporary = tmp_path / "tmp"  # the run's own temporary folder: other processes' files do not land there
    temporary.mkdir()
    r = run(cli, "optimize", problem, "-o", out,
            env={"DIFFIPC_GMSH_REMESHER": fake_remesher(tmp_path, output), "TMPDIR": str(temporary)})
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["remeshes"] == [] and s["remesh_failure"], s
    assert not [f for f in os.listdir(temporary) if f.startswith("diffipc_remesh_")]


def test_a_failing_remesh_is_not_retried_at_every_iteration(cli, tmp_path):
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(beam(iterations=30)))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out, env={"DIFFIPC_GMSH_REMESHER": str(tmp_path / "missing")})
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    state = json.loads((out / "remeshes.json").read_text())
    # Each failure lowers the trigger to 0.9 of the quality it saw: far fewer attempts than iterations.
    assert 1 <= state["attempts"] <= 3 < s["iterations"], (state, s["iterations"])
    assert s["wall_time"]["remeshing"] == pytest.approx(state["failed_seconds"])


def test_a_design_that_moves_the_body_across_a_region_is_not_remeshed(cli, tmp_path):
    # The lattice moves the root (clamped by the region x <= 1e-6) along x: the new mesh at the
    # design would select other vertices than the start's rest shape does.
    p = beam(iterations=6, quality=0.99)
    p["parameters"][0] = {"type": "shape", "initial": [0.02] * 8, "lower": -0.05, "upper": 0.05, "maps": [
        {"type": "ffd", "box": {"min": [-0.5, -0.01], "max": [0.9, 0.21]}, "degree": [5, 1], "axes": [0],
         "fixed_border": [0]}]}
    problem = tmp_path / "beam.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "out"
    r = run(cli, "optimize", problem, "-o", out)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["remeshes"] == []
    assert "region of dirichlet[0]" in s["remesh_failure"], s["remesh_failure"]


def test_per_element_parameters_cannot_be_remeshed(cli, tmp_path):
    p = beam()
    p["parameters"].append({"type": "E", "per": "element", "maps": [{"type": "exp"}]})
    problem = tmp_path / "bad.json"
    problem.write_text(json.dumps(p))
    r = run(cli, "optimize", problem, "-o", tmp_path / "out")
    assert r.returncode == 1 and "remesh" in r.stderr and "per element" in r.stderr.replace("one per element", "per element")
    p["parameters"][1] = {"type": "E", "per": "body", "maps": [{"type": "exp"}]}
    problem.write_text(json.dumps(p))
    r = run(cli, "validate", problem)
    assert "remesh" not in r.stderr
