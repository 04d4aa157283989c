#!/usr/bin/env python3
"""Study 208: the lattice block compressed by a traction-driven plate, for E in {5e4, 1e5, 2e5} Pa
and nu in {0.3, 0.48} (the traction scales with E: 3 kPa at E = 1e5, the same collapse).

    PYTHONPATH=build/python /usr/bin/python3 studies/208_lattice_block/run.py [--cli build/cli/diffipc]
        [-o output/208] [--threads N] [--jobs N] [--cases E:nu ...] [--summarize-only]

Writes per case the run folder (trajectory.h5, summary.json, VTU frames), and results.md with
each run's outcome, Newton iterations per step and per solve, cuts, control and relaxation solves,
and force_displacement.png (the plate's traction against its mean downward displacement).
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def case_folder(out, E, nu):
    return os.path.join(out, f"E{E:g}_nu{nu:g}")


def run_case(cli, out, E, nu, threads):
    scene = json.load(open(os.path.join(HERE, "scene.json")))
    scene["bodies"][0]["material"].update(E=E, nu=nu)
    pressure = 3000.0 * E / 1e5
    scene["neumann"][0]["traction"] = [0, 0, f"-{pressure:g}*t"]
    scene["bodies"][0]["mesh"]["file"] = os.path.join(HERE, "lattice.msh")
    folder = case_folder(out, E, nu)
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "scene.json")
    json.dump(scene, open(path, "w"), indent=1)
    cmd = [cli, "simulate", path, "-o", folder] + (["--threads", str(threads)] if threads else [])
    done = subprocess.run(cmd, capture_output=True, text=True)
    (open(os.path.join(folder, "log.txt"), "w")).write(done.stdout + done.stderr)
    return folder, pressure, done.returncode


def summarize(folder, pressure):
    with h5py.File(os.path.join(folder, "trajectory.h5"), "r") as f:
        x = f["positions"][:]
        body = f["mesh/body"][:]
        t = f["time"][:]
        its = f["newton_iterations"][:]
        cols = {k: f[k][:] for k in ("substeps", "cuts", "control_steps", "relaxation_steps") if k in f}
    plate = body == 1
    settle = -(x[:, plate, 2] - x[0, plate, 2]).mean(axis=1)  # mean downward displacement, m
    solves = 1 + sum(cols[k] for k in cols)
    return dict(t=t, load=pressure * t, settle=settle, its=its, per_solve=its / solves, **cols)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default="build/cli/diffipc")
    p.add_argument("-o", "--output", default="output/208")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--cases", nargs="*", default=["5e4:0.3", "1e5:0.3", "2e5:0.3", "5e4:0.48", "1e5:0.48", "2e5:0.48"])
    p.add_argument("--jobs", type=int, default=1, help="cases run at once")
    p.add_argument("--summarize-only", action="store_true", help="do not run; summarize the case folders")
    a = p.parse_args(argv)
    cases = [tuple(float(v) for v in case.split(":")) for case in a.cases]
    if not a.summarize_only:
        with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
            list(pool.map(lambda c: run_case(a.cli, a.output, c[0], c[1], a.threads), cases))
    rows, curves = [], []
    for E, nu in cases:
        folder, pressure = case_folder(a.output, E, nu), 3000.0 * E / 1e5
        summary = json.load(open(os.path.join(folder, "summary.json")))
        s = summarize(folder, pressure)
        curves.append((E, nu, s))
        steps = len(s["t"]) - 1
        # The committed states checked by exact tests independent of the solver's contact code.
        check = subprocess.run([a.cli, "check", folder, "--scene", os.path.join(folder, "scene.json"), "-q"],
                               capture_output=True, text=True)
        valid = (check.stdout.strip().splitlines() or [check.stderr.strip()])[-1]
        rows.append(f"| {E:g} | {nu:g} | {summary.get('status')} | {steps} | {s['settle'][-1] * 1e3:.2f} | "
                    f"{np.median(s['its']) if steps else float('nan'):.0f} | "
                    f"{np.median(s['per_solve']) if steps else float('nan'):.1f} | "
                    f"{int(sum(s.get('cuts', [0])))} | {int(sum(s.get('control_steps', [0])))} | "
                    f"{int(sum(s.get('relaxation_steps', [0])))} | {valid} |")
        print(rows[-1], flush=True)
    with open(os.path.join(a.output, "results.md"), "w") as f:
        f.write("| E (Pa) | nu | status | steps | plate settlement (mm) | median Newton its / step | "
                "median its / solve | cuts | control solves | relaxation solves | diffipc check |\n|" + " --- |" * 11 + "\n")
        f.write("\n".join(rows) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for E, nu, s in curves:
            ax.plot(s["settle"] * 1e3, s["load"] / E, "o-", ms=3, label=f"E {E:g}, nu {nu:g}")
        ax.set_xlabel("plate displacement (mm)")
        ax.set_ylabel("traction / E")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(a.output, "force_displacement.png"), dpi=120)
    except ImportError:
        print("matplotlib missing: no figure", file=sys.stderr)


if __name__ == "__main__":
    main()
