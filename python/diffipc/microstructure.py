"""Microstructure cells for shock-protecting cushions (docs/microstructures.md).

A cell family is a wire graph (OBJ `v`/`l` records in [-1, 1]^2, or a pattern library's `.wire`
file with nodes in [0, 1]^2, read as 2 x - 1) with a symmetry and bounds;
its design variables move the graph's nodes, thicken its edges, set the blend of the smooth
union and stretch the cell's width. From a design p:

    family = diffipc.microstructure.family("reentrant")
    phi = family.sdf(p, points)                 # the level set, solid where < 0
    vertices, triangles = family.mesh(p, size=0.025)
    design = diffipc.microstructure.CellDesign(family, {"target_stress": 500, "shear": "fixed"})
    result = design.evaluate(p, gradient=True)  # strain, stress (Pa), shear, lateral, J, gradient
    run = design.optimize(p, algorithm="lbfgsb", max_iterations=30)
    drop = diffipc.microstructure.DropDesign(family, {"cells": [4, 2], "block": {"mass": 1.25},
                                                      "kappa": 1e17, "target_stress": 500})
    result = drop.evaluate(p, gradient=True)    # time, stress on the block (Pa), peak, J, gradient
    run = drop.optimize(p, algorithm="lbfgsb", fixed=["width"], max_iterations=10)

All arrays are numpy arrays; bad input raises ValueError naming the field or variable (a cell
whose 3 x 3 tiling is not one connected solid: naming the graph file).
"""

import os

from ._diffipc import CellDesign, CellFamily, DropDesign  # noqa: F401

_TOPOLOGIES = os.path.join(os.path.dirname(__file__), "topologies")


def topologies():
    """The names of the shipped cell families (their files are in diffipc/topologies/)."""
    return sorted(f[:-5] for f in os.listdir(_TOPOLOGIES) if f.endswith(".json"))


def family(name_or_path):
    """A shipped family by name ("reentrant", "square_grid", "diamond", "diamond_stop",
    "curved_beam") or a family file by path."""
    path = os.fspath(name_or_path)
    if not path.endswith(".json"):
        if path not in topologies():
            raise ValueError(f"family: unknown topology {path!r} (shipped: {', '.join(topologies())})")
        path = os.path.join(_TOPOLOGIES, path + ".json")
    return CellFamily(path)


def stress_strain(design, p):
    """(strain, stress) of design p's compression: numpy arrays per load step, stress in Pa
    (compressive positive)."""
    result = design.evaluate(p, gradient=False)
    if not result["ok"]:
        raise RuntimeError(result["message"])
    return result["strain"], result["stress"]
