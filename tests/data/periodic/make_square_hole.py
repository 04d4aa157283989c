"""Writes square_hole.msh: the unit square with a centred circular hole of radius 0.3, triangles of
about 0.1, periodic along x and y (gmsh's setPeriodic: the mesh of the right edge is the left
edge's translated, the top's the bottom's). Test data of tests/forward/mesh/test_periodic.cpp.

    /usr/bin/python3 tests/data/periodic/make_square_hole.py
"""
import os

import gmsh

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("square_hole")
occ = gmsh.model.occ
square = occ.addRectangle(0, 0, 0, 1, 1)
hole = occ.addDisk(0.5, 0.5, 0, 0.3, 0.3)
occ.cut([(2, square)], [(2, hole)])
occ.synchronize()
edges = gmsh.model.getEntities(1)


def edge_at(x, y):
    for _, tag in edges:
        lo = gmsh.model.getBoundingBox(1, tag)
        if abs((lo[0] + lo[3]) / 2 - x) < 1e-6 and abs((lo[1] + lo[4]) / 2 - y) < 1e-6:
            return tag
    raise RuntimeError(f"no edge at ({x}, {y})")


left, right, bottom, top = edge_at(0, 0.5), edge_at(1, 0.5), edge_at(0.5, 0), edge_at(0.5, 1)
translate = lambda dx, dy: [1, 0, 0, dx, 0, 1, 0, dy, 0, 0, 1, 0, 0, 0, 0, 1]
gmsh.model.mesh.setPeriodic(1, [right], [left], translate(1, 0))
gmsh.model.mesh.setPeriodic(1, [top], [bottom], translate(0, 1))
gmsh.option.setNumber("Mesh.MeshSizeMax", 0.1)
gmsh.model.mesh.generate(2)
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.write(os.path.join(os.path.dirname(os.path.abspath(__file__)), "square_hole.msh"))
gmsh.finalize()
