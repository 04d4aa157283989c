#!/usr/bin/env python3
"""Study 408, the transient objective: the cell optimized for the drop test's peak stress itself.

    PYTHONPATH=build/python /usr/bin/python3 studies/408_shock_microstructure/transient.py
        --params output/408_shock_microstructure/params.json [--start L-BFGS-B] [--iterations 10]
        [-o output/408_shock_microstructure/transient]

From a quasi-static optimum of params.json (run.py), L-BFGS-B minimizes the drop objective of
diffipc.microstructure.DropDesign (shape_opt/microstructure/drop_design.hpp):

    J = (sum_k max(sigma_k, 0)^8)^(1/8) / sigma*,   sigma_k = F_k / W,

the smooth maximum of the stress on the block's bottom face over the run, on a pad of 4 x 3 cells
(cell height 1 cm, mesh size 0.03 of it) under a block of 1.25 kg per metre of depth falling at
0.5 m/s from 0.5 mm, 300 steps of 0.1 ms (the drop of drop.py on half its width, for 30 ms instead
of 40), contact with a fixed barrier stiffness and friction mu = 0.3. The gradient is the adjoint of
the whole drop pulled back through the pad's tiling and the cell mesh's velocity. The width is held
(the block's width is given); the other six variables move within the family's bounds, between
remeshes on the cell mesh moved with the design. Writes transient.json (the design, the history,
J and the peak stress before and after, and what the change did to the quasi-static plateau: the
start's and the result's max abs(sigma/sigma* - 1) over 10-40% at params.json's mesh size) and
transient_history.png (J per iteration, the drop's stress before and after, the stress-strain
curves before and after).
"""
import argparse
import json
import os
import re
import time

import numpy as np

from diffipc import microstructure as ms

import drop
import run as plateau

NX, NY, SIZE, STEPS = 4, 3, 0.03, 300


def rejection_kinds(rejections):
    """How many trial designs were rejected for each reason, numbers in the reasons replaced by N
    (a vertex, a step, a residual), most frequent first."""
    kinds = {}
    for r in rejections:
        kind = re.sub(r"-?\d+(\.\d+)?(e[-+]?\d+)?", "N", r["reason"])
        kinds[kind] = kinds.get(kind, 0) + 1
    return dict(sorted(kinds.items(), key=lambda k: -k[1]))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--params", default="output/408_shock_microstructure/params.json")
    parser.add_argument("--start", default="L-BFGS-B", help="the design of params.json to start from")
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("-o", "--output", default="output/408_shock_microstructure/transient")
    args = parser.parse_args()
    params = json.load(open(args.params))
    os.makedirs(args.output, exist_ok=True)
    family = ms.family("reentrant")
    settings = drop.drop_settings(NX, NY, SIZE, STEPS, params["target_stress"])
    design = ms.DropDesign(family, settings)
    x0 = np.array(params["designs"][args.start])
    t0 = time.time()
    before = design.evaluate(x0)
    if not before["ok"]:
        raise SystemExit(f"transient.py: the drop on the start design failed: {before['message']}")
    run = design.optimize(x0, algorithm="lbfgsb", max_iterations=args.iterations, fixed=["width"],
                          callback=lambda e: print(f"transient {e['iteration']:3d} J {e['J']:.5g}", flush=True))
    after = design.evaluate(run["x"])
    seconds = time.time() - t0
    cell = ms.CellDesign(family, plateau.settings(params["size"]))
    curves = {"start": cell.evaluate(x0), "transient": cell.evaluate(run["x"])}
    out = {
        "settings": settings, "start": args.start, "names": family.names,
        "x0": list(map(float, x0)), "x": list(map(float, run["x"])),
        "J": [before["J"], after["J"]], "peak": [before["peak"], after["peak"]],
        "history": [{"iteration": e["iteration"], "mesh": e["mesh"], "J": e["J"]} for e in run["history"]],
        "evaluations": run["evaluations"], "rejected": run["rejected"], "remeshes": run["remeshes"],
        "rejections": rejection_kinds(run["rejections"]),
        "reason": run["reason"], "seconds": seconds,
        "curves": {"time": list(map(float, before["time"])), "before": list(map(float, before["stress"])),
                   "after": list(map(float, after["stress"]))},
        "plateau": {"size": params["size"], "start": plateau.deviation(curves["start"]),
                    "transient": plateau.deviation(curves["transient"])},
    }
    json.dump(out, open(os.path.join(args.output, "transient.json"), "w"), indent=1)
    plt = drop.pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(17, 4))
    axes[0].plot([e["iteration"] for e in run["history"]], [e["J"] for e in run["history"]], marker=".")
    axes[0].set_xlabel("iteration")
    axes[0].set_ylabel("J (smooth maximum of sigma / sigma*)")
    axes[1].plot(1000 * before["time"], before["stress"], label=f"{args.start} (quasi-static optimum)")
    axes[1].plot(1000 * after["time"], after["stress"], label="transient optimum")
    axes[1].axhline(params["target_stress"], color="k", lw=0.8, ls="--", label="sigma*")
    axes[1].set_xlabel("t (ms)")
    axes[1].set_ylabel(f"stress on the block, {NX} x {NY} pad (Pa)")
    axes[1].legend(fontsize=8)
    for name, r in curves.items():
        if r["ok"]:
            axes[2].plot(100 * np.r_[0, r["strain"]], np.r_[0, r["stress"]], marker=".",
                         label=f"{args.start}" if name == "start" else "transient optimum")
    axes[2].axhspan(0.9 * params["target_stress"], 1.1 * params["target_stress"], color="#d8ecd8",
                    label="sigma* +- 10%")
    axes[2].set_xlabel("compressive strain (%)")
    axes[2].set_ylabel(f"cell's quasi-static stress (Pa), mesh size {params['size']} m")
    axes[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.output, "transient_history.png"), dpi=110)
    plt.close(fig)
    print(f"transient: J {before['J']:.4g} -> {after['J']:.4g}, peak {before['peak']:.0f} -> {after['peak']:.0f} Pa "
          f"({len(run['history']) - 1 - run['remeshes']} iterations, {run['evaluations']} evaluations, "
          f"{seconds:.0f} s); plateau deviation {100 * out['plateau']['start']:.1f}% -> "
          f"{100 * out['plateau']['transient']:.1f}%")
    for kind, count in out["rejections"].items():
        print(f"  rejected {count}x: {kind}")


if __name__ == "__main__":
    main()
