#!/usr/bin/python3
"""Compares two runs of one scene step by step (e.g. `diffipc simulate --device cpu` and `--device gpu`).

Usage: /usr/bin/python3 scripts/compare_trajectories.py A/trajectory.h5 B/trajectory.h5 [--quiet]

Per committed step: max |x_B - x_A| over the vertices, relative to the scene size (the diagonal of
the bounding box of A's initial positions); for periodic cells the homogenized stress's largest difference relative to A's
largest entry; with contact the barrier stiffness and active pairs of both; Newton iterations. Then the worst
of each. Exits with 2 if the files do not hold the same scene (vertex counts) or a step count differs.
"""
import argparse
import sys

import h5py
import numpy as np


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("a", help="the reference run's trajectory.h5")
    parser.add_argument("b", help="the compared run's trajectory.h5")
    parser.add_argument("--quiet", action="store_true", help="only the summary line")
    args = parser.parse_args()
    with h5py.File(args.a, "r") as a, h5py.File(args.b, "r") as b:
        xa, xb = a["positions"], b["positions"]
        if xa.shape[1:] != xb.shape[1:]:
            print(f"{args.b}: positions {xb.shape[1:]}, {args.a}: {xa.shape[1:]}: not the same scene", file=sys.stderr)
            return 2
        steps = min(xa.shape[0], xb.shape[0]) - 1
        if xa.shape[0] != xb.shape[0]:
            print(f"note: {args.a} has {xa.shape[0] - 1} committed steps, {args.b} {xb.shape[0] - 1}; "
                  f"comparing the first {steps}", file=sys.stderr)
        rest = xa[0]
        size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
        periodic = "macro_stress" in a and "macro_stress" in b
        contact = all(key in f for f in (a, b) for key in ("kappa", "active_contacts"))
        worst_x, worst_stress, kappa_differs, worst_kappa = 0.0, 0.0, 0, 0.0
        for k in range(1, steps + 1):
            dx = float(np.abs(xa[k] - xb[k]).max()) / size
            worst_x = max(worst_x, dx)
            line = f"step {k:4d}: x {dx:.1e} of the size"
            if periodic:
                sa, sb = a["macro_stress"][k - 1], b["macro_stress"][k - 1]
                scale = float(np.abs(sa).max())
                ds = float(np.abs(sa - sb).max()) / scale if scale > 0 else float(np.abs(sb).max())
                worst_stress = max(worst_stress, ds)
                line += f", stress {ds:.1e}"
            if contact:
                ka, kb = float(a["kappa"][k - 1]), float(b["kappa"][k - 1])
                kappa_differs += ka != kb
                worst_kappa = max(worst_kappa, abs(ka - kb) / max(abs(ka), abs(kb), 1e-300))
                line += (f"; kappa {ka:.3g} / {kb:.3g}; active pairs {a['active_contacts'][k - 1]} / "
                         f"{b['active_contacts'][k - 1]}")
            line += f"; Newton {a['newton_iterations'][k - 1]} / {b['newton_iterations'][k - 1]}"
            if not args.quiet:
                print(line)
        summary = f"{steps} steps: states within {worst_x:.1e} of the size {size:.3g} m"
        if periodic:
            summary += f", homogenized stress within {worst_stress:.1e} relative"
        if contact:
            summary += f"; kappa differs in {kappa_differs} steps (by up to {worst_kappa:.1e} relative)"
        print(summary)
    return 2 if xa.shape[0] != xb.shape[0] else 0


if __name__ == "__main__":
    sys.exit(main())
