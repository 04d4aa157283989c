#!/usr/bin/env python3
"""Study 210: a periodic cell whose posts touch across its boundary, compressed by 30%.

    PYTHONPATH=build/python /usr/bin/python3 studies/210_periodic_posts/run.py [--cli build/cli/diffipc]
        [-o output/210] [--threads N]

Runs scene.json (contact through the periodic images) and scene_no_contact.json (the same without
contact), checks every committed state of both with `diffipc check` (exact inversion and
intersection tests on the cell's 3 x 3 tiling, independent of the contact code), and writes
results.md (status, steps, Newton iterations, wall time, first step with contact, valid states)
and stress_strain.png (the homogenized stress P_yy against the compression -G_yy, from
trajectory.h5's macro_stress and macro_gradient).
"""
import argparse
import json
import os
import re
import subprocess

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = {"contact": "scene.json", "no contact": "scene_no_contact.json"}


def run_case(cli, out, name, scene, threads):
    folder = os.path.join(out, name.replace(" ", "_"))
    os.makedirs(folder, exist_ok=True)
    cmd = [cli] + (["--threads", str(threads)] if threads else [])
    done = subprocess.run(cmd + ["simulate", os.path.join(HERE, scene), "-o", folder, "-q"], capture_output=True,
                          text=True)
    check = subprocess.run(cmd + ["check", folder, "-q"], capture_output=True, text=True)
    summary = json.load(open(os.path.join(folder, "summary.json")))
    with h5py.File(os.path.join(folder, "trajectory.h5"), "r") as f:
        G = f["macro_gradient"][:]
        P = f["macro_stress"][:]
        its = f["newton_iterations"][:]
        contacts = f["active_contacts"][:] if "active_contacts" in f else np.zeros_like(its)
        wall = f["wall_time"][:]
    valid = re.search(r"(\d+) of (\d+) states valid", check.stdout + check.stderr)
    touching = np.nonzero(contacts > 0)[0]
    return {
        "name": name,
        "status": summary.get("status", "?") if done.returncode == 0 else "FAILED: " + (done.stderr.strip() or "?"),
        "steps": len(its),
        "strain": -G[:, 1, 1],
        "stress": P[:, 1, 1],
        "lateral": P[:, 0, 0],
        "newton": int(its.sum()),
        "max_newton": int(its.max()),
        "wall": float(wall.sum()),
        "first_contact": float(-G[touching[0], 1, 1]) if len(touching) else None,
        "check": valid.group(0) if valid else (check.stdout + check.stderr).strip().splitlines()[-1],
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cli", default="build/cli/diffipc")
    parser.add_argument("-o", "--output", default="output/210")
    parser.add_argument("--threads", type=int, default=0)
    args = parser.parse_args()
    results = [run_case(args.cli, args.output, name, scene, args.threads) for name, scene in CASES.items()]

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for r, style in zip(results, ("o-", "s--")):
        ax.plot(100 * np.r_[0, r["strain"]], -np.r_[0, r["stress"]] / 1e3, style, ms=3, label=r["name"])
    first = results[0]["first_contact"]
    if first is not None:
        ax.axvline(100 * first, color="gray", lw=0.8)
        ax.text(100 * first, ax.get_ylim()[1] * 0.95, " first contact", color="gray", va="top")
    ax.set_xlabel("compression -G_yy (%)")
    ax.set_ylabel("compressive stress -P_yy (kPa)")
    ax.set_title("periodic post cell, E = 100 kPa, nu = 0.3")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "stress_strain.png"), dpi=120)

    lines = ["| case | status | steps | Newton its | max its / step | wall time of the steps (s) | "
             "first contact at | P_yy at 30% (kPa) | max abs P_xx (Pa, free) | diffipc check |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in results:
        first = "-" if r["first_contact"] is None else f"{100 * r['first_contact']:.1f}%"
        lines.append(f"| {r['name']} | {r['status']} | {r['steps']} | {r['newton']} | {r['max_newton']} | "
                     f"{r['wall']:.1f} | {first} | {r['stress'][-1] / 1e3:.2f} | "
                     f"{np.abs(r['lateral']).max():.1e} | {r['check']} |")
    open(os.path.join(args.output, "results.md"), "w").write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
