#!/usr/bin/python3
"""Problem file of study 402: the initial velocity of a ring thrown against a wall, fitted so
that the ring's centre of mass is at a target point at the final step.

The target is made by the forward itself: the ring is thrown with the true velocity
TRUE_VELOCITY, and its mass-weighted centre at the final step (lumped P1 masses, the
centre the `center_of_mass` objective measures) becomes the target. The problem starts
from START_VELOCITY, far from the truth, inside the bounds LOWER..UPPER. The lower bound
of the horizontal speed makes the ring reach the wall well before the final step, so every
design in the box bounces (a direct throw onto the target without the wall, vx = 0.6 m/s,
is outside the box). Nothing here is random.

    PYTHONPATH=build/python /usr/bin/python3 studies/402_throw_target/generate.py

Writes problem.json next to this script and prints the target and a check: the problem's
J at the true velocity (zero up to round-off, by construction) and the steps at which the
ring touches the wall in the true run.
"""
import json
import pathlib

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent

TRUE_VELOCITY = [3.2, 1.8]        # m/s, the throw that makes the target
START_VELOCITY = [5.5, -1.0]      # m/s, where the fit starts
LOWER = [2.2, -2.0]               # m/s: vx >= 2.2 reaches the wall (0.45 m away) by t = 0.205 s
UPPER = [6.0, 4.0]
STEPS, DT = 60, 0.005             # 0.3 s, BDF2


def scene_dict(velocity):
    return {
        "description": "A 2D neo-Hookean ring (outer radius 5 cm, 24 x 1 cells, 48 triangles) thrown under "
                       "gravity against a wall 0.45 m to its right; BDF2, 60 steps of 5 ms.",
        "dimension": 2,
        "bodies": [{"name": "ring",
                    "mesh": {"annulus": {"center": [0.0, 0.3], "inner_radius": 0.035, "outer_radius": 0.05,
                                         "segments": 24, "layers": 1}},
                    "material": {"model": "neo_hookean", "E": 3e5, "nu": 0.4, "density": 1000},
                    "initial_velocity": list(velocity)}],
        "obstacles": [{"name": "wall", "plane": {"point": [0.5, 0.0], "normal": [-1.0, 0.0]}}],
        "contact": {"dhat": 1e-3, "kappa": 1e8},
        "gravity": [0.0, -9.81],
        "time": {"integrator": "bdf2", "dt": DT, "steps": STEPS},
        "solver": {"residual_tolerance": 1e-10},
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


def problem_dict(target):
    return {
        "description": "Initial velocity of a 2D ring thrown against a wall so that its centre of mass is at a "
                       f"target at the final step (0.3 s), after the bounce. Target made with v = {TRUE_VELOCITY} "
                       f"m/s (generate.py); the fit starts at {START_VELOCITY} m/s, L-BFGS-B within "
                       f"[{LOWER}, {UPPER}] m/s.",
        "scene": scene_dict(START_VELOCITY),
        "objective": {"type": "center_of_mass", "body": "ring", "targets": [target], "steps": [STEPS]},
        "parameters": [{"type": "initial_velocity", "per": "body", "body": "ring", "lower": LOWER, "upper": UPPER}],
        "optimizer": {"algorithm": "lbfgsb", "max_iterations": 50, "relative_gradient_tolerance": 1e-6},
        "output": {"design_every": 0},
        "gradcheck": {"directions": 2, "seed": 2, "step": 0.001, "halvings": 4},
    }


def contact_steps(trajectory):
    return [k + 1 for k, n in enumerate(trajectory["active_contacts"]) if n > 0]


def main():
    scene = diffipc.scene(scene_dict(TRUE_VELOCITY))
    sim, tr = diffipc.simulate(scene)
    if tr["final_status"] != "CONVERGED":
        raise SystemExit(f"the true run failed: {tr['final_status']} {tr['failure_message']}")
    target = [round(float(c), 12) for c in lumped_center(scene, tr["positions"][STEPS])]
    problem = problem_dict(target)
    (HERE / "problem.json").write_text(json.dumps(problem, indent=1) + "\n")

    J = diffipc.ReducedFunctional(problem)
    print(f"true velocity {TRUE_VELOCITY} m/s: centre at step {STEPS} = [{target[0]:.9f}, {target[1]:.9f}] m "
          f"(the target)")
    print(f"  wall contact (active pairs > 0) at steps {contact_steps(tr)}")
    print(f"  J(true velocity) = {J(np.array(TRUE_VELOCITY)):.3e} m^2 (round-off of the 12-digit target)")
    start = diffipc.scene(scene_dict(START_VELOCITY))
    _, tr0 = diffipc.simulate(start)
    c0 = lumped_center(start, tr0["positions"][STEPS])
    print(f"start velocity {START_VELOCITY} m/s: centre at step {STEPS} = [{c0[0]:.6f}, {c0[1]:.6f}] m, "
          f"J = {J(np.array(START_VELOCITY)):.6e} m^2, wall contact at steps {contact_steps(tr0)}")
    print(f"wrote {HERE / 'problem.json'}")


if __name__ == "__main__":
    main()
