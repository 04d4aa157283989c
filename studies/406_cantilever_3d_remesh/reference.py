"""Discretization reference for study 406: J at the design of the run's last remesh, on the
structured start mesh (from summary.json), on the remeshed mesh, and on finer gmsh meshes of
the same domain, so that the change of J across the remesh can be compared with the
discretization error of each mesh.

    PYTHONPATH=build/python /usr/bin/python3 studies/406_cantilever_3d_remesh/reference.py \
        output/406 [--sizes 0.03 0.02 0.015]
"""
import argparse
import json
import pathlib
import subprocess
import tempfile

import numpy as np

import diffipc

ROOT = pathlib.Path(__file__).resolve().parents[2]


def boundary_faces(cells):
    faces = {}
    for t in cells:
        for f in ((t[1], t[2], t[3]), (t[0], t[3], t[2]), (t[0], t[1], t[3]), (t[0], t[2], t[1])):
            faces.setdefault(tuple(sorted(f)), []).append(f)
    return [v[0] for v in faces.values() if len(v) == 1]


def read_msh(path):
    """Nodes and tetrahedra of a gmsh 2.2 ASCII file as diffipc writes it."""
    lines = pathlib.Path(path).read_text().split("\n")
    i = lines.index("$Nodes")
    n = int(lines[i + 1])
    points = np.array([[float(v) for v in lines[i + 2 + k].split()[1:4]] for k in range(n)])
    j = lines.index("$Elements")
    m = int(lines[j + 1])
    tets = np.array([[int(v) - 1 for v in lines[j + 2 + k].split()[5:9]] for k in range(m)])
    return points, tets


def write_msh(path, points, tets):
    with open(path, "w") as out:
        out.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(points))
        for k, p in enumerate(points):
            out.write("%d %.17g %.17g %.17g\n" % (k + 1, *p))
        out.write("$EndNodes\n$Elements\n%d\n" % len(tets))
        for k, t in enumerate(tets):
            out.write("%d 4 2 1 1 %d %d %d %d\n" % (k + 1, *(t + 1)))
        out.write("$EndElements\n")


def remesh(points, tets, size, workdir, remesher):
    faces = boundary_faces(tets)
    src, dst = workdir / "in.txt", workdir / "out.txt"
    with open(src, "w") as f:
        f.write("3 %.17g 1 %d %d\n" % (size, len(points), len(faces)))
        for p in points:
            f.write("%.17g %.17g %.17g\n" % tuple(p))
        for face in faces:
            f.write("%d %d %d\n" % tuple(face))
    subprocess.run([remesher, src, dst], check=True, capture_output=True)
    lines = dst.read_text().split("\n")
    head = lines[0].split()
    if head[0] != "ok":
        raise RuntimeError(lines[0])
    np_, ne = int(head[1]), int(head[2])
    P = np.array([[float(v) for v in lines[1 + k].split()] for k in range(np_)])
    T = np.array([[int(v) for v in lines[1 + np_ + k].split()] for k in range(ne)])
    a, b, c, d = (P[T[:, i]] for i in range(4))
    flip = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) < 0
    T[flip, 0], T[flip, 1] = T[flip, 1], T[flip, 0].copy()
    return P, T


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="the output directory of diffipc optimize on problem.json")
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.03, 0.02, 0.015])
    parser.add_argument("--remesher", default=str(ROOT / "build" / "shape_opt" / "diffipc-gmsh-remesh"))
    args = parser.parse_args()
    run = pathlib.Path(args.run)
    summary = json.loads((run / "summary.json").read_text())
    last = summary["remeshes"][-1]
    problem = json.loads((run / "current_problem.json").read_text())
    entry = problem["parameters"][0]
    x = np.array(entry["initial"])  # the design at the last remesh
    mesh_file = problem["scene"]["bodies"][0]["mesh"]["file"]
    points, tets = read_msh(mesh_file)  # the domain at x
    print("design of the remesh after iteration %d" % last["iteration"])
    print("%-34s %8s  %12s" % ("mesh", "tets", "J"))
    print("%-34s %8d  %12.6f" % ("start mesh (structured)", last["elements_before"], last["J_before"]))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for size in args.sizes:
            P, T = remesh(points, tets, size, tmp, args.remesher)
            path = tmp / ("size_%g.msh" % size)
            write_msh(path, P, T)
            p = json.loads(json.dumps(problem))
            p["scene"]["bodies"][0]["mesh"]["file"] = str(path)
            rf = diffipc.ReducedFunctional(p)
            J = rf(rf.parameters_of(x))
            rows.append((size, len(T), J))
            print("%-34s %8d  %12.6f" % ("gmsh, size %g" % size, len(T), J))
    print("%-34s %8d  %12.6f" % ("remeshed mesh of the run", last["elements_after"], last["J_after"]))
    finest = rows[-1][2]
    print("relative to the finest: start mesh %+.2f%%, remeshed %+.2f%%" % (
        100 * (last["J_before"] / finest - 1), 100 * (last["J_after"] / finest - 1)))


if __name__ == "__main__":
    main()
