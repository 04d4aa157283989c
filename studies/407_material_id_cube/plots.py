"""Study 407 (README.md): three figures of the cube's material fit, drawn after run_study.py.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/plots.py \
        [--out output/407] [--grid-e 5] [--grid-nu 9]

Reads run_study.py's runs in --out (lbfgsb_10_10, lbfgsb_13_10, lbfgsb_7_9.5, ipopt_10_10:
summary.json, history.csv) and writes into --out:

- markers.png: the face x = +0.02 m seen along x, in the (y, z) plane (mm): the 24 markers'
  rest positions (light), measured deformed positions, and the positions simulated with
  lbfgsb_10_10's fitted material, a line from each measured to its simulated position, and the
  simulated deformed face (its mesh vertices, small grey dots). The title gives the RMS and the
  worst marker residual (3-D distance, mm; the out-of-plane x component is not drawn).
- landscape.png (and landscape.csv): the RMS marker residual (mm; sqrt(2 J / 24)) over a grid
  of (log10 E, nu), one simulation per point, the four fits marked and their nu dashed. J does
  not change along E (displacement-only loading, no body force: only nu is determined); the
  printed per-nu spread (max - min) / mean of J over E shows by how little (1e-16 to 1e-15: round-off).
- convergence.png: J (log scale) and the optimizer's gradient norm (inf-norm of the projected
  gradient of J / |J(x0)|; for Ipopt, of the Lagrangian) against iteration, one curve per run.

The residuals are computed by cube_markers.Markers (each marker's rest position located once
in the rest mesh, carried to the deformed mesh by its barycentric coordinates); J is checked
against lbfgsb_10_10's final_J. The landscape (45 simulations by default) takes about 70 s on
2 cores.
"""
import argparse
import csv
import json
import math
import pathlib
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
import run_study  # noqa: E402
from cube_markers import Markers  # noqa: E402

from diffipc.identifiability import young_poisson  # noqa: E402

RUNS = [f"lbfgsb_{m:g}_{l:g}" for m, l in run_study.STARTS] + ["ipopt_%g_%g" % run_study.STARTS[0]]
FIT = RUNS[0]
FACE_X = 0.0199  # rest x of the marker face's vertices (m)


def design(out, run):
    """The fitted (log mu, log lambda) of a run."""
    return json.loads((out / run / "summary.json").read_text())["design"]


def rms_mm(J, n):
    return 1e3 * math.sqrt(2 * J / n)


def plot_markers(m, markers, E, nu, path):
    """markers.png: rest, measured and simulated markers on the face, in (y, z) mm."""
    deformed = m.simulate(E, nu)
    sim = m.carry(deformed)
    r = np.linalg.norm(sim - m.measured, axis=1)
    face = deformed[m.rest[:, 0] >= FACE_X] * 1e3
    rest, meas, sim = markers[:, :3] * 1e3, m.measured * 1e3, sim * 1e3
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(face[:, 1], face[:, 2], ".", color="0.75", ms=2, label="simulated face (mesh vertices)")
    ax.plot(rest[:, 1], rest[:, 2], "s", mfc="none", mec="0.6", ms=6, label="rest")
    for a, b in zip(meas, sim):
        ax.plot([a[1], b[1]], [a[2], b[2]], "-", color="tab:red", lw=1)
    ax.plot(meas[:, 1], meas[:, 2], "o", color="k", ms=5, label="measured")
    ax.plot(sim[:, 1], sim[:, 2], "x", color="tab:blue", ms=7, mew=1.5, label="simulated (fit)")
    ax.set_aspect("equal")
    ax.set_xlabel("y (mm)")
    ax.set_ylabel("z (mm)")
    ax.set_title("face x = +20 mm, fit %s (E = %.3g Pa, nu = %.4f)\nresidual (3-D): RMS %.3f mm, worst %.3f mm"
                 % (FIT, E, nu, 1e3 * math.sqrt(np.mean(r ** 2)), 1e3 * r.max()))
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return 0.5 * np.sum(r ** 2)


def landscape(m, es, nus):
    """J (m^2) on the grid, J[i, j] at (nu_i, E_j)."""
    J = np.empty((len(nus), len(es)))
    for i, nu in enumerate(nus):
        for j, E in enumerate(es):
            J[i, j] = m.objective(E, nu)
    return J


def write_landscape_csv(path, es, nus, J, n):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["E", "nu", "J", "rms_mm"])
        for i, nu in enumerate(nus):
            for j, E in enumerate(es):
                w.writerow([repr(E), repr(nu), repr(J[i, j]), repr(rms_mm(J[i, j], n))])


def print_landscape(es, nus, J):
    print("J (m^2) on the grid, rows nu, columns E:")
    print("  nu \\ E   " + " ".join("%13.4g" % E for E in es) + "   spread (max-min)/mean over E")
    for i, nu in enumerate(nus):
        spread = (J[i].max() - J[i].min()) / J[i].mean()
        print("  %.4f   " % nu + " ".join("%13.6e" % v for v in J[i]) + "   %.2e" % spread)


def plot_landscape(es, nus, J, fits, n, path):
    """landscape.png: the RMS residual (mm) over (log10 E, nu), the fits marked."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    rms = np.sqrt(2 * J / n) * 1e3
    pc = ax.pcolormesh(np.log10(es), nus, rms, shading="nearest", cmap="viridis")
    fig.colorbar(pc, ax=ax, label="RMS marker residual (mm) = 1e3 sqrt(2 J / 24)")
    X, Y = np.meshgrid(np.log10(es), nus)
    ax.plot(X.ravel(), Y.ravel(), ".", color="w", ms=3, alpha=0.7)
    for (name, (E, nu)), mk in zip(fits.items(), "o^sD"):
        ax.plot(math.log10(E), nu, mk, mfc="none", mec="r", ms=9, mew=1.5, label="%s: E = %.3g Pa, nu = %.4f" % (name, E, nu))
    ax.axhline(fits[FIT][1], color="r", ls="--", lw=1, label="fitted nu = %.4f" % fits[FIT][1])
    ax.set_xlabel("log10 E (Pa)")
    ax.set_ylabel("nu")
    ax.set_title("marker residual over (E, nu): flat along E, only nu is determined")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=8)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)


def read_history(path):
    """history.csv's columns as float arrays."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def plot_convergence(out, path):
    """convergence.png: J and the gradient norm against iteration, one curve per run."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for run, mk in zip(RUNS, "o^sD"):
        h = read_history(out / run / "history.csv")
        a.semilogy(h["iteration"], h["J"], "-" + mk, ms=4, label=run)
        b.semilogy(h["iteration"], h["gradient_norm"], "-" + mk, ms=4, label=run)
    a.set_ylabel("J = 1/2 sum |p_m - y_m|^2 (m^2)")
    b.set_ylabel("gradient inf-norm of J / |J(x0)|\n(projected; Ipopt: of the Lagrangian)")
    for ax in (a, b):
        ax.set_xlabel("iteration")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("study 407: convergence of the four fits")
    fig.tight_layout()
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(ROOT / "output" / "407"))
    parser.add_argument("--grid-e", type=int, default=5, help="values of E, log-spaced in [1e3, 1e6] Pa")
    parser.add_argument("--grid-nu", type=int, default=9, help="values of nu in [0.30, 0.49]")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    problem = run_study.absolute(json.loads((HERE / "problem.json").read_text()))
    markers = np.loadtxt(problem["objective"]["file"])
    n = len(markers)
    fits = {run: young_poisson(design(out, run))[0] for run in RUNS}
    for run, (E, nu) in fits.items():
        print("%-13s E = %.4g Pa, nu = %.5f" % (run, E, nu))
    t0 = time.perf_counter()
    m = Markers(problem["scene"], markers)

    paths = [out / "markers.png", out / "landscape.png", out / "convergence.png"]
    J_fit = plot_markers(m, markers, *fits[FIT], paths[0])
    final_J = json.loads((out / FIT / "summary.json").read_text())["final_J"]
    print("fit %s: J = %.6e m^2 here, %.6e in summary.json (relative difference %.1e); RMS %.3f mm"
          % (FIT, J_fit, final_J, abs(J_fit - final_J) / final_J, rms_mm(J_fit, n)))

    es = np.logspace(3, 6, args.grid_e)
    nus = np.linspace(0.30, 0.49, args.grid_nu)
    t1 = time.perf_counter()
    J = landscape(m, es, nus)
    t_land = time.perf_counter() - t1
    print_landscape(es, nus, J)
    write_landscape_csv(out / "landscape.csv", es, nus, J, n)
    plot_landscape(es, nus, J, fits, n, paths[1])
    plot_convergence(out, paths[2])
    print("landscape: %d simulations in %.1f s (%.2f s each); total %.1f s"
          % (J.size, t_land, t_land / J.size, time.perf_counter() - t0))
    print("wrote " + str(out / "landscape.csv"))
    for p in paths:
        print("wrote " + str(p))


if __name__ == "__main__":
    main()
