#!/usr/bin/python3
"""Synthetic marker data for study 404: a clamped bar with a smooth modulus field, hit by a moving plane.

Simulates the true field with diffipc (the same forward, with the same fixed barrier
stiffness, that the problem files' reduced functional runs), reads the marker
trajectories, adds seeded Gaussian noise and writes the problem files of the study and
truth.json (the true per-element modulus that evaluate.py compares a fit with).

    PYTHONPATH=build/python /usr/bin/python3 studies/404_bar_modulus_field/generate.py

writes, next to this script (or into --out DIR):

    problem.json                    noisy markers, filter radius 0.2 m (the study)
    problem_filter_0.1.json         noisy markers, filter radius 0.1 m
    problem_no_filter.json          noisy markers, no filter (one log-modulus per element)
    problem_exact.json              noise-free markers, filter radius 0.2 m
    problem_exact_filter_0.1.json   noise-free markers, filter radius 0.1 m
    problem_exact_no_filter.json    noise-free markers, no filter
    problem_ipopt.json              as problem.json, with Ipopt (100 iterations)
    problem_discrepancy.json        as problem.json, stopped by the discrepancy principle
                                    (optimizer.objective_target = 1.03 n sigma^2 / 2)
    truth.json                      the true field, the markers, the noise level
"""
import argparse
import json
import math
import pathlib

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent

LENGTH, HEIGHT = 1.0, 0.1           # m
CELLS = [40, 4]                     # 320 triangles
E_MEAN, NU, DENSITY = 1.5e5, 0.3, 1000.0
E_START = E_MEAN / 3                # the fit starts from a uniform field 3x too soft
E_LOWER, E_UPPER = 1e4, 1e6         # bounds of every element's modulus (Pa)
GAP = 0.002                         # m between the bar's free end and the plane at t = 0
# The plane moves in at 1 m/s for 50 ms, then back out at 1 m/s (muparser's ternary).
HAMMER_MOTION = ["t < 0.05 ? t : 0.1 - t", "0"]
STEPS, DT = 50, 0.004               # 0.2 s: the pulse runs to the clamp and back to the free end
MARKER_EVERY = 2                    # a marker on every 2nd vertex of the top and bottom edges
STEP_EVERY = 2                      # markers compared at every 2nd step
ROUND = 10                          # decimals (m) of the written targets


def true_modulus(x):
    """A smooth field that varies 2x along the bar (1e5 to 2e5 Pa), one full sine period."""
    return E_MEAN * (1.0 + np.sin(2.0 * math.pi * x / LENGTH) / 3.0)


def scene_dict():
    return {
        "description": "A 2D neo-Hookean bar (1 m x 0.1 m, 40 x 4 cells) clamped at x = 1 m, hit at its free end "
                       "by a plane that moves in at 1 m/s for 50 ms and then withdraws; BDF2, 50 steps of 4 ms.",
        "dimension": 2,
        "bodies": [{"name": "bar",
                    "mesh": {"box": {"min": [0.0, 0.0], "max": [LENGTH, HEIGHT], "cells": CELLS}},
                    "material": {"model": "neo_hookean", "E": E_START, "nu": NU, "density": DENSITY}}],
        "dirichlet": [{"body": "bar", "region": {"min": [LENGTH - 1e-6, -1.0], "max": [LENGTH + 1.0, 1.0]},
                       "displacement": [0, 0]}],
        "obstacles": [{"name": "hammer", "plane": {"point": [-GAP, 0.0], "normal": [1.0, 0.0],
                                                   "motion": HAMMER_MOTION}}],
        "contact": {"dhat": 1e-3, "kappa": 1e10},
        "time": {"integrator": "bdf2", "dt": DT, "steps": STEPS},
        "solver": {"residual_tolerance": 1e-10},
    }


def problem_dict(scene, markers, steps, targets, radius, description, algorithm="lbfgsb", iterations=200,
                 target=None):
    maps = ([{"type": "filter", "radius": radius}] if radius else []) + [{"type": "exp"}]
    return {
        "description": description,
        "scene": scene,
        "objective": {"type": "markers", "vertices": markers, "steps": steps, "targets": targets},
        "parameters": [{"type": "E", "per": "element", "initial": math.log(E_START),
                        "lower": math.log(E_LOWER), "upper": math.log(E_UPPER), "maps": maps}],
        "optimizer": {"algorithm": algorithm, "max_iterations": iterations,
                      **({"objective_target": target} if target else {})},
        "output": {"design_every": 20},
        "gradcheck": {"directions": 2, "seed": 4, "step": 0.1, "halvings": 4},
    }


def dump(tree, indent=""):
    """JSON with lists of numbers on one line, and one line per target step."""
    def scalar_list(node):
        return isinstance(node, list) and all(not isinstance(v, (list, dict)) for v in node)

    inner = indent + "  "
    if isinstance(tree, dict):
        items = [f"{inner}{json.dumps(k)}: {dump(v, inner)}" for k, v in tree.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(tree, list) and not scalar_list(tree):
        if all(isinstance(v, list) and all(scalar_list(w) for w in v) for v in tree):  # targets
            return "[\n" + ",\n".join(inner + json.dumps(v) for v in tree) + "\n" + indent + "]"
        return "[\n" + ",\n".join(inner + dump(v, inner) for v in tree) + "\n" + indent + "]"
    return json.dumps(tree)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=404, help="seed of the noise (default 404)")
    ap.add_argument("--noise", type=float, default=0.01,
                    help="noise standard deviation per coordinate, as a fraction of the displacement scale "
                         "(the largest marker displacement of the true run); default 0.01")
    ap.add_argument("--out", type=pathlib.Path, default=HERE, help="output folder (default: this script's)")
    args = ap.parse_args()
    if not args.noise >= 0:
        ap.error(f"--noise: must be >= 0, got {args.noise}")
    args.out.mkdir(parents=True, exist_ok=True)

    scene = scene_dict()
    sc = diffipc.scene(scene)
    X = sc.rest_positions
    elements = sc.elements
    body = np.where(sc.vertex_body == 0)[0]
    centroids = X[elements].mean(axis=1)
    E_true = true_modulus(centroids[:, 0])

    sim = diffipc.Simulator(sc)
    sim.set_element_materials(E_true, np.full(len(elements), NU))
    tr = sim.run()
    if tr["final_status"] != "CONVERGED":
        raise SystemExit(f"the true run failed: {tr['final_status']} {tr['failure_message']}")

    tol = 1e-9
    top = sorted((int(v) for v in body if abs(X[v, 1] - HEIGHT) < tol), key=lambda v: X[v, 0])
    bottom = sorted((int(v) for v in body if abs(X[v, 1]) < tol), key=lambda v: X[v, 0])
    markers = top[::MARKER_EVERY] + bottom[::MARKER_EVERY]
    steps = list(range(STEP_EVERY, STEPS + 1, STEP_EVERY))
    clean = tr["positions"][steps][:, markers, :]                     # [steps, markers, 2]
    scale = float(np.linalg.norm(clean - X[markers][None], axis=2).max())
    sigma = args.noise * scale
    rng = np.random.default_rng(args.seed)
    noisy = clean + rng.normal(0.0, sigma, size=clean.shape)

    def rounded(a):
        return [[[round(float(c), ROUND) for c in p] for p in row] for row in a]

    base = ("Study 404 (README.md): per-element Young's modulus (log-space) of a clamped 2D bar hit by a "
            f"moving plane, fitted to {len(markers)} marker vertices at {len(steps)} steps of a run with a smooth "
            "true field. ")
    noise_text = (f"Markers with Gaussian noise, sigma {sigma:.3e} m ({args.noise:g} of the displacement scale "
                  f"{scale:.4f} m, seed {args.seed}). ")
    exact_text = "Noise-free markers. "
    variants = [
        ("problem.json", noisy, 0.2, noise_text + "Filter radius 0.2 m.", "lbfgsb", 200),
        ("problem_filter_0.1.json", noisy, 0.1, noise_text + "Filter radius 0.1 m.", "lbfgsb", 200),
        ("problem_no_filter.json", noisy, None, noise_text + "No filter.", "lbfgsb", 200),
        ("problem_exact.json", clean, 0.2, exact_text + "Filter radius 0.2 m.", "lbfgsb", 200),
        ("problem_exact_filter_0.1.json", clean, 0.1, exact_text + "Filter radius 0.1 m.", "lbfgsb", 200),
        ("problem_exact_no_filter.json", clean, None, exact_text + "No filter.", "lbfgsb", 200),
        ("problem_ipopt.json", noisy, 0.2, noise_text + "Filter radius 0.2 m, Ipopt.", "ipopt", 100),
    ]
    # The discrepancy principle: stop once the misfit is down to what the noise explains,
    # J <= tau n sigma^2 / 2 (n coordinates, tau = 1.03).
    discrepancy = float("%.6g" % (1.03 * clean.size * sigma ** 2 / 2))
    variants.append(("problem_discrepancy.json", noisy, 0.2, noise_text + "Filter radius 0.2 m; stops at J <= "
                     f"1.03 n sigma^2 / 2 = {discrepancy:g} m^2 (the discrepancy principle).", "lbfgsb", 200))
    for name, data, radius, text, algorithm, iterations in variants:
        tree = problem_dict(scene, markers, steps, rounded(data), radius, base + text, algorithm, iterations,
                            discrepancy if name == "problem_discrepancy.json" else None)
        (args.out / name).write_text(dump(tree) + "\n")

    truth = {
        "description": "Study 404: the true per-element Young's modulus (Pa, in the scene's element order), "
                       "E = 1.5e5 (1 + sin(2 pi x / 1 m) / 3) at the element centroid x, and the noise added "
                       "to the markers.",
        "E_start": E_START,
        "noise": {"seed": args.seed, "relative": args.noise, "sigma": sigma, "displacement_scale": scale},
        "markers": markers,
        "steps": steps,
        "E": [float(e) for e in E_true],
        "centroids": [[float(c) for c in p] for p in centroids],
    }
    (args.out / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    print(f"{len(elements)} elements, {len(markers)} markers x {len(steps)} steps; displacement scale "
          f"{scale:.6f} m, noise sigma {sigma:.6e} m (seed {args.seed}); true E in "
          f"[{E_true.min():.4g}, {E_true.max():.4g}] Pa; wrote {len(variants)} problem files and truth.json "
          f"to {args.out}")


if __name__ == "__main__":
    main()
