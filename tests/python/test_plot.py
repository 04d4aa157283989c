"""diffipc.plot (docs/python.md): the figures of a short `diffipc optimize` run of study 401 are
valid PNGs that draw exactly what history.csv, summary.json and the problem say; the objective
over time reproduces the run's J and an independent aggregation of the same states; the design
figure's von Mises stresses agree with closed forms and with the VTU frames of `diffipc simulate`,
on one colour scale; bad directories and files are errors naming them."""
import csv
import json
import math
import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import diffipc  # noqa: E402
from diffipc import plot  # noqa: E402
from conftest import ROOT  # noqa: E402

STUDY = ROOT / "studies" / "401_cantilever_area"


def optimize(cli, tmp_path, name="problem", iterations=4, edit=None):
    """A short run of study 401 into tmp_path/o; returns (output directory, problem path)."""
    p = json.loads((STUDY / f"{name}.json").read_text())
    p["optimizer"]["max_iterations"] = iterations
    p["output"]["design_every"] = 0
    if edit:
        edit(p)
    problem = tmp_path / f"{name}.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "o"
    r = subprocess.run([cli, "optimize", str(problem), "-o", str(out), "-q"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return out, problem


def history_columns(out):
    """history.csv read here with the csv module, independently of diffipc.plot's reader."""
    rows = list(csv.DictReader((out / "history.csv").open()))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def png_size(path):
    """Width and height from the PNG's IHDR chunk, after checking the signature and its CRC."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    length, kind = struct.unpack(">I4s", data[8:16])
    assert kind == b"IHDR" and length == 13
    body = data[16:16 + 13]
    assert struct.unpack(">I", data[29:33])[0] == zlib.crc32(kind + body)
    return struct.unpack(">II", body[:8])


def check_png(result):
    path = result.path if hasattr(result, "path") else result
    import pathlib

    path = pathlib.Path(path)
    assert path.is_file() and path.stat().st_size > 10_000, path
    width, height = png_size(path)
    inches = result.figure.get_size_inches()
    assert (width, height) == (round(inches[0] * 110), round(inches[1] * 110))
    from matplotlib.image import imread

    pixels = imread(path)  # decodes every row: a truncated or corrupt file fails here
    assert pixels.shape[:2] == (height, width)
    assert pixels[..., :3].std() > 0.05  # not a blank canvas


def line(ax, label):
    found = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(found) == 1, [ln.get_label() for ln in ax.get_lines()]
    return np.asarray(found[0].get_xdata(), dtype=float), np.asarray(found[0].get_ydata(), dtype=float)


def test_convergence_draws_the_history(cli, tmp_path):
    out, _ = optimize(cli, tmp_path)
    h = history_columns(out)
    summary = json.loads((out / "summary.json").read_text())
    assert len(h["J"]) == summary["iterations"] + 1 >= 3

    result = plot.plot_convergence(out)
    assert result.path == os.path.join(str(out), "convergence.png")
    check_png(result)
    ax_j, ax_gap, ax_norm = result.figure.axes
    x, y = line(ax_j, "J")
    np.testing.assert_array_equal(x, h["iteration"])
    np.testing.assert_array_equal(y, h["J"])
    assert y[0] == summary["initial_J"] and y[-1] == summary["final_J"]
    x, y = line(ax_norm, "gradient norm (J / |J(x0)|)")
    np.testing.assert_array_equal(y, h["gradient_norm"])
    # The step norm of iteration 0 is 0: a log axis cannot show it, so it is left out.
    assert h["step_norm"][0] == 0
    x, y = line(ax_norm, "step norm")
    np.testing.assert_array_equal(x, h["iteration"][1:])
    np.testing.assert_array_equal(y, h["step_norm"][1:])
    gap = np.abs(h["J"] - h["J"][-1]) / abs(h["J"][-1])
    x, y = ax_gap.get_lines()[0].get_xdata(), ax_gap.get_lines()[0].get_ydata()
    np.testing.assert_array_equal(x, h["iteration"][:-1])
    np.testing.assert_allclose(y, gap[:-1], rtol=1e-15)
    assert ax_gap.get_yscale() == "log" and ax_norm.get_yscale() == "log"
    assert ax_j.get_yscale() == "linear"  # J falls by 4.9% in these 4 iterations: a log axis would hide it


def test_constraints_draw_values_bounds_and_violations(cli, tmp_path):
    out, problem = optimize(cli, tmp_path)
    h = history_columns(out)
    bound = json.loads(problem.read_text())["constraints"][0]["upper"]
    assert bound == 0.2
    result = plot.plot_constraints(out)
    check_png(result)
    ax_g, ax_v = result.figure.axes
    x, y = line(ax_g, "area (g)")
    np.testing.assert_array_equal(x, h["iteration"])
    np.testing.assert_array_equal(y, h["area"])
    _, y = line(ax_g, "bound: g <= 0.2")
    assert set(y) == {bound}
    expected = np.maximum(0.0, (h["area"] - bound) / bound)
    assert expected.max() > 1e-6  # Ipopt's first iterate of this run is infeasible: the check sees a violation
    _, y = line(ax_v, "area")
    np.testing.assert_allclose(y, expected, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(result.data["area violation"], y)
    _, y = line(ax_v, "constraint_tolerance 1e-06")
    assert set(y) == {1e-6}


def test_violations_follow_the_optimizers_scaling():
    g = np.array([-1.0, 0.0, 0.5, 3.0])
    np.testing.assert_allclose(plot.violations(g, "upper", 2.0), [0, 0, 0, 0.5])
    np.testing.assert_allclose(plot.violations(g, "lower", 2.0), [1.5, 1.0, 0.75, 0])
    np.testing.assert_allclose(plot.violations(g, "equals", -2.0), [0.5, 1.0, 1.25, 2.5])
    np.testing.assert_allclose(plot.violations(g, "upper", 0.0), [0, 0, 0.5, 3.0])  # |b| = 0 -> 1
    with pytest.raises(ValueError, match="constraint kind"):
        plot.violations(g, "below", 1.0)


def test_objective_over_time_reproduces_the_run(cli, tmp_path):
    out, problem = optimize(cli, tmp_path)
    h = history_columns(out)
    summary = json.loads((out / "summary.json").read_text())
    result = plot.plot_objective_over_time(out, problem=problem, refine=4)
    check_png(result)
    c = result.data
    assert c["kind"] == "per_state" and c["objective"] == "compliance" and c["unit"] == "J"
    # The scene: 2 static steps of dt = 0.5; the objective: the compliance at the final state.
    np.testing.assert_array_equal(c["steps"], [1, 2])
    np.testing.assert_array_equal(c["time"], [0.5, 1.0])
    assert c["initial"][-1] == pytest.approx(h["J"][0], rel=1e-12)
    assert c["optimal"][-1] == pytest.approx(summary["final_J"], rel=1e-12)
    assert c["check"]["initial"][1] == h["J"][0] and c["check"]["optimal"][1] == summary["final_J"]
    # Independently: the same problem with time "sum" in one full run of each design is f_1 + f_2.
    p = json.loads(problem.read_text())
    p["objective"]["time"] = "sum"
    for key in ("constraints", "optimizer", "output"):
        p.pop(key)
    J = diffipc.ReducedFunctional(p, base_directory=tmp_path)
    for name, x in (("initial", J.design_initial), ("optimal", np.array(summary["design"]))):
        total, _ = J.evaluate(J.parameters_of(x), gradient=False)
        assert c[name].sum() == pytest.approx(total, rel=1e-10), name
    # The load grows: compliance at half the load is below that at the full load, and the
    # optimal design is stiffer at both load levels.
    assert (np.diff(c["initial"]) > 0).all() and (c["optimal"] < c["initial"]).all()
    # refine=4: 8 states at dt / 4 that pass through the problem's two states.
    np.testing.assert_allclose(c["fine_time"], np.arange(1, 9) * 0.125)
    np.testing.assert_allclose(c["fine_initial"][[3, 7]], c["initial"], rtol=1e-7)
    np.testing.assert_allclose(c["fine_optimal"][[3, 7]], c["optimal"], rtol=1e-7)
    assert c["fine_difference"] < 1e-7
    ax = result.figure.axes[0]
    x, y = line(ax, "initial design, the problem's states")
    np.testing.assert_array_equal(x, c["time"])
    np.testing.assert_array_equal(y, c["initial"])
    _, y = line(ax, "optimal design, dt / 4")
    np.testing.assert_array_equal(y, c["fine_optimal"])


def test_objective_over_time_refuses_another_start(cli, tmp_path):
    # A problem whose start is not the run's: the curve would not be the run's, and the check says so.
    out, problem = optimize(cli, tmp_path)
    p = json.loads(problem.read_text())
    p["parameters"][0]["initial"] = 0.01
    other = tmp_path / "other.json"
    other.write_text(json.dumps(p))
    with pytest.raises(RuntimeError, match="the initial design's J recomputed"):
        plot.objective_over_time(out, problem=other)
    with pytest.raises(ValueError, match="refine: must be at least 1"):
        plot.objective_over_time(out, problem=problem, refine=0)
    with pytest.raises(ValueError, match="nope.json: problem file not found"):
        plot.objective_over_time(out, problem=tmp_path / "nope.json")


def test_tracking_objective_contributions_sum_to_J(cli, tmp_path):
    # Study 302's markers at steps 2 and 4 of a dynamic bar: one contribution per listed state.
    p = json.loads((ROOT / "studies" / "302_bar_youngs_markers" / "problem.json").read_text())
    p["scene"] = str(ROOT / "studies" / "302_bar_youngs_markers" / p["scene"]) if isinstance(p["scene"], str) \
        else p["scene"]
    p.pop("gradcheck", None)
    p["optimizer"] = {"algorithm": "lbfgsb", "max_iterations": 2}
    problem = tmp_path / "bar.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "o"
    r = subprocess.run([cli, "optimize", str(problem), "-o", str(out), "-q"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    c = plot.objective_over_time(out, problem=problem)
    assert c["kind"] == "contributions"
    np.testing.assert_array_equal(c["steps"], p["objective"]["steps"])
    summary = json.loads((out / "summary.json").read_text())
    assert c["initial"].sum() == pytest.approx(summary["initial_J"], rel=1e-10)
    assert c["optimal"].sum() == pytest.approx(summary["final_J"], rel=1e-10)
    assert (c["initial"] > 0).all()
    with pytest.raises(ValueError, match="refine: applies to per-state objectives"):
        plot.objective_over_time(out, problem=problem, refine=2)


def test_plot_run_skips_what_does_not_apply(cli, tmp_path):
    # The penalty version: no constraints, and a `sum` objective, which has no per-state curve.
    out, problem = optimize(cli, tmp_path, name="problem_penalty")
    lines = []
    plots = plot.plot_run(out, problem=problem, printer=lines.append)
    assert [os.path.basename(p.path) for p in plots] == ["convergence.png"]
    assert not (out / "constraints.png").exists() and not (out / "objective_over_time.png").exists()
    assert any("constraints.png: not written (the run has no constraints)" in s for s in lines), lines
    assert any("objective_over_time.png: not written" in s and "type 'sum'" in s for s in lines), lines
    with pytest.raises(ValueError, match="has no constraints"):
        plot.plot_constraints(out)


def test_module_command_writes_and_prints_the_figures(cli, tmp_path):
    out, _ = optimize(cli, tmp_path)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    # summary.json's problem path is the one given to diffipc optimize (absolute here).
    r = subprocess.run([sys.executable, "-m", "diffipc.plot", str(out), "--refine", "2"], capture_output=True,
                       text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    printed = r.stdout.splitlines()
    for name in ("convergence.png", "constraints.png", "objective_over_time.png"):
        assert str(out / name) in printed, r.stdout
        assert (out / name).stat().st_size > 10_000
    assert "relative difference to the run's J" in r.stdout
    assert "Traceback" not in r.stderr
    r = subprocess.run([sys.executable, "-m", "diffipc.plot", str(tmp_path / "missing")], capture_output=True,
                       text=True, timeout=120, env=env)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stderr.strip() == f"diffipc.plot: {tmp_path / 'missing'}: not a directory (expected the output " \
                               "of `diffipc optimize -o DIR`)"


def copy_run(out, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(out, bad)
    return bad


def test_bad_directories_name_the_file(cli, tmp_path):
    out, _ = optimize(cli, tmp_path, iterations=1)
    with pytest.raises(ValueError, match="nowhere: not a directory"):
        plot.plot_convergence(tmp_path / "nowhere")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match=r"empty/history.csv: missing"):
        plot.plot_convergence(empty)

    bad = copy_run(out, tmp_path)
    text = (bad / "history.csv").read_text().splitlines()
    (bad / "history.csv").write_text("\n".join(text[:1] + [text[1].replace(text[1].split(",")[1], "abc", 1)]) + "\n")
    with pytest.raises(ValueError, match=r"bad/history.csv line 2: column 'J': not a number: 'abc'"):
        plot.plot_convergence(bad)
    (bad / "history.csv").write_text("\n".join(text[:1]) + "\n")
    with pytest.raises(ValueError, match=r"history.csv: no iteration rows"):
        plot.plot_convergence(bad)
    (bad / "history.csv").write_text("\n".join(["iteration,J,area"] + text[1:]) + "\n")
    with pytest.raises(ValueError, match=r"history.csv: header 'iteration,J,area' is not"):
        plot.plot_convergence(bad)
    (bad / "history.csv").write_text("\n".join(text[:2] + [text[1]]) + "\n")
    with pytest.raises(ValueError, match=r"history.csv: column 'iteration' must count 0, 1, 2"):
        plot.plot_convergence(bad)
    (bad / "history.csv").write_text("\n".join(text) + "\n")
    (bad / "summary.json").write_text("{not json")
    with pytest.raises(ValueError, match=r"bad/summary.json: not readable as JSON"):
        plot.plot_convergence(bad)
    (bad / "summary.json").write_text((out / "summary.json").read_text())
    problem = json.loads((bad / "optimal_problem.json").read_text())
    problem["constraints"][0]["name"] = "mass"
    (bad / "optimal_problem.json").write_text(json.dumps(problem))
    with pytest.raises(ValueError, match=r"optimal_problem.json: constraints\[0\].name: 'mass' is not history.csv's"):
        plot.plot_constraints(bad)
    (bad / "optimal_problem.json").unlink()
    with pytest.raises(ValueError, match=r"optimal_problem.json: missing; history.csv has constraint columns \(area\)"):
        plot.plot_constraints(bad)


def test_readme_first_command_runs_the_optimization_and_plots(cli, tmp_path):
    # README's first command is scripts/run_example.sh; here it runs on this build (the two
    # variables skip install and build) in a copy holding the script and study 401.
    import re
    import shutil

    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## The two commands"):]
    assert re.search(r"\n    (\S.*)\n", section).group(1) == "bash scripts/run_example.sh"
    (tmp_path / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "run_example.sh", tmp_path / "scripts")
    shutil.copytree(STUDY, tmp_path / "studies" / STUDY.name)
    env = dict(os.environ, DIFFIPC_CLI=cli, DIFFIPC_PYTHONPATH=os.path.dirname(os.path.dirname(diffipc.__file__)))
    r = subprocess.run(["bash", str(tmp_path / "scripts" / "run_example.sh")], capture_output=True, text=True,
                       timeout=600, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr
    out = tmp_path / "output" / "401_cantilever_area"
    assert f"== results in {out}/" in r.stdout
    listed = re.findall(r"^  (\S+\.(?:json|csv|png|pvd)) ", r.stdout, flags=re.M)
    assert len(listed) == 8 and "design.png" in listed, r.stdout
    for name in listed:
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["final_J"] < summary["initial_J"] and summary["max_violation"] <= 1e-6
    assert re.search(r"optimize \+ plot: \d+\.\d s wall", r.stdout)
    env.pop("DIFFIPC_PYTHONPATH")
    r = subprocess.run(["bash", str(tmp_path / "scripts" / "run_example.sh")], capture_output=True, text=True,
                       timeout=60, env=env)
    assert r.returncode == 1 and "set both DIFFIPC_CLI and DIFFIPC_PYTHONPATH" in r.stderr


def simple_shear_von_mises(mu, g):
    """Neo-Hookean under simple shear F = I + g e_x e_y^T (det F = 1): sigma = mu (F F^T - I),
    whose von Mises stress (in-plane in 2D, the full one in 3D: sigma_zz = 0 both) is
    mu sqrt(g^4 + 3 g^2)."""
    return mu * math.sqrt(g**4 + 3 * g**2)


@pytest.mark.parametrize("dim", [2, 3])
def test_von_mises_of_homogeneous_deformations_matches_closed_forms(dim):
    # The C++ stresses that the VTU frames and design.png show (Simulator.element_von_mises), on a
    # small box mesh whose element edges are not all along the axes.
    sc = diffipc.scene(box_scene_of(dim))
    rest, elements = np.asarray(sc.rest_positions), np.asarray(sc.elements)
    sim = diffipc.Simulator(sc)
    mu, lam = diffipc.lame_parameters(2e5, 0.3)
    g = 0.3
    F = np.eye(dim)
    F[0, 1] = g
    vm = sim.element_von_mises(rest @ F.T)
    assert vm.shape == (len(elements),)
    np.testing.assert_allclose(vm, simple_shear_von_mises(mu, g), rtol=1e-10)
    # A stretch diag(a, b[, c]): sigma = (mu (F F^T - I) + lam log J I) / J, principal and
    # diagonal; von Mises sqrt(1/2 sum_{i<j} (s_i - s_j)^2) (2D: with s_z = 0 in the sum).
    stretch = np.array([1.2, 0.9, 1.05])[:dim]
    J = np.prod(stretch)
    s_p = (mu * (stretch**2 - 1) + lam * math.log(J)) / J
    full = np.concatenate([s_p, [0.0]]) if dim == 2 else s_p
    expected = math.sqrt(0.5 * sum((full[i] - full[j]) ** 2 for i in range(3) for j in range(i + 1, 3)))
    np.testing.assert_allclose(sim.element_von_mises(rest * stretch), expected, rtol=1e-10)
    # Per-element materials are taken element by element; a rigid rotation is stress free.
    E = np.full(len(elements), 2e5)
    E[0] *= 2
    other = diffipc.Simulator(sc)
    other.set_element_materials(E, np.full(len(elements), 0.3))
    vm = other.element_von_mises(rest @ F.T)
    assert vm[0] == pytest.approx(2 * vm[1], rel=1e-10)
    c, s_ = math.cos(0.7), math.sin(0.7)
    R = np.eye(dim)
    R[:2, :2] = [[c, -s_], [s_, c]]
    assert np.abs(sim.element_von_mises(rest @ R.T)).max() < 1e-6 * mu
    with pytest.raises(ValueError, match=r"positions: expected an array of shape"):
        sim.element_von_mises(rest[:-1])


@pytest.mark.parametrize("plane_stress", [False, True])
def test_young_poisson_of_lame_inverts_lame_parameters(plane_stress):
    E, nu = np.array([2e5, 7e9, 1.5]), np.array([0.3, -0.2, 0.45])
    lame = np.array([diffipc.lame_parameters(e, n, plane_stress) for e, n in zip(E, nu)])
    E2, nu2 = diffipc.young_poisson_of_lame(lame[:, 0], lame[:, 1], plane_stress=plane_stress)
    np.testing.assert_allclose(E2, E, rtol=1e-12)
    np.testing.assert_allclose(nu2, nu, rtol=1e-12)
    with pytest.raises(ValueError, match="mu"):
        diffipc.young_poisson_of_lame([-1.0], [1.0])


def box_scene_of(dim):
    hi = [0.3, 0.2] if dim == 2 else [0.3, 0.2, 0.1]
    return {"dimension": dim,
            "bodies": [{"name": "b", "mesh": {"box": {"min": [0.0] * dim, "max": hi, "cells": [3, 2, 1][:dim]}},
                        "material": {"model": "neo_hookean", "E": 2e5, "nu": 0.3, "density": 1000.0}}],
            "time": {"integrator": "static", "dt": 1.0, "steps": 1}}


def simulate_von_mises(cli, scene, tmp_path, name):
    """von_mises of the final frame of `diffipc simulate` (the VTU writer's, computed in C++)."""
    meshio = pytest.importorskip("meshio")
    s = json.loads(json.dumps(scene))
    s["output"] = {"vtu_every": 1, "hdf5": False}
    (tmp_path / f"{name}.json").write_text(json.dumps(s))
    r = subprocess.run([cli, "simulate", str(tmp_path / f"{name}.json"), "-o", str(tmp_path / name), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    steps = s["time"]["steps"]
    frame = meshio.read(tmp_path / name / f"frame_{steps}.vtu")
    return np.asarray(frame.cell_data["von_mises"][0], dtype=float).ravel(), frame


def test_design_png_shows_both_designs_on_one_colour_scale(cli, tmp_path):
    """design.png of a short run of study 401 (its designs written): two panels coloured by the
    von Mises stress at the final load with the same colour limits, J in the titles. The stresses
    are checked against `diffipc simulate`'s VTU frames: of the problem's own scene (box mesh) for
    the initial design, and of a scene on design_final.vtu written as a gmsh mesh by meshio for
    the optimal one."""
    meshio = pytest.importorskip("meshio")

    def designs(p):
        p["output"]["design_every"] = 1
    out, problem = optimize(cli, tmp_path, iterations=3, edit=designs)
    result = plot.plot_design(out)
    check_png(result)
    assert os.path.basename(result.path) == "design.png"
    d = result.data
    h = history_columns(out)
    summary = json.loads((out / "summary.json").read_text())
    assert d["J"] == (h["J"][0], summary["final_J"])
    # one colour scale: 0 to the larger maximum, on both panels, and one colour bar
    top = max(d["initial_von_mises"].max(), d["optimal_von_mises"].max())
    assert d["norm"] == (0.0, top)
    panels = [ax for ax in result.figure.axes if ax.collections and ax.get_title()]
    assert len(panels) == 2
    for ax, name, J in zip(panels, ("initial", "optimal"), d["J"]):
        (mesh,) = ax.collections
        assert mesh.get_clim() == d["norm"]
        np.testing.assert_array_equal(mesh.get_array(), d[f"{name}_von_mises"])
        assert ax.get_title().startswith(f"{name} design: J = {J:.6g}")
    assert len(result.figure.axes) == 3  # the two panels and the colour bar
    # the re-simulated scenes reproduce the run's J (their regions pick the run's vertices)
    for name, (again, written) in d["check"].items():
        assert again == pytest.approx(written, rel=1e-9), name
    # The initial design is the problem's own scene: its VTU frame's von Mises, element by element.
    scene = json.loads(problem.read_text())["scene"]
    reference, _ = simulate_von_mises(cli, scene, tmp_path, "initial")
    np.testing.assert_allclose(d["initial_von_mises"], reference, rtol=1e-6, atol=1e-9 * reference.max())
    # The optimal design: its rest mesh written by meshio as gmsh 2.2 (elements keep their order).
    design = meshio.read(out / "design_final.vtu")
    msh = tmp_path / "optimal.msh"
    meshio.write(msh, meshio.Mesh(design.points[:, :2], [("triangle", design.cells_dict["triangle"])]),
                 file_format="gmsh22", binary=False)
    scene["bodies"][0]["mesh"] = {"file": str(msh)}
    reference, _ = simulate_von_mises(cli, scene, tmp_path, "optimal")
    np.testing.assert_allclose(d["optimal_von_mises"], reference, rtol=1e-6, atol=1e-9 * reference.max())
    # a design whose re-simulation does not give the run's J is not drawn
    bad = copy_run(out, tmp_path)
    tampered = dict(summary, final_J=summary["final_J"] * 1.01)
    (bad / "summary.json").write_text(json.dumps(tampered))
    with pytest.raises(ValueError, match=r"design_final.vtu: J of the scene re-simulated on this design is "):
        plot.plot_design(bad)
    # plot_run draws it too; without design_0.vtu it says why it does not
    lines = []
    names = [os.path.basename(p.path) for p in plot.plot_run(out, problem=problem, printer=lines.append)]
    assert "design.png" in names
    (out / "design_0.vtu").unlink()
    lines = []
    names = [os.path.basename(p.path) for p in plot.plot_run(out, problem=problem, objective=False,
                                                               printer=lines.append)]
    assert "design.png" not in names
    assert any(s.startswith("design.png: not written (") and "design_0.vtu: missing" in s for s in lines), lines


def test_design_png_in_3d_draws_the_boundary_surface(cli, tmp_path):
    """A 3D run (a block's Young's modulus against its compliance, two iterations): each panel
    draws the block's boundary triangles that face the viewer (2 per face square of the 3 x 3 x 3
    box mesh on the three sides turned towards matplotlib's default view: 54), each coloured as
    its tetrahedron, on the shared colour scale; the initial design's stresses are those of
    `diffipc simulate`'s frame."""
    scene = {"dimension": 3,
             "bodies": [{"name": "block", "mesh": {"box": {"min": [0, 0, 0], "max": [0.04] * 3, "cells": [3, 3, 3]}},
                         "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
             "dirichlet": [{"body": "block", "region": {"min": [-1, -1, -1], "max": [1, 1e-6, 1]},
                            "displacement": [0, 0, 0]}],
             "neumann": [{"body": "block", "region": {"min": [-1, 0.04 - 1e-6, -1], "max": [1, 1, 1]},
                          "traction": ["2e3*t", 0, 0]}],
             "time": {"integrator": "static", "dt": 0.5, "steps": 2},
             "solver": {"residual_tolerance": 1e-10}}
    problem = {"scene": scene, "objective": {"type": "compliance"},
               "parameters": [{"type": "E", "per": "body", "lower": 5e4, "upper": 2e5}],
               "optimizer": {"algorithm": "lbfgsb", "max_iterations": 2},
               "output": {"design_every": 1}}
    (tmp_path / "problem.json").write_text(json.dumps(problem))
    out = tmp_path / "o"
    r = subprocess.run([cli, "optimize", str(tmp_path / "problem.json"), "-o", str(out), "-q"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    result = plot.plot_design(out)
    check_png(result)
    d = result.data
    panels = [ax for ax in result.figure.axes if ax.name == "3d"]
    assert len(panels) == 2
    for ax, name in zip(panels, ("initial", "optimal")):
        (surface,) = ax.collections
        assert surface.get_clim() == d["norm"]
        # the view (elevation 30, azimuth -60 degrees) looks at the sides +x, -y and +z
        eye = [math.cos(math.radians(ax.elev)) * math.cos(math.radians(ax.azim)),
               math.cos(math.radians(ax.elev)) * math.sin(math.radians(ax.azim)), math.sin(math.radians(ax.elev))]
        assert eye[0] > 0 and eye[1] < 0 and eye[2] > 0
        colours = np.asarray(surface.get_array())
        assert colours.shape == (3 * 9 * 2,)
        assert set(colours) <= set(d[f"{name}_von_mises"])
    reference, _ = simulate_von_mises(cli, scene, tmp_path, "initial")
    np.testing.assert_allclose(d["initial_von_mises"], reference, rtol=1e-6, atol=1e-9 * reference.max())
    assert d["optimal_von_mises"].max() > 0 and d["norm"][1] == max(d["initial_von_mises"].max(),
                                                                    d["optimal_von_mises"].max())
