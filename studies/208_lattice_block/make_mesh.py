#!/usr/bin/env python3
"""The lattice block of study 208: a cubic grid of square beams along x, y and z (cells of
`cell` m, beams `beam` m thick), fused by gmsh's OpenCASCADE kernel and meshed with tetrahedra
of size `size` m. Writes a gmsh 2.2 ASCII file that diffipc reads.

    /usr/bin/python3 make_mesh.py [--cells 3 3 3] [--cell 0.01] [--beam 0.002] [--size 0.002] -o lattice.msh
"""
import argparse
import itertools
import sys

import gmsh


def lattice_block(cells, cell, beam, size, path):
    gmsh.initialize(["make_mesh", "-v", "2"])  # errors and warnings only
    try:
        gmsh.model.add("lattice")
        occ = gmsh.model.occ
        extent = [n * cell + beam for n in cells]
        beams = []
        for axis in range(3):
            a, b = [i for i in range(3) if i != axis]
            for i, j in itertools.product(range(cells[a] + 1), range(cells[b] + 1)):
                origin = [0.0, 0.0, 0.0]
                origin[a], origin[b] = i * cell, j * cell
                lengths = [beam, beam, beam]
                lengths[axis] = extent[axis]
                beams.append((3, occ.addBox(*origin, *lengths)))
        solid, _ = occ.fuse(beams[:1], beams[1:])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [tag for _, tag in solid], 1)
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.optimize("")
        types, tags, _ = gmsh.model.mesh.getElements(3)
        tets = sum(len(t) for t in tags)
        gmsh.write(path)
        return tets, extent
    finally:
        gmsh.finalize()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cells", type=int, nargs=3, default=[3, 3, 3])
    p.add_argument("--cell", type=float, default=0.01)
    p.add_argument("--beam", type=float, default=0.002)
    p.add_argument("--size", type=float, default=0.002)
    p.add_argument("-o", "--output", default="lattice.msh")
    a = p.parse_args(argv)
    if min(a.cells) < 1 or not 0 < a.beam < a.cell or a.size <= 0:
        sys.exit("make_mesh.py: need cells >= 1, 0 < beam < cell and size > 0")
    tets, extent = lattice_block(a.cells, a.cell, a.beam, a.size, a.output)
    print(f"{a.output}: {tets} tetrahedra, block {extent[0]:g} x {extent[1]:g} x {extent[2]:g} m")


if __name__ == "__main__":
    main()
