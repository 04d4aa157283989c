"""Independent validity checks of written designs (used by the optimization tests): triangle
areas and tetrahedron volumes from coordinates, and boundary crossings by brute force over
every pair of boundary edges with orientation tests (not the code under test)."""
import numpy as np


def triangle_areas(points, cells):
    a, b, c = points[cells[:, 0], :2], points[cells[:, 1], :2], points[cells[:, 2], :2]
    u, v = b - a, c - a
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def boundary_edges(cells):
    count = {}
    for tri in cells:
        for i in range(3):
            e = tuple(sorted((tri[i], tri[(i + 1) % 3])))
            count[e] = count.get(e, 0) + 1
    return [e for e, n in count.items() if n == 1]


def crossing(points, edges):
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            (a, b), (c, d) = edges[i], edges[j]
            if len({a, b, c, d}) < 4:
                continue
            A, B, C, D = points[a], points[b], points[c], points[d]
            o1, o2, o3, o4 = orient(A, B, C), orient(A, B, D), orient(C, D, A), orient(C, D, B)
            if o1 * o2 < 0 and o3 * o4 < 0:
                return True
    return False


def tet_volumes(points, cells):
    a, b, c, d = (points[cells[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6
