#!/usr/bin/env python3
"""Study 504: the gradient's error against run time, and the checkpointed adjoint's cost against
its memory. Three adjoint examples (implicit Euler):

  bar       studies/302_bar_youngs_markers: a 3D bar, dJ/dE per element of markers at two times
            (no contact)
  friction  studies/303_block_slope_friction: a block sliding down a slope, dJ/dmu of its centre
            of mass at the final step (contact and friction)
  ring      studies/304_ring_wall_velocity: a ring thrown at a wall, dJ/dv0 of two markers at the
            final step (contact)

For each: the gradient dJ/dp at the problem's initial design against a tightly converged reference
(relative error |g - g_ref| / |g_ref|) as the forward Newton tolerance varies (reference 1e-12),
and as the time step varies over the same time span (reference dt / 32: the gradient of the
time-continuous problem, to which the discrete gradients converge at the integrator's order);
then the checkpointed adjoint (docs/problem_format.md "checkpointing") of the ring with 8 times
more steps at several strides: peak step records held, bytes, recomputed steps, adjoint time and
its cost relative to the forward, against the full-memory adjoint.

    PYTHONPATH=build/python /usr/bin/python3 studies/504_gradient_error/run.py \
        [--results studies/504_gradient_error] [--full] [-o output/504]

(or `diffipc study 504`).
"""
import argparse
import copy
import json
import math
import os
import sys

import numpy as np

import diffipc
import diffipc.studies

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
EXAMPLES = {"bar": "302_bar_youngs_markers", "friction": "303_block_slope_friction", "ring": "304_ring_wall_velocity"}
ORDER_EXPECTED = ("bar", "friction")  # smooth in dt; the ring's contact sequence changes with dt


def problem_of(example):
    folder = os.path.join(ROOT, "studies", EXAMPLES[example])
    problem = json.load(open(os.path.join(folder, "problem.json")))
    problem.pop("gradcheck", None)
    problem.pop("checkpointing", None)
    return problem, folder


def with_tolerance(problem, tolerance):
    p = copy.deepcopy(problem)
    p["scene"].setdefault("solver", {})["residual_tolerance"] = tolerance
    return p


def with_refinement(problem, factor):
    """The same time span in `factor` times more steps; the objective reads the same times."""
    p = copy.deepcopy(problem)
    t = p["scene"]["time"]
    t.update(dt=t["dt"] / factor, steps=t["steps"] * factor)
    p["objective"]["steps"] = [k * factor for k in p["objective"]["steps"]]
    return p


def gradient(problem, folder, checkpointing=None):
    if checkpointing is not None:
        problem = copy.deepcopy(problem)
        problem["checkpointing"] = checkpointing
    J = diffipc.ReducedFunctional(problem, base_directory=folder)
    e = J.evaluation(J.initial, True)
    return np.array(e.gradient), e


def error(g, ref):
    return float(np.linalg.norm(g - ref) / np.linalg.norm(ref))


def sweeps(full):
    rows = []
    tolerances = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    factors = [1, 2, 4, 8] + ([16] if full else [])
    for example in EXAMPLES:
        problem, folder = problem_of(example)
        ref, _ = gradient(with_tolerance(problem, 1e-12), folder)
        for tol in tolerances:
            g, e = gradient(with_tolerance(problem, tol), folder)
            rows.append(dict(example=example, knob="residual tolerance", value=tol, error=error(g, ref),
                             forward=e.forward_time, adjoint=e.adjoint_time))
        ref_dt, _ = gradient(with_refinement(problem, 32), folder)
        dt0 = problem["scene"]["time"]["dt"]
        for f in factors:
            g, e = gradient(with_refinement(problem, f), folder)
            rows.append(dict(example=example, knob="dt", value=dt0 / f, error=error(g, ref_dt),
                             forward=e.forward_time, adjoint=e.adjoint_time))
    return rows


def checkpoint_rows(full):
    problem, folder = problem_of("ring")
    problem = with_refinement(problem, 16 if full else 8)
    full_g, full_e = gradient(problem, folder)
    rows = [dict(stride="full memory", steps=problem["scene"]["time"]["steps"], peak_records="all",
                 peak_bytes=float("nan"), recomputed=0, forward=full_e.forward_time, adjoint=full_e.adjoint_time,
                 cost_ratio=(full_e.forward_time + full_e.adjoint_time) / full_e.forward_time, difference=0.0)]
    for stride in [1, 2, 4, 8, 16, 0]:
        g, e = gradient(problem, folder, {"stride": stride})
        c = e.checkpoints[0]
        rows.append(dict(stride=f"{c['stride']}" + (" (auto)" if stride == 0 else ""), steps=c["steps"],
                         peak_records=c["peak_stored_states"], peak_bytes=c["peak_stored_bytes"],
                         recomputed=c["recomputed_steps"], forward=c["forward_time"], adjoint=c["adjoint_time"],
                         cost_ratio=c["cost_ratio"], difference=error(g, full_g)))
    return rows


def ring_gradients():
    problem, folder = problem_of("ring")
    out = []
    for f in (1, 2, 4, 8, 16, 32):
        g, e = gradient(with_refinement(problem, f), folder)
        out.append(dict(dt=problem["scene"]["time"]["dt"] / f, g=g, J=e.value))
    return out


def observed_order(points):
    x = np.log([p[0] for p in points])
    y = np.log([p[1] for p in points])
    return float(np.polyfit(x, y, 1)[0])


def plot(rows, checkpoints, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.8))
    for example in EXAMPLES:
        for knob, marker in (("residual tolerance", "o-"), ("dt", "s-")):
            pts = [r for r in rows if r["example"] == example and r["knob"] == knob and r["error"] > 0]
            t = [r["forward"] + r["adjoint"] for r in pts]
            line, = a.plot(t, [r["error"] for r in pts], marker, ms=4, label=f"{example}: {knob}")
            for r, ti in zip(pts, t):
                a.annotate(f"{r['value']:g}", (ti, r["error"]), fontsize=6, color=line.get_color(),
                           xytext=(3, 2), textcoords="offset points")
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlabel("forward + adjoint time (s)")
    a.set_ylabel("relative gradient error")
    a.set_title("gradient error against run time")
    a.legend(fontsize=7)
    a.grid(True, which="both", lw=0.3)
    pts = [c for c in checkpoints if c["stride"] != "full memory"]
    b.plot([c["peak_bytes"] / 1024 for c in pts], [c["cost_ratio"] for c in pts], "o-")
    for c in pts:
        b.annotate(f"stride {c['stride']}", (c["peak_bytes"] / 1024, c["cost_ratio"]), fontsize=7,
                   xytext=(3, 2), textcoords="offset points")
    full = checkpoints[0]
    b.axhline(full["cost_ratio"], color="k", ls="--", lw=1, label="full-memory adjoint (all records held)")
    b.set_xlabel("peak step records held by the checkpointed adjoint (KiB)")
    b.set_ylabel("(forward + adjoint) / forward time")
    b.set_title(f"checkpointed adjoint, ring, {full['steps']} steps")
    b.legend(fontsize=7)
    b.grid(True, lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--results", default=None, help="write results.md, results.csv and gradient_error.png here")
    p.add_argument("--full", action="store_true", help="dt / 16 too, and the checkpointing run with 16x the steps")
    p.add_argument("-o", "--output", default=None, help="also write every gradient computed (gradients.json) here")
    a = p.parse_args(argv)
    rows = sweeps(a.full)
    ring_path = ring_gradients()
    if a.output:
        os.makedirs(a.output, exist_ok=True)
        json.dump({"ring_dt": [dict(dt=r["dt"], gradient=r["g"].tolist(), J=r["J"]) for r in ring_path]},
                  open(os.path.join(a.output, "gradients.json"), "w"), indent=1)
    checkpoints = checkpoint_rows(a.full)
    if not a.results:
        for r in rows + checkpoints:
            print(r)
        return rows, checkpoints
    os.makedirs(a.results, exist_ok=True)
    diffipc.studies.write_csv(os.path.join(a.results, "results.csv"), rows)
    plot(rows, checkpoints, os.path.join(a.results, "gradient_error.png"))
    text = diffipc.studies.provenance(ROOT, __file__, sys.argv[1:] if argv is None else argv)
    text += "\n![gradient error against run time; checkpointed adjoint](gradient_error.png)\n"
    text += ("\n| example | knob | value | relative gradient error | forward (s) | adjoint (s) |\n"
             "| --- | --- | --- | --- | --- | --- |\n")
    for r in rows:
        text += (f"| {r['example']} | {r['knob']} | {r['value']:g} | {r['error']:.2e} | {r['forward']:.3f} | "
                 f"{r['adjoint']:.3f} |\n")
    text += "\nObserved order of the gradient's error in dt (least squares over the sweep): "
    text += ", ".join(f"{ex} {observed_order([(r['value'], r['error']) for r in rows if r['example'] == ex and r['knob'] == 'dt']):.2f}"
                      for ex in ORDER_EXPECTED) + " (implicit Euler: 1 expected).\n"
    text += "\nThe ring's gradient dJ/dv0 at each refinement of dt (its contact sequence changes with dt):\n\n"
    text += "| dt | dJ/dv0 | J |\n| --- | --- | --- |\n"
    for r in ring_path:
        text += f"| {r['dt']:g} | {np.array2string(r['g'], precision=5)} | {r['J']:.6g} |\n"
    text += ("\n### Checkpointed adjoint (ring)\n\n| stride | steps | peak records held | peak bytes | recomputed steps "
             "| forward (s) | adjoint (s) | (forward + adjoint) / forward | gradient difference to full memory |\n"
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n")
    for c in checkpoints:
        text += (f"| {c['stride']} | {c['steps']} | {c['peak_records']} | "
                 f"{'—' if math.isnan(c['peak_bytes']) else format(c['peak_bytes'] / 1024, '.1f') + ' KiB'} | "
                 f"{c['recomputed']} | {c['forward']:.3f} | {c['adjoint']:.3f} | {c['cost_ratio']:.2f} | "
                 f"{c['difference']:.1e} |\n")
    open(os.path.join(a.results, "results.md"), "w").write(text)
    return rows, checkpoints


if __name__ == "__main__":
    main()
