"""Study 407 (README.md): the cube's Lame parameters fitted to its 24 scanned markers, with
L-BFGS-B from three far-off starts and with Ipopt, and the marker residual of each fit.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/run_study.py \
        [--cli build/cli/diffipc] [--out output/407]

Prints a markdown table: start, optimizer, stop, iterations, fitted log mu and log lambda, E, nu,
the marker residual's RMS and worst (mm) at the start and at the fit. The residuals are computed
here, independently of the objective: the fitted problem is simulated, and each marker's rest
position is located in the rest mesh and carried to the deformed mesh by its barycentric
coordinates.
"""
import argparse
import json
import math
import pathlib
import subprocess

import numpy as np

from cube_markers import Markers

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
STARTS = [(10.0, 10.0), (13.0, 10.0), (7.0, 9.5)]


def absolute(problem):
    """The problem with its file paths absolute (it is written elsewhere)."""
    p = json.loads(json.dumps(problem))
    body = p["scene"]["bodies"][0]
    body["mesh"]["file"] = str((HERE / body["mesh"]["file"]).resolve())
    p["objective"]["file"] = str((HERE / p["objective"]["file"]).resolve())
    return p


def residuals(problem, log_mu, log_lambda, markers):
    """Per-marker distance (m) between the simulated and the measured position."""
    return np.linalg.norm(positions(problem, log_mu, log_lambda, markers) - markers[:, 3:], axis=1)


def positions(problem, log_mu, log_lambda, markers):
    """The markers' simulated positions (m), located in the rest mesh and carried to the deformed
    mesh by their barycentric coordinates (cube_markers.Markers)."""
    return Markers(problem["scene"], markers).positions(log_mu, log_lambda)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407"))
    args = parser.parse_args()
    base = absolute(json.loads((HERE / "problem.json").read_text()))
    markers = np.loadtxt(base["objective"]["file"])
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = [(s, "lbfgsb") for s in STARTS] + [(STARTS[0], "ipopt")]
    print("| start (log mu, log lambda) | optimizer | stop | iterations | evaluations | log mu | log lambda "
          "| E (Pa) | nu | RMS start (mm) | worst start (mm) | RMS fit (mm) | worst fit (mm) | wall (s) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for (m0, l0), algorithm in runs:
        p = json.loads(json.dumps(base))
        p["parameters"][0]["initial"], p["parameters"][1]["initial"] = m0, l0
        p["optimizer"]["algorithm"] = algorithm
        name = f"{algorithm}_{m0:g}_{l0:g}"
        path = out / f"{name}.json"
        path.write_text(json.dumps(p, indent=1))
        subprocess.run([args.cli, "optimize", str(path), "-o", str(out / name), "-q"], check=True)
        s = json.loads((out / name / "summary.json").read_text())
        lm, ll = s["design"]
        mu, lam = math.exp(lm), math.exp(ll)
        r0 = residuals(p, m0, l0, markers)
        r = residuals(p, lm, ll, markers)
        print("| (%g, %g) | %s | %s | %d | %d | %.4f | %.4f | %.4g | %.5f | %.3f | %.3f | %.3f | %.3f | %.1f |" % (
            m0, l0, algorithm, s["stop_reason"], s["iterations"], s["evaluations"], lm, ll,
            mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu)),
            1e3 * math.sqrt(np.mean(r0 ** 2)), 1e3 * r0.max(), 1e3 * math.sqrt(np.mean(r ** 2)), 1e3 * r.max(),
            s["wall_time"]["total"]))


if __name__ == "__main__":
    main()
