"""Study 407: what a transient experiment adds. A synthetic drop test on the cube's mesh: the
cube falls at 0.1 m/s onto a rigid floor, bounces, and its 24 markers are tracked at three
times. Inertia sets the scale (the density is known), so E is determined as well as nu.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/drop.py \
        [--cli build/cli/diffipc] [--out output/407/drop] [--no-fit]

The synthetic data: the scene below with E = 2e4 Pa, nu = 0.4687 (the cube's fitted ratio),
density 1070 kg/m^3, the markers' simulated positions at steps 5, 10 and 14 (t = 10, 20, 28 ms)
plus Gaussian noise of 0.05 mm per coordinate (seed 407; a high-speed stereo camera's order),
written as a marker file with a time column. The Fisher matrix of the 216 weighted residuals
(sigma = 0.05 mm) is computed at the truth by diffipc.identifiability.fisher_matrix (one adjoint
per residual and its shifted twin, one factorization per step for all of them); unless --no-fit,
the data are then fitted from (log mu, log lambda) = (10, 10) (E = 5.5e4 Pa, nu = 0.25) with
L-BFGS-B, and the fit is compared with the truth in units of its standard errors.
"""
import argparse
import json
import math
import pathlib
import subprocess
import sys
import time

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
from confidence import e_nu_to_design, report  # noqa: E402
from cube_markers import Markers  # noqa: E402

from diffipc.identifiability import young_poisson  # noqa: E402

E_TRUE, NU_TRUE, DENSITY = 2e4, 0.4687, 1070.0
SIGMA = 5e-5  # m, noise per coordinate
MEASURED_STEPS = [5, 10, 14]
DT = 0.002


def drop_scene():
    """The cube 0.05 mm above a floor, falling at 0.1 m/s under gravity; implicit Euler, 14 steps
    of 2 ms (the impact and the rebound); contact with a fixed barrier stiffness (a gradient
    needs one; 1e9 keeps the gaps near 3e-5 m of dhat = 1e-4 m)."""
    return {
        "dimension": 3,
        "bodies": [{"name": "cube", "mesh": {"file": str(HERE / "data" / "cube.msh")}, "scale": 0.004,
                    "translation": [-0.02, -0.02, -0.02],
                    "material": {"model": "neo_hookean", "E": E_TRUE, "nu": NU_TRUE, "density": DENSITY},
                    "initial_velocity": [0, 0, -0.1]}],
        "obstacles": [{"name": "floor", "plane": {"point": [0, 0, -0.02005], "normal": [0, 0, 1]}}],
        "gravity": [0, 0, -9.81],
        "contact": {"dhat": 1e-4, "kappa": 1e9},
        "time": {"integrator": "implicit_euler", "dt": DT, "steps": max(MEASURED_STEPS)},
        "solver": {"residual_tolerance": 1e-9},
    }


def synthetic_markers(scene, path):
    """Writes the noisy transient marker file; returns the number of rows."""
    markers = np.loadtxt(HERE / "data" / "markers.txt")
    m = Markers(scene, markers)
    _, tr = diffipc.simulate(scene)
    if tr["final_status"] != "CONVERGED":
        raise RuntimeError(f"the drop test failed: {tr['failure_message']}")
    rng = np.random.default_rng(407)
    lines = []
    for k in MEASURED_STEPS:
        p = m.carry(tr["positions"][k]) + rng.normal(0, SIGMA, size=(len(markers), 3))
        lines += ["%.17g %.17g %.17g %.17g %.17g %.17g %.17g" % (*X, k * DT, *x) for X, x in zip(markers[:, :3], p)]
    path.write_text("# drop test (synthetic): X Y Z t x y z (m, s)\n" + "\n".join(lines) + "\n")
    return len(lines)


def problem(marker_file):
    return {
        "description": "Study 407's synthetic drop test: the cube's Lame parameters fitted to tracked markers.",
        "scene": drop_scene(),
        "objective": {"type": "markers", "file": str(marker_file), "sigma": SIGMA},
        "parameters": [{"type": t, "per": "body", "maps": [{"type": "exp"}], "initial": 10, "lower": 3,
                        "upper": 20} for t in ("mu", "lambda")],
        "optimizer": {"algorithm": "lbfgsb", "max_iterations": 50},
        "output": {"design_every": 0},
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407" / "drop"))
    parser.add_argument("--no-fit", action="store_true", help="only the Fisher matrix at the truth")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    rows = synthetic_markers(drop_scene(), out / "drop_markers.txt")
    p = problem(out / "drop_markers.txt")
    (out / "problem_drop.json").write_text(json.dumps(p, indent=1))
    truth = e_nu_to_design(E_TRUE, NU_TRUE)
    print("synthetic drop test: %d marker rows (24 markers x %d times), noise %.2f mm; truth E = %g Pa, nu = %g"
          % (rows, len(MEASURED_STEPS), 1e3 * SIGMA, E_TRUE, NU_TRUE))
    R, F, J = diffipc.identifiability.fisher_matrix(p, truth)
    print("Fisher matrix at the truth (log mu, log lambda), %d weighted residuals (%.0f s):" % (len(R), time.time() - t0))
    lines, _ = report(R, F, J, truth)
    print("\n".join(lines[:2]))
    if args.no_fit:
        return
    t1 = time.time()
    subprocess.run([args.cli, "optimize", str(out / "problem_drop.json"), "-o", str(out / "fit"), "-q"], check=True)
    s = json.loads((out / "fit" / "summary.json").read_text())
    x = np.array(s["design"])
    R, F, J = diffipc.identifiability.fisher_matrix(p, x)
    lines, cov = report(R, F, J, x)
    E, nu = young_poisson(x)[0]
    print("fit from (10, 10): %s after %d iterations (%.0f s); RMS weighted residual %.2f (1 if the noise model holds)"
          % (s["stop_reason"], s["iterations"], time.time() - t1, math.sqrt(2 * J / len(R))))
    print("\n".join(lines))
    if cov is not None:
        z = (x - truth) / np.sqrt(np.diag(cov))
        print("  fit - truth in standard errors: log mu %.2f, log lambda %.2f" % tuple(z))


if __name__ == "__main__":
    main()
