#!/usr/bin/env python3
"""Study 408, the drop's regime: when does a flat quasi-static plateau lower the peak of a drop?

    PYTHONPATH=build/python /usr/bin/python3 studies/408_shock_microstructure/regimes.py
        --params output/408_shock_microstructure/params.json [-o .../regimes]
        [--speeds 0.3 0.4 0.5 0.7] [--densities 1000 46] [--designs initial L-BFGS-B]

The drop of DropDesign (drop.py's scene on a 4 x 3 pad at mesh size 0.03 of the cell: a block of
1.25 kg per metre of depth: its weight is 0.61 sigma* on the initial design's pad, 0.70 sigma* on
the narrower L-BFGS-B pad) at
several impact speeds, on pads of two materials that differ only in density: the study's material
(E = 1 MPa, rho = 1000 kg/m^3, wave speed sqrt(E / rho) = 32 m/s) and one with the wave speed of
printed TPU (E about 26 MPa, rho about 1200: 147 m/s), rho = 46 kg/m^3 at E = 1 MPa. A TPU pad of
the same design carries 26 times the stress (the quasi-static response scales with E), so under a
block 26 times heavier it moves exactly as the rho = 46 pad under this block: Newton's law is
homogeneous in forces and masses. The pad's inertia decides how far a drop is from quasi-static:
the impact stress of an elastic branch of modulus E_eff is about rho_eff c_eff v, against the
plateau sigma* = E_eff eps_y when the branch ends at strain eps_y, so the ratio is
v / (c_eff eps_y).

Per run: the peak of sigma_k (DropDesign's own stress on the block, the body-force objective, which
drop.py checks independently against the trajectory), its time, and the peak's reduction against
the initial design's pad at the same speed and density. Writes regimes.json, regimes.md and
regimes.png (the peak against the speed, and the stress histories).
"""
import argparse
import json
import os
import time

import numpy as np

from diffipc import microstructure as ms

import drop

NX, NY, SIZE, DT = 4, 3, 0.03, 1e-4


def steps_for(speed):
    """Steps to cover the first compression and its peak: 40 ms at 0.5 m/s and longer when slower
    (the peak came at 55 ms at 0.29 m/s)."""
    return int(round(max(0.04, 0.02 * 0.5 / speed + 0.03) / DT))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--params", default="output/408_shock_microstructure/params.json")
    parser.add_argument("-o", "--output", default="output/408_shock_microstructure/regimes")
    parser.add_argument("--speeds", type=float, nargs="*", default=[0.3, 0.4, 0.5, 0.7])
    parser.add_argument("--densities", type=float, nargs="*", default=[1000.0, 46.0])
    parser.add_argument("--designs", nargs="*", default=["initial", "L-BFGS-B"])
    args = parser.parse_args()
    params = json.load(open(args.params))
    os.makedirs(args.output, exist_ok=True)
    family = ms.family("reentrant")
    runs = []
    for rho in args.densities:
        for speed in args.speeds:
            settings = drop.drop_settings(NX, NY, SIZE, steps_for(speed), params["target_stress"], speed=speed)
            settings["material"] = {"model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": rho, "plane": "stress"}
            design = ms.DropDesign(family, settings)
            for name in args.designs:
                t0 = time.time()
                r = design.evaluate(np.array(params["designs"][name]))
                run = {"design": name, "density": rho, "speed": speed, "steps": settings["steps"], "ok": r["ok"],
                       "message": r["message"], "seconds": time.time() - t0}
                if r["ok"]:
                    k = int(np.argmax(r["stress"]))
                    run.update(peak=float(r["stress"][k]), peak_time=float(r["time"][k]),
                               time=np.asarray(r["time"]).tolist(), stress=np.asarray(r["stress"]).tolist())
                runs.append(run)
                print(f"rho {rho:g} v {speed:g} {name}: "
                      + (f"peak {run['peak']:.0f} Pa at {1000 * run['peak_time']:.1f} ms" if r["ok"] else r["message"])
                      + f" ({run['seconds']:.0f} s)", flush=True)
                json.dump(runs, open(os.path.join(args.output, "regimes.json"), "w"))
    report(runs, args, params["target_stress"])


def report(runs, args, target):
    """regimes.md and regimes.png from the runs."""
    def find(name, rho, speed):
        return next((r for r in runs if r["design"] == name and r["density"] == rho and r["speed"] == speed), None)

    lines = ["| pad density (kg/m^3) | speed (m/s) | steps | " + " | ".join(f"{n} peak (Pa, at ms)" for n in args.designs)
             + " | " + " | ".join(f"{n} against initial" for n in args.designs if n != "initial") + " |",
             "| --- " * (3 + 2 * len(args.designs) - 1) + "|"]
    for rho in args.densities:
        for speed in args.speeds:
            cells, versus = [], []
            base = find("initial", rho, speed)
            for name in args.designs:
                r = find(name, rho, speed)
                cells.append(f"{r['peak']:.0f} ({1000 * r['peak_time']:.1f})" if r and r["ok"] else "failed")
                if name != "initial":
                    good = r and r["ok"] and base and base["ok"]
                    versus.append(f"{100 * (1 - r['peak'] / base['peak']):.0f}%" if good else "-")
            steps = find(args.designs[0], rho, speed)["steps"]
            lines.append(f"| {rho:g} | {speed:g} | {steps} | " + " | ".join(cells) + " | " + " | ".join(versus) + " |")
    text = "\n".join(lines) + "\n"
    open(os.path.join(args.output, "regimes.md"), "w").write(text)
    print(text)
    plt = drop.pyplot()
    fig, axes = plt.subplots(1, 1 + len(args.densities), figsize=(5 * (1 + len(args.densities)), 4))
    for rho, style in zip(args.densities, ["-", "--", ":", "-."]):
        for name in args.designs:
            points = [(r["speed"], r["peak"]) for r in runs if r["design"] == name and r["density"] == rho and r["ok"]]
            if points:
                axes[0].plot(*zip(*points), style, marker="o", label=f"{name}, rho {rho:g}")
    axes[0].axhline(target, color="k", lw=0.8, ls="--")
    axes[0].set_xlabel("impact speed (m/s)")
    axes[0].set_ylabel("peak stress on the block (Pa)")
    axes[0].legend(fontsize=8)
    for ax, rho in zip(axes[1:], args.densities):
        for r in runs:
            if r["density"] == rho and r["ok"]:
                ax.plot(1000 * np.array(r["time"]), r["stress"], lw=0.8, label=f"{r['design']}, {r['speed']:g} m/s")
        ax.axhline(target, color="k", lw=0.8, ls="--")
        ax.set_title(f"pad density {rho:g} kg/m^3")
        ax.set_xlabel("t (ms)")
        ax.set_ylabel("stress on the block (Pa)")
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(args.output, "regimes.png"), dpi=110)


if __name__ == "__main__":
    main()
