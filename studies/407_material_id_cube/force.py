"""Study 407: what a load cell adds. The same cube and markers, with the force on the top plate
at full compression added to the objective (a reaction_force objective with a target): E is
then determined as well as nu.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/force.py \
        [--cli build/cli/diffipc] [--out output/407/force]

The experiment recorded no force, so the reading is synthetic: the z force of the top plate
(dirichlet entry 0) at step 4, simulated with E = 2e4 Pa (a soft silicone) and nu = 0.4687 (the
markers' fit), plus 1% Gaussian noise (seed 407; a load cell's order). The objective is the sum
of the markers term with sigma = 0.472 mm (the markers-only fit's residual level, fisher.py) and
the force term with sigma = 1% of the reading, so J = chi^2 / 2. The fit runs with L-BFGS-B from
the three starts of run_study.py; the Fisher matrix of the 73 weighted residuals (72 marker
coordinates and the force) is computed at each fit (diffipc.identifiability.fisher_matrix).
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
from run_study import STARTS, absolute, residuals  # noqa: E402

from diffipc.identifiability import identifiability, young_poisson  # noqa: E402

E_ASSUMED, NU_FIT = 2e4, 0.4687
FORCE_NOISE = 0.01  # relative
MARKER_SIGMA = 4.72e-4  # m
STEP = 4


def top_force(problem, x):
    """The top plate's z force (N) at step 4 for the design x, by the reaction_force objective."""
    p = json.loads(json.dumps(problem))
    p["objective"] = {"type": "reaction_force", "dirichlet": 0, "axis": "z", "time": "final"}
    for key in ("optimizer", "output", "gradcheck"):
        p.pop(key, None)
    rf = diffipc.ReducedFunctional(p)
    return rf(rf.parameters_of(np.asarray(x, dtype=float)))


def force_problem(base, reading):
    p = json.loads(json.dumps(base))
    markers = dict(p["objective"], sigma=MARKER_SIGMA)
    force = {"type": "reaction_force", "dirichlet": 0, "axis": "z", "targets": [reading], "steps": [STEP],
             "sigma": FORCE_NOISE * abs(reading)}
    p["objective"] = {"type": "sum", "terms": [{"objective": markers}, {"objective": force}]}
    p["description"] = ("Study 407 with a (synthetic) load cell: markers and the top plate's force fitted together.")
    p.pop("gradcheck", None)
    return p


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407" / "force"))
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    base = absolute(json.loads((HERE / "problem.json").read_text()))
    truth = e_nu_to_design(E_ASSUMED, NU_FIT)
    exact = top_force(base, truth)
    reading = exact * (1 + FORCE_NOISE * np.random.default_rng(407).normal())
    print("synthetic load cell: top plate force at step %d = %.5f N (model at E = %g Pa, nu = %g: %.5f N; 1%% noise)"
          % (STEP, reading, E_ASSUMED, NU_FIT, exact))
    p = force_problem(base, reading)
    markers = np.loadtxt(base["objective"]["file"])
    notes = []
    print("| start (log mu, log lambda) | stop | iterations | E (Pa) | nu | SE log E | SE nu | force (N) | "
          "RMS markers (mm) | worst (mm) | eigenvalue ratio | wall (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for m0, l0 in STARTS:
        t0 = time.time()
        q = json.loads(json.dumps(p))
        q["parameters"][0]["initial"], q["parameters"][1]["initial"] = m0, l0
        name = f"lbfgsb_{m0:g}_{l0:g}"
        (out / f"{name}.json").write_text(json.dumps(q, indent=1))
        subprocess.run([args.cli, "optimize", str(out / f"{name}.json"), "-o", str(out / name), "-q"], check=True)
        s = json.loads((out / name / "summary.json").read_text())
        x = np.array(s["design"])
        R, F, J = diffipc.identifiability.fisher_matrix(q, x)
        lines, cov = report(R, F, J, x)
        (E, nu), se = young_poisson(x, cov)
        se = se or (math.inf, math.inf)
        r = residuals(q, x[0], x[1], markers)
        lam = [v for v, _, _ in identifiability(F)]
        print("| (%g, %g) | %s | %d | %.4g | %.4f | %.3f | %.4f | %.4f | %.3f | %.3f | %.2e | %.1f |" % (
            m0, l0, s["stop_reason"], s["iterations"], E, nu, se[0], se[1], top_force(q, x),
            1e3 * math.sqrt(np.mean(r ** 2)), 1e3 * r.max(), lam[1] / lam[0], time.time() - t0))
        notes += lines
    print("\n".join(notes))


if __name__ == "__main__":
    main()
