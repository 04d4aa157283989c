"""Markers from a file (docs/objectives.md) on the real experiment of ../shared/data/material-id-cube:
the 24 scanned markers attach to the cube's mesh (at vertices or inside elements), and the
objective equals 1/2 sum |p_m - y_m|^2 with p_m interpolated here from a simulation's deformed mesh
(barycentric coordinates computed here, not by the code under test). A relative file path is
resolved against the problem file's folder, and a file in millimetres is refused."""
import json
import pathlib
import shutil

import numpy as np
import pytest

import diffipc
from conftest import ROOT

DATA = ROOT.parent / "shared" / "data" / "material-id-cube"
if not DATA.exists():
    DATA = pathlib.Path("/work/shared/data/material-id-cube")


def cube_problem(markers="markers.txt"):
    return {
        "scene": {
            "dimension": 3,
            "bodies": [{"name": "cube", "mesh": {"file": "cube.msh"}, "scale": 0.004,
                        "translation": [-0.02, -0.02, -0.02],
                        "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.45, "density": 1000}}],
            "dirichlet": [
                {"body": "cube", "region": {"min": [-1, -1, 0.0199], "max": [1, 1, 1]}, "displacement": [0, 0, "-0.0029*t"]},
                {"body": "cube", "region": {"min": [-1, -1, -1], "max": [1, 1, -0.0199]}, "displacement": [0, 0, "0.0034*t"]}],
            "time": {"integrator": "static", "dt": 0.5, "steps": 2},
            "solver": {"residual_tolerance": 1e-9},
        },
        "objective": {"type": "markers", "file": markers},
        "parameters": [{"type": "nu", "per": "body"}],
    }


@pytest.fixture
def cube_dir(tmp_path):
    if not (DATA / "cube.msh").exists():
        pytest.skip("the material-id-cube data is not here")
    for name in ("cube.msh", "markers.txt"):
        shutil.copy(DATA / name, tmp_path / name)
    return tmp_path


def interpolate(rest, deformed, tets, points):
    """Deformed positions of material points given at rest, by barycentric coordinates in the
    containing tetrahedron (brute force)."""
    a = rest[tets[:, 0]]
    A = np.stack([rest[tets[:, i]] - a for i in (1, 2, 3)], axis=2)  # (E, 3, 3)
    inv = np.linalg.inv(A)
    out = []
    for X in points:
        lam = np.einsum("eij,ej->ei", inv, X - a)
        w = np.concatenate([1 - lam.sum(1, keepdims=True), lam], axis=1)
        e = np.argmax(w.min(1))
        assert w[e].min() > -1e-9, X
        out.append(sum(w[e, i] * deformed[tets[e, i]] for i in range(4)))
    return np.array(out)


def test_the_cube_markers_attach_and_the_objective_matches_an_independent_interpolation(cube_dir):
    problem = cube_dir / "problem.json"
    problem.write_text(json.dumps(cube_problem()))
    rf = diffipc.ReducedFunctional(str(problem))  # "markers.txt" and "cube.msh" relative to it
    nu = 0.45
    J = rf(np.array([nu]))
    scene = cube_problem()["scene"]
    scene["bodies"][0]["mesh"]["file"] = str(cube_dir / "cube.msh")
    sim, tr = diffipc.simulate(scene)
    rest = tr["positions"][0]
    deformed = tr["positions"][-1]
    meshio = pytest.importorskip("meshio")
    tets = meshio.read(cube_dir / "cube.msh").cells_dict["tetra"]
    # meshio keeps gmsh's node order; diffipc's reader drops unused nodes: map by position.
    raw = meshio.read(cube_dir / "cube.msh").points * 0.004 - 0.02
    order = {tuple(np.round(p, 12)): i for i, p in enumerate(rest)}
    remap = np.array([order[tuple(np.round(p, 12))] for p in raw])
    tets = remap[tets]
    data = np.loadtxt(cube_dir / "markers.txt")
    p = interpolate(rest, deformed, tets, data[:, :3])
    expected = 0.5 * np.sum((p - data[:, 3:]) ** 2)
    assert J == pytest.approx(expected, rel=1e-9)
    # The residual is in the millimetre range (0.8 mm RMS at nu = 0.45, measured).
    rms = np.sqrt(2 * J / len(data))
    assert 1e-4 < rms < 2e-3


def test_marker_file_errors(cube_dir):
    (cube_dir / "mm.txt").write_text("\n".join(
        " ".join(str(1000 * v) for v in row) for row in np.loadtxt(cube_dir / "markers.txt")) + "\n")
    problem = cube_dir / "problem.json"
    problem.write_text(json.dumps(cube_problem("mm.txt")))
    with pytest.raises(ValueError, match="mm.txt:1.*millimetres"):
        diffipc.ReducedFunctional(str(problem))
    p = cube_problem()
    p["objective"]["targets"] = [[[0, 0, 0]]]
    problem.write_text(json.dumps(p))
    with pytest.raises(ValueError, match="objective.targets.*not with \"file\""):
        diffipc.ReducedFunctional(str(problem))
