"""Study 406 (studies/406_cantilever_3d_remesh): a short run that remeshes a 3D cantilever
during Ipopt's optimization of its free-form deformation. The remesh keeps the variables and
the iteration count, changes J and the volume by a discretization amount only, and every
written design has positive tetrahedron volumes (computed here from the VTU's coordinates)."""
import csv
import json
import subprocess

import pytest

from conftest import ROOT
from design_checks import tet_volumes


def test_study_406_short(cli, tmp_path):
    meshio = pytest.importorskip("meshio")
    p = json.loads((ROOT / "studies" / "406_cantilever_3d_remesh" / "problem.json").read_text())
    # Remesh a little earlier than the study. gmsh's mesh depends on the design to its last
    # bits, and so on the solver's round-off (measured: after iteration 10, 0.392 -> 0.444 with
    # one build; with the next one's tiled Cholesky a refused attempt at iteration 10, 0.356 not
    # above 0.392, then after iteration 12, 0.337 -> 0.346).
    p["remesh"]["quality"] = 0.4
    p["optimizer"]["max_iterations"] = 16  # a few iterations on the new mesh
    p["output"] = {"design_every": 1}
    problem = tmp_path / "problem.json"
    problem.write_text(json.dumps(p))
    out = tmp_path / "out"
    r = subprocess.run([cli, "optimize", problem, "-o", out], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert len(s["remeshes"]) == 1, (s.get("remesh_failure"), r.stdout[-2000:])
    rm = s["remeshes"][0]
    # The trigger fired, and the new mesh was kept only because it is better (docs/remeshing.md).
    assert rm["quality_before"] < 0.4
    assert rm["quality_after"] > rm["quality_before"]
    # Discretization tolerances (README: at the study's remesh the structured mesh is 3.6% too
    # stiff against a fine reference, the new one 1.2%; measured here: J +2.0%, volume +0.0045%
    # with one build, J +2.3%, volume +0.0065% with the next):
    # J within 4%, the volume within 0.1% (chords of the new surface triangles).
    assert rm["J_after"] == pytest.approx(rm["J_before"], rel=0.04)
    assert rm["constraints_after"][0] == pytest.approx(rm["constraints_before"][0], rel=1e-3)
    rows = list(csv.DictReader((out / "history.csv").open()))
    assert [int(row["iteration"]) for row in rows] == list(range(s["iterations"] + 1))
    J = [float(row["J"]) for row in rows]
    assert J[-1] < 0.75 * J[0]
    assert J[-1] < rm["J_after"]  # it goes on improving on the new mesh
    assert s["max_violation"] <= 1e-6
    counts = set()
    for row in rows:
        m = meshio.read(out / f"design_{row['iteration']}.vtu")
        cells = m.cells_dict["tetra"]
        assert tet_volumes(m.points, cells).min() > 0, row["iteration"]
        counts.add(len(cells))
    assert counts == {rm["elements_before"], rm["elements_after"]}
    m = meshio.read(out / "design_final.vtu")
    assert tet_volumes(m.points, m.cells_dict["tetra"]).sum() <= 0.045 * (1 + 1e-6)
