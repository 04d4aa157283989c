#!/usr/bin/env python3
"""Study 408: a cushion cell optimized for a flat stress plateau, then for a drop test (issue 15).

    PYTHONPATH=build/python /usr/bin/python3 studies/408_shock_microstructure/run.py [--full]
        [-o output/408] [--cli build/cli/diffipc] [--no-drop]

The re-entrant cell (shape_opt/microstructure/topologies/reentrant.json: 7 design variables)
compressed quasi-statically as a periodic cell to 40% (plane stress neo-Hookean E = 1 MPa,
nu = 0.3, contact dhat 1 mm, kappa 1e10 (the default 1e4 E / h^2), G_xy held at 0, G_xx free),
its plateau objective J = sum_i (sigma_i / sigma* - 1)^2 + 10 sum_i G_xx(i)^2 over the strains
10%, 15%, ..., 40% (sigma* = 500 Pa), minimized from the family's initial design by L-BFGS-B and
by MMA. Writes into the output folder: params.json (the designs), cells.png (before and after,
2 x 2 cells), stress_strain.png (curves against the +-10% band), history.png (J per iteration,
remeshes), results.md (the tables), and each design's scene (cell.msh, scene.json) with its
`diffipc simulate` run checked by `diffipc check` (exact inversion and intersection tests on the
cell's tiling, independent of the contact code). Then transient.py (the L-BFGS-B optimum
optimized further on the drop test's peak stress) and drop.py (the drop test of the designs'
pads against a solid pad). The default: mesh size 0.025 m in a 1 m cell, 40 iterations each, 3
transient iterations, drops of 25 ms (250 steps). --full: a mesh continuation (40 iterations at 0.025 m, 30 more at 0.0125 m,
20 more at 0.00625 m), the plateau checked at half the last size, 12 transient iterations, every
design dropped for 40 ms.
"""
import argparse
import json
import os
import re
import subprocess
import time

import numpy as np

from diffipc import microstructure as ms

from drop import pyplot

TARGET = 500.0
BAND = 0.10
RANGE = (0.10, 0.40)


def settings(size):
    return {
        "height": 1.0, "size": size,
        "material": {"model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": 1000, "plane": "stress"},
        "dhat": 1e-3, "max_strain": 0.4, "steps": 16, "samples": [4, 6, 8, 10, 12, 14, 16],
        "target_stress": TARGET, "shear": "fixed", "shear_weight": 50, "lateral_weight": 10,
        "solver": {"max_iterations": 400},
    }


def deviation(result):
    """Largest |sigma / sigma* - 1| over the steps with strain in RANGE (nan for a failed compression)."""
    if not result["ok"]:
        return float("nan")
    strain, stress = result["strain"], result["stress"]
    inside = (strain >= RANGE[0] - 1e-12) & (strain <= RANGE[1] + 1e-12)
    return float(np.max(np.abs(stress[inside] / TARGET - 1)))


def check_scene(design, p, folder, cli):
    """The design's compression through the CLI, and `diffipc check` of every state."""
    scene = design.write_scene(p, folder)
    out = os.path.join(folder, "output")
    sim = subprocess.run([cli, "simulate", scene, "-o", out, "-q"], capture_output=True, text=True)
    check = subprocess.run([cli, "check", out, "-q"], capture_output=True, text=True)
    found = re.search(r"(\d+) of (\d+) states valid", check.stdout + check.stderr)
    if sim.returncode != 0:
        return "simulate failed: " + sim.stderr.strip()
    return found.group(0) if found else (check.stdout + check.stderr).strip()


def plot_cells(family, designs, size, path):
    plt = pyplot()
    fig, axes = plt.subplots(1, len(designs), figsize=(4 * len(designs), 4.4))
    for ax, (name, p) in zip(axes, designs.items()):
        v, t = family.mesh(p, size=size)
        w = p[family.width_index]
        for i in range(2):
            for j in range(2):
                ax.tripcolor(v[:, 0] + i * w, v[:, 1] + j, t, np.zeros(len(t)), cmap="Greys", vmin=-1, vmax=1.5,
                             edgecolors="none")
        ax.set_title(f"{name}\n({len(t)} triangles per cell)")
        ax.set_aspect("equal")
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_curves(results, path):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ax.axhspan(TARGET * (1 - BAND), TARGET * (1 + BAND), xmin=0, xmax=1, color="#d8ecd8", label="sigma* +- 10%")
    ax.axvspan(0, RANGE[0] * 100, color="#eeeeee")
    for name, r in results.items():
        ax.plot(100 * np.r_[0, r["strain"]], np.r_[0, r["stress"]], marker=".", label=name)
    ax.axhline(TARGET, color="k", lw=0.8)
    ax.set_xlabel("compressive strain (%)")
    ax.set_ylabel("homogenized stress -P_yy (Pa)")
    ax.set_xlim(0, 40)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_history(runs, path):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for name, run in runs.items():
        h = run["history"]
        ax.semilogy([e["iteration"] for e in h], [e["J"] for e in h], marker=".", label=name)
        for a, b in zip(h, h[1:]):
            if b["mesh"] != a["mesh"]:
                ax.plot([b["iteration"]], [b["J"]], "kx")
    ax.set_xlabel("iteration (x: a new mesh)")
    ax.set_ylabel("J")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--full", action="store_true",
                        help="continue on meshes of size 0.0125 and 0.00625 m (30 and 20 more iterations)")
    parser.add_argument("-o", "--output", default="output/408_shock_microstructure")
    parser.add_argument("--cli", default="build/cli/diffipc")
    parser.add_argument("--no-drop", action="store_true",
                        help="skip the transient optimization (transient.py) and the drop test (drop.py)")
    args = parser.parse_args()
    # mesh continuation: (size, iterations) per level, each level starting from the last one's design
    levels = [(0.025, 40), (0.0125, 30), (0.00625, 20)] if args.full else [(0.025, 40)]
    size = levels[-1][0]
    iterations = sum(n for _, n in levels)
    os.makedirs(args.output, exist_ok=True)
    family = ms.family("reentrant")
    design = ms.CellDesign(family, settings(size))
    fine = ms.CellDesign(family, settings(size / 2))
    x0 = family.initial
    start = time.time()
    runs = {}
    for algorithm in ("mma", "lbfgsb"):
        t0 = time.time()
        x, run = x0, None
        for level, (h, n) in enumerate(levels):
            try:
                r = ms.CellDesign(family, settings(h)).optimize(
                    x, algorithm=algorithm, max_iterations=n, remesh_quality=0.3,
                    callback=lambda e: print(f"{algorithm} size {h} {e['iteration']:3d} J {e['J']:.5g}", flush=True))
            except ValueError as error:  # this level's mesh cannot simulate the last level's design
                if run is None:
                    raise
                run["stopped"] = f"the continuation stopped at mesh size {h} m: {error}"
                print(f"{algorithm}: {run['stopped']}", flush=True)
                break
            for e in r["history"]:
                e["level"] = level
            if run is None:
                run = r
            else:  # one history over the levels; a new level is a new mesh
                last = run["history"][-1]
                for e in r["history"]:
                    e["iteration"] += last["iteration"]
                    e["mesh"] += last["mesh"] + 1
                run["history"] += r["history"]
                for key in ("evaluations", "rejected"):
                    run[key] += r[key]
                run["remeshes"] += r["remeshes"] + 1
            x = run["x"] = r["x"]
            run["size"] = h
            with open(os.path.join(args.output, f"{algorithm}_levels.json"), "a") as f:  # progress, per level
                f.write(json.dumps({"size": h, "x": list(map(float, x)), "J": r["history"][-1]["J"]}) + "\n")
        runs[algorithm] = run
        runs[algorithm]["seconds"] = time.time() - t0
    designs = {"initial": x0, "L-BFGS-B": runs["lbfgsb"]["x"], "MMA": runs["mma"]["x"]}
    results, checks, rows = {}, {}, []
    for name, p in designs.items():
        r = design.evaluate(p)
        rf = fine.evaluate(p)
        results[name] = r
        checks[name] = check_scene(design, p, os.path.join(args.output, name.replace("-", "").lower()), args.cli)
        run = runs.get({"L-BFGS-B": "lbfgsb", "MMA": "mma"}.get(name, ""), {})
        rows.append((name, r["J"] if r["ok"] else float("nan"), deviation(r), deviation(rf),
                     len(run.get("history", [])) - 1 - run.get("remeshes", 0) if run else 0,
                     run.get("evaluations", 0), run.get("remeshes", 0), run.get("seconds", 0.0), checks[name]))
    with open(os.path.join(args.output, "params.json"), "w") as f:
        json.dump({"names": family.names, "target_stress": TARGET, "strain_range": RANGE, "size": size, "height": 1.0,
                   "designs": {k: list(map(float, v)) for k, v in designs.items()}}, f, indent=2)
    plot_cells(family, designs, size, os.path.join(args.output, "cells.png"))
    plot_curves(results, os.path.join(args.output, "stress_strain.png"))
    plot_history(runs, os.path.join(args.output, "history.png"))
    with open(os.path.join(args.output, "results.md"), "w") as f:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                             cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip() or "?"
        f.write(f"Mesh size {size} m (cell height 1 m), {iterations} iterations at most; "
                f"wall time {time.time() - start:.0f} s (optimizations and checks); build {rev}.\n\n")
        f.write("| design | J (new mesh) | max abs(sigma/sigma* - 1), 10-40% | same at half the mesh size "
                "| iterations | evaluations | remeshes | optimizer wall time (s) | diffipc check |\n")
        f.write("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n")
        for row in rows:
            f.write(f"| {row[0]} | {row[1]:.4g} | {100 * row[2]:.1f}% | {100 * row[3]:.1f}% | {row[4]} | {row[5]} "
                    f"| {row[6]} | {row[7]:.0f} | {row[8]} |\n")
        for name, run in runs.items():
            if "stopped" in run:
                f.write(f"\n{name}: {run['stopped']}\n")
        for name, r in results.items():
            if not r["ok"]:
                f.write(f"\n{name} at mesh size {size} m: {r['message']}\n")
        f.write("\n| variable | " + " | ".join(designs) + " |\n| --- |" + " --- |" * len(designs) + "\n")
        for i, n in enumerate(family.names):
            f.write(f"| {n} | " + " | ".join(f"{designs[k][i]:.4f}" for k in designs) + " |\n")
    if not args.no_drop:
        here = os.path.dirname(os.path.abspath(__file__))
        params_path = os.path.join(args.output, "params.json")
        # the transient objective from the L-BFGS-B optimum, then the drop test of the designs
        transient = os.path.join(args.output, "transient")
        subprocess.run(["/usr/bin/python3", os.path.join(here, "transient.py"), "--params", params_path, "-o", transient,
                        "--iterations", "12" if args.full else "3"], check=True)
        t = json.load(open(os.path.join(transient, "transient.json")))
        drop = os.path.join(args.output, "drop")
        subprocess.run(["/usr/bin/python3", os.path.join(here, "drop.py"), "--params", params_path, "-o", drop,
                        "--cli", args.cli, "--transient", os.path.join(transient, "transient.json")]
                       + (["--full"] if args.full else ["--steps", "250"]),
                       check=True)
        with open(os.path.join(args.output, "results.md"), "a") as f:
            f.write(f"\nTransient objective (transient.py; transient/transient_history.png), from {t['start']}, "
                    f"width held, on the {' x '.join(map(str, t['settings']['cells']))} pad: J {t['J'][0]:.4g} -> "
                    f"{t['J'][1]:.4g}, peak stress {t['peak'][0]:.0f} -> {t['peak'][1]:.0f} Pa (new meshes), "
                    f"{len(t['history']) - 1 - t['remeshes']} iterations, {t['evaluations']} evaluations "
                    f"({t['rejected']} rejected), {t['remeshes']} remeshes, {t['seconds']:.0f} s. The plateau's max "
                    f"abs(sigma/sigma* - 1) over 10-40% at mesh size {t['plateau']['size']} m: "
                    f"{100 * t['plateau']['start']:.1f}% -> {100 * t['plateau']['transient']:.1f}%.\n\n"
                    "| variable | " + t["start"] + " | transient |\n| --- | --- | --- |\n"
                    + "".join(f"| {n} | {a:.4f} | {b:.4f} |\n" for n, a, b in zip(t["names"], t["x0"], t["x"])))
            f.write("\nDrop test (drop.py; drop/drop_stress.png):\n\n" + open(os.path.join(drop, "drop.md")).read())
    print(open(os.path.join(args.output, "results.md")).read())


if __name__ == "__main__":
    main()
