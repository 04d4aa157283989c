"""diffipc.microstructure from Python (docs/microstructures.md): the shipped families, the level
set and meshes as numpy arrays, a coarse compression's stress-strain curve and gradient, a
parameter sweep, and errors that name the variable."""

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
