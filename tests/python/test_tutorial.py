"""docs/tutorial_optimization.md, run: every command of the tutorial on its files in
docs/tutorial/, with this build's CLI and Python module, and the checks of what the text says.

The commands are run as the tutorial writes them, from a scratch "repository root" (a temporary
folder with `docs` linked to the repository's), so that they and their outputs read exactly as on
the page: `./build/cli/diffipc` becomes the `cli` fixture's path, `PYTHONPATH=build/python
/usr/bin/python3` this interpreter with the imported diffipc's folder on PYTHONPATH. Each command
must appear in one of the page's ```sh blocks, and every ```sh block must be one of the commands
here. Where the page shows a command's output (the ```text block that follows it), each shown
line must be in the output, in order (`...` stands for lines left out): same words, same numbers
(to one unit of the last printed digit, or 1e-6 relative where that is larger: the round-off of
another machine's BLAS kernel in numbers printed to many digits; numbers below 1e-5 in magnitude, round-off-level
quantities such as a converged gradient norm, only need to stay below it), wall times and
percentages masked. The
files shown on the page (scene, problem, Python code) must be the files in docs/tutorial/.
"""
import csv
import json
import os
import re

import numpy as np
import pytest

import diffipc
from conftest import ROOT
from tutorial_page import ACROSS_MACHINES_AFTER_A_REMESH, NUMBER, TutorialPage, TutorialRun, same_number

DOC = ROOT / "docs" / "tutorial_optimization.md"
TUTORIAL = ROOT / "docs" / "tutorial"
PACKAGE_PATH = os.path.dirname(os.path.dirname(os.path.abspath(diffipc.__file__)))

# Every command of the page, in the page's order.
VALIDATE = "./build/cli/diffipc validate docs/tutorial/bracket.json"
SIMULATE = "./build/cli/diffipc simulate docs/tutorial/bracket.json -o output/tutorial/simulate"
HEAD_SUMMARY = "head -20 output/tutorial/simulate/summary.json"
READ_TRAJECTORY = """/usr/bin/python3 -c '
import h5py, meshio
with h5py.File("output/tutorial/simulate/trajectory.h5", "r") as f:
    bracket = f["mesh/body"][()] == 0
    u = f["positions"][-1] - f["mesh/rest_positions"][()]
    print("time (s):", f["time"][()], " status:", f["status"][()])
    print("largest downward displacement (m):", u[bracket, 1].min())
    print("closest distance to the support (m):", f["min_distance"][()], " active contact pairs:", f["active_contacts"][()])
frame = meshio.read("output/tutorial/simulate/frame_2.vtu")
print("force of the support on the bracket (N per m of depth):", frame.point_data["contact_force"].sum(axis=0)[:2])
print("largest von Mises stress (Pa):", frame.cell_data["von_mises"][0].max())'"""
GRADCHECK = "./build/cli/diffipc gradcheck docs/tutorial/problem.json"
GRADCHECK_STRESS = "./build/cli/diffipc gradcheck docs/tutorial/problem_stress.json"
OPTIMIZE = "./build/cli/diffipc optimize docs/tutorial/problem.json -o output/tutorial/optimize"
CAT_SUMMARY = "cat output/tutorial/optimize/summary.json"
READ_HISTORY = """PYTHONPATH=build/python /usr/bin/python3 -c '
import json, h5py, diffipc
with h5py.File("output/tutorial/optimize/history.h5", "r") as f:
    print(f.attrs["algorithm"], list(f.attrs["constraint_names"]), f["x"].shape, f["J"][-1], f["constraints"][-1])
J = diffipc.ReducedFunctional("output/tutorial/optimize/optimal_problem.json")
print(J(J.parameters_of(J.design_initial)), json.load(open("output/tutorial/optimize/summary.json"))["final_J"])'"""
DEPTHS = """/usr/bin/python3 -c '
import meshio, numpy as np
points = meshio.read("output/tutorial/optimize/design_final.vtu").points
for x in np.linspace(0, 0.8, 9):
    column = points[np.abs(points[:, 0] - x) < 1e-9]
    print(f"x = {x:.1f} m: depth {column[:, 1].max() - column[:, 1].min():.4f} m")'"""
PLOT = "PYTHONPATH=build/python /usr/bin/python3 -m diffipc.plot output/tutorial/optimize"
STOP = "./build/cli/diffipc optimize docs/tutorial/problem.json -o output/tutorial/stopped --max-iterations 4"
RESUME = "./build/cli/diffipc optimize --resume output/tutorial/stopped"
OPTIMIZE_STRESS = "./build/cli/diffipc optimize docs/tutorial/problem_stress.json -o output/tutorial/stress"
OPTIMIZE_REMESH = "./build/cli/diffipc optimize docs/tutorial/problem_remesh.json -o output/tutorial/remesh"
READ_REMESHES = """/usr/bin/python3 -c '
import json
s = json.load(open("output/tutorial/remesh/summary.json"))
for r in s["remeshes"]:
    print({k: r[k] for k in ("iteration", "quality_before", "quality_after", "elements_before", "elements_after",
                              "J_before", "J_after", "constraints_before", "constraints_after")})
a = json.load(open("output/tutorial/remesh/remeshes.json"))
print("attempts", a["attempts"], "next trigger", a["trigger"], "failure", s.get("remesh_failure"))
print(s["stop_reason"], s["iterations"], s["final_J"], s["max_violation"])'"""
FINE_MESH = """PYTHONPATH=build/python /usr/bin/python3 -c '
import json, diffipc
problem = json.load(open("docs/tutorial/problem.json"))
problem["scene"] = json.load(open("docs/tutorial/bracket.json"))
problem["scene"]["bodies"][0]["mesh"]["box"]["cells"] = [128, 16]
J = diffipc.ReducedFunctional(problem, base_directory="docs/tutorial")
for run in ("optimize", "remesh"):
    x = json.load(open(f"output/tutorial/{run}/summary.json"))["design"]
    print(run, "design on 128 x 16:", J(J.parameters_of(x)))
print("start on 128 x 16:", J(J.parameters_of(J.design_initial)))'"""
TAYLOR = """PYTHONPATH=build/python /usr/bin/python3 -c '
import numpy as np, diffipc
J = diffipc.ReducedFunctional("docs/tutorial/problem.json")
print(J.layout, J.design_layout, J.constraints)
x = J.design_initial
value, dJ_dp = J.value_and_gradient(J.parameters_of(x))
dJ_dx = J.design_gradient(x, dJ_dp)
print(value, dJ_dx.round(1))
dx = np.random.default_rng(1).uniform(-0.05, 0.05, J.design_size)
print(diffipc.taylor_test(lambda x: J(J.parameters_of(x)), x, dx, dJdp=dJ_dx, printer=print))'"""
SCIPY = "PYTHONPATH=build/python /usr/bin/python3 docs/tutorial/scipy_slsqp.py"
MINIMIZE = "PYTHONPATH=build/python /usr/bin/python3 docs/tutorial/minimize_ipopt.py"

COMMANDS = [VALIDATE, SIMULATE, HEAD_SUMMARY, READ_TRAJECTORY, GRADCHECK, GRADCHECK_STRESS, OPTIMIZE, CAT_SUMMARY,
            READ_HISTORY, DEPTHS, PLOT, STOP, RESUME, OPTIMIZE_STRESS, OPTIMIZE_REMESH, READ_REMESHES, FINE_MESH,
            TAYLOR, SCIPY, MINIMIZE]


# ---------------------------------------------------------------------------------------------
# The page (tutorial_page.py: its fenced blocks, and the comparison of a shown output with a printed one).

PAGE = TutorialPage(DOC)
page_blocks = PAGE.blocks


# ---------------------------------------------------------------------------------------------
# Running the commands.

class Tutorial(TutorialRun):
    """A scratch repository root: docs/ linked to the repository's, outputs under output/."""

    def __init__(self, root, cli):
        super().__init__(root, cli, PAGE, COMMANDS, PACKAGE_PATH)

    def summary(self, run):
        return json.loads(self.path("output", "tutorial", run, "summary.json").read_text())

    def history(self, run):
        return list(csv.DictReader(self.path("output", "tutorial", run, "history.csv").open()))


@pytest.fixture
def tutorial(tmp_path, cli):
    return Tutorial(tmp_path, cli)


def numbers(line):
    return [float(v) for v in NUMBER.findall(line.split(":", 1)[-1])]


# ---------------------------------------------------------------------------------------------

def test_numbers_compare_at_the_stated_tolerance():
    """Numbers printed to many digits may differ at round-off on another machine (another OpenBLAS
    kernel printed these two); a difference in a digit that a shorter number shows may not."""
    assert same_number("0.0001882995779305319", "0.00018829957793053338")
    assert same_number("3.3416427659", "3.3416427657")
    assert same_number("7104.1", "7104.14")
    assert not same_number("7104.1", "7104.3")
    assert same_number("1.9996678410493423", "1.9996676730662537")
    assert not same_number("3.3416427659", "3.3416827659")
    assert not same_number("25", "26")
    # After a remesh: 1e-3 relative, counts within one (the page says so).
    assert same_number("2.107648e+02", "2.107748e+02", **ACROSS_MACHINES_AFTER_A_REMESH)
    assert same_number("18", "17", **ACROSS_MACHINES_AFTER_A_REMESH)
    assert not same_number("2.107648e+02", "2.110648e+02", **ACROSS_MACHINES_AFTER_A_REMESH)
    assert not same_number("18", "16", **ACROSS_MACHINES_AFTER_A_REMESH)


def test_the_page_and_its_files():
    """Every ```sh block is a command run here; the files shown are the files in docs/tutorial/."""
    blocks = page_blocks()
    commands = [text.rstrip("\n") for language, text in blocks if language == "sh"]
    assert set(commands) == set(COMMANDS)
    assert sorted(commands) == sorted(COMMANDS + [RESUME])   # the resume is shown twice
    shown = [text for language, text in blocks if language in ("json", "python")]
    assert shown[0] == (TUTORIAL / "bracket.json").read_text()
    assert shown[1] == (TUTORIAL / "problem.json").read_text()
    stress_line, remesh_line = shown[2].strip(), shown[3].strip()
    assert stress_line in (TUTORIAL / "problem_stress.json").read_text()
    assert remesh_line in (TUTORIAL / "problem_remesh.json").read_text()
    for name, other in (("problem_stress.json", stress_line), ("problem_remesh.json", remesh_line)):
        a = json.loads((TUTORIAL / "problem.json").read_text())
        b = json.loads((TUTORIAL / name).read_text())
        added = json.loads("{" + other.rstrip(",") + "}")
        for d in (a, b):
            d.pop("description")
            for key in added:
                d.pop(key, None)
        assert a == b, f"{name} differs from problem.json in more than {other}"
    assert shown[4] in (TUTORIAL / "design.py").read_text()
    assert shown[5] in (TUTORIAL / "scipy_slsqp.py").read_text()
    assert shown[6] in (TUTORIAL / "minimize_ipopt.py").read_text()
    assert len(shown) == 7
    # The support: a closed polyline of 24 segments on a circle of radius 0.02 m about
    # (0.5, -0.0205), its top 0.5 mm below the bracket.
    lines = (TUTORIAL / "support.obj").read_text().splitlines()
    v = np.array([[float(t) for t in l.split()[1:3]] for l in lines if l.startswith("v ")])
    assert len(v) == 24 and len([l for l in lines if l.startswith("l ")]) == 24
    assert np.allclose(np.hypot(v[:, 0] - 0.5, v[:, 1] + 0.0205), 0.02, atol=1e-14)
    assert v[:, 1].max() == pytest.approx(-0.0005, abs=1e-15)


def test_step_1_the_scene(tutorial):
    tutorial.run(VALIDATE)
    tutorial.run(SIMULATE)
    out = tutorial.path("output", "tutorial", "simulate")
    for name in ("trajectory.h5", "summary.json", "trajectory.pvd", "frame_0.vtu", "frame_1.vtu", "frame_2.vtu",
                 "obstacles_0.vtu", "obstacles_2.vtu"):
        assert (out / name).is_file(), name
    tutorial.run(HEAD_SUMMARY)
    summary = tutorial.summary("simulate")
    assert summary["status"] == "CONVERGED" and summary["counts"]["vertices"] == 609
    printed = tutorial.run(READ_TRAJECTORY).splitlines()
    # The bracket rests on the support: pairs active, gap below dhat, and the support carries
    # about 1.9 times the 1e4 N load (a propped cantilever with the load 0.3 m beyond the prop).
    deflection = numbers(printed[1])[0]
    gaps, pairs = numbers(printed[2])[:2], numbers(printed[2])[2:]
    force = numbers(printed[3])
    assert -0.03 < deflection < -0.02
    assert all(0 < g < 0.001 for g in gaps) and all(p >= 1 for p in pairs)
    assert 1.8e4 < force[1] < 1.95e4 and abs(force[0]) < 0.05 * force[1]


def test_step_2_gradcheck(tutorial):
    for command in (GRADCHECK, GRADCHECK_STRESS):
        printed = tutorial.run(command)
        assert printed.count("PASS") == 2 and "gradcheck passed" in printed
        assert "1170 parameters (shape x 1170)" in printed


def test_step_3_optimize_and_its_outputs(tutorial):
    tutorial.run(OPTIMIZE)
    out = tutorial.path("output", "tutorial", "optimize")
    summary = tutorial.summary("optimize")
    assert summary["stop_reason"] == "gradient_tolerance"
    assert (summary["iterations"], summary["evaluations"], summary["rejected"]) == (11, 12, 0)
    assert 0.31 < 1 - summary["final_J"] / summary["initial_J"] < 0.33        # "falls by 32%"
    assert summary["max_violation"] == 0
    design = np.array(summary["design"])
    assert np.sum(np.isclose(design, -0.1, atol=1e-8)) == 2 and np.sum(np.isclose(design, 0.1, atol=1e-8)) == 3
    rows = tutorial.history("optimize")
    assert [int(r["iteration"]) for r in rows] == list(range(12))
    J = [float(r["J"]) for r in rows]
    assert J[-1] < J[0] and float(rows[1]["area"]) < 0.08                      # the area dips, then returns
    assert all(float(r["area"]) <= 0.08 * (1 + 1e-6) for r in rows)            # feasible at every iterate
    assert all(b <= a * (1 + 1e-12) for a, b in zip(J, J[1:]))                 # J decreases here at every step
    for name in ["history.h5", "history.csv", "designs.pvd", "design_final.vtu", "optimal_problem.json",
                 "initial_problem.json", "optimizer_state.h5"] + [f"design_{k}.vtu" for k in range(12)]:
        assert (out / name).is_file(), name
    optimal = json.loads((out / "optimal_problem.json").read_text())
    assert optimal["parameters"][0]["initial"] == summary["design"]
    tutorial.run(CAT_SUMMARY)
    tutorial.run(READ_HISTORY)
    depths = [numbers(line)[-1] for line in tutorial.run(DEPTHS).splitlines()]
    assert depths[-1] == pytest.approx(0.1, abs=5e-5)                          # the end face keeps its depth
    assert all(0.05 - 5e-5 <= d <= 0.15 + 5e-5 for d in depths)
    assert max(depths) == depths[5]                                            # deepest over the support
    # The figures.
    tutorial.run(PLOT, timeout=300)
    for name in ("convergence.png", "constraints.png", "objective_over_time.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10000, name


def test_step_3_stop_and_resume(tutorial):
    tutorial.run(STOP)
    stopped = tutorial.summary("stopped")
    assert (stopped["stop_reason"], stopped["iterations"]) == ("iteration_budget", 4)
    tutorial.run(RESUME)
    resumed = tutorial.summary("stopped")
    assert resumed["stop_reason"] == "gradient_tolerance" and resumed["resumed_at_iteration"] == 4
    assert resumed["iterations"] == 12 and resumed["max_violation"] == 0
    rows = tutorial.history("stopped")
    assert [int(r["iteration"]) for r in rows] == list(range(13))
    assert float(rows[5]["area"]) > 0.08                                       # "leaves the area limit for a moment"
    assert resumed["final_J"] == pytest.approx(157.50010974532523, rel=1e-10)   # the uninterrupted run's
    assert resumed["final_J"] < resumed["initial_J"]
    # A converged run is not resumed: exit 0, nothing changes (the page's second resume).
    before = {p.name: p.stat().st_mtime_ns for p in tutorial.path("output", "tutorial", "stopped").iterdir()}
    assert "nothing to resume" in tutorial.run(RESUME, occurrence=1)
    after = {p.name: p.stat().st_mtime_ns for p in tutorial.path("output", "tutorial", "stopped").iterdir()}
    assert before == after


def test_step_3_stress_objective(tutorial):
    tutorial.run(OPTIMIZE_STRESS)
    summary = tutorial.summary("stress")
    assert summary["stop_reason"] == "gradient_tolerance" and summary["max_violation"] == 0
    assert 0.32 < 1 - summary["final_J"] / summary["initial_J"] < 0.35       # "falls by a third"


def test_step_3_remesh(tutorial):
    tutorial.run(OPTIMIZE_REMESH, across_machines=ACROSS_MACHINES_AFTER_A_REMESH)
    out = tutorial.path("output", "tutorial", "remesh")
    summary = tutorial.summary("remesh")
    assert summary["stop_reason"] == "gradient_tolerance" and summary["max_violation"] == 0
    assert summary["final_J"] < summary["initial_J"]
    (remesh,) = summary["remeshes"]
    assert remesh["iteration"] == 1 and remesh["quality_before"] < 0.8 < remesh["quality_after"]
    assert 0.03 < remesh["J_after"] / remesh["J_before"] - 1 < 0.04             # "J jumps by 3.5%"
    assert remesh["constraints_after"][0] == pytest.approx(remesh["constraints_before"][0], rel=1e-12)
    # Two attempts: the next waits for min(threshold 0.8, 0.9 x the new mesh's worst quality); a later
    # iterate fell below it, gmsh's mesh of it was worse, so the run kept its mesh, said why, and
    # lowered the trigger to 0.9 x that iterate's quality ("kept its mesh, recorded why").
    attempts = json.loads((out / "remeshes.json").read_text())
    assert attempts["attempts"] == 2
    failure = summary["remesh_failure"]
    assert "is not above the old one's" in failure and "kept the old mesh" in failure, failure
    old = float(re.search(r"the old one's ([0-9.]+)", failure).group(1))
    assert old < min(0.8, 0.9 * remesh["quality_after"])
    assert attempts["trigger"] == pytest.approx(0.9 * old, rel=1e-5)           # old is printed to 6 digits
    for name in ("remesh_1_body0.msh", "current_problem.json", "design_final.vtu"):
        assert (out / name).is_file(), name
    tutorial.run(READ_REMESHES, across_machines=ACROSS_MACHINES_AFTER_A_REMESH)
    tutorial.run(OPTIMIZE)
    printed = [numbers(line)[-1] for line in
               tutorial.run(FINE_MESH, across_machines=ACROSS_MACHINES_AFTER_A_REMESH).splitlines()]
    structured, remeshed, start = printed
    assert abs(structured / remeshed - 1) < 2e-4                                # "differ by 0.012%"
    coarse = tutorial.summary("optimize")["initial_J"]
    assert 0.03 < 1 - coarse / start < 0.04                                     # "about 3% too stiff"


def test_step_4_python(tutorial):
    printed = tutorial.run(TAYLOR).splitlines()
    assert float(printed[-1]) > 1.9                                             # second-order convergence
    gradient = numbers(printed[1])[1:]
    assert len(gradient) == 8 and all(g < 0 for g in gradient)
    tutorial.run(OPTIMIZE)
    cli_summary = tutorial.summary("optimize")
    cli_J = [float(r["J"]) for r in tutorial.history("optimize")]
    # scipy's SLSQP reaches the CLI run's optimum.
    printed = tutorial.run(SCIPY).splitlines()
    assert "successfully" in printed[0]
    J0, J, area = numbers(printed[1])[:3]
    assert J == pytest.approx(cli_summary["final_J"], rel=1e-7) and area <= 0.08 * (1 + 1e-9) and J < J0
    # diffipc.minimize with Ipopt takes the CLI run's iterates.
    printed = tutorial.run(MINIMIZE).splitlines()
    rows = [l for l in printed if re.match(r"^\s*\d+\s+J ", l)]
    assert [int(l.split()[0]) for l in rows] == list(range(len(cli_J)))
    assert [float(l.split()[2]) for l in rows] == pytest.approx(cli_J, rel=1e-12, abs=5.1e-7)   # printed to 1e-6
    assert printed[len(rows)].startswith("gradient_tolerance:")
    assert numbers(printed[len(rows) + 1])[1] == pytest.approx(cli_summary["final_J"], rel=1e-12, abs=5.1e-7)
