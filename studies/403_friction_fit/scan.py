#!/usr/bin/python3
"""J(mu) of study 403 on a grid: the value, the adjoint derivative, a central difference,
and the step at which the block comes to rest.

    PYTHONPATH=build/python /usr/bin/python3 studies/403_friction_fit/scan.py [--lo 0.86 --hi 0.94 --n 17]

Where the block stops before the final step (mu above tan 30 deg = 0.577), the step at
which it comes to rest (the first state whose centre moves slower than the friction's
eps_v = 1e-3 m/s) changes with mu in jumps, and dJ/dmu jumps with it: the adjoint
derivative and the central difference agree inside each smooth piece, and the difference
disagrees only where its stencil straddles a jump.
"""
import argparse
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import generate  # noqa: E402  (the study's scene)

import diffipc  # noqa: E402


def rest_step(mu, eps_v=1e-3):
    scene = diffipc.scene(generate.scene_dict(mu))
    _, tr = diffipc.simulate(scene)
    for k, v in enumerate(tr["velocities"]):
        if np.linalg.norm(generate.lumped_center(scene, v)) < eps_v:
            return k
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lo", type=float, default=0.86)
    ap.add_argument("--hi", type=float, default=0.94)
    ap.add_argument("--n", type=int, default=17)
    ap.add_argument("--h", type=float, default=1e-5, help="central-difference step (default 1e-5)")
    args = ap.parse_args()
    J = diffipc.ReducedFunctional(generate.HERE / "problem.json")
    print(f"{'mu':>8}  {'J (m^2)':>18}  {'dJ/dmu adjoint':>15}  {'central diff.':>15}  {'rel. diff.':>9}  rest step")
    for mu in np.linspace(args.lo, args.hi, args.n):
        value, g = J.value_and_gradient([mu])
        fd = (J([mu + args.h]) - J([mu - args.h])) / (2 * args.h)
        rel = abs(g[0] - fd) / max(abs(g[0]), abs(fd))
        k = rest_step(mu)
        print(f"{mu:8.5f}  {value:18.10e}  {g[0]:15.6e}  {fd:15.6e}  {rel:9.1e}  {'-' if k is None else k}")


if __name__ == "__main__":
    main()
