#!/usr/bin/python3
"""Check a run of study 402 independently of the optimizer's own numbers.

    PYTHONPATH=build/python /usr/bin/python3 studies/402_throw_target/evaluate.py output/402

Reads DIR/summary.json and DIR/optimal_problem.json, re-evaluates J at the optimal design
with diffipc.ReducedFunctional (against the summary's final_J), re-simulates the throw
with the recovered velocity and prints: the recovered and the true velocity, the ring's
centre at the final step against the target, its velocity there (vx < 0: it came
back from the wall), the steps at which the ring touches the wall
(active contact pairs > 0; also for the start and the true velocity), the centre's
sensitivity to the velocity there (central differences of the forward), and the run's
counts and wall times from summary.json.
"""
import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import generate  # noqa: E402  (the study's scene, truth and start)

import diffipc  # noqa: E402


def throw(velocity):
    scene = diffipc.scene(generate.scene_dict(velocity))
    _, tr = diffipc.simulate(scene)
    if tr["final_status"] != "CONVERGED":
        raise SystemExit(f"the run with v = {velocity} failed: {tr['final_status']} {tr['failure_message']}")
    T = generate.STEPS
    return (generate.lumped_center(scene, tr["positions"][T]), generate.contact_steps(tr),
            generate.lumped_center(scene, tr["velocities"][T]))


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    out = pathlib.Path(sys.argv[1])
    summary = json.loads((out / "summary.json").read_text())
    problem = json.loads((out / "optimal_problem.json").read_text())
    target = np.array(problem["objective"]["targets"][0])
    v = np.array(summary["design"])
    J = diffipc.ReducedFunctional(problem)
    J_again = J(v)
    center, steps, velocity = throw(v)
    _, steps_start, _ = throw(generate.START_VELOCITY)
    _, steps_true, _ = throw(generate.TRUE_VELOCITY)
    w = summary["wall_time"]
    print(f"stop {summary['stop_reason']}, {summary['iterations']} iterations, {summary['evaluations']} evaluations, "
          f"{summary['rejected']} rejected")
    print(f"J {summary['initial_J']:.6e} -> {summary['final_J']:.6e} m^2 (re-evaluated at the design: {J_again:.6e})")
    print(f"velocity: start {generate.START_VELOCITY}, recovered [{v[0]:.9f}, {v[1]:.9f}], "
          f"true {generate.TRUE_VELOCITY} m/s; error [{v[0] - generate.TRUE_VELOCITY[0]:.3e}, "
          f"{v[1] - generate.TRUE_VELOCITY[1]:.3e}] m/s")
    print(f"centre at step {generate.STEPS}: [{center[0]:.9f}, {center[1]:.9f}] m, target "
          f"[{target[0]:.9f}, {target[1]:.9f}] m, distance {np.linalg.norm(center - target):.3e} m")
    print(f"centre velocity at step {generate.STEPS} (after the bounce): [{velocity[0]:.6f}, {velocity[1]:.6f}] m/s "
          f"(thrown at vx = {v[0]:.6f} m/s towards the wall)")
    print(f"wall contact at steps: start {steps_start}, recovered {steps}, true {steps_true}")
    # The centre's sensitivity to the velocity at the result, by central differences of the forward.
    h = 1e-4
    dc = [(throw(v + h * e)[0] - throw(v - h * e)[0]) / (2 * h) for e in np.eye(2)]
    print(f"d(centre)/d(vx) = [{dc[0][0]:.4f}, {dc[0][1]:.4f}] s, d(centre)/d(vy) = [{dc[1][0]:.4f}, {dc[1][1]:.4f}] s "
          f"(central differences, h = {h:g} m/s)")
    print(f"wall time {w['total']:.3f} s: evaluations {w['evaluation']:.3f} s, optimizer {w['optimizer']:.5f} s "
          f"({100 * w['optimizer'] / w['total']:.3f}% of the total)")


if __name__ == "__main__":
    main()
