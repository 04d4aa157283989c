#!/usr/bin/env python3
"""Study 503: a stability atlas. A grid of extreme 2D cases (stiffness, incompressibility, time
step, impact speed, mass ratio, friction, thin features, a stack of bodies, a body squeezed
between walls), each run to its end through `diffipc simulate`, with IPC and with the penalty
baseline. Per cell: status, steps, Newton iterations per step, line-search cuts, the smallest gap,
the smallest volume ratio, intersections and inversions by `diffipc check` (exact tests
independent of the solver) and, against planes, the signed gap computed here from the positions,
the energy drift where energy is conserved by the physics (frictionless, no prescribed motion),
and the wall time.

    PYTHONPATH=build/python /usr/bin/python3 studies/503_stability_atlas/run.py [--cli build/cli/diffipc]
        [-o output/503] [--jobs 2] [--families E nu ...] [--full] [--results studies/503_stability_atlas]

The penalty baseline runs every contact cell with contact.model "penalty" and penalty_stiffness =
10 E (Pa: 2D energies are per unit thickness, so the stiffness of a contact pair per unit
thickness has the units of E; 10 E keeps the penetration of the resting cases below a tenth of
dhat), the same dhat, everything else equal.
"""
import argparse
import concurrent.futures
import copy
import json
import math
import os
import re
import subprocess
import sys

import h5py
import numpy as np

import diffipc.energy
import diffipc.studies

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
G = 9.81
DHAT = 1e-4


def body(lo, hi, cells, E=1e6, nu=0.3, density=1000.0, name="box", velocity=None):
    b = {"name": name, "mesh": {"box": {"min": lo, "max": hi, "cells": cells}},
         "material": {"model": "neo_hookean", "E": E, "nu": nu, "density": density}}
    if velocity is not None:
        b["initial_velocity"] = velocity
    return b


def drop(E=1e6, nu=0.3, dt=1e-3, speed=1.0, T=0.1):
    """A 0.1 m x 0.05 m box (8 x 4 cells) 1 cm above a plane, thrown down at `speed`, under gravity."""
    return {"dimension": 2, "bodies": [body([0.0, 0.01], [0.1, 0.06], [8, 4], E, nu, velocity=[0.0, -speed])],
            "gravity": [0.0, -G], "obstacles": [{"name": "ground", "plane": {"point": [0, 0], "normal": [0, 1]}}],
            "contact": {"dhat": DHAT}, "time": {"integrator": "implicit_euler", "dt": dt, "steps": int(round(T / dt))},
            "solver": {"residual_tolerance": 1e-8}}


def impact(speed):
    """The box thrown at `speed` onto a fixed 1 cm slab (a mesh, not a plane: contact between
    surfaces, which a step can jump across), no gravity."""
    s = drop(speed=speed, T=0.05)
    s.pop("obstacles")
    s["bodies"].append(body([-0.1, -0.01], [0.2, 0.0], [30, 1], name="slab"))
    s["dirichlet"] = [{"body": "slab", "region": {"min": [-1, -1], "max": [1, 1]}, "displacement": [0, 0]}]
    s["gravity"] = [0.0, 0.0]
    return s


def mass_ratio(ratio):
    """A box of density 1000 ratio resting on a box of density 1000, on a plane (T = 0.1 s)."""
    s = drop(speed=0.0)
    s["bodies"] = [body([0.0, 2 * DHAT], [0.1, 0.05], [8, 4], name="bottom"),
                   body([0.0, 0.05 + 4 * DHAT], [0.1, 0.1], [8, 4], density=1000.0 * ratio, name="top")]
    return s


def friction(mu):
    """The box released on a 30 degree slope with friction coefficient mu (sticks for mu > 0.577)."""
    s = drop(speed=0.0)
    s["bodies"][0]["mesh"]["box"]["min"] = [0.0, 2 * DHAT]
    s["bodies"][0]["mesh"]["box"]["max"] = [0.1, 0.05 + 2 * DHAT]
    s["bodies"][0]["rotation"] = [-30]
    s["obstacles"][0]["plane"]["normal"] = [0.5, math.sqrt(3) / 2]
    if mu > 0:
        s["friction"] = {"coefficient": mu, "eps_v": 1e-3, "iterations": 3}
    return s


def thin(ratio):
    """The box falling at 1 m/s onto a plate of thickness ratio * dhat held at its ends."""
    s = drop(speed=1.0, T=0.05)
    s.pop("obstacles")
    h = ratio * DHAT
    s["bodies"].append(body([-0.1, -h], [0.2, 0.0], [60, 1], name="plate"))
    s["dirichlet"] = [{"body": "plate", "region": {"min": [-1, -1], "max": [-0.1, 1]}, "displacement": [0, 0]},
                      {"body": "plate", "region": {"min": [0.2, -1], "max": [1, 1]}, "displacement": [0, 0]}]
    return s


def stack(n):
    """n boxes of 0.05 m (2 x 2 cells) stacked 3 dhat apart on a plane, falling under gravity (0.2 s)."""
    s = drop(speed=0.0, T=0.2)
    s["bodies"] = [body([0.0, 3 * DHAT + k * (0.05 + 3 * DHAT)], [0.05, 0.05 + 3 * DHAT + k * (0.05 + 3 * DHAT)],
                        [2, 2], name=f"b{k}") for k in range(n)]
    return s


def squeeze(ratio):
    """The box between two walls (planes) that approach until the gap is `ratio` of its 0.1 m
    width at T = 0.2 s; no gravity."""
    s = drop(speed=0.0, T=0.2)
    s["gravity"] = [0.0, 0.0]
    s["bodies"][0]["mesh"]["box"]["min"] = [0.0, 0.0]
    s["bodies"][0]["mesh"]["box"]["max"] = [0.1, 0.05]
    travel = (0.1 + 4 * DHAT) * (1 - ratio) / 2
    rate = f"{travel / 0.2:.12g}*t"
    s["obstacles"] = [{"name": "left", "plane": {"point": [-2 * DHAT, 0], "normal": [1, 0], "motion": [rate, "0"]}},
                      {"name": "right", "plane": {"point": [0.1 + 2 * DHAT, 0], "normal": [-1, 0],
                                                  "motion": [f"-{rate}", "0"]}}]
    return s


# (family, label of its values, values, builder, energy conserved by the physics?); --full adds FULL's.
FAMILIES = [
    ("E", "Young's modulus (Pa)", [1e3, 1e5, 1e7, 1e9, 1e11], lambda v: drop(E=v), True),
    ("nu", "Poisson's ratio", [0.3, 0.45, 0.49, 0.499], lambda v: drop(nu=v), True),
    ("dt", "time step (s)", [1e-5, 1e-4, 1e-3, 1e-2, 0.1],
     lambda v: drop(dt=v, T=max(0.1 if v >= 1e-4 else 0.02, 2 * v)), True),
    ("speed", "impact speed (m/s)", [1, 10, 30, 100], impact, True),
    ("mass_ratio", "mass ratio", [1, 1e2, 1e4, 1e6], mass_ratio, True),
    ("mu", "friction coefficient", [0, 0.5, 1, 2], friction, False),
    ("thin", "plate thickness / dhat", [20, 5, 2, 1], thin, True),
    ("stack", "bodies in the stack", [5, 10, 20], stack, True),
    ("squeeze", "final gap / width", [0.5, 0.2, 0.1, 0.05], squeeze, False),
]
FULL = {"E": [1e4, 1e6, 1e8, 1e10], "nu": [0.0, 0.4, 0.495], "dt": [3e-5, 3e-4, 3e-3, 3e-2],
        "speed": [3, 50], "mass_ratio": [10, 1e3, 1e5], "mu": [0.25, 0.577, 0.75, 1.5], "thin": [10, 0.5],
        "stack": [15, 30], "squeeze": [0.3, 0.02]}


def families(full):
    """FAMILIES with FULL's values merged in when `full`."""
    if not full:
        return FAMILIES
    return [(f, label, sorted(set(values) | set(FULL.get(f, []))), build, conserved)
            for f, label, values, build, conserved in FAMILIES]


# What would fix a cell that did not finish valid: a note per failure kind, with a change to the
# cell's scene that the study runs to verify it (the outcome is printed beside the note).


def fix_substeps(scene):
    s = copy.deepcopy(scene)
    s["time"]["adaptive"] = True
    return s, "time.adaptive (automatic sub-stepping of a step whose solve fails)"


def fix_stiffer(scene, factor=100):
    s = copy.deepcopy(scene)
    s["contact"]["penalty_stiffness"] *= factor
    return s, f"penalty_stiffness x {factor:g} (= {s['contact']['penalty_stiffness']:g})"


MAX_FIX_STEPS = 20000


def fix_smaller_dt(scene, speed):
    """dt small enough that no vertex crosses the dhat layer in one step: dt = dhat / (2 v)."""
    s = copy.deepcopy(scene)
    T = s["time"]["dt"] * s["time"]["steps"]
    dt = min(s["time"]["dt"], s["contact"]["dhat"] / (2 * speed))
    steps = int(math.ceil(T / dt))
    if steps > MAX_FIX_STEPS:
        return None, f"dt = dhat / (2 v) = {dt:.1e} s ({steps} steps, beyond this study's {MAX_FIX_STEPS})"
    s["time"].update(dt=T / steps, steps=steps)
    return s, f"dt = dhat / (2 v) = {T / steps:.1e} s ({steps} steps)"


def fix_both(scene, speed):
    s, what = fix_smaller_dt(scene, speed)
    if s is None:
        return None, what
    s, more = fix_stiffer(s)
    return s, what + " and " + more


# Families whose penalty failures come from the load (weight, squeeze) and from the speed.
LOADED = ("E", "nu", "dt", "mass_ratio", "squeeze", "mu")
SPEED = {"speed": None, "thin": 1.0, "stack": 2.0}  # fastest vertex, m/s (None: the cell's value)


def note_for(r):
    """(why, what would fix it, fixes to try in order) for a cell that did not finish valid; each
    fix maps the cell's scene to (scene or None, what it changes)."""
    if r["model"] == "IPC":
        return ("the step's Newton solve did not converge within solver.max_iterations",
                "take the step in sub-steps", [fix_substeps])
    if r["family"] in LOADED:
        return (("the penalty springs are too soft for the load: the weight or squeeze per contact vertex over the "
                 "stiffness exceeds dhat, so vertices sink behind the plane or into the body below"),
                "a penalty stiffness of at least the load per contact vertex over dhat, which grows with the load "
                "(at the cost of a stiffer, worse-conditioned Newton system), and then a time step short enough that "
                "the stiffer springs' fast motion does not carry vertices across the layer",
                [fix_stiffer, lambda scene: fix_both(scene, 1.0)])
    v = SPEED[r["family"]] or float(r["value"])
    return ((f"the penalty has no CCD: a vertex moving at up to {v:g} m/s crosses the {DHAT:g} m contact layer "
             "within one step, and the penalty on the unsigned distance then pushes it further through"),
            "a time step below dhat / (2 v), so that every vertex is seen inside the layer, and a penalty stiff "
            "enough to stop it within the layer",
            [lambda scene: fix_smaller_dt(scene, v), lambda scene: fix_both(scene, v)])


# The penalty baseline at two stiffnesses per cell, factor x the largest E of the scene (Pa: 2D
# energies are per unit thickness, so a pair's stiffness per unit thickness has E's units).
PENALTY_FACTORS = (10, 1000)
MODELS = ["IPC"] + [f"penalty {k}E" for k in PENALTY_FACTORS]


def penalty_version(scene, factor):
    s = copy.deepcopy(scene)
    E = max(b["material"]["E"] for b in s["bodies"])
    s["contact"] = {"dhat": s["contact"]["dhat"], "model": "penalty", "penalty_stiffness": factor * E}
    return s


# ---------------------------------------------------------------- measuring


def check_states(cli, folder):
    """Counts of states with inverted elements and with intersections or containment, by `diffipc check`."""
    done = subprocess.run([cli, "check", folder], capture_output=True, text=True)
    inverted = intersecting = 0
    for line in done.stdout.splitlines():
        m = re.match(r"state \d+ .*: (\d+) inverted elements, (.*), (.*)$", line)
        if m:
            inverted += int(m.group(1)) > 0
            intersecting += m.group(2) != "no intersection" or m.group(3) != "no containment"
    return inverted, intersecting


def plane_gap(f, scene):
    """The smallest signed distance of a body vertex to a plane obstacle over all states (m), from
    the positions (moving planes follow their motion through their stored vertex)."""
    if not scene.get("obstacles"):
        return float("nan")
    nb = len(scene["bodies"])
    owner = f["mesh/body"][:]
    x = f["positions"][:]
    gap = float("inf")
    for k, o in enumerate(scene["obstacles"]):
        n = np.array(o["plane"]["normal"], float)
        n /= np.linalg.norm(n)
        point = x[:, owner == nb + k][:, 0, :]  # the plane's point is its vertex
        d = np.einsum("svd,d->sv", x[:, owner < nb] - point[:, None, :], n)
        gap = min(gap, float(d.min()))
    return gap


def passed_through(f, scene):
    """States in which the box (body 0) has passed through the slab or plate below it (body 1):
    its centre lies below the mean of the slab's vertices under it (within its horizontal extent).
    The intersection test cannot see a body that went through within one step."""
    if len(scene["bodies"]) < 2 or scene["bodies"][1]["name"] not in ("slab", "plate"):
        return 0
    owner = f["mesh/body"][:]
    x = f["positions"][:]
    count = 0
    for state in x:
        box, slab = state[owner == 0], state[owner == 1]
        under = slab[(slab[:, 0] >= box[:, 0].min()) & (slab[:, 0] <= box[:, 0].max())]
        count += len(under) > 0 and box[:, 1].mean() < under[:, 1].mean()
    return int(count)


def run_cell(cli, out, family, value, model, scene, conserved):
    folder = os.path.join(out, f"{family}_{value:g}_{model.replace(' ', '_')}")
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "scene.json")
    json.dump(scene, open(path, "w"), indent=1)
    done = subprocess.run([cli, "simulate", path, "-o", folder, "-q", "--vtu-every", "0", "--threads", "1"],
                          capture_output=True, text=True, timeout=3600)
    row = dict(family=family, value=value, model=model, exit=done.returncode, status="NO_OUTPUT", steps=0,
               requested=scene["time"]["steps"], newton_per_step=float("nan"), cuts=0, min_distance=float("nan"),
               plane_gap=float("nan"), min_volume_ratio=float("nan"), inverted_states=0, intersecting_states=0,
               passed_through=0, energy_drift=float("nan"), time=float("nan"), failure="",
               folder=os.path.relpath(folder, ROOT))
    summary_path = os.path.join(folder, "summary.json")
    if not os.path.exists(summary_path):
        row["failure"] = (done.stderr.strip() or done.stdout.strip())[-300:]
        return row
    s = json.load(open(summary_path))
    row.update(status=s["status"], steps=s["steps_committed"], cuts=s.get("line_search_cuts", 0),
               min_volume_ratio=s["min_volume_ratio"], time=s["wall_time"]["total"], failure=s.get("failure", ""))
    row["newton_per_step"] = s["counts"]["newton_iterations"] / max(s["steps_committed"], 1)
    md = s.get("contact", {}).get("min_distance")
    row["min_distance"] = float("inf") if md is None else md
    h5 = os.path.join(folder, "trajectory.h5")
    if os.path.exists(h5):
        row["inverted_states"], row["intersecting_states"] = check_states(cli, folder)
        with h5py.File(h5, "r") as f:
            row["plane_gap"] = plane_gap(f, scene)
            row["passed_through"] = passed_through(f, scene)
            if conserved and row["steps"] > 0:
                e = diffipc.energy.mechanical_energy(f, scene)
                scale = max(abs(e[0]), 1e-300)
                row["energy_drift"] = float((e[-1] - e[0]) / scale)
    return row


# ---------------------------------------------------------------- outputs


def verdict(r):
    """'ok', 'invalid' (a committed state intersects, is inverted or lies behind a plane) or 'failed'."""
    if r["intersecting_states"] > 0 or r["inverted_states"] > 0 or r["plane_gap"] < 0 or r["passed_through"] > 0:
        return "invalid"
    if r["status"] != "CONVERGED" or r["steps"] < r["requested"]:
        return "failed"
    return "ok"


def short(r):
    v = verdict(r)
    if v == "invalid":
        if r["passed_through"] > 0:
            return f"INVALID\npassed through"
        if r["intersecting_states"] > 0:
            return f"INVALID\n{r['intersecting_states']} states"
        return f"INVALID\ngap {r['plane_gap']:.0e} m"
    if v == "failed":
        return f"{r['status'][:14]}\n{r['steps']}/{r['requested']}"
    return f"{r['newton_per_step']:.1f} it/step\n{r['time']:.2g} s"


def plot_atlas(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    colours = {"ok": "#9fd89f", "failed": "#f3c26b", "invalid": "#e57373"}
    fams = [f for f in FAMILIES if any(r["family"] == f[0] for r in rows)]
    width = max(len(f[2]) for f in fams)
    fig, axes = plt.subplots(1, len(MODELS), figsize=(1.05 * width * len(MODELS) + 1.5, 0.55 * len(fams) + 1.2))
    for ax, model in zip(axes, MODELS):
        ax.set_xlim(0, width)
        ax.set_ylim(0, len(fams))
        ax.invert_yaxis()
        ax.axis("off")
        ax.set_title(model.replace("penalty ", "penalty, stiffness ").replace("E", " E") if model != "IPC" else model,
                     fontsize=10)
        for i, (fam, label, values, _, _) in enumerate(fams):
            if model == MODELS[0]:
                ax.text(-0.05, i + 0.5, label, ha="right", va="center", fontsize=7)
            for j, v in enumerate(values):
                r = next((r for r in rows if r["family"] == fam and r["value"] == v and r["model"] == model), None)
                colour = colours[verdict(r)] if r else "#eeeeee"
                ax.add_patch(plt.Rectangle((j, i), 0.96, 0.92, color=colour))
                ax.text(j + 0.48, i + 0.25, f"{v:g}", ha="center", va="center", fontsize=7, weight="bold")
                ax.text(j + 0.48, i + 0.62, short(r) if r else "no contact", ha="center", va="center", fontsize=5.5)
    fig.suptitle("Stability atlas (2D): green finished with every state valid, orange stopped with a status, "
                 "red a committed state intersects or is inverted", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def fmt(x, spec=".2e"):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def tables(rows):
    text = ""
    for fam, label, values, _, conserved in FAMILIES:
        sel = [r for r in rows if r["family"] == fam]
        if not sel:
            continue
        text += f"\n#### {label}\n\n| value | contact | verdict | status | steps | Newton/step | cuts | min distance (m) " \
                f"| plane gap (m) | min volume ratio | inverted / intersecting / passed-through states | energy drift | time (s) |\n"
        text += "|" + " --- |" * 13 + "\n"
        for r in sorted(sel, key=lambda r: (r["value"], MODELS.index(r["model"]))):
            text += (f"| {r['value']:g} | {r['model']} | {verdict(r)} | {r['status']} | {r['steps']}/{r['requested']} | "
                     f"{fmt(r['newton_per_step'], '.1f')} | {r['cuts']} | {fmt(r['min_distance'])} | "
                     f"{fmt(r['plane_gap'])} | {fmt(r['min_volume_ratio'], '.3f')} | "
                     f"{r['inverted_states']} / {r['intersecting_states']} / {r['passed_through']} | "
                     f"{fmt(r['energy_drift'], '+.2e') if conserved else 'n/a'} | {fmt(r['time'], '.2f')} |\n")
    return text


def verify_fixes(cli, out, rows, jobs):
    """Runs each failing cell again with its note's fixes, in order until one finishes valid;
    returns {cell key: [(what, row or None), ...]}."""
    failing = [r for r in rows if verdict(r) != "ok"]
    tried = {(r["family"], r["value"], r["model"]): [] for r in failing}
    for attempt in range(2):
        todo = []
        for r in failing:
            key = (r["family"], r["value"], r["model"])
            fixes = note_for(r)[2]
            if attempt >= len(fixes) or any(row and verdict(row) == "ok" for _, row in tried[key]):
                continue
            scene = json.load(open(os.path.join(ROOT, r["folder"], "scene.json")))
            fixed, what = fixes[attempt](scene)
            conserved = next(f[4] for f in FAMILIES if f[0] == r["family"])
            if fixed is None:
                tried[key].append((what, None))
            else:
                todo.append((key, what, fixed, conserved, attempt))
        with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
            done = list(pool.map(lambda t: run_cell(cli, os.path.join(out, f"fix{t[4]}"), t[0][0], t[0][1], t[0][2],
                                                    t[2], t[3]), todo))
        for t, row in zip(todo, done):
            tried[t[0]].append((t[1], row))
    return tried


def failures(rows, fixes):
    text = ""
    for r in rows:
        if verdict(r) == "ok":
            continue
        key = (r["family"], r["value"], r["model"])
        why, remedy, _ = note_for(r)
        found = r["failure"] or (f"{r['intersecting_states']} intersecting and {r['passed_through']} passed-through "
                                 f"states, signed plane gap {fmt(r['plane_gap'])} m")
        outcomes = []
        for what, fixed in fixes[key]:
            if fixed is None:
                outcomes.append(f"{what}: not run")
            else:
                outcomes.append(f"{what}: {verdict(fixed)} ({fixed['status']}, {fixed['steps']}/{fixed['requested']} "
                                f"steps, {fixed['intersecting_states']} intersecting / {fixed['passed_through']} "
                                f"passed-through states, plane gap {fmt(fixed['plane_gap'])} m, "
                                f"{fmt(fixed['time'], '.2f')} s)")
        text += (f"- **{r['family']} = {r['value']:g}, {r['model']}** ({verdict(r)}: {found}). Why: {why}.\n"
                 f"  - Would fix it: {remedy}. Tried: " + "; then ".join(outcomes) + ".\n")
    return text


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default=os.environ.get("DIFFIPC_CLI", os.path.join(ROOT, "build", "cli", "diffipc")))
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "output", "503"))
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--families", nargs="*", default=[f[0] for f in FAMILIES])
    p.add_argument("--full", action="store_true", help="more values per family (about 3 times the runs)")
    p.add_argument("--results", default=None, help="write results.md, results.csv and atlas.png here")
    a = p.parse_args(argv)
    FAMILIES[:] = families(a.full)  # the other functions read the module's list
    todo = []
    for fam, _, values, build, conserved in FAMILIES:
        if fam not in a.families:
            continue
        for v in values:
            scene = build(v)
            todo.append((fam, v, "IPC", scene, conserved))
            for k in PENALTY_FACTORS:
                todo.append((fam, v, f"penalty {k}E", penalty_version(scene, k), conserved))
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as pool:
        rows = list(pool.map(lambda t: run_cell(a.cli, a.output, *t), todo))
    if not a.results:
        for r in rows:
            print({k: r[k] for k in ("family", "value", "model", "status", "steps", "intersecting_states",
                                     "plane_gap", "energy_drift", "time")}, verdict(r))
        return rows
    os.makedirs(a.results, exist_ok=True)
    diffipc.studies.write_csv(os.path.join(a.results, "results.csv"), rows)
    plot_atlas(rows, os.path.join(a.results, "atlas.png"))
    notes = failures(rows, verify_fixes(a.cli, a.output, rows, a.jobs))
    text = diffipc.studies.provenance(ROOT, __file__, sys.argv[1:] if argv is None else argv)
    text += f"\n{len(rows)} runs, each single-threaded, {a.jobs} at a time.\n\n"
    text += "| contact | cells finished, every state valid | stopped with a status | with invalid states | " \
            "invalid states in all |\n| --- | --- | --- | --- | --- |\n"
    for m in MODELS:
        sel = [r for r in rows if r["model"] == m]
        bad = sum(r["intersecting_states"] + r["inverted_states"] + (r["plane_gap"] < 0) + r["passed_through"]
                  for r in sel)
        text += (f"| {m} | {sum(verdict(r) == 'ok' for r in sel)} of {len(sel)} | "
                 f"{sum(verdict(r) == 'failed' for r in sel)} | {sum(verdict(r) == 'invalid' for r in sel)} | {bad} |\n")
    text += "\n![stability atlas](atlas.png)\n" + tables(rows)
    text += "\n### Cells that did not finish valid\n\n" + (notes or "None.\n")
    open(os.path.join(a.results, "results.md"), "w").write(text)
    return rows


if __name__ == "__main__":
    main()
