#!/usr/bin/python3
"""Check a run of study 403 independently of the optimizer's own numbers.

    PYTHONPATH=build/python /usr/bin/python3 studies/403_friction_fit/evaluate.py output/403

Reads DIR/summary.json and DIR/optimal_problem.json, re-evaluates J at the fitted
coefficient with diffipc.ReducedFunctional (against the summary's final_J), re-simulates
the slide with it and prints: the fitted and the true coefficient, the block's centre at
the final step against the measurement, and the run's counts and wall times.
"""
import json
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import generate  # noqa: E402  (the study's scene, truth and start)

import diffipc  # noqa: E402


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    out = pathlib.Path(sys.argv[1])
    summary = json.loads((out / "summary.json").read_text())
    problem = json.loads((out / "optimal_problem.json").read_text())
    measured = np.array(problem["objective"]["targets"][0])
    mu = float(summary["design"][0])
    J_again = diffipc.ReducedFunctional(problem)([mu])
    center = generate.final_center(mu)
    w = summary["wall_time"]
    print(f"{summary['algorithm']}: stop {summary['stop_reason']}, {summary['iterations']} iterations, "
          f"{summary['evaluations']} evaluations, {summary['rejected']} rejected")
    print(f"J {summary['initial_J']:.6e} -> {summary['final_J']:.6e} m^2 (re-evaluated at the design: {J_again:.6e})")
    print(f"mu: start {generate.START_MU}, fitted {mu:.9f}, true {generate.TRUE_MU}; error {mu - generate.TRUE_MU:.3e}")
    print(f"centre at step {generate.STEPS}: [{center[0]:.9f}, {center[1]:.9f}] m, measured "
          f"[{measured[0]:.9f}, {measured[1]:.9f}] m, distance {np.linalg.norm(center - measured):.3e} m")
    print(f"wall time {w['total']:.3f} s: evaluations {w['evaluation']:.3f} s, optimizer {w['optimizer']:.5f} s "
          f"({100 * w['optimizer'] / w['total']:.3f}% of the total); optimizer CPU time "
          f"{summary['optimizer_cpu_seconds']:.5f} s ({100 * summary['optimizer_cpu_seconds'] / w['total']:.3f}%)")


if __name__ == "__main__":
    main()
