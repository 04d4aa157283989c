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

import diffipc

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


def tetrahedra(path, rest):
    """The mesh's tetrahedra in the simulation's vertex numbering (matched by position)."""
    lines = pathlib.Path(path).read_text().split("\n")
    i = lines.index("$Nodes")
    n = int(lines[i + 1])
    nodes = {}
    for k in range(n):
        f = lines[i + 2 + k].split()
        nodes[int(f[0])] = np.array([float(v) for v in f[1:4]]) * 0.004 - 0.02
    j = lines.index("$Elements")
    order = {tuple(np.round(p, 12)): v for v, p in enumerate(rest)}
    tets = []
    for k in range(int(lines[j + 1])):
        f = [int(v) for v in lines[j + 2 + k].split()]
        if f[1] == 4:
            tags = f[2]
            tets.append([order[tuple(np.round(nodes[t], 12))] for t in f[3 + tags:7 + tags]])
    return np.array(tets)


def residuals(problem, log_mu, log_lambda, markers):
    """Per-marker distance (m) between the simulated and the measured position."""
    return np.linalg.norm(positions(problem, log_mu, log_lambda, markers) - markers[:, 3:], axis=1)


def positions(problem, log_mu, log_lambda, markers):
    """The markers' simulated positions (m): each rest position located in the rest mesh and
    carried to the deformed mesh by its barycentric coordinates."""
    scene = json.loads(json.dumps(problem["scene"]))
    mu, lam = math.exp(log_mu), math.exp(log_lambda)
    material = scene["bodies"][0]["material"]
    material["E"] = mu * (3 * lam + 2 * mu) / (lam + mu)
    material["nu"] = lam / (2 * (lam + mu))
    _, tr = diffipc.simulate(scene)
    rest, deformed = tr["positions"][0], tr["positions"][-1]
    tets = tetrahedra(scene["bodies"][0]["mesh"]["file"], rest)
    a = rest[tets[:, 0]]
    inv = np.linalg.inv(np.stack([rest[tets[:, i]] - a for i in (1, 2, 3)], axis=2))
    out = []
    for X in markers[:, :3]:
        lam_ = np.einsum("eij,ej->ei", inv, X - a)
        w = np.concatenate([1 - lam_.sum(1, keepdims=True), lam_], axis=1)
        e = np.argmax(w.min(1))
        out.append(sum(w[e, i] * deformed[tets[e, i]] for i in range(4)))
    return np.array(out)


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
