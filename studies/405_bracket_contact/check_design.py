"""Independent check of a rest design written by `diffipc optimize` for study 405.

It reads the design's rest mesh from a design_*.vtu, checks it (every triangle has a
positive area, no two boundary edges cross), writes it as a gmsh 2.2 mesh, puts it in
place of the problem's box mesh (same Dirichlet region, gravity, roller and contact
settings: the box selections do not change, since the design moves only y and keeps the
bottom edge and the faces x = 0 and x = 1 at their x) and simulates it with
`diffipc simulate`. From that run it reports what the optimizer does not: the contact
(minimum gap to the roller, active pairs, the total contact force against the weight),
the largest element von Mises stress (with its element's rest centroid, the largest over
the roller: elements whose rest centroid lies in 0.05 <= x <= 0.15 m, and the largest
elsewhere, with its centroid), and the objective recomputed from the frame's per-element
von Mises stress and rest areas, (sum_e |e| s_e^p / sum_e |e|)^(1/p), with the share of
that sum that comes from the elements over the roller.

    /usr/bin/python3 studies/405_bracket_contact/check_design.py \
        studies/405_bracket_contact/problem.json output/405/design_final.vtu [--cli build/cli/diffipc]

Exit code 0 if the design is valid, the run converged and the roller carries the
bridge's weight within 1e-6; 1 otherwise.
"""
import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

import meshio
import numpy as np


def triangle_areas(points, cells):
    a, b, c = points[cells[:, 0], :2], points[cells[:, 1], :2], points[cells[:, 2], :2]
    u, v = b - a, c - a
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def boundary_edges(cells):
    count = {}
    for tri in cells:
        for i in range(3):
            e = tuple(sorted((int(tri[i]), int(tri[(i + 1) % 3]))))
            count[e] = count.get(e, 0) + 1
    return [e for e, n in count.items() if n == 1]


def crossing_pairs(points, edges):
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    found = []
    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            (a, b), (c, d) = edges[i], edges[j]
            if len({a, b, c, d}) < 4:
                continue
            A, B, C, D = points[a], points[b], points[c], points[d]
            o1, o2, o3, o4 = orient(A, B, C), orient(A, B, D), orient(C, D, A), orient(C, D, B)
            if o1 * o2 < 0 and o3 * o4 < 0:
                found.append((edges[i], edges[j]))
    return found


def write_msh22(path, points, cells):
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(points))]
    lines += [f"{i + 1} {p[0]!r} {p[1]!r} 0" for i, p in enumerate(points)]
    lines += ["$EndNodes", "$Elements", str(len(cells))]
    lines += [f"{k + 1} 2 2 1 1 {c[0] + 1} {c[1] + 1} {c[2] + 1}" for k, c in enumerate(cells)]
    lines += ["$EndElements"]
    pathlib.Path(path).write_text("\n".join(lines) + "\n")


def check(problem_path, design_path, cli):
    problem_path = pathlib.Path(problem_path).resolve()
    for path, what in ((problem_path, "problem file"), (pathlib.Path(design_path), "design VTU")):
        if not path.is_file():
            raise SystemExit(f"{path}: no such {what}")
    if not pathlib.Path(cli).is_file():
        raise SystemExit(f"{cli}: no diffipc CLI there (give --cli)")
    try:
        problem = json.loads(problem_path.read_text())
    except json.JSONDecodeError as e:
        raise SystemExit(f"{problem_path}: not JSON: {e}")
    scene = problem["scene"]
    if not isinstance(scene, dict):
        raise SystemExit(f"{problem_path}: scene: expected the inline scene of study 405")
    objective = problem["objective"]
    if objective["type"] == "sum":  # the penalty form: its first term is the stress p-norm
        objective = objective["terms"][0]["objective"]
    p = float(objective["p"])

    mesh = meshio.read(design_path)
    if "triangle" not in mesh.cells_dict:
        raise SystemExit(f"{design_path}: no triangles (expected a 2D design_*.vtu of diffipc optimize)")
    points = np.asarray(mesh.points[:, :2], dtype=float)
    cells = np.asarray(mesh.cells_dict["triangle"], dtype=int)
    areas = triangle_areas(points, cells)
    crossings = crossing_pairs(points, boundary_edges(cells))
    report = {"design": str(design_path), "vertices": len(points), "triangles": len(cells),
              "area": float(areas.sum()), "min_triangle_area": float(areas.min()),
              "boundary_crossings": len(crossings)}
    # The top edge's height (the highest vertex of each column) at x = 0, 0.1, ..., 1.
    report["top_edge"] = {f"{x:.1f}": float(points[np.abs(points[:, 0] - x) < 1e-9, 1].max())
                          for x in np.linspace(0, 1, 11)}
    # The area bound: the true constraint's, or the penalty term's.
    bounds = [c["upper"] for c in problem.get("constraints", []) if "upper" in c]
    if problem["objective"]["type"] == "sum":
        bounds += [t["objective"]["upper"] for t in problem["objective"]["terms"]
                   if t["objective"]["type"] == "constraint" and "upper" in t["objective"]]
    if bounds:
        report["area_bound"] = bounds[0]
        report["area_violation_relative"] = max(0.0, (report["area"] - bounds[0]) / abs(bounds[0]))
    if areas.min() <= 0 or crossings:
        report["valid"] = False
        return report
    report["valid"] = True

    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        write_msh22(tmp / "design.msh", points, cells)
        scene = json.loads(json.dumps(scene))
        scene["bodies"][0]["mesh"] = {"file": str(tmp / "design.msh")}
        for obstacle in scene.get("obstacles", []):
            if "mesh" in obstacle:
                obstacle["mesh"]["file"] = str((problem_path.parent / obstacle["mesh"]["file"]).resolve())
        scene["output"] = {"vtu_every": 1, "hdf5": False}
        (tmp / "scene.json").write_text(json.dumps(scene))
        r = subprocess.run([cli, "simulate", str(tmp / "scene.json"), "-o", str(tmp / "out")],
                           capture_output=True, text=True)
        if r.returncode != 0:
            report["simulate"] = f"exit {r.returncode}: {r.stderr.strip()[-500:]}"
            return report
        summary = json.loads((tmp / "out" / "summary.json").read_text())
        steps = summary["steps_committed"]
        # The gmsh reader numbers the vertices in their order of first use by the triangles
        # (the triangles keep theirs), so the rest positions are read back from frame 0.
        rest = meshio.read(tmp / "out" / "frame_0.vtu")
        frame = meshio.read(tmp / "out" / f"frame_{steps}.vtu")
        rest_points = np.asarray(rest.points[:, :2], dtype=float)
        rest_areas = triangle_areas(rest_points, np.asarray(frame.cells_dict["triangle"], dtype=int))
        if len(rest_areas) != len(areas) or np.abs(rest_areas - areas).max() > 1e-12 * np.abs(areas).max():
            raise SystemExit(f"{design_path}: the re-simulated mesh's triangles are not the design's")
        von_mises = np.asarray(frame.cell_data["von_mises"][0]).ravel()
        contact = np.asarray(frame.point_data["contact_force"])[:, :2]

    centroids = rest_points[np.asarray(frame.cells_dict["triangle"], dtype=int)].mean(axis=1)  # rest
    rho = scene["bodies"][0]["material"]["density"]
    g = -scene["gravity"][1]
    weight = rho * g * areas.sum()  # N per metre of depth (2D)
    over_roller = (centroids[:, 0] >= 0.05) & (centroids[:, 0] <= 0.15)
    off_roller = np.flatnonzero(~over_roller)
    off_max = off_roller[np.argmax(von_mises[off_roller])]
    terms = areas * von_mises ** p  # each element's part of the p-norm's sum
    report.update({
        "status": summary["status"],
        "min_gap": summary["contact"]["min_distance"],
        "dhat": scene["contact"]["dhat"],
        "active_contacts": summary["contact"]["max_active_contacts"],
        "contact_force_y": float(contact[:, 1].sum()),
        "contact_force_x": float(contact[:, 0].sum()),
        "weight": weight,
        "vertices_in_contact": int((np.linalg.norm(contact, axis=1) > 0).sum()),
        "contact_x": [float(x) for x in rest_points[np.linalg.norm(contact, axis=1) > 0, 0]],
        "max_von_mises": float(von_mises.max()),
        "max_von_mises_at": [float(v) for v in centroids[np.argmax(von_mises)]],
        "max_von_mises_over_roller": float(von_mises[over_roller].max()),
        "max_von_mises_off_roller": float(von_mises[off_max]),
        "max_von_mises_off_roller_at": [float(v) for v in centroids[off_max]],
        "p_norm_sum_share_over_roller": float(terms[over_roller].sum() / terms.sum()),
        "stress_p_norm": float((terms.sum() / areas.sum()) ** (1 / p)),
    })
    return report


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("problem")
    parser.add_argument("design")
    parser.add_argument("--cli", default="build/cli/diffipc")
    args = parser.parse_args()
    report = check(args.problem, args.design, args.cli)
    print(json.dumps(report, indent=1))
    ok = (report["valid"] and report.get("status") == "CONVERGED"
          and abs(report["contact_force_y"] - report["weight"]) <= 1e-6 * report["weight"])
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
