#!/usr/bin/env python3
"""Study 501: only the work a scene needs. Runs every example scene (studies/*/scene*.json and
docs/tutorial/bracket.json) through `diffipc simulate` for a few steps and tabulates, per
potential, how often the solver evaluated it and its wall time (summary.json "potentials"),
with the contact phases (broad phase, CCD, barrier) and the linear algebra.

    PYTHONPATH=build/python /usr/bin/python3 studies/501_scene_work/run.py [--cli build/cli/diffipc] [-o output/501]
        [--steps 2 | --full] [--threads N] [--results studies/501_scene_work | --table FILE.md]

(or `diffipc study 501`).

What each scene needs is read from its JSON, independently of the solver: inertia only in a
dynamic scene (or while a static step relaxes with its proximal term, which is inertia's mass
term), external forces only with gravity or tractions, contact only with a contact block or
obstacles, friction only with a positive coefficient (a periodic cell adds no term: it maps
the same potentials to the fluctuation and the macroscopic gradient).

Then one gradient of each example problem (studies/30x, 401-404, the tutorials'), with the
parameter blocks the adjoint computed against those its parameters read (shape: rest positions;
E, nu, mu, lambda: the Lame parameters; ...). The script exits with status 1, naming the scene and
the potential or the problem and the blocks, if work ran that is not needed or needed work did
not run.
"""
import argparse
import csv
import glob
import json
import os
import subprocess
import sys

import diffipc.studies

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

POTENTIALS = ["inertia", "elastic", "external_force", "contact", "friction"]


def example_scenes():
    found = sorted(glob.glob(os.path.join(ROOT, "studies", "*", "scene*.json")))
    return found + [os.path.join(ROOT, "docs", "tutorial", "bracket.json")]


def needs(scene):
    """The potentials a scene needs, from its JSON alone (docs/scene_format.md)."""
    contact_block = scene.get("contact")
    obstacles = scene.get("obstacles", [])
    contact = (contact_block is not None or len(obstacles) > 0) and (contact_block or {}).get("enabled", True)
    mu = scene.get("friction", {}).get("coefficient", 0.0)
    sides = [side.get("friction", {}).get("coefficient", mu) for side in scene["bodies"] + obstacles]
    external = any(g != 0 for g in scene.get("gravity", [])) or len(scene.get("neumann", [])) > 0
    return {
        "inertia": scene["time"]["integrator"] != "static",
        "elastic": True,
        "external_force": external,
        "contact": contact,
        "friction": contact and any(m > 0 for m in sides),
    }


# The parameter blocks of the adjoint each parameter type reads (docs/problem_format.md "parameters").
BLOCKS = {"shape": "rest_positions", "E": "lame", "nu": "lame", "mu": "lame", "lambda": "lame",
          "density": "density", "friction": "friction", "initial_velocity": "initial_velocity",
          "initial_displacement": "initial_displacement", "prescribed": "prescribed"}


def example_problems():
    """The gradient examples and the optimization studies that run in seconds, and the tutorials'."""
    found = sorted(glob.glob(os.path.join(ROOT, "studies", "30*", "problem.json")))
    found += sorted(glob.glob(os.path.join(ROOT, "studies", "40[1-4]*", "problem.json")))
    return found + sorted(glob.glob(os.path.join(ROOT, "docs", "tutorial", "**", "problem*.json"), recursive=True))


def adjoint_work(path):
    """One gradient of a problem at its initial design: (parameter types, blocks needed, blocks the
    adjoint computed, forward time, adjoint time)."""
    import diffipc
    problem = json.load(open(path))
    types = sorted({p["type"] for p in problem["parameters"]})
    J = diffipc.ReducedFunctional(path)
    e = J.evaluation(J.initial, True)
    return types, sorted({BLOCKS[t] for t in types}), sorted(e.adjoint_blocks), e.forward_time, e.adjoint_time


def check_adjoint(name, types, needed, computed):
    """The violations of 'no derivative nobody asked for' (and of 'every derivative asked for')."""
    extra, missing = sorted(set(computed) - set(needed)), sorted(set(needed) - set(computed))
    out = [f"{name}: the adjoint computed {extra}, which its parameters {types} do not read"] if extra else []
    return out + ([f"{name}: the adjoint did not compute {missing}, which its parameters {types} read"] if missing else [])


def evaluations(entry):
    return entry["values"] + entry["gradients"] + entry["hessians"] + entry["step_bounds"]


def check(name, scene, summary):
    """The violations of 'only the work a scene needs' in one run, as messages."""
    need = needs(scene)
    ran = {k: evaluations(v) > 0 for k, v in summary["potentials"].items()}
    problems = []
    for k in sorted(set(ran) | set(need)):
        if k not in POTENTIALS:
            problems.append(f"{name}: unknown potential '{k}' ran")
            continue
        relaxed = summary.get("load_stepping", {}).get("relaxation_steps", 0) > 0
        allowed = need[k] or (k == "inertia" and relaxed)
        if ran.get(k, False) and not allowed:
            problems.append(f"{name}: '{k}' ran but the scene does not need it")
        if need[k] and not ran.get(k, False):
            problems.append(f"{name}: the scene needs '{k}' but it did not run")
    contact_phases = [p for p in ("broad_phase", "ccd", "barrier") if p in summary["wall_time"]]
    if not need["contact"] and contact_phases:
        problems.append(f"{name}: contact phases {contact_phases} ran without contact")
    if need["contact"] and summary["wall_time"].get("broad_phase", 0) <= 0:
        problems.append(f"{name}: contact without a broad phase")
    return problems


def run_scene(cli, path, out, steps, threads):
    rel = os.path.relpath(path, ROOT)
    folder = os.path.join(out, rel.replace(os.sep, "_").replace(".json", ""))
    cmd = [cli, "simulate", path, "-o", folder, "--vtu-every", "0", "-q"]
    cmd += ["--steps", str(steps)] if steps else []
    cmd += ["--threads", str(threads)] if threads else []
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode not in (0, 2):
        raise RuntimeError(f"{rel}: {' '.join(cmd)} exited {done.returncode}: {done.stderr.strip()}")
    summary = json.load(open(os.path.join(folder, "summary.json")))
    return rel, summary


def cell(summary, k):
    entry = summary["potentials"].get(k)
    if entry is None or evaluations(entry) == 0:
        return "—"
    return f"{1e3 * entry['time']:.1f} ms ({entry['hessians']} H)"


def table(rows):
    head = ["scene", "integrator", "status", "steps", "Newton"] + [p.replace("_", " ") for p in POTENTIALS]
    head += ["broad phase", "CCD", "factor + solve", "total"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for rel, scene, s in rows:
        w = s["wall_time"]
        contact = [f"{1e3 * w[p]:.1f} ms" if p in w else "—" for p in ("broad_phase", "ccd")]
        line = [f"`{rel}`", scene["time"]["integrator"], s["status"], str(s["steps_committed"])]
        line += [str(s["counts"]["newton_iterations"])] + [cell(s, p) for p in POTENTIALS] + contact
        line += [f"{1e3 * (w['factorization'] + w['solve']):.1f} ms", f"{w['total']:.3f} s"]
        lines.append("| " + " | ".join(line) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default=os.environ.get("DIFFIPC_CLI", os.path.join(ROOT, "build", "cli", "diffipc")))
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "output", "501"))
    p.add_argument("--steps", type=int, default=2, help="time steps per scene (default 2)")
    p.add_argument("--full", action="store_true", help="each scene's own number of steps")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--table", default=None,
                   help="write the markdown table here, and the raw numbers beside it as CSV (default: print it)")
    p.add_argument("--results", default=None, help="write results.md and results.csv into this folder")
    p.add_argument("--scenes", nargs="*", help="scene files (default: every example scene)")
    p.add_argument("--problems", nargs="*", help="problem files for the adjoint's table (default: the examples)")
    p.add_argument("--no-adjoint", action="store_true", help="scenes only")
    a = p.parse_args(argv)
    if a.results:
        a.table = os.path.join(a.results, "results.md")
    rows, problems = [], []
    for path in a.scenes or example_scenes():
        rel, summary = run_scene(a.cli, os.path.abspath(path), a.output, None if a.full else a.steps, a.threads)
        scene = json.load(open(path))
        rows.append((rel, scene, summary))
        problems += check(rel, scene, summary)
    adjoint_rows = []
    if not a.no_adjoint:
        for path in a.problems or example_problems():
            rel = os.path.relpath(os.path.abspath(path), ROOT)
            types, needed, computed, forward, adjoint = adjoint_work(path)
            adjoint_rows.append((rel, types, needed, computed, forward, adjoint))
            problems += check_adjoint(rel, types, needed, computed)
    text = table(rows)
    if adjoint_rows:
        text += ("\nThe adjoint, one gradient per problem at its initial design: the parameter blocks its "
                 "parameters read and those the backward sweep computed (adjoint/sensitivity.hpp).\n\n")
        text += "| problem | parameters | blocks needed | blocks computed | forward | adjoint |\n"
        text += "| --- | --- | --- | --- | --- | --- |\n"
        for rel, types, needed, computed, forward, adjoint in adjoint_rows:
            text += (f"| `{rel}` | {', '.join(types)} | {', '.join(needed)} | {', '.join(computed)} | "
                     f"{1e3 * forward:.1f} ms | {1e3 * adjoint:.1f} ms |\n")
    if a.table:
        open(a.table, "w").write(diffipc.studies.provenance(ROOT, __file__, sys.argv[1:] if argv is None else argv) + "\n" + text)
        with open(os.path.splitext(a.table)[0] + ".csv", "w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["scene", "potential", "values", "gradients", "hessians", "step_bounds", "time_s"])
            for rel, _, s in rows:
                for k, v in s["potentials"].items():
                    out.writerow([rel, k, v["values"], v["gradients"], v["hessians"], v["step_bounds"], v["time"]])
    else:
        print(text)
    for msg in problems:
        print("VIOLATION:", msg, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
