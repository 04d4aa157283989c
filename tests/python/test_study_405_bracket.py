"""Study 405 (studies/405_bracket_contact): a half bridge girder resting on a roller by IPC
contact, its top edge shaped to lower the von Mises stress p-norm under a rest-area limit.
Short runs of both problem files through `diffipc optimize`, with checks made here from the
written files: every design_*.vtu is a valid rest mesh with the bottom edge and the x of
every vertex unchanged, the area holds (true constraint), the optimal problem evaluates to
final_J, and at the final design the roller really carries the bridge (the design is
simulated again from its VTU: converged, contact pairs active, contact force = weight, and
the objective recomputed from that run's element stresses)."""
import csv
import importlib.util
import json
import subprocess
import sys

import numpy as np
import pytest

import diffipc
from conftest import ROOT
from design_checks import boundary_edges, crossing, triangle_areas

STUDY = ROOT / "studies" / "405_bracket_contact"
AREA_BOUND = 0.15


def run(cli, *args, timeout=120):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def check_design_module():
    spec = importlib.util.spec_from_file_location("check_design_405", STUDY / "check_design.py")
    module = importlib.util.module_from_spec(spec)
    dont_write = sys.dont_write_bytecode
    sys.dont_write_bytecode = True  # no __pycache__ in the study folder
    try:
        spec.loader.exec_module(module)
    finally:
        sys.dont_write_bytecode = dont_write
    return module


def short_problem(tmp_path, name, iterations=6):
    p = json.loads((STUDY / f"{name}.json").read_text())
    p["optimizer"]["max_iterations"] = iterations
    p["output"]["design_every"] = 1
    roller = p["scene"]["obstacles"][0]["mesh"]
    roller["file"] = str(STUDY / roller["file"])  # the copy lives in tmp_path
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(p))
    return p, path


@pytest.mark.parametrize("name", ["problem", "problem_penalty"])
def test_study_405_short(cli, tmp_path, name):
    meshio = pytest.importorskip("meshio")
    problem, path = short_problem(tmp_path, name)
    out = tmp_path / "out"
    r = run(cli, "optimize", path, "-o", out, "-q")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["stop_reason"] in ("iteration_budget", "gradient_tolerance"), summary
    assert summary["rejected"] == 0, summary
    # Six iterations lower the stress p-norm by more than 10%: on the 120 x 18 mesh to 0.787 x J0
    # (Ipopt) and 0.878 x J0 (penalty 1e10, L-BFGS-B), the full runs to 0.781 x J0 (README).
    assert summary["final_J"] < 0.9 * summary["initial_J"], summary
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert len(rows) == summary["iterations"] + 1 and rows[0]["iteration"] == "0"
    assert float(rows[0]["J"]) == pytest.approx(summary["initial_J"], rel=1e-12)
    assert float(rows[-1]["J"]) == pytest.approx(summary["final_J"], rel=1e-12)

    # Every written rest design is valid and moves only the top: the bottom edge (which
    # rests on the roller) and every vertex's x stay where the box mesh put them.
    rest = diffipc.scene(problem["scene"], base_directory=str(STUDY))
    nb = int((np.asarray(rest.vertex_body) == 0).sum())
    X0 = np.asarray(rest.rest_positions)[:nb]
    designs = sorted(out.glob("design_*.vtu"))
    assert len(designs) == summary["iterations"] + 2  # design_0 .. design_<n> and design_final
    for design in designs:
        m = meshio.read(design)
        points, cells = m.points[:, :2], m.cells_dict["triangle"]
        assert points.shape == X0.shape, design
        assert (triangle_areas(points, cells) > 0).all(), design
        assert not crossing(points, boundary_edges(cells)), design
        np.testing.assert_array_equal(points[:, 0], X0[:, 0], err_msg=str(design))
        bottom = X0[:, 1] == 0
        np.testing.assert_array_equal(points[bottom, 1], 0.0, err_msg=str(design))
    final = meshio.read(out / "design_final.vtu")
    area = triangle_areas(final.points[:, :2], final.cells_dict["triangle"]).sum()
    assert np.max(np.abs(final.points[:, 1] - X0[:, 1])) > 0.01  # the shape changed
    if name == "problem":
        assert summary["max_violation"] <= 1e-6
        assert area <= AREA_BOUND * (1 + 1e-6), area
        assert float(rows[-1]["area"]) == pytest.approx(area, rel=1e-9)

    # The optimal problem starts from the optimum: its J is the final J.
    J = diffipc.ReducedFunctional(str(out / "optimal_problem.json"))
    np.testing.assert_allclose(J.design_initial, summary["design"], rtol=0, atol=0)
    value, _ = J.evaluate(J.parameters_of(J.design_initial), gradient=False)
    assert value == pytest.approx(summary["final_J"], rel=1e-10)

    # The final design simulated again from its VTU (a gmsh mesh in place of the box): the
    # roller carries the whole weight through active contact pairs, and the stress p-norm
    # recomputed from that run's per-element von Mises stress is the optimizer's J (plus the
    # penalty, recomputed from the VTU's area, for the penalty form).
    report = check_design_module().check(path, out / "design_final.vtu", cli)
    assert report["valid"] and report["status"] == "CONVERGED", report
    assert report["area"] == pytest.approx(area, rel=1e-12)
    assert report["active_contacts"] >= 1 and 0 < report["min_gap"] < report["dhat"], report
    assert report["contact_force_y"] == pytest.approx(report["weight"], rel=1e-6), report
    assert all(0.05 <= x <= 0.15 for x in report["contact_x"]) and report["contact_x"], report  # on the roller
    # The largest element stress is the larger of the two parts that check_design.py splits
    # it into (over the roller, elsewhere), and the roller's share of the p-norm's sum is a share.
    assert max(report["max_von_mises_over_roller"], report["max_von_mises_off_roller"]) == report["max_von_mises"]
    assert 0 < report["p_norm_sum_share_over_roller"] < 1, report
    stress = report["stress_p_norm"]
    if name == "problem_penalty":
        weight = problem["objective"]["terms"][1]["weight"]
        stress += weight * max(0.0, area - AREA_BOUND) ** 2
    assert stress == pytest.approx(summary["final_J"], rel=1e-8), (stress, summary["final_J"])
