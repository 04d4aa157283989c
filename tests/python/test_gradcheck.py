"""`diffipc gradcheck` on every example problem in the repo, and its errors on bad input."""
import json
import subprocess

import pytest

from conftest import ROOT, box_scene


def run(cli, *args):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=600)


EXAMPLES = sorted(ROOT.glob("studies/*/problem.json"))


def test_there_are_example_problems():
    assert len(EXAMPLES) >= 2


@pytest.mark.parametrize("problem", EXAMPLES, ids=lambda p: p.parent.name)
def test_every_example_problem_passes_gradcheck(cli, problem):
    r = run(cli, "gradcheck", problem)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "gradcheck passed" in r.stdout
    # A table per direction with the second-order rates.
    assert r.stdout.count("PASS") >= 2
    assert "|J(h)-J(0)-h g.dp|" in r.stdout


def write_problem(tmp_path, scene, objective, parameters):
    p = tmp_path / "problem.json"
    p.write_text(json.dumps({"scene": scene, "objective": objective, "parameters": parameters}))
    return p


def test_parameter_the_scene_does_not_have_is_an_error(cli, tmp_path):
    p = write_problem(tmp_path, box_scene(), {"type": "elastic_energy"}, [{"type": "friction"}])
    r = run(cli, "gradcheck", p)
    assert r.returncode == 1
    assert "parameters[0]" in r.stderr and "no friction" in r.stderr
    p = write_problem(tmp_path, box_scene(), {"type": "elastic_energy"}, [{"type": "prescribed"}])
    r = run(cli, "gradcheck", p)
    assert r.returncode == 1 and "no prescribed dofs" in r.stderr
    p = write_problem(tmp_path, box_scene(), {"type": "elastic_energy"}, [{"type": "E", "body": "nope"}])
    r = run(cli, "gradcheck", p)
    assert r.returncode == 1 and "parameters[0].body" in r.stderr


def test_failed_forward_step_returns_no_gradient(cli, tmp_path):
    s = box_scene()
    # A clamped beam under a large tip load with one Newton iteration allowed: step 1 fails.
    s["dirichlet"] = [{"body": "b", "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [0, 0]}]
    s["neumann"] = [{"body": "b", "region": {"min": [0.499, -1], "max": [1, 1]}, "traction": [0, "-5e5*t"]}]
    s["solver"]["max_iterations"] = 1
    p = write_problem(tmp_path, s, {"type": "elastic_energy"}, [{"type": "E"}])
    r = run(cli, "gradcheck", p)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "no value and no gradient" in r.stderr
    assert "J =" not in r.stdout


def test_bad_objective_names_the_field(cli, tmp_path):
    p = write_problem(tmp_path, box_scene(), {"type": "stress_norm", "p": -1}, [{"type": "E"}])
    r = run(cli, "gradcheck", p)
    assert r.returncode == 1 and "objective.p" in r.stderr


def test_an_objective_that_does_not_depend_on_the_parameters_is_not_a_pass(cli, tmp_path):
    # Before: every rate printed as -nan and the check said PASS (exit 0). Without gravity
    # the bar never moves, so the markers objective does not depend on the density.
    problem = json.loads((ROOT / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())
    problem["scene"]["gravity"] = [0, 0, 0]
    problem["parameters"] = [{"type": "density"}]
    path = tmp_path / "flat.json"
    path.write_text(json.dumps(problem))
    r = run(cli, "gradcheck", path)
    assert r.returncode == 4, r.stdout + r.stderr
    assert "nan" not in r.stdout.lower() and "inf " not in r.stdout
    assert "INCONCLUSIVE" in r.stdout and "PASS" not in r.stdout


def _problem():
    return json.loads((ROOT / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())


def _scenes(p):
    return {"scenes": [{"scene": p["scene"], "objective": p["objective"]}], "parameters": p["parameters"]}


# Before: unknown keys were ignored, "scene" beside "scenes" silently dropped, and wrong kinds
# converted (directions true -> 1, 2.7 -> 2, seed 0.5 -> 0, a string weight a library error).
BAD_PROBLEMS = [
    ("unknown_root_key", lambda p: p.update(objectiv=1) or p, "objectiv"),
    ("unknown_gradcheck_key", lambda p: p["gradcheck"].update(direction=3) or p, "gradcheck.direction"),
    ("directions_true", lambda p: p["gradcheck"].update(directions=True) or p, "gradcheck.directions"),
    ("directions_fraction", lambda p: p["gradcheck"].update(directions=2.7) or p, "gradcheck.directions"),
    ("seed_fraction", lambda p: p["gradcheck"].update(seed=0.5) or p, "gradcheck.seed"),
    # Before: accepted, and gradcheck ran a forward solve per halving (2e9 of them).
    ("halvings_huge", lambda p: p["gradcheck"].update(halvings=2000000000) or p, "gradcheck.halvings"),
    ("gradcheck_not_object", lambda p: p.update(gradcheck=[1, 2]) or p, "gradcheck"),
    ("weight_string", lambda p: p.update(weight="heavy") or p, "weight"),
    ("scene_beside_scenes", lambda p: dict(_scenes(p), scene=p["scene"]), "scene"),
    ("unknown_case_key", lambda p: (lambda q: q["scenes"][0].update(wieght=2) or q)(_scenes(p)), "scenes[0].wieght"),
    # Before: accepted, and the gradient was then wrong (the forward used the last entry).
    ("element_block_twice", lambda p: p.update(parameters=[{"type": "E", "per": "element"}, {"type": "E"}]) or p,
     "parameters[1]"),
    ("vertex_listed_twice", lambda p: p.update(parameters=[{"type": "shape", "vertices": [3, 5, 3]}]) or p,
     "parameters[0]"),
    ("vertex_in_two_entries", lambda p: p.update(parameters=[{"type": "shape", "vertices": [3, 5]},
                                                             {"type": "shape", "vertices": [5]}]) or p,
     "parameters[1]"),
    # Before: errors in an inline scene named no load case.
    ("inline_scene_error", lambda p: p["scene"]["bodies"][0]["material"].update(nu=0.7) or p,
     "scene.bodies[0].material.nu"),
    ("case_scene_error", lambda p: (lambda q: q["scenes"][0]["scene"].update(dimension=4) or q)(_scenes(p)),
     "scenes[0].scene.dimension"),
    # Before: unknown keys inside a vertex selection were ignored.
    ("vertices_unknown_key", lambda p: p.update(parameters=[{"type": "shape", "vertices": {"body": "bar", "bdy": 1}}]) or p,
     "parameters[0].vertices"),
    # Before: accepted, and the parameter was dead (prescribed dofs keep the prescription).
    ("initial_velocity_on_dirichlet_vertex",
     lambda p: p.update(parameters=[{"type": "initial_velocity", "per": "vertex", "vertices": [0, 11]}]) or p,
     "parameters[0].vertices"),
    # Before: accepted, then exit 2 when the gradient was asked for.
    ("friction_iterations", lambda p: p["scene"].update(
        obstacles=[{"plane": {"point": [0, -1, 0], "normal": [0, 1, 0]}}], contact={"kappa": 1e6},
        friction={"coefficient": 0.3, "iterations": 2}) or p, "scene.friction.iterations"),
    # Found by the fuzz test: messages that named no field, or ended at a NUL character.
    ("scene_null", lambda p: p.update(scene=None) or p, "scene: expected a scene file path"),
    ("scene_number", lambda p: p.update(scene=3) or p, "scene: expected a scene file path"),
    ("scene_empty_path", lambda p: p.update(scene="") or p, "scene: an empty path"),
    ("case_scene_null", lambda p: (lambda q: q["scenes"][0].update(scene=None) or q)(_scenes(p)), "scenes[0].scene"),
    ("empty_key", lambda p: p.update({"": 1}) or p, '"": unknown field'),
    ("nul_in_key", lambda p: p["gradcheck"].update({"seed\u0000x": 1}) or p, "gradcheck.seed\\0x: unknown field"),
    ("nul_in_scene_path", lambda p: p.update(scene="scene\u0000.json") or p, "scene: contains a NUL"),
    # Before: J = inf, a table of nan and exit 4 (Python returned inf).
    ("objective_overflows", lambda p: p["objective"].update(targets=[[[1e300, 0, 0], [1, 0.09, 0.1]],
                                                                       [[0.99, -0.04, 0], [0.99, 0.06, 0.1]]]) or p,
     "objective: J = inf"),
]


def test_a_difference_lost_to_round_off_prints_a_finite_relative_error(cli, tmp_path):
    # Before: "relative error inf" (found by the fuzz test). A marker target 1e15 m away makes
    # J = 5e29, so J(p + h dp) - J(p) rounds to 0 while the adjoint's dJ.dp is -1.7e10.
    problem = _problem()
    problem["objective"]["targets"][1][1][0] = -1e15
    path = tmp_path / "far.json"
    path.write_text(json.dumps(problem))
    r = run(cli, "gradcheck", path, "--directions", "1")
    assert r.returncode == 4, r.stdout + r.stderr
    line = next(x for x in r.stdout.splitlines() if "relative error" in x)
    assert float(line.rsplit(" ", 1)[1]) <= 2, line
    assert "nan" not in r.stdout.lower() and "inf" not in r.stdout.lower().replace("inconclusive", "")


@pytest.mark.parametrize("name,mutate,field", BAD_PROBLEMS, ids=[b[0] for b in BAD_PROBLEMS])
def test_bad_problem_files_exit_1_naming_the_field(cli, tmp_path, name, mutate, field):
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(mutate(_problem())))
    r = run(cli, "gradcheck", path)
    assert r.returncode == 1, (name, r.returncode, r.stdout[-300:], r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0], (name, r.stderr)
