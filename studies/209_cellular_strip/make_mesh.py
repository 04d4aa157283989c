#!/usr/bin/env python3
"""The cellular strip of study 209: a rectangle with a square array of circular holes (`columns`
x `rows` cells of `cell` m, holes of diameter `hole` m, solid bands of `band` m above and below),
meshed with triangles of size `size` m by gmsh's OpenCASCADE kernel. Writes a gmsh 2.2 ASCII file.

    /usr/bin/python3 make_mesh.py [--columns 6] [--rows 4] [--cell 0.01] [--hole 0.0085] \
        [--band 0.002] [--size 0.0006] -o strip.msh
"""
import argparse
import sys

import gmsh


def cellular_strip(columns, rows, cell, hole, band, size, path):
    gmsh.initialize(["make_mesh", "-v", "2"])  # errors and warnings only
    try:
        gmsh.model.add("strip")
        occ = gmsh.model.occ
        width, height = columns * cell, rows * cell + 2 * band
        plate = occ.addRectangle(0, 0, 0, width, height)
        holes = [(2, occ.addDisk((i + 0.5) * cell, band + (j + 0.5) * cell, 0, hole / 2, hole / 2))
                 for i in range(columns) for j in range(rows)]
        solid, _ = occ.cut([(2, plate)], holes)
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [tag for _, tag in solid], 1)
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.model.mesh.generate(2)
        _, tags, _ = gmsh.model.mesh.getElements(2)
        gmsh.write(path)
        return sum(len(t) for t in tags), (width, height)
    finally:
        gmsh.finalize()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--columns", type=int, default=6)
    p.add_argument("--rows", type=int, default=4)
    p.add_argument("--cell", type=float, default=0.01)
    p.add_argument("--hole", type=float, default=0.0085)
    p.add_argument("--band", type=float, default=0.002)
    p.add_argument("--size", type=float, default=0.0006)
    p.add_argument("-o", "--output", default="strip.msh")
    a = p.parse_args(argv)
    if min(a.columns, a.rows) < 1 or not 0 < a.hole < a.cell or a.band < 0 or a.size <= 0:
        sys.exit("make_mesh.py: need columns, rows >= 1, 0 < hole < cell, band >= 0 and size > 0")
    triangles, extent = cellular_strip(a.columns, a.rows, a.cell, a.hole, a.band, a.size, a.output)
    print(f"{a.output}: {triangles} triangles, strip {extent[0]:g} x {extent[1]:g} m")


if __name__ == "__main__":
    main()
