import json
import os
import subprocess

import numpy as np
import pytest

from conftest import box_scene


def run(cli, *args, cwd=None):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_simulate_writes_hdf5_summary_and_vtu(cli, tmp_path):
    h5py = pytest.importorskip("h5py")
    s = box_scene(dim=3, steps=4)
    s["gravity"] = [0, -9.81, 0]
    s["output"] = {"vtu_every": 2}
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(s))
    out = tmp_path / "out"
    r = run(cli, "simulate", scene, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "step 4/4" in r.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "CONVERGED"
    assert summary["steps_committed"] == 4
    for phase in ("assembly", "factorization", "solve", "line_search"):
        assert summary["wall_time"][phase] >= 0
    with h5py.File(out / "trajectory.h5", "r") as f:
        N = f["mesh/rest_positions"].shape[0]
        assert f["time"].shape == (5,)
        assert f["positions"].shape == (5, N, 3)
        assert f["velocities"].shape == (5, N, 3)
        for name in ("status", "newton_iterations", "residual", "min_volume_ratio"):
            assert f[name].shape == (4,)
        assert (f["status"][:] == 0).all()
        assert f["mesh/elements"].shape[1] == 4
        assert f["mesh/body"].shape == (N,)
        np.testing.assert_allclose(f["positions"][0], f["mesh/rest_positions"][:])
    pvd = (out / "trajectory.pvd").read_text()
    assert pvd.count("<DataSet") == 3  # frames 0, 2, 4 (no obstacles: no part 1)
    assert (out / "frame_4.vtu").read_bytes().startswith(b"<?xml")


def test_validate_and_help(cli, root):
    r = run(cli, "validate", root / "studies" / "101_cantilever" / "scene.json")
    assert r.returncode == 0 and "valid 3D scene" in r.stdout
    for sub in ("simulate", "validate", "bench"):
        r = run(cli, sub, "--help")
        assert r.returncode == 0 and "Usage" in r.stdout


def _set(path, value):
    def mutate(s):
        node = s
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
    return mutate


def _drop(path):
    def mutate(s):
        node = s
        for key in path[:-1]:
            node = node[key]
        del node[path[-1]]
    return mutate


# 24 malformed scenes, each must exit 1 with one line naming the field.
BAD = [
    ("bodies[0].material.E", _set(["bodies", 0, "material", "E"], -1.0)),
    ("bodies[0].material.E", _set(["bodies", 0, "material", "E"], "stiff")),
    ("bodies[0].material.nu", _set(["bodies", 0, "material", "nu"], 0.5)),
    ("bodies[0].material.density", _set(["bodies", 0, "material", "density"], -3)),
    ("bodies[0].material.model", _set(["bodies", 0, "material", "model"], "ogden")),
    ("bodies[0].material", _drop(["bodies", 0, "material"])),
    ("time.dt", _set(["time", "dt"], 0)),
    ("time.steps", _set(["time", "steps"], -2)),
    ("time.integrator", _set(["time", "integrator"], "euler")),
    ("time", _drop(["time"])),
    ("bodies[0].mesh.file", _set(["bodies", 0, "mesh"], {"file": "missing.msh"})),
    ("bodies[0].mesh.box.cells", _set(["bodies", 0, "mesh", "box", "cells"], [4])),
    ("bodies[0].mesh.box.max", _set(["bodies", 0, "mesh", "box", "max"], [0.0, 0.2])),
    ("bodies[0].mesh", _set(["bodies", 0, "mesh"], {})),
    ("dimension", _set(["dimension"], 5)),
    ("bodies", _set(["bodies"], [])),
    ("gravity", _set(["gravity"], [0, 0, 0])),
    ("gravity[1]", _set(["gravity"], [0, 1e999])),
    ("colour", _set(["colour"], "red")),
    ("solver.max_iterations", _set(["solver", "max_iterations"], 0)),
    ("solver.linear_solver", _set(["solver", "linear_solver"], "mumps")),
    ("dirichlet[0].body", _set(["dirichlet"], [{"body": "ghost", "region": {"min": [0, 0], "max": [1, 1]}, "displacement": [0, 0]}])),
    ("dirichlet[0].displacement[0]", _set(["dirichlet"], [{"body": 0, "region": {"min": [0, 0], "max": [1, 1]}, "displacement": ["t +", 0]}])),
    ("neumann[0].region", _set(["neumann"], [{"body": 0, "region": {"min": [5, 5], "max": [6, 6]}, "traction": [1, 0]}])),
    ("contact.dhat", _set(["contact"], {"dhat": -1e-3})),
    ("contact.kappa", _set(["contact"], {"kappa": "stiff"})),
    ("contact.min_distance", _set(["contact"], {"min_distance": -1})),
    ("contact.ccd_rescaling", _set(["contact"], {"ccd_rescaling": 1.5})),
    ("contact.typo", _set(["contact"], {"typo": 1})),
    ("obstacles[0].plane.normal", _set(["obstacles"], [{"plane": {"point": [0, 0], "normal": [0, 0]}}])),
    ("obstacles[0]", _set(["obstacles"], [{"name": "nothing"}])),
    ("obstacles[0].mesh.file", _set(["obstacles"], [{"mesh": {"file": "missing.obj"}}])),
    ("obstacles[0].plane.motion[1]", _set(["obstacles"], [{"plane": {"point": [0, 0], "normal": [0, 1], "motion": [0, "t +"]}}])),
    ("bodies[0].mesh.annulus.outer_radius", _set(["bodies", 0, "mesh"], {"annulus": {"inner_radius": 0.5, "outer_radius": 0.4, "segments": 8}})),
    ("bodies[0].self_contact", _set(["bodies", 0, "self_contact"], "yes")),
    # Checks that run after placement or in the simulator: validate makes them too.
    ("contact.dhat", _set(["contact"], {"dhat": 1e300})),
    ("contact.dhat", _set(["contact"], {"dhat": 1e-12, "kappa": "adaptive"})),
    ("bodies[0]", _set(["bodies", 0, "translation"], [0, 1e11])),
    # Found by the fuzz test: a file name too long for the system (exit 3 before), NUL characters.
    ("bodies[0].mesh.file", _set(["bodies", 0, "mesh"], {"file": "x" * 5000 + ".msh"})),
    ("bodies[0].material.model", _set(["bodies", 0, "material", "model"], "neo\u0000hookean")),
    ('bodies[0].\\0colour', _set(["bodies", 0, "\u0000colour"], 1)),
    ("neumann[0].traction[0]", _set(["neumann"], [{"body": 0, "region": {"min": [0.5, -1], "max": [1, 1]}, "traction": ["t=5", 0]}])),
    ("neumann[0].traction[0]", _set(["neumann"], [{"body": 0, "region": {"min": [0.5, -1], "max": [1, 1]}, "traction": ["1,5", 0]}])),
]


@pytest.mark.parametrize("field, mutate", BAD)
def test_bad_scene_exits_nonzero_with_one_line(cli, tmp_path, field, mutate):
    s = box_scene()
    mutate(s)
    scene = tmp_path / "bad.json"
    # 1e999 is written as Infinity by json.dumps; write it as a JSON number that overflows instead.
    scene.write_text(json.dumps(s).replace("Infinity", "1e999"))
    for sub in ("simulate", "validate"):
        r = run(cli, sub, scene, *(["-o", tmp_path / "o"] if sub == "simulate" else []))
        assert r.returncode == 1
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and field in lines[0] and str(scene) in lines[0], r.stderr


def test_malformed_json_and_missing_file(cli, tmp_path):
    bad = tmp_path / "broken.json"
    bad.write_text("{ not json")
    r = run(cli, "validate", bad)
    assert r.returncode == 1 and "invalid JSON" in r.stderr
    r = run(cli, "validate", tmp_path / "nope.json")
    assert r.returncode == 1 and "cannot open" in r.stderr


def test_failed_step_exits_2_and_keeps_committed_steps(cli, tmp_path):
    s = box_scene(dim=2, steps=3, dt=0.05)
    s["gravity"] = [0, -9.81]
    s["dirichlet"] = [{"body": 0, "region": {"min": [-1, -1], "max": [0, 1]}, "displacement": [0, 0]}]
    s["solver"] = {"residual_tolerance": 1e-12, "max_iterations": 1}
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "simulate", scene, "-o", tmp_path / "o", "-q")
    assert r.returncode == 2
    assert "NEWTON_EXHAUSTED" in r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["status"] == "NEWTON_EXHAUSTED"
    assert summary["failed_step"] == 1


def test_validate_refuses_an_initial_state_that_simulate_cannot_start(cli, tmp_path):
    s = box_scene(dim=2, steps=2)
    s["obstacles"] = [{"name": "cutter", "plane": {"point": [0, 0.1], "normal": [0, 1]}}]  # through the box
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "validate", scene)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(scene) in lines[0] and "initial state is invalid" in lines[0], r.stderr
    r = run(cli, "simulate", scene, "-o", tmp_path / "o", "-q")
    assert r.returncode == 2 and "INVALID_INITIAL_STATE" in r.stderr and "behind a plane" in r.stderr, r.stderr


def test_contact_scene_writes_contact_datasets(cli, tmp_path, root):
    h5py = pytest.importorskip("h5py")
    s = json.loads((root / "studies" / "201_ring_on_plane" / "scene.json").read_text())
    s["bodies"][0]["mesh"]["annulus"].update({"segments": 24, "layers": 1})
    s["time"]["steps"] = 30
    s.pop("output")
    scene = tmp_path / "ring.json"
    scene.write_text(json.dumps(s))
    out = tmp_path / "out"
    r = run(cli, "simulate", scene, "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["contact"]["max_active_contacts"] > 0
    for phase in ("broad_phase", "ccd", "barrier"):
        assert summary["wall_time"][phase] >= 0
    with h5py.File(out / "trajectory.h5", "r") as f:
        active = f["active_contacts"][:]
        dist = f["min_distance"][:]
        kappa = f["kappa"][:]
        assert active.shape == dist.shape == kappa.shape == f["ccd_time"].shape == f["broad_phase_time"].shape == (30,)
        assert f["friction_residual"].shape == (30,) and (f["friction_residual"][:] == 0).all()  # no friction here
        assert active.max() > 0 and (kappa > 0).all()
        touching = active > 0
        # Where contacts are active the minimum distance is below dhat and positive.
        assert (dist[touching] > 0).all() and (dist[touching] < s["contact"]["dhat"]).all()
        # The plane's point follows the body vertices; every body vertex stays above the plane.
        body = f["mesh/body"][:]
        y = f["positions"][:, body == 0, 1]
        assert (y > 0).all()


def test_friction_study_slides_with_the_closed_form_acceleration(cli, tmp_path, root):
    h5py = pytest.importorskip("h5py")
    out = tmp_path / "slope"
    r = run(cli, "simulate", root / "studies" / "207_block_on_slope" / "scene.json", "-o", out, "-q", "--vtu-every", "0")
    assert r.returncode == 0, r.stderr
    with h5py.File(out / "trajectory.h5", "r") as f:
        body = f["mesh/body"][:] == 0
        t = f["time"][:]
        v = f["velocities"][:, body, :].mean(axis=1)
        residual = f["friction_residual"][:]
    direction = np.array([np.cos(np.pi / 6), -np.sin(np.pi / 6)])  # down the slope
    speed = v @ direction
    half = len(t) // 2
    a = (speed[-1] - speed[half]) / (t[-1] - t[half])
    expected = 9.81 * (np.sin(np.pi / 6) - 0.2 * np.cos(np.pi / 6))
    assert abs(a / expected - 1) < 0.01, (a, expected)
    assert residual.max() < 1e-6


def test_usage_errors_exit_1_with_one_line(cli, tmp_path):
    # Before: CLI11's own codes (106, 109, ...) and negative counts silently ignored.
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(box_scene(dim=2, steps=1)))
    cases = [
        ["simulate", str(scene), "--bogus", "1"],
        ["simulate", str(scene), "--vtu-every", "-3"],
        ["gradcheck", str(scene), "--directions", "-2"],
        ["simulate", str(scene), "--vtu-every", "many"],
        [],
    ]
    for args in cases:
        r = run(cli, *args)
        assert r.returncode == 1, (args, r.returncode, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("diffipc: error:"), (args, r.stderr)
        assert len(lines[0]) < 200, lines[0]
    assert run(cli, "--help").returncode == 0
    assert run(cli, "--version").returncode == 0


def test_inputs_that_are_not_json_files_are_refused(cli, tmp_path, root):
    # Before: /dev/zero was read until memory ran out, a directory gave "invalid JSON", and a
    # problem file nested two million levels deep crashed gradcheck (exit -11).
    for path, message in (("/dev/zero", "larger than the limit"), (str(tmp_path), "directory")):
        for command in ("validate", "gradcheck"):
            r = run(cli, command, path)
            assert r.returncode == 1, (command, path, r.stderr)
            assert message in r.stderr and path in r.stderr
    problem = json.loads((root / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())
    text = json.dumps(problem)[:-1] + ', "deep": ' + "[" * 2000000 + "]" * 2000000 + "}"
    deep = tmp_path / "deep.json"
    deep.write_text(text)
    r = run(cli, "gradcheck", deep)
    assert r.returncode == 1 and "nested deeper than" in r.stderr and str(deep) in r.stderr
    s = box_scene(dim=2, steps=1)
    text = json.dumps(s)[:-1] + ', "description": ' + "[" * 100 + "]" * 100 + "}"
    scene = tmp_path / "deep_scene.json"
    scene.write_text(text)
    r = run(cli, "validate", scene)
    assert r.returncode == 1 and "nested deeper than" in r.stderr
    # A scene through a pipe (as with the shell's process substitution) is still read.
    r = subprocess.run([cli, "validate", "/dev/stdin"], input=json.dumps(box_scene(dim=2, steps=1)),
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "valid 2D scene" in r.stdout, r.stderr


def test_readme_documents_every_exit_code(root):
    readme = (root / "README.md").read_text()
    section = readme[readme.index("Exit codes:"):]
    for code in ("0 success", "1 bad input", "2 a time step failed", "3 an internal error", "4 `gradcheck`", "130",
                 "143"):
        assert code in section, code
    assert "in progress" not in readme


@pytest.mark.parametrize("scale", [1e308, 1e200])
def test_an_obstacle_scaled_out_of_range_is_refused(cli, tmp_path, root, scale):
    # Before: validate accepted it and simulate spun forever in the hash-grid broad phase.
    study = root / "studies" / "205_plate_on_sphere"
    s = json.loads((study / "scene.json").read_text())
    s["obstacles"][0]["mesh"]["file"] = str(study / s["obstacles"][0]["mesh"]["file"])
    s["obstacles"][0]["mesh"]["scale"] = scale
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(s))
    for command in ("validate", "simulate"):
        r = run(cli, command, scene, *(["-o", tmp_path / "out"] if command == "simulate" else []))
        assert r.returncode == 1, (command, r.stderr)
        assert "obstacles[0]" in r.stderr and "1e12" in r.stderr


def test_errors_quote_at_most_a_line_of_the_input(cli, tmp_path):
    # Before: a malformed 1 MB .msh line was echoed whole on stderr.
    s = box_scene(dim=3, steps=1)
    s["bodies"][0]["mesh"] = {"file": "bad.msh"}
    (tmp_path / "bad.msh").write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n" + "x" * 1000000 + "\n")
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "validate", scene)
    assert r.returncode == 1, r.stderr
    assert len(r.stderr) < 1000 and len(r.stderr.strip().splitlines()) == 1
    assert "bad.msh" in r.stderr and "more characters" in r.stderr


def test_a_long_thin_mesh_solves(cli, tmp_path):
    # Before: SIGSEGV. A 40000 x 4 strip has a supernodal elimination tree 31,000 levels deep,
    # and the recursive top-down solve overflowed the stack (found by the fuzz test).
    s = box_scene(dim=2, model="linear", E=1e6, steps=1)
    s["bodies"][0]["mesh"]["box"] = {"min": [0, 0], "max": [1, 0.1], "cells": [40000, 4]}
    s["dirichlet"] = [{"body": 0, "region": {"min": [-1, -1], "max": [1e-9, 1]}, "displacement": [0, 0]}]
    s["gravity"] = [0, -9.81]
    s["time"] = {"integrator": "static", "dt": 0.1, "steps": 1}
    del s["solver"]  # the default tolerance: 1e-10 is below this long strip's round-off
    scene = tmp_path / "strip.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "simulate", scene, "-o", tmp_path / "o", "-q")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["steps_committed"] == 1


def test_an_inverted_start_fails_step_1_with_its_reason_for_every_material(cli, tmp_path):
    # Before: validate said "inverted" but simulate failed with LINE_SEARCH_EXHAUSTED and no
    # reason: StVK and linear elasticity have a finite energy at an inverted element, so Newton
    # started and its volume-bounded line search found no step (found by the fuzz test).
    for model in ("stvk", "linear"):
        s = box_scene(dim=2, model=model, steps=1)
        s["time"]["integrator"] = "static"
        s["dirichlet"] = [{"body": 0, "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [2, 0]}]
        scene = tmp_path / f"{model}.json"
        scene.write_text(json.dumps(s))
        r = run(cli, "validate", scene)
        assert r.returncode == 1 and "inverted" in r.stderr, r.stderr
        r = run(cli, "simulate", scene, "-o", tmp_path / model, "-q")
        assert r.returncode == 2 and "INVALID_INITIAL_STATE" in r.stderr and "inverted" in r.stderr, r.stderr


def test_a_mesh_larger_than_memory_is_refused_before_allocation(cli, tmp_path):
    # Before: validate allocated the mesh and its simulator until std::bad_alloc (exit 3) or the
    # kernel killed it (a 7000 x 7000 box on a 24 GB machine). Under a 2 GB address-space limit,
    # a 1500 x 1500 box (4.5 million triangles, about 3 GB to set up) is now refused at once.
    import resource

    def limit_memory():
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    s = box_scene(dim=2, steps=1)
    s["bodies"][0]["mesh"]["box"] = {"min": [0, 0], "max": [1, 1], "cells": [1500, 1500]}
    scene = tmp_path / "big.json"
    scene.write_text(json.dumps(s))
    for command in (["validate", scene], ["simulate", scene, "-o", tmp_path / "o", "-q"]):
        r = subprocess.run([cli, *map(str, command)], capture_output=True, text=True, timeout=120,
                           preexec_fn=limit_memory)
        assert r.returncode == 1, (command[0], r.returncode, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "bodies[0].mesh.box.cells" in lines[0] and "GB" in lines[0], r.stderr


def test_a_huge_newton_step_fails_the_step_instead_of_hanging(cli, root, tmp_path):
    # Before: the first step ran for 7 minutes (timeout(1) sent SIGTERM at 60 s; the step
    # finished long after) and then failed with CCD_UNRESOLVED. A static scene with a free
    # body (found by the fuzz test) has a rigid mode, so the Newton step is ~1e15 m long; CCD
    # swept every pair of the obstacle mesh across the whole scene. The step is now capped at
    # the bodies' bounding-box diagonal, and the solve runs out of Newton iterations in seconds.
    s = {
        "dimension": 3,
        "bodies": [{"name": "plate",
                    "mesh": {"box": {"min": [-0.6, 0.35, -0.6], "max": [0.6, 0.37, 0.6], "cells": [4, 1, 4]}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
        "obstacles": [{"name": "sphere", "mesh": {"file": str(root / "studies" / "205_plate_on_sphere" / "sphere.obj"),
                                                  "scale": 0.3}}],
        "contact": {"dhat": 1e-3, "kappa": "adaptive"},
        "gravity": [0, -9.81, 0],
        "time": {"integrator": "static", "dt": 0.05, "steps": 2},
    }
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(s))
    r = subprocess.run([cli, "simulate", scene, "-o", tmp_path / "o", "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and "NEWTON_EXHAUSTED" in r.stderr, r.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["status"] == "NEWTON_EXHAUSTED" and summary["steps_committed"] == 0

    # The cap counts free dofs only, and allows the inertial drift: an obstacle that moves
    # 10 km per step (prescribed: lifted in one iteration) and a plate falling freely beside it
    # still take one Newton iteration per step (a cap on every dof took 100 and failed).
    s["time"] = {"integrator": "implicit_euler", "dt": 0.01, "steps": 3}
    s["obstacles"][0]["mesh"]["motion"] = ["1e6*t", "0", "0"]
    scene.write_text(json.dumps(s))
    r = subprocess.run([cli, "simulate", scene, "-o", tmp_path / "fast", "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    summary = json.loads((tmp_path / "fast" / "summary.json").read_text())
    assert summary["steps_committed"] == 3 and summary["counts"]["newton_iterations"] <= 6, summary


def test_an_initial_state_with_inverted_elements_writes_no_nan(cli, tmp_path):
    # Before: validate passed and frame_0.vtu held NaN stresses (a Dirichlet displacement that
    # moves the clamped end past the rest of the body inverts its elements at t = 0).
    s = box_scene(dim=2, steps=1)
    s["dirichlet"] = [{"body": 0, "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [2, 0]}]
    s["output"] = {"vtu_every": 1}
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "validate", scene)
    assert r.returncode == 1 and "inverted" in r.stderr, r.stderr
    out = tmp_path / "o"
    r = run(cli, "simulate", scene, "-o", out, "-q")
    assert r.returncode == 2 and "INVALID_INITIAL_STATE" in r.stderr and "inverted" in r.stderr, r.stderr
    for vtu in out.glob("*.vtu"):
        assert "nan" not in vtu.read_bytes().decode("latin-1").lower(), vtu
    assert not list(out.glob("frame_*.vtu"))


def test_check_validates_a_run_and_names_corrupted_states(cli, tmp_path):
    # `diffipc check` re-checks every stored state with the exact tests; states edited in the file
    # to overlap or to invert an element are named, and the exit code is 2.
    h5py = pytest.importorskip("h5py")
    box = lambda name, y0: {"name": name, "mesh": {"box": {"min": [0, y0], "max": [1, y0 + 1], "cells": [2, 2]}},
                            "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}
    s = {"dimension": 2, "bodies": [box("low", 0), box("high", 1.05)], "gravity": [0, -9.81],
         "dirichlet": [{"body": "low", "region": {"min": [-1, -1], "max": [2, 1e-6]}, "displacement": [0, 0]}],
         "contact": {"dhat": 0.01, "kappa": 1e5},
         "time": {"integrator": "implicit_euler", "dt": 0.05, "steps": 3}}
    scene = tmp_path / "stack.json"
    scene.write_text(json.dumps(s))
    out = tmp_path / "out"
    assert run(cli, "simulate", scene, "-o", out, "-q").returncode == 0
    r = run(cli, "check", out, "--scene", scene)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "4 of 4 states valid" in r.stdout
    with h5py.File(out / "trajectory.h5", "r+") as f:
        x = f["positions"][:]
        body = f["mesh/body"][:]
        elements = f["mesh/elements"][:]
        high = np.flatnonzero(body == 1)
        lowest = high[np.argmin(x[2, high, 1])]
        x[2, lowest, 1] = 0.5  # a vertex of the upper box inside the lower one: its edges cross
        a, b, c = elements[0]
        x[3, a], x[3, b] = x[3, b].copy(), x[3, a].copy()  # two vertices of an element swapped: inverted
        f["positions"][...] = x
    r = run(cli, "check", out, "--scene", scene, "-q")
    assert r.returncode == 2, r.stdout + r.stderr
    assert "2 of 4 states valid" in r.stdout
    lines = [l for l in r.stdout.splitlines() if l.startswith("state ")]
    assert len(lines) == 2
    assert lines[0].startswith("state 2") and "intersection: " in lines[0]
    assert lines[1].startswith("state 3") and "0 inverted" not in lines[1]
    r = run(cli, "check", tmp_path / "missing")
    assert r.returncode == 1 and "trajectory.h5" in r.stderr


def test_a_periodic_cell_writes_its_macro_datasets_and_restarts_bit_for_bit(cli, tmp_path):
    # A periodic cell compressed by 30% along x, its lateral component free (scene "periodic"):
    # trajectory.h5 holds G and the cell-average stress per step, and a run restarted from its
    # step 5 (`simulate --restart`) ends where the run in one go does.
    h5py = pytest.importorskip("h5py")

    scene = {"dimension": 2,
             "bodies": [{"name": "cell", "mesh": {"box": {"min": [0, 0], "max": [1, 1], "cells": [6, 6]}},
                         "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
             "periodic": {"gradient": [["-0.3*t", 0], [0, None]]},
             "time": {"integrator": "static", "dt": 0.1, "steps": 10},
             "output": {"vtu_every": 0}}
    (tmp_path / "ten.json").write_text(json.dumps(scene))
    scene["time"]["steps"] = 5
    (tmp_path / "five.json").write_text(json.dumps(scene))
    assert run(cli, "simulate", "ten.json", "-o", "whole", "-q", cwd=tmp_path).returncode == 0
    assert run(cli, "simulate", "five.json", "-o", "parts", "-q", cwd=tmp_path).returncode == 0
    r = run(cli, "simulate", "--restart", "parts", "ten.json", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "whole" / "trajectory.h5") as a, h5py.File(tmp_path / "parts" / "trajectory.h5") as b:
        assert a["macro_gradient"].shape == (10, 2, 2)
        assert np.allclose(a["macro_gradient"][:, 0, 0], -0.03 * np.arange(1, 11), rtol=0, atol=1e-15)
        assert a["macro_gradient"][-1, 1, 1] > 0.1  # the free lateral component expands
        assert abs(a["macro_stress"][-1, 1, 1]) < 1e-6 * abs(a["macro_stress"][-1, 0, 0])
        for name in ("positions", "macro_gradient", "macro_stress"):
            assert np.array_equal(a[name][:], b[name][:]), name
    # `diffipc check` checks each state on the cell's 3 x 3 tiling; an inverted element is named.
    r = run(cli, "check", "whole", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "11 of 11 states valid (exact inversion and intersection (on the cell's tiling) tests)" in r.stdout
    with h5py.File(tmp_path / "whole" / "trajectory.h5", "r+") as f:
        x = f["positions"][:]
        a, b, _ = f["mesh/elements"][0]
        x[4, a], x[4, b] = x[4, b].copy(), x[4, a].copy()
        f["positions"][...] = x
    r = run(cli, "check", "whole", "-q", cwd=tmp_path)
    assert r.returncode == 2 and r.stdout.startswith("state 4 "), r.stdout + r.stderr


def test_steps_option_replaces_the_scenes_step_count(cli, tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(box_scene(dim=2, steps=5)))
    for steps in (2, 7):
        out = tmp_path / f"out{steps}"
        r = run(cli, "simulate", scene, "-o", out, "--steps", steps, "-q")
        assert r.returncode == 0, r.stderr
        summary = json.loads((out / "summary.json").read_text())
        assert summary["steps_requested"] == steps and summary["steps_committed"] == steps
    r = run(cli, "simulate", scene, "-o", tmp_path / "bad", "--steps", 0)
    assert r.returncode != 0 and "--steps" in r.stderr


def test_line_search_cuts_are_recorded_per_step_and_in_total(cli, tmp_path, root):
    h5py = pytest.importorskip("h5py")
    out = tmp_path / "boxes"
    r = run(cli, "simulate", root / "studies" / "202_boxes_head_on" / "scene.json", "-o", out, "--steps", 3, "-q",
            "--vtu-every", 0)
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "summary.json").read_text())
    with h5py.File(out / "trajectory.h5", "r") as f:
        cuts = f["line_search_cuts"][:]
    assert len(cuts) == 3 and cuts.min() >= 0
    assert cuts.sum() == summary["line_search_cuts"] > 0  # the boxes' impact needs backtracking
    # A restarted run keeps the stored steps' counts.
    r = run(cli, "simulate", "--restart", out, "--steps", 4, "-q")
    assert r.returncode == 0, r.stderr
    with h5py.File(out / "trajectory.h5", "r") as f:
        assert list(f["line_search_cuts"][:3]) == list(cuts)


def test_study_runs_a_studys_script_with_this_build(cli, tmp_path, root):
    r = run(cli, "study", "--list")
    assert r.returncode == 0
    for name in ("501_scene_work", "502_error_vs_time", "503_stability_atlas", "504_gradient_error"):
        assert name in r.stdout.split()
    r = run(cli, "study", "999")
    assert r.returncode == 1 and "no study '999'" in r.stderr and "502_error_vs_time" in r.stderr
    # A stand-in study (DIFFIPC_STUDIES) records what it was given: the options its run.py declares,
    # this CLI, the module's path; its exit code is the command's.
    studies = tmp_path / "studies"
    (studies / "900_probe").mkdir(parents=True)
    (studies / "900_probe" / "run.py").write_text(
        "import argparse, json, os, sys\n"
        "p = argparse.ArgumentParser()\n"
        "p.add_argument(\"--results\"); p.add_argument(\"-o\"); p.add_argument(\"--cli\")\n"
        "p.add_argument(\"--full\", action=\"store_true\")\n"
        "a = p.parse_args()\n"
        "json.dump(dict(vars(a), env_cli=os.environ.get('DIFFIPC_CLI'), path=os.environ.get('PYTHONPATH')),\n"
        "          open(os.path.join(a.results, 'args.json'), 'w'))\n"
        "sys.exit(3)\n")
    env = dict(os.environ, DIFFIPC_STUDIES=str(studies))
    r = subprocess.run([cli, "study", "900", "--full"], capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 3, r.stderr
    got = json.loads((studies / "900_probe" / "args.json").read_text())
    assert got["results"] == str(studies / "900_probe") and got["full"] is True
    assert got["o"] == str(tmp_path / "output" / "900_probe")
    assert os.path.samefile(got["cli"], cli) and os.path.samefile(got["env_cli"], cli)
    assert got["path"].split(":")[0].endswith("python")
