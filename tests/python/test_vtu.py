"""VTU frames for ParaView (docs/output_format.md, "VTU frames"), read with meshio, a reader
independent of ours, in both encodings: the bodies' points, cells and fields against
trajectory.h5 and a stress computed here from the positions, the obstacles' geometry, the
.pvd's parts, contact and friction forces against the weight m g, and write failures."""
import json
import math
import resource
import signal
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest

meshio = pytest.importorskip("meshio")
h5py = pytest.importorskip("h5py")

DENSITY, G = 1000.0, 9.81
E, NU = 1e6, 0.3
OBJ = "v -1 -0.2 -1\nv 2 -0.2 -1\nv -1 -0.2 2\nv 2 -0.2 2\nf 1 3 2\nf 2 3 4\n"


def run(cli, *args, **kw):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=600, **kw)


def falling_box_scene(tmp_path, encoding, steps=6):
    """A 3D box falling onto a plane that rises (motion), above an obstacle mesh, with friction."""
    (tmp_path / "floor.obj").write_text(OBJ)
    s = {
        "dimension": 3,
        "bodies": [{"name": "box", "mesh": {"box": {"min": [0, 0.002, 0], "max": [0.3, 0.102, 0.2], "cells": [3, 1, 2]}},
                    "material": {"model": "neo_hookean", "E": E, "nu": NU, "density": DENSITY},
                    "initial_velocity": [0.2, -0.5, 0]}],
        "obstacles": [{"name": "ground", "plane": {"point": [0, 0, 0], "normal": [0, 1, 0], "motion": [0, "0.01*t", 0]}},
                      {"name": "floor", "mesh": {"file": "floor.obj"}}],
        "contact": {"dhat": 1e-3},
        "friction": {"coefficient": 0.3},
        "gravity": [0, -G, 0],
        "time": {"integrator": "implicit_euler", "dt": 0.01, "steps": steps},
        "solver": {"residual_tolerance": 1e-9},
        "output": {"vtu_every": 2, "vtu_encoding": encoding},
    }
    path = tmp_path / f"scene_{encoding}.json"
    path.write_text(json.dumps(s))
    return path


def frames(pvd):
    """The .pvd's DataSets as (time, part, file)."""
    root = ET.parse(pvd).getroot()
    assert root.get("type") == "Collection"
    return [(float(d.get("timestep")), int(d.get("part")), d.get("file")) for d in root.iter("DataSet")]


def cauchy_neo_hookean(F):
    """sigma = P F^T / J with P = mu (F - F^-T) + lambda ln J F^-T, per element (E, 3, 3)."""
    mu, lam = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
    J = np.linalg.det(F)
    FinvT = np.transpose(np.linalg.inv(F), (0, 2, 1))
    P = mu * (F - FinvT) + lam * np.log(J)[:, None, None] * FinvT
    return P @ np.transpose(F, (0, 2, 1)) / J[:, None, None]


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_frames_match_the_trajectory(cli, tmp_path, encoding):
    out = tmp_path / "out"
    r = run(cli, "simulate", falling_box_scene(tmp_path, encoding), "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    entries = frames(out / "trajectory.pvd")
    # Every frame time has the bodies (part 0) and the obstacles (part 1).
    assert [(t, p) for t, p, _ in entries] == [(t, p) for t in (0, 0.02, 0.04, 0.06) for p in (0, 1)]
    raw = (out / "frame_2.vtu").read_bytes()
    assert raw.startswith(b"<?xml")
    assert (b'<AppendedData encoding="raw">' in raw) == (encoding == "binary")
    assert b'header_type="UInt64"' in raw

    with h5py.File(out / "trajectory.h5", "r") as f:
        X = f["mesh/rest_positions"][:]
        elements = f["mesh/elements"][:]
        element_body = f["mesh/element_body"][:]
        body = f["mesh/body"][:]
        positions, velocities, times = f["positions"][:], f["velocities"][:], f["time"][:]
    nb = int((body == 0).sum())
    floor = np.flatnonzero(body == 2)  # the obstacle mesh's vertices (bodies, then obstacles)
    plane_vertex = int(np.flatnonzero(body == 1)[0])
    obj = meshio.read(tmp_path / "floor.obj")
    for t, part, name in entries:
        k = int(round(t / 0.01))
        assert times[k] == pytest.approx(t)
        m = meshio.read(out / name)
        x = positions[k]
        if part == 0:
            np.testing.assert_array_equal(m.points, x[:nb])
            assert [c.type for c in m.cells] == ["tetra"]
            np.testing.assert_array_equal(m.cells[0].data, elements)
            np.testing.assert_array_equal(m.point_data["displacement"], x[:nb] - X[:nb])
            np.testing.assert_array_equal(m.point_data["velocity"], velocities[k][:nb])
            np.testing.assert_array_equal(m.cell_data["body"][0].ravel(), element_body)
            # Stress and volume ratio computed here from the positions.
            Dm = np.stack([X[elements[:, i]] - X[elements[:, 0]] for i in (1, 2, 3)], axis=2)
            Ds = np.stack([x[elements[:, i]] - x[elements[:, 0]] for i in (1, 2, 3)], axis=2)
            F = Ds @ np.linalg.inv(Dm)
            sigma = cauchy_neo_hookean(F)
            stress = m.cell_data["stress"][0].reshape(-1, 3, 3)
            scale = np.abs(sigma).max() + 1.0
            np.testing.assert_allclose(stress, sigma, rtol=0, atol=1e-9 * scale)
            dev = stress - np.trace(stress, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
            np.testing.assert_allclose(m.cell_data["von_mises"][0].ravel(),
                                       np.sqrt(1.5 * (dev ** 2).sum(axis=(1, 2))), rtol=1e-12, atol=1e-9 * scale)
            np.testing.assert_allclose(m.cell_data["volume_ratio"][0].ravel(), np.linalg.det(F), rtol=1e-12)
            for name in ("contact_force", "friction_force"):
                assert m.point_data[name].shape == (nb, 3)
        else:
            types = [c.type for c in m.cells]
            assert types == ["quad", "vertex", "triangle"]
            quad = m.points[m.cells[0].data[0]]
            plane_point = x[plane_vertex]
            assert plane_point[1] == pytest.approx(0.01 * t, abs=1e-15)  # the plane moved
            np.testing.assert_allclose(quad[:, 1], plane_point[1], atol=1e-15)  # the patch lies on it
            np.testing.assert_array_equal(m.points[m.cells[1].data[0, 0]], plane_point)
            # The obstacle mesh: its vertices where trajectory.h5 has them, the .obj's triangles.
            tri_points = m.points[m.cells[2].data]
            np.testing.assert_array_equal(tri_points, x[floor][obj.cells_dict["triangle"]])
            np.testing.assert_array_equal(m.cell_data["obstacle"][0].ravel(), [0])
            np.testing.assert_array_equal(m.cell_data["obstacle"][2].ravel(), [1, 1])
            assert m.point_data["contact_force"].shape == (len(m.points), 3)


def test_plane_patch_size(cli, tmp_path):
    out = tmp_path / "out"
    assert run(cli, "simulate", falling_box_scene(tmp_path, "binary", steps=2), "-o", out, "-q").returncode == 0
    m = meshio.read(out / "obstacles_0.vtu")
    quad = m.points[m.cells[0].data[0]]
    # Twice the diagonal of the rest bounding box of the bodies and obstacle meshes, centred
    # at the foot of its centre on the plane.
    lo = np.array([-1, -0.2, -1.0]); hi = np.array([2, 0.102, 2.0])
    side = 2 * np.linalg.norm(hi - lo)
    assert np.linalg.norm(quad[1] - quad[0]) == pytest.approx(side)
    assert np.linalg.norm(quad[3] - quad[0]) == pytest.approx(side)
    np.testing.assert_allclose(quad.mean(0), [(lo[0] + hi[0]) / 2, 0, (lo[2] + hi[2]) / 2], atol=1e-12)


def test_ascii_and_binary_hold_the_same_values(cli, tmp_path):
    read = {}
    for encoding in ("ascii", "binary"):
        out = tmp_path / encoding
        assert run(cli, "simulate", falling_box_scene(tmp_path, encoding, steps=2), "-o", out, "-q").returncode == 0
        read[encoding] = [meshio.read(out / n) for n in ("frame_2.vtu", "obstacles_2.vtu")]
    for a, b in zip(read["ascii"], read["binary"]):
        np.testing.assert_array_equal(a.points, b.points)
        for key in a.point_data:
            np.testing.assert_array_equal(a.point_data[key], b.point_data[key])
        for key in a.cell_data:
            for x, y in zip(a.cell_data[key], b.cell_data[key]):
                np.testing.assert_array_equal(x, y)
    assert (tmp_path / "binary" / "frame_2.vtu").stat().st_size < (tmp_path / "ascii" / "frame_2.vtu").stat().st_size


def block_on_plane_scene(tmp_path, degrees, mu, integrator, steps):
    """A 2D 0.1 x 0.05 block 1e-4 above a plane tilted by `degrees`, E = 1e6, rho = 1000."""
    a = math.radians(degrees)
    s = {
        "dimension": 2,
        "bodies": [{"name": "block", "mesh": {"box": {"min": [0, 1e-4], "max": [0.1, 0.0501], "cells": [4, 2]}},
                    "rotation": [degrees], "material": {"model": "neo_hookean", "E": E, "nu": NU, "density": DENSITY}}],
        "obstacles": [{"name": "ground", "plane": {"point": [0, 0], "normal": [-math.sin(a), math.cos(a)]}}],
        "contact": {"dhat": 2e-4},
        "gravity": [0, -G],
        "time": {"integrator": integrator, "dt": 0.01, "steps": steps},
        "solver": {"residual_tolerance": 1e-10},
        "output": {"vtu_every": steps},
    }
    if mu > 0:
        s["friction"] = {"coefficient": mu, "eps_v": 1e-3, "iterations": 3}
    path = tmp_path / "block.json"
    path.write_text(json.dumps(s))
    return path


def test_contact_forces_carry_the_weight(cli, tmp_path):
    # Quasi-static: the block rests on the plane in equilibrium after one step.
    out = tmp_path / "out"
    r = run(cli, "simulate", block_on_plane_scene(tmp_path, 0, 0, "static", 1), "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    weight = DENSITY * 0.1 * 0.05 * G  # m g from the density and the block's area (per unit depth)
    m = meshio.read(out / "frame_1.vtu")
    total = m.point_data["contact_force"].sum(0)
    np.testing.assert_allclose(total, [0, weight, 0], rtol=0, atol=1e-6 * weight)
    assert "friction_force" not in m.point_data  # no friction in this scene
    # Zero where there is no contact: the vertices above the bottom row.
    up = m.points[:, 1] > 0.01
    assert np.abs(m.point_data["contact_force"][up]).max() == 0
    # The plane's point (a vertex cell in the obstacles file) carries the reaction.
    o = meshio.read(out / "obstacles_1.vtu")
    point = o.cells_dict["vertex"][0, 0]
    np.testing.assert_allclose(o.point_data["contact_force"][point], [0, -weight, 0], rtol=0, atol=1e-6 * weight)


def test_friction_holds_a_block_on_a_slope(cli, tmp_path):
    """mu = 0.5 > tan 20 deg: the block sticks. Smoothed friction holds it by a creep below eps_v
    (f1(y) = tan(theta)/mu = 0.73 < 1); a steady creep does not accelerate, so after 1 s the
    forces balance gravity to the residual and the inertia left (< 1e-6 m g)."""
    theta, mu = math.radians(20), 0.5
    out = tmp_path / "out"
    r = run(cli, "simulate", block_on_plane_scene(tmp_path, 20, mu, "implicit_euler", 100), "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    weight = DENSITY * 0.1 * 0.05 * G
    m = meshio.read(out / "frame_100.vtu")
    n = np.array([-math.sin(theta), math.cos(theta), 0])
    t = np.array([math.cos(theta), math.sin(theta), 0])
    contact = m.point_data["contact_force"].sum(0)
    friction = m.point_data["friction_force"].sum(0)
    assert contact @ n == pytest.approx(weight * math.cos(theta), rel=1e-6)
    assert friction @ t == pytest.approx(weight * math.sin(theta), rel=1e-6)
    assert abs(friction @ n) < 1e-6 * weight
    assert np.linalg.norm(friction) < mu * (contact @ n)  # inside the Coulomb cone
    assert np.linalg.norm(m.point_data["velocity"], axis=1).max() < 1e-3  # creep below eps_v


def test_restart_keeps_both_parts_in_the_pvd(cli, tmp_path):
    scene = falling_box_scene(tmp_path, "binary", steps=2)
    out = tmp_path / "out"
    assert run(cli, "simulate", scene, "-o", out, "-q").returncode == 0
    s = json.loads(scene.read_text())
    s["time"]["steps"] = 4
    scene.write_text(json.dumps(s))
    r = run(cli, "simulate", "--restart", out, scene, "-q")
    assert r.returncode == 0, r.stderr
    assert [(t, p, f) for t, p, f in frames(out / "trajectory.pvd")] == [
        (t, p, f"{'frame' if p == 0 else 'obstacles'}_{k}.vtu") for k, t in ((0, 0), (2, 0.02), (4, 0.04)) for p in (0, 1)]


def test_a_failed_vtu_write_is_an_error(cli, tmp_path):
    """A full disk, imitated by a file-size limit: the run stops with exit 1 naming the frame."""
    scene = falling_box_scene(tmp_path, "ascii", steps=2)
    s = json.loads(scene.read_text())
    s["output"]["hdf5"] = False
    scene.write_text(json.dumps(s))

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (2000, 2000))

    out = tmp_path / "out"
    r = run(cli, "simulate", scene, "-o", out, preexec_fn=limit)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "frame_0.vtu" in r.stderr and "cannot write file" in r.stderr, r.stderr
    assert "wrote" not in r.stdout
    assert not (out / "frame_0.vtu").exists() and not (out / "frame_0.vtu.tmp").exists()


def test_unknown_vtu_encoding_names_the_field(cli, tmp_path):
    scene = falling_box_scene(tmp_path, "base64")
    r = run(cli, "validate", scene)
    assert r.returncode == 1
    assert "output.vtu_encoding" in r.stderr and "binary" in r.stderr, r.stderr


@pytest.mark.parametrize("encoding", ["binary", "ascii"])
def test_vtk_reads_what_meshio_reads(cli, tmp_path, encoding):
    """ParaView reads .vtu files with VTK's vtkXMLUnstructuredGridReader: where VTK's Python
    module is installed (Debian's python3-vtk9; not a dependency), it must find the same arrays."""
    vtk = pytest.importorskip("vtkmodules.vtkIOXML")
    from vtkmodules.util.numpy_support import vtk_to_numpy
    out = tmp_path / "out"
    assert run(cli, "simulate", falling_box_scene(tmp_path, encoding, steps=2), "-o", out, "-q").returncode == 0
    for name in ("frame_2.vtu", "obstacles_2.vtu"):
        reader = vtk.vtkXMLUnstructuredGridReader()
        reader.SetFileName(str(out / name))
        reader.Update()
        assert reader.GetErrorCode() == 0
        grid, m = reader.GetOutput(), meshio.read(out / name)
        np.testing.assert_array_equal(vtk_to_numpy(grid.GetPoints().GetData()), m.points)
        assert grid.GetNumberOfCells() == sum(len(c.data) for c in m.cells)
        pd, cd = grid.GetPointData(), grid.GetCellData()
        assert sorted(pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())) == sorted(m.point_data)
        for key, value in m.point_data.items():
            np.testing.assert_array_equal(vtk_to_numpy(pd.GetArray(key)), value)
        for key, blocks in m.cell_data.items():
            expected = np.concatenate([np.asarray(b).reshape(len(b), -1) for b in blocks])
            got = vtk_to_numpy(cd.GetArray(key))
            np.testing.assert_array_equal(got.reshape(len(got), -1), expected)


def test_python_forces_are_the_written_ones(cli, tmp_path):
    diffipc = pytest.importorskip("diffipc")
    path = block_on_plane_scene(tmp_path, 20, 0.5, "implicit_euler", 5)
    sim = diffipc.Simulator(diffipc.scene(str(path)))
    assert np.abs(sim.friction_forces).max() == 0  # no step yet
    for _ in range(5):
        sim.step()
    out = tmp_path / "out"
    assert run(cli, "simulate", path, "-o", out, "-q").returncode == 0
    m = meshio.read(out / "frame_5.vtu")
    nb = len(m.points)
    np.testing.assert_array_equal(m.point_data["contact_force"][:, :2], sim.contact_forces[:nb])
    np.testing.assert_array_equal(m.point_data["friction_force"][:, :2], sim.friction_forces[:nb])
    assert sim.contact_forces.shape == sim.positions.shape
