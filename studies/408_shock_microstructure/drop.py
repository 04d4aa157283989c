#!/usr/bin/env python3
"""Study 408, the drop test: a block falls on a pad of cells; the stress it feels.

    PYTHONPATH=build/python /usr/bin/python3 studies/408_shock_microstructure/drop.py
        --params output/408_shock_microstructure/params.json [--full] [-o DIR] [--cli build/cli/diffipc]

A pad of nx x ny cells (default 8 x 3; cell height 1 cm, the designs of params.json at the mesh
size of their optimization, relative to the cell) is bonded to the ground (its bottom vertices
fixed); a stiff block (E = 100 MPa, the pad's width, 1 cm tall, density set for 2.5 kg per metre of
depth) starts 0.5 mm above it at 0.5 m/s downward under gravity, implicit Euler, dt = 0.1 ms, 400 steps,
contact (dhat 10 um, adaptive kappa) and friction mu = 0.3 between the block and the pad. The same
drop on the pad of the initial and the L-BFGS-B design (--full: every design of params.json) and on
a solid pad of the optimized pad's mass (the same material, the same width, as tall as its area
requires).

The stress on the block's bottom face, per step (plane stress, per metre of depth):
    sigma(t_k) = F_y(t_k) / W,  F_y(t_k) = (P_k - P_(k-1)) / dt + M g,
with P_k the block's vertical momentum (lumped masses rho A_e / 3 per triangle corner) and M its
mass: implicit Euler's discrete momentum balance of the block, where its own elastic forces cancel,
so F_y is the pad's contact force (the barrier and friction) on the block, exactly. The block's
deceleration is (P_k - P_(k-1)) / (M dt). The headline figure: the peak of sigma over the run, and
its reduction 1 - peak(pad) / peak(reference). Every state is checked by `diffipc check` (exact
inversion and intersection tests, independent of the contact code).
"""
import argparse
import json
import os
import re
import subprocess

import h5py
import numpy as np

from diffipc import microstructure as ms

H_CELL = 0.01
MASS = 2.5  # kg per metre of depth: its weight on the pad, 31 Pa per cm of width, stays below the plateau
SPEED = 0.5
GAP = 5e-4
DT = 1e-4
STEPS = 400


def write_msh(path, vertices, triangles):
    """gmsh 2.2 ASCII, triangles only."""
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(vertices))
        for i, v in enumerate(vertices):
            f.write("%d %.17g %.17g 0\n" % (i + 1, v[0], v[1]))
        f.write("$EndNodes\n$Elements\n%d\n" % len(triangles))
        for i, t in enumerate(triangles):
            f.write("%d 2 2 1 1 %d %d %d\n" % (i + 1, t[0] + 1, t[1] + 1, t[2] + 1))
        f.write("$EndElements\n")


def pad_mesh(family, p, nx, ny, size):
    """The design's cell tiled nx x ny, opposite sides' vertices welded; x in [0, nx w], y in [0, ny h]."""
    v, t = family.mesh(p, size=size * H_CELL, height=H_CELL)
    w = p[family.width_index] * H_CELL
    verts, tris = [], []
    for i in range(nx):
        for j in range(ny):
            tris.append(t + len(verts) * len(v))
            verts.append(v + [w / 2 + i * w, H_CELL / 2 + j * H_CELL])
    V = np.vstack(verts)
    T = np.vstack(tris)
    key = np.round(V / (1e-9 * H_CELL)).astype(np.int64)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return V[first], first.size, inverse.reshape(-1)[T], nx * w


def run_drop(name, pad, width, out, cli, pad_height):
    folder = os.path.join(out, name)
    os.makedirs(folder, exist_ok=True)
    rho_block = MASS / (width * H_CELL)
    top = pad_height
    bodies = []
    if isinstance(pad, tuple):
        V, T = pad
        write_msh(os.path.join(folder, "pad.msh"), V, T)
        bodies.append({"name": "pad", "mesh": {"file": "pad.msh"}})
    else:
        bodies.append({"name": "pad", "mesh": {"box": pad}})
    bodies[0]["material"] = {"model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": 1000, "plane": "stress"}
    cells = [max(8, int(round(width / (H_CELL / 4)))), 4]
    bodies.append({"name": "block",
                   "mesh": {"box": {"min": [0, top + GAP], "max": [width, top + GAP + H_CELL], "cells": cells}},
                   "material": {"model": "neo_hookean", "E": 1e8, "nu": 0.3, "density": rho_block, "plane": "stress"},
                   "initial_velocity": [0, -SPEED]})
    scene = {
        "description": f"Study 408 drop test: a block on the {name} pad",
        "dimension": 2, "bodies": bodies, "gravity": [0, -9.81],
        "dirichlet": [{"body": 0, "region": {"min": [-1, -1e-9], "max": [width + 1, 1e-9]}, "displacement": [0, 0]}],
        "contact": {"dhat": 1e-3 * H_CELL},
        "friction": {"coefficient": 0.3},
        "time": {"integrator": "implicit_euler", "dt": DT, "steps": STEPS},
        "solver": {"max_iterations": 400},
    }
    path = os.path.join(folder, "scene.json")
    json.dump(scene, open(path, "w"), indent=1)
    run = subprocess.run([cli, "simulate", path, "-o", os.path.join(folder, "output"), "-q"], capture_output=True,
                         text=True)
    check = subprocess.run([cli, "check", os.path.join(folder, "output"), "-q"], capture_output=True, text=True)
    found = re.search(r"(\d+) of (\d+) states valid", check.stdout + check.stderr)
    with h5py.File(os.path.join(folder, "output", "trajectory.h5"), "r") as f:
        t = f["time"][:]
        vel = f["velocities"][:]
        X = f["mesh/rest_positions"][:]
        E = f["mesh/elements"][:]
        body = f["mesh/body"][:]
        ebody = f["mesh/element_body"][:]
        status = f["status"][:]
        wall = f["wall_time"][:]
    # lumped masses of the block: rho A_e / 3 per corner
    m = np.zeros(len(X))
    for e in np.nonzero(ebody == 1)[0]:
        a, b, c = X[E[e]]
        area = 0.5 * abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        m[E[e]] += rho_block * area / 3
    M = m.sum()
    P = (m[None, :] * vel[:, :, 1]).sum(axis=1)
    dP = np.diff(P) / np.diff(t)
    force = dP + M * 9.81
    stress = force / width
    return {
        "name": name, "t": t[1:], "stress": stress, "deceleration": dP / M, "mass": M,
        "steps": int((status == 0).sum()), "requested": STEPS,
        "status": "ok" if run.returncode == 0 else run.stderr.strip()[-200:],
        "check": found.group(0) if found else (check.stdout + check.stderr).strip()[-200:],
        "wall": float(wall.sum()),
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--params", default="output/408_shock_microstructure/params.json")
    parser.add_argument("--full", action="store_true")
    parser.add_argument("-o", "--output", default="output/408_shock_microstructure/drop")
    parser.add_argument("--cli", default="build/cli/diffipc")
    parser.add_argument("--nx", type=int, default=8)
    parser.add_argument("--ny", type=int, default=3)
    args = parser.parse_args()
    params = json.load(open(args.params))
    size = params["size"] / params.get("height", 1.0)
    family = ms.family("reentrant")
    results = []
    area_optimized = None
    for name, p in params["designs"].items():
        if not args.full and name not in ("initial", "L-BFGS-B"):
            continue
        p = np.array(p)
        V, nv, T, width = pad_mesh(family, p, args.nx, args.ny, size)
        a = V[T[:, 1]] - V[T[:, 0]]
        b = V[T[:, 2]] - V[T[:, 0]]
        area = 0.5 * np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        if name == "L-BFGS-B":
            area_optimized, width_optimized = area, width
        print(f"{name}: {len(T)} triangles, solid area {area:.4g} m^2", flush=True)
        r = run_drop(name.replace("-", "").lower(), (V, T), width, args.output, args.cli, args.ny * H_CELL)
        r["label"] = name + " pad"
        results.append(r)
    solid_height = area_optimized / width_optimized
    r = run_drop("solid", {"min": [0, 0], "max": [width_optimized, solid_height],
                           "cells": [int(round(width_optimized / (size * H_CELL))), max(2, int(round(solid_height / (size * H_CELL))))]},
                 width_optimized, args.output, args.cli, solid_height)
    r["label"] = f"solid pad, same mass ({1000 * solid_height:.1f} mm tall)"
    results.append(r)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    for r in results:
        axes[0].semilogy(1000 * r["t"], np.maximum(r["stress"], 1.0), label=r["label"])
        if r["name"] != "solid":
            axes[1].plot(1000 * r["t"], r["stress"], label=r["label"])
        axes[2].plot(1000 * r["t"], r["deceleration"] / 9.81, label=r["label"])
    axes[0].set_ylabel("stress on the block's bottom face (Pa, log)")
    axes[1].set_ylabel("the same, cellular pads (Pa)")
    axes[1].axhline(params["target_stress"], color="k", lw=0.8, ls="--", label="plateau target sigma*")
    axes[2].set_ylabel("block's deceleration (g)")
    for ax in axes:
        ax.set_xlabel("t (ms)")
    axes[0].legend(fontsize=8)
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.output, "drop_stress.png"), dpi=110)
    ref = {r["name"]: r for r in results}
    lines = ["| pad | steps | peak stress (Pa) | peak deceleration (g) | reduction against solid | against initial "
             "| wall time (s) | diffipc check |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in results:
        peak = r["stress"].max()
        lines.append(f"| {r['label']} | {r['steps']} of {r['requested']} ({r['status']}) | {peak:.0f} "
                     f"| {r['deceleration'].max() / 9.81:.2f} | {100 * (1 - peak / ref['solid']['stress'].max()):.0f}% "
                     f"| {100 * (1 - peak / ref['initial']['stress'].max()):.0f}% | {r['wall']:.0f} | {r['check']} |")
    text = "\n".join(lines) + "\n"
    open(os.path.join(args.output, "drop.md"), "w").write(text)
    print(text)


if __name__ == "__main__":
    main()
