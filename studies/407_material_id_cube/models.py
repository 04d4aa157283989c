"""Study 407: which material model the markers support. The same fit (log mu, log lambda from
e^10, L-BFGS-B) with linear elasticity, Saint Venant-Kirchhoff, neo-Hookean and stable
neo-Hookean, each fit's marker residual computed as in run_study.py, and each fit's confidence:
nu's standard error from the Fisher matrix of the marker residuals at that fit (fisher.py's
method; E has none, the data do not determine it for any model).

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/models.py [--out output/407/models]
"""
import argparse
import json
import math
import pathlib
import subprocess
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
import run_study  # noqa: E402
from fisher import nu_and_standard_error  # noqa: E402

from diffipc.identifiability import fisher_matrix  # noqa: E402

MODELS = ["linear", "stvk", "neo_hookean", "stable_neo_hookean"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407" / "models"))
    args = parser.parse_args()
    base = run_study.absolute(json.loads((HERE / "problem.json").read_text()))
    markers = np.loadtxt(base["objective"]["file"])
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("| model | stop | iterations | nu | SE nu | E (Pa) | RMS (mm) | worst (mm) | wall (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for model in MODELS:
        p = json.loads(json.dumps(base))
        p["scene"]["bodies"][0]["material"]["model"] = model
        path = out / f"{model}.json"
        path.write_text(json.dumps(p, indent=1))
        r = subprocess.run([args.cli, "optimize", str(path), "-o", str(out / model), "-q"], capture_output=True,
                           text=True)
        if r.returncode != 0:
            print("| %s | failed: %s | | | | | | | |" % (model, r.stderr.strip().splitlines()[-1]))
            continue
        s = json.loads((out / model / "summary.json").read_text())
        lm, ll = s["design"]
        mu, lam = math.exp(lm), math.exp(ll)
        res = run_study.residuals(p, lm, ll, markers)
        nu, se_nu = nu_and_standard_error(np.array([lm, ll]), *fisher_matrix(p, [lm, ll]))
        print("| %s | %s | %d | %.5f | %.4f | %.4g | %.3f | %.3f | %.1f |" % (
            model, s["stop_reason"], s["iterations"], nu, se_nu, mu * (3 * lam + 2 * mu) / (lam + mu),
            1e3 * math.sqrt(np.mean(res ** 2)), 1e3 * res.max(), s["wall_time"]["total"]))


if __name__ == "__main__":
    main()
