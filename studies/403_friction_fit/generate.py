#!/usr/bin/python3
"""Problem files of study 403: the friction coefficient of a block sliding down a slope,
fitted to the block's "measured" final position.

The measurement is made by the forward itself: the block slides with the true coefficient
TRUE_MU, and its mass-weighted centre at the final step (lumped P1 masses, the centre the
`center_of_mass` objective measures) is the measured position. The noisy variant adds
seeded Gaussian noise of NOISE m per coordinate to it. Every problem starts from START_MU,
far from the truth, within [LOWER, UPPER].

    PYTHONPATH=build/python /usr/bin/python3 studies/403_friction_fit/generate.py

Writes, next to this script:
    problem.json         exact measurement, L-BFGS-B
    problem_ipopt.json   exact measurement, Ipopt
    problem_slsqp.json   exact measurement, SLSQP (NLopt)
    problem_noisy.json   measurement + noise (seed 403, sigma NOISE), L-BFGS-B
and prints the measurement, J at the true coefficient (zero up to round-off for the exact
measurement), the sensitivity d(centre)/d(mu) and the error in mu that the noise should
cause to first order: minimizing |c(mu) - c_true - n|^2 with c(mu) ~ c_true + dc (mu - mu_true)
gives mu - mu_true = (dc . n) / |dc|^2.
"""
import argparse
import json
import math
import pathlib

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent

TRUE_MU = 0.3                     # the coefficient that makes the measurement
START_MU = 0.88                  # where every fit starts (above tan 30 deg = 0.577: the block stops)
LOWER, UPPER = 0.01, 1.0
NOISE = 1e-3                      # m, standard deviation per coordinate of the noisy measurement
STEPS, DT = 40, 0.01              # 0.4 s, implicit Euler
SLOPE_DEG = 30.0
SPEED = 0.2309401076758503        # m/s down the slope at t = 0 (0.2 m/s horizontally)


def scene_dict(mu):
    s = math.radians(SLOPE_DEG)
    return {
        "description": f"A 2D neo-Hookean block (0.1 m x 0.05 m, 8 x 4 cells, 64 triangles) sliding down a "
                       f"{SLOPE_DEG:g} degree slope (a plane obstacle) with Coulomb friction; implicit Euler, "
                       f"{STEPS} steps of {DT * 1e3:g} ms.",
        "dimension": 2,
        "bodies": [{"name": "block",
                    "mesh": {"box": {"min": [0.0, 0.0001], "max": [0.1, 0.0501], "cells": [8, 4]}},
                    "rotation": [-SLOPE_DEG],
                    "material": {"model": "neo_hookean", "E": 1e7, "nu": 0.3, "density": 1000},
                    "initial_velocity": [SPEED * math.cos(s), -SPEED * math.sin(s)]}],
        "obstacles": [{"name": "slope", "plane": {"point": [0.0, 0.0], "normal": [math.sin(s), math.cos(s)]}}],
        "contact": {"dhat": 2e-4, "kappa": 1e11},
        "friction": {"coefficient": mu, "eps_v": 1e-3, "iterations": 1},
        "gravity": [0.0, -9.81],
        "time": {"integrator": "implicit_euler", "dt": DT, "steps": STEPS},
        # 1e-12: at 1e-11 the slope of the computed J(mu) at the start is off by 2-3e-6 (the solves' bias),
        # which on the 8 x 4 block is enough to spoil gradcheck's second-order rates (README).
        "solver": {"residual_tolerance": 1e-12},
    }


def lumped_center(scene, positions):
    """Mass-weighted centre of body 0 with lumped P1 masses (a third of each triangle's mass per vertex)."""
    X = scene.rest_positions
    elements = scene.elements
    a, b, c = X[elements[:, 0]], X[elements[:, 1]], X[elements[:, 2]]
    area = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    mass = np.zeros(len(X))
    np.add.at(mass, elements.ravel(), np.repeat(area / 3.0, 3))
    body = np.where(scene.vertex_body == 0)[0]
    return (mass[body, None] * positions[body]).sum(axis=0) / mass[body].sum()


def final_state(mu):
    """The block's centre and the centre's velocity at the final step, slid with coefficient mu."""
    scene = diffipc.scene(scene_dict(mu))
    _, tr = diffipc.simulate(scene)
    if tr["final_status"] != "CONVERGED":
        raise SystemExit(f"the run with mu = {mu} failed: {tr['final_status']} {tr['failure_message']}")
    return lumped_center(scene, tr["positions"][STEPS]), lumped_center(scene, tr["velocities"][STEPS])


def final_center(mu):
    return final_state(mu)[0]


def problem_dict(measured, algorithm, what):
    return {
        "description": f"Friction coefficient of a block sliding down a {SLOPE_DEG:g} degree slope, fitted to its "
                       f"{what} centre of mass at the final step (0.4 s). Measurement made with mu = {TRUE_MU} "
                       f"(generate.py); the fit starts at mu = {START_MU}, {algorithm} within [{LOWER}, {UPPER}].",
        "scene": scene_dict(START_MU),
        "objective": {"type": "center_of_mass", "body": "block", "targets": [measured], "steps": [STEPS]},
        "parameters": [{"type": "friction", "per": "global", "lower": LOWER, "upper": UPPER}],
        "optimizer": {"algorithm": algorithm, "max_iterations": 50, "relative_gradient_tolerance": 1e-6},
        "output": {"design_every": 0},
        "gradcheck": {"directions": 2, "seed": 3, "step": 0.01, "halvings": 4},
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=403, help="seed of the noise (default 403)")
    args = ap.parse_args()

    exact, exact_velocity = final_state(TRUE_MU)
    rng = np.random.default_rng(args.seed)
    noise = rng.normal(0.0, NOISE, size=2)
    noisy = exact + noise

    def rounded(v):
        return [round(float(c), 12) for c in v]

    files = {
        "problem.json": problem_dict(rounded(exact), "lbfgsb", "measured"),
        "problem_ipopt.json": problem_dict(rounded(exact), "ipopt", "measured"),
        "problem_slsqp.json": problem_dict(rounded(exact), "slsqp", "measured"),
        "problem_noisy.json": problem_dict(rounded(noisy), "lbfgsb", f"noisy (sigma {NOISE:g} m) measured"),
    }
    for name, problem in files.items():
        (HERE / name).write_text(json.dumps(problem, indent=1) + "\n")

    start, start_velocity = final_state(START_MU)
    # d(centre)/d(mu) by a central difference of the forward (an independent look at the sensitivity).
    h = 1e-4
    dc = (final_center(TRUE_MU + h) - final_center(TRUE_MU - h)) / (2 * h)
    predicted = float(dc @ noise) / float(dc @ dc)
    J = diffipc.ReducedFunctional(HERE / "problem.json")
    print(f"true mu {TRUE_MU}: centre at step {STEPS} = [{exact[0]:.9f}, {exact[1]:.9f}] m (the measurement), "
          f"speed {np.linalg.norm(exact_velocity):.4f} m/s")
    print(f"  J(true mu) = {J([TRUE_MU]):.3e} m^2 (round-off of the 12-digit measurement)")
    print(f"  d(centre)/d(mu) = [{dc[0]:.6f}, {dc[1]:.6f}] m (central difference, h = {h:g})")
    print(f"start mu {START_MU}: centre at step {STEPS} = [{start[0]:.6f}, {start[1]:.6f}] m, "
          f"speed {np.linalg.norm(start_velocity):.2e} m/s, J = {J([START_MU]):.6e} m^2")
    print(f"noise (seed {args.seed}, sigma {NOISE:g} m) = [{noise[0]:.6e}, {noise[1]:.6e}] m: first-order error "
          f"in mu (dc . noise) / |dc|^2 = {predicted:.6e} (its standard deviation sigma / |dc| = "
          f"{NOISE / np.linalg.norm(dc):.3e})")
    print("wrote " + ", ".join(files))


if __name__ == "__main__":
    main()
