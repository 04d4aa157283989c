#!/usr/bin/env python3
"""Study 408, the drop test: a block falls on a pad of cells; the stress it feels.

    PYTHONPATH=build/python /usr/bin/python3 studies/408_shock_microstructure/drop.py
        --params output/408_shock_microstructure/params.json [--transient .../transient.json] [--full]
        [-o DIR] [--cli build/cli/diffipc]

A pad of nx x ny cells (default 8 x 3; cell height 1 cm, mesh size 0.025 of the cell's height)
is bonded to the ground (its bottom vertices fixed); a stiff block (E = 100 MPa, the pad's width,
1 cm tall, 2.5 kg per metre of depth for 8 cells: 306 Pa of weight on a pad 8 cm wide) starts 0.5 mm above it at
0.5 m/s downward under gravity, implicit Euler, dt = 0.1 ms, 400 steps, contact (dhat 10 um, the
fixed barrier stiffness of the drop objective, drop_settings()) and friction mu = 0.3 between the
block and the pad: the scene of diffipc.microstructure.DropDesign (shape_opt/microstructure/
drop_design.hpp), the one the transient optimization (run.py) differentiates. The same drop on
the pads of the designs of params.json (without --full: the initial one and those named in
--designs), of transient.py's design (--transient), and on a solid pad of the quasi-static optimum's mass (the same material, the same
width, as tall as its area requires).

The stress on the block's bottom face, per step (plane stress, per metre of depth), computed here
from the trajectory file (independently of DropDesign's own figure):
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
KAPPA = 1e17  # fixed barrier stiffness (the barrier is on squared distances: dhat^2 = 1e-10 m^2); the adjoint needs a fixed one


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def drop_settings(nx, ny, size, steps, target_stress, speed=0.5):
    """The drop's settings (DropDesign): the block's mass per depth scales with the pad's width
    (2.5 kg/m for 8 cells)."""
    return {"height": H_CELL, "size": size * H_CELL, "cells": [nx, ny],
            "block": {"E": 1e8, "mass": 2.5 * nx / 8, "speed": speed, "gap": 5e-4},
            "dhat": 1e-3 * H_CELL, "kappa": KAPPA, "friction": 0.3, "dt": 1e-4, "steps": steps, "max_p": 8,
            "target_stress": target_stress, "solver": {"max_iterations": 400}}


def simulate(folder, scene, cli):
    """Runs `scene` (a dict) in `folder` through the CLI, checks every state, and measures the stress on the block."""
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
        ebody = f["mesh/element_body"][:]
        status = f["status"][:]
        wall = f["wall_time"][:]
    block = scene["bodies"][1]
    rho = block["material"]["density"]
    width = block["mesh"]["box"]["max"][0] - block["mesh"]["box"]["min"][0]
    # lumped masses of the block: rho A_e / 3 per corner
    m = np.zeros(len(X))
    for e in np.nonzero(ebody == 1)[0]:
        a, b, c = X[E[e]]
        area = 0.5 * abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        m[E[e]] += rho * area / 3
    M = m.sum()
    P = (m[None, :] * vel[:, :, 1]).sum(axis=1)
    dP = np.diff(P) / np.diff(t)
    force = dP + M * 9.81
    return {
        "t": t[1:], "stress": force / width, "deceleration": dP / M, "mass": M,
        "steps": int((status == 0).sum()), "requested": scene["time"]["steps"],
        "status": "ok" if run.returncode == 0 else run.stderr.strip()[-200:],
        "check": found.group(0) if found else (check.stdout + check.stderr).strip()[-200:],
        "wall": float(wall.sum()),
    }


def run_drop(name, design, p, out, cli):
    """The drop on the pad of design p (DropDesign's scene)."""
    folder = os.path.join(out, name)
    scene = json.load(open(design.write_scene(p, folder)))
    r = simulate(folder, scene, cli)
    r["name"] = name
    return r


def run_solid(design, nx, cell_width, height, size, gap, out, cli):
    """The same drop on a solid pad as wide as nx cells of width cell_width, `height` tall (a
    structured mesh at the given size), the block starting `gap` above it."""
    folder = os.path.join(out, "solid")
    os.makedirs(folder, exist_ok=True)
    scene = json.loads(design.scene("pad.msh", cell_width))
    width = nx * cell_width * H_CELL
    scene["description"] = "Study 408 drop test: a block on a solid pad"
    scene["bodies"][0]["mesh"] = {"box": {"min": [0, 0], "max": [width, height],
                                          "cells": [int(round(width / size)), max(2, int(round(height / size)))]}}
    box = scene["bodies"][1]["mesh"]["box"]
    box["min"][1], box["max"][1] = height + gap, height + gap + H_CELL
    r = simulate(folder, scene, cli)
    r["name"] = "solid"
    return r


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--params", default="output/408_shock_microstructure/params.json")
    parser.add_argument("--full", action="store_true", help="drop every design of params.json")
    parser.add_argument("--designs", nargs="*", default=["L-BFGS-B"],
                        help="the designs of params.json dropped besides the initial one (without --full)")
    parser.add_argument("-o", "--output", default="output/408_shock_microstructure/drop")
    parser.add_argument("--cli", default="build/cli/diffipc")
    parser.add_argument("--nx", type=int, default=8)
    parser.add_argument("--ny", type=int, default=3)
    parser.add_argument("--size", type=float, default=0.025, help="mesh size relative to the cell's height")
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--transient", help="transient.json of transient.py: its design is dropped too, as 'transient'")
    args = parser.parse_args()
    params = json.load(open(args.params))
    if args.transient:
        params["designs"]["transient"] = json.load(open(args.transient))["x"]
        args.designs = list(args.designs) + ["transient"]
    family = ms.family("reentrant")
    settings = drop_settings(args.nx, args.ny, args.size, args.steps, params["target_stress"])
    design = ms.DropDesign(family, settings)
    results = []
    reference = None  # the solid pad has the mass of this design's pad
    for name, p in params["designs"].items():
        if not args.full and name != "initial" and name not in args.designs:
            continue
        p = np.array(p)
        V, T = family.mesh(p, size=args.size * H_CELL, height=H_CELL)
        a = V[T[:, 1]] - V[T[:, 0]]
        b = V[T[:, 2]] - V[T[:, 0]]
        area = args.nx * args.ny * 0.5 * np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        if reference is None and name != "initial":
            reference = (name, area, p[family.width_index])
        print(f"{name}: solid area {area:.4g} m^2", flush=True)
        r = run_drop(name.replace("-", "").lower(), design, p, args.output, args.cli)
        r["label"] = name + " pad"
        results.append(r)
    ref_name, ref_area, ref_width = reference
    solid_height = ref_area / (args.nx * ref_width * H_CELL)
    r = run_solid(design, args.nx, ref_width, solid_height, args.size * H_CELL, settings["block"]["gap"], args.output,
                  args.cli)
    r["label"] = f"solid pad, {ref_name}'s mass ({1000 * solid_height:.1f} mm tall)"
    results.append(r)
    plt = pyplot()
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
