#!/usr/bin/env python3
"""Writes cell.msh for study 210: the periodic post cell of tests/forward/periodic/post_cell.hpp
(a unit square: a column |x| < 0.1 across the x faces, a beam 0.3 < y < 0.7, a post
0.4 < x < 0.6 up to y = 0.95 and a wider one 0.35 < x < 0.65 down to y = 0.05; the up post's top
faces the next cell's down post across the face y = 1, 0.1 apart), on an N x N grid of squares
split into two triangles each, the squares outside the solid dropped, the grid sheared inside the
cell (x += 0.012 sin(2 pi y) sin^2(pi x), zero on the faces) so that the posts' facing vertices
are not aligned. Pure Python: the faces' vertices match by construction.

    /usr/bin/python3 studies/210_periodic_posts/make_mesh.py [-n 62] [-o studies/210_periodic_posts/cell.msh]
"""
import argparse
import math
import os


def inside(x, y):
    x -= math.floor(x)
    y -= math.floor(y)
    column = x < 0.1 or x > 0.9
    beam = 0.3 < y < 0.7
    up = 0.4 < x < 0.6 and 0.7 < y < 0.95
    down = 0.35 < x < 0.65 and 0.05 < y < 0.3
    return column or beam or up or down


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("-n", type=int, default=62, help="squares per unit length")
    parser.add_argument("-o", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "cell.msh"))
    args = parser.parse_args()
    n = args.n
    index, points, triangles = {}, [], []

    def vertex(i, j):
        if (i, j) not in index:
            x, y = i / n, j / n
            index[(i, j)] = len(points) + 1
            points.append((x + 0.012 * math.sin(2 * math.pi * y) * math.sin(math.pi * x) ** 2, y))
        return index[(i, j)]

    for i in range(n):
        for j in range(n):
            # The (min, min)-(max, max) diagonal, as forward/mesh/mesh.hpp's box_mesh.
            for t in (((i, j), (i + 1, j), (i + 1, j + 1)), ((i, j), (i + 1, j + 1), (i, j + 1))):
                cx = sum(p[0] for p in t) / (3 * n)
                cy = sum(p[1] for p in t) / (3 * n)
                if inside(cx, cy):
                    triangles.append([vertex(*p) for p in t])
    with open(args.o, "w") as out:
        out.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(points))
        for k, (x, y) in enumerate(points):
            out.write("%d %.17g %.17g 0\n" % (k + 1, x, y))
        out.write("$EndNodes\n$Elements\n%d\n" % len(triangles))
        for k, t in enumerate(triangles):
            out.write("%d 2 2 1 1 %d %d %d\n" % (k + 1, *t))
        out.write("$EndElements\n")
    print(f"{args.o}: {len(points)} vertices, {len(triangles)} triangles")


if __name__ == "__main__":
    main()
