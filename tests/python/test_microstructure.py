"""diffipc.microstructure from Python (docs/microstructures.md): the shipped families, the level
set and meshes as numpy arrays, a coarse compression's stress-strain curve and gradient, a
parameter sweep, errors that name the variable, a cell whose tiling falls apart refused naming its
graph file, and a pattern library's .wire graph read from the unit cell."""

import json
import os
import re

import numpy as np
import pytest

import diffipc
from diffipc import microstructure as ms


def test_shipped_families_and_their_variables():
    assert {"square_grid", "diamond", "diamond_stop", "reentrant", "curved_beam"} <= set(ms.topologies())
    f = ms.family("reentrant")
    assert f.names == ["node[0].y", "node[4].y", "thickness[0]", "thickness[2]", "thickness[6]", "blend", "width"]
    assert f.names[f.width_index] == "width"
    assert np.all(f.lower <= f.initial) and np.all(f.initial <= f.upper)
    assert f.symmetry == "reflection_xy"
    with pytest.raises(ValueError, match="unknown topology 'hexagon'"):
        ms.family("hexagon")


def test_level_set_and_mesh_are_numpy_arrays():
    f = ms.family("square_grid")
    p = f.initial
    # on a beam (the centre) solid, in the middle of a hole empty
    phi = f.sdf(p, np.array([[0.0, 0.0], [0.5, 0.5]]))
    assert phi.shape == (2,) and phi[0] < 0 < phi[1]
    vertices, triangles = f.mesh(p, size=0.05, height=2.0)
    assert vertices.shape[1] == 2 and triangles.shape[1] == 3
    assert np.isclose(vertices[:, 0].min(), -1.0) and np.isclose(vertices[:, 1].max(), 1.0)
    a = vertices[triangles[:, 1]] - vertices[triangles[:, 0]]
    b = vertices[triangles[:, 2]] - vertices[triangles[:, 0]]
    assert np.all(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0)


def test_compression_curve_gradient_and_a_sweep():
    f = ms.family("reentrant")
    settings = {"target_stress": 500, "shear": "fixed", "size": 0.05, "steps": 4, "max_strain": 0.2, "samples": [2, 4]}
    d = ms.CellDesign(f, settings)
    r = d.evaluate(f.initial, gradient=True)
    assert r["ok"], r["message"]
    assert r["stress"].shape == (4,) and np.all(r["stress"] > 0)
    assert np.allclose(r["strain"], [0.05, 0.1, 0.15, 0.2])
    assert r["gradient"].shape == (len(f.names),)
    # J = sum (sigma_i / 500 - 1)^2 + 10 G_xx^2 at steps 2 and 4 (G_xy held at 0)
    expected = np.sum((r["stress"][[1, 3]] / 500 - 1) ** 2) + 10 * np.sum(r["lateral"][[1, 3]] ** 2)
    assert r["J"] == pytest.approx(expected, rel=1e-10)
    # a sweep of the strut thickness: thicker struts carry more
    peaks = []
    for t in (0.1, 0.16):
        p = f.initial.copy()
        p[f.names.index("thickness[0]")] = t
        strain, stress = ms.stress_strain(d, p)
        peaks.append(stress[-1])
    assert peaks[1] > peaks[0]


def test_errors_name_the_variable():
    f = ms.family("reentrant")
    p = f.upper.copy()
    p[f.width_index] *= 1.1
    with pytest.raises(ValueError, match=r"design\.width"):
        f.mesh(p)
    with pytest.raises(ValueError, match="expected a vector"):
        f.mesh(f.initial[:3])
    with pytest.raises(ValueError, match=r"settings\.shear"):
        ms.CellDesign(f, {"target_stress": 1, "shear": "sideways"})
    with pytest.raises(ValueError, match=r"settings\.target_stress"):
        ms.CellDesign(f, {})


def test_drop_design_from_python():
    """A block dropped on a pad of 2 x 1 cells: the stress history, J above the peak, a gradient per
    variable, a held width in a short optimization (its rejected designs listed with their reasons),
    and errors naming the field."""
    f = ms.family("reentrant")
    settings = {"size": 0.01 / 20, "cells": [2, 1], "block": {"mass": 0.625}, "kappa": 1e17, "steps": 16,
                "target_stress": 500}
    d = ms.DropDesign(f, settings)
    r = d.evaluate(f.initial, gradient=True)
    assert r["ok"], r["message"]
    assert r["stress"].shape == r["time"].shape == (16,)
    assert np.all(np.abs(r["stress"][:8]) < 1e-6)  # in free fall until step 10
    assert r["peak"] > 100 and r["J"] * 500 >= r["peak"]
    assert r["gradient"].shape == (len(f.names),)
    run = d.optimize(f.initial, max_iterations=1, fixed=["width"])
    assert all(e["x"][f.width_index] == f.initial[f.width_index] for e in run["history"])
    assert run["final"]["ok"]
    assert len(run["rejections"]) == run["rejected"]  # each with its design and reason
    assert all(len(r["x"]) == len(f.names) and r["reason"] for r in run["rejections"])
    with pytest.raises(ValueError, match="settings.block.mass"):
        ms.DropDesign(f, {"block": {}, "kappa": 1e17, "target_stress": 500})
    with pytest.raises(ValueError, match="fixed"):
        d.optimize(f.initial, max_iterations=1, fixed=["depth"])


def test_a_cell_whose_tiling_falls_apart_is_refused_naming_its_graph(tmp_path):
    """One beam from the centre to a corner is one piece on the torus but tiles into separate
    strokes: its compression used to "succeed" at stresses near 1e-5 Pa with G_xx drifting to 1.
    Now meshing it is refused, naming the graph file."""
    (tmp_path / "diagonal.obj").write_text("v 0 0\nv 1 1\nl 1 2\n")
    (tmp_path / "diagonal.json").write_text(json.dumps({"graph": "diagonal.obj"}))
    f = ms.family(tmp_path / "diagonal.json")
    d = ms.CellDesign(f, {"target_stress": 500, "size": 0.03, "steps": 3, "max_strain": 0.3, "samples": [3]})
    graph = str(tmp_path / "diagonal.obj")
    with pytest.raises(ValueError, match=re.escape(graph) + ": the cell's 3 x 3 tiling is not one connected solid"):
        d.evaluate(f.initial, gradient=False)
    with pytest.raises(ValueError, match=re.escape(graph)):
        f.mesh(f.initial, size=0.03)


def test_a_wire_pattern_in_the_unit_cell_is_the_obj_graph_rescaled(tmp_path):
    """A pattern library's .wire file (nodes in [0, 1]^2, one edge per "l") of the square grid's
    cross gives the same family and mesh as the shipped square_grid.obj in [-1, 1]^2."""
    (tmp_path / "cross.wire").write_text("v 0.0 0.5 0.0\nv 0.5 0.5 0.0\nv 1.0 0.5 0.0\nv 0.5 0.0 0.0\n"
                                         "v 0.5 1.0 0.0\nl 1 2\nl 2 3\nl 4 2\nl 2 5\n")
    shipped = json.loads(open(os.path.join(os.path.dirname(ms.__file__), "topologies", "square_grid.json")).read())
    shipped["graph"] = "cross.wire"
    (tmp_path / "cross.json").write_text(json.dumps(shipped))
    f, g = ms.family(tmp_path / "cross.json"), ms.family("square_grid")
    assert f.names == g.names
    assert np.array_equal(f.initial, g.initial)
    v1, t1 = f.mesh(f.initial, size=0.05)
    v2, t2 = g.mesh(g.initial, size=0.05)
    assert v1.shape == v2.shape and np.allclose(v1, v2, rtol=0, atol=1e-12)
    assert np.array_equal(t1, t2)
    # nodes outside the unit cell: the message says how such a graph is read
    (tmp_path / "big.wire").write_text("v -1 0\nv 1 0\nl 1 2\n")
    (tmp_path / "big.json").write_text(json.dumps({"graph": "big.wire"}))
    with pytest.raises(ValueError, match=r"big\.wire: line 1: .*give it the extension \.obj"):
        ms.family(tmp_path / "big.json")
