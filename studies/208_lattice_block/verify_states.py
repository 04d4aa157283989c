#!/usr/bin/python3
"""Checks another run's committed states of a static scene with the CPU solver: the CPU's own force residual there.

Usage: PYTHONPATH=build/python /usr/bin/python3 studies/208_lattice_block/verify_states.py SCENE TRAJECTORY.h5

For each committed step k (time t_k) of TRAJECTORY.h5 (e.g. `diffipc simulate SCENE --device gpu`), the scene
is run for one static step of dt = t_k on the CPU, started from the state of step k: the load is that of
t_k, so a state that is an equilibrium by the CPU's measure converges with 0 Newton iterations and its
residual is the CPU's residual at that state. Where the CPU needs iterations, the line says how many and
how far (relative to the scene size) they moved the state. Static scenes only (no inertia: dt enters the
step only through the load's time). Exits with 1 if some state is not within the scene's residual tolerance.
"""
import argparse
import json
import os
import sys
import tempfile

import h5py
import numpy as np

import diffipc


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scene")
    parser.add_argument("trajectory")
    parser.add_argument("--steps", type=int, default=0, help="only the first N steps (0: all)")
    args = parser.parse_args()
    with open(args.scene) as f:
        scene = json.load(f)
    if scene.get("time", {}).get("integrator") != "static":
        sys.exit(f"{args.scene}: time.integrator must be \"static\" (this check has no inertia)")
    base = os.path.dirname(os.path.abspath(args.scene))
    with h5py.File(args.trajectory, "r") as f:
        positions = np.array(f["positions"])
        times = np.array(f["time"])
    rest = positions[0]
    size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0)))
    steps = len(times) - 1 if args.steps <= 0 else min(args.steps, len(times) - 1)
    outside = 0
    for k in range(1, steps + 1):
        one = json.loads(json.dumps(scene))
        one["time"]["dt"] = float(times[k])
        one["time"]["steps"] = 1
        one["time"].pop("adaptive", None)
        one["output"] = {"directory": tempfile.gettempdir(), "vtu_every": 0}
        simulator = diffipc.Simulator(diffipc.scene(one, base))
        simulator.set_initial_state(positions[k], np.zeros_like(positions[k]))
        status = simulator.step()
        record = simulator.trajectory()
        iterations = int(record["newton_iterations"][-1]) if status == "CONVERGED" else -1
        moved = float(np.abs(simulator.positions - positions[k]).max()) / size
        within = status == "CONVERGED" and iterations == 0
        outside += not within
        residual = f"residual {record['residual'][-1]:.2e}" if within else "not within the tolerance"
        print(f"step {k:3d} (t = {times[k]:.4g}): CPU {status}, {iterations} Newton iterations, {residual}, "
              f"moved {moved:.1e} of the size", flush=True)
    print(f"{steps - outside} of {steps} states are equilibria within the CPU's residual tolerance")
    return 1 if outside else 0


if __name__ == "__main__":
    sys.exit(main())
