"""Study 407: the Gauss-Newton (Fisher) matrix of the marker residuals at a fit, its eigenvalues
and eigenvectors, and which parameter directions the data determine.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/fisher.py \
        [--run output/407/lbfgsb_10_10] [--threshold 1e-6]

F = sum_i grad r_i grad r_i^T over the 72 residual components r = p_m - y_m (marker m,
coordinate c), with respect to the design (log mu, log lambda). Each grad r_i comes from the
adjoint: the markers objective of marker m alone, G_m = 1/2 |p_m - y_m|^2, and the same with
its target moved by 1 m along c, F_mc; since the objective is quadratic in the target,
grad G_m - grad F_mc = grad r_mc exactly. All 96 functionals are the problem's constraints,
evaluated with their adjoint gradients from one forward run (96 adjoint solves; forward
sensitivities would take 2 linearized solves per step, but the toolkit has adjoints).
A direction whose eigenvalue is below `threshold` times the largest is reported as not
identifiable from this data.
"""
import argparse
import json
import math
import pathlib
import tempfile

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", default=str(ROOT / "output" / "407" / "lbfgsb_10_10"),
                        help="a run's output folder (its summary.json design is the point); run_study.py writes it")
    parser.add_argument("--threshold", type=float, default=1e-6)
    args = parser.parse_args()
    problem = json.loads((HERE / "problem.json").read_text())
    problem["scene"]["bodies"][0]["mesh"]["file"] = str(HERE / "data" / "cube.msh")
    markers = np.loadtxt(HERE / "data" / "markers.txt")
    x = np.array(json.loads((pathlib.Path(args.run) / "summary.json").read_text())["design"])
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        constraints = []
        for m, row in enumerate(markers):
            for c in (None, 0, 1, 2):
                shifted = row.copy()
                if c is not None:
                    shifted[3 + c] += 1.0
                path = tmp / f"m{m}_{c}.txt"
                path.write_text(" ".join("%.17g" % v for v in shifted) + "\n")
                constraints.append({"name": f"m{m}_{c}", "objective": {"type": "markers", "file": str(path)},
                                    "upper": 1e9})
        problem["objective"]["file"] = str(HERE / "data" / "markers.txt")
        problem["constraints"] = constraints
        problem.pop("optimizer", None)
        problem.pop("output", None)
        rf = diffipc.ReducedFunctional(problem)
        p = rf.parameters_of(x)
        e = rf.evaluation(p, True, True)
        dG = np.array([rf.design_gradient(x, g) for g in np.asarray(e.constraint_gradients)])
    residual_gradients = []
    for m in range(len(markers)):
        base = dG[4 * m]
        for c in range(3):
            residual_gradients.append(base - dG[4 * m + 1 + c])
    R = np.array(residual_gradients)  # 72 x 2: d r_i / d (log mu, log lambda)
    F = R.T @ R
    values, vectors = np.linalg.eigh(F)
    J = e.value
    n, k = R.shape
    s2 = 2 * J / (n - k)  # residual variance per coordinate (m^2)
    print("design (log mu, log lambda) = (%.4f, %.4f); J = %.6e m^2; residual sigma = %.3f mm"
          % (x[0], x[1], J, 1e3 * math.sqrt(s2)))
    print("Fisher (Gauss-Newton) matrix J^T J, per (log mu, log lambda):")
    print("  [[%.6e, %.6e], [%.6e, %.6e]]" % (F[0, 0], F[0, 1], F[1, 0], F[1, 1]))
    largest = values.max()
    for lam, v in sorted(zip(values, vectors.T), key=lambda t: -t[0]):
        v = v if v[-1] > 0 or (v[-1] == 0 and v.sum() >= 0) else -v  # sign: the last component positive
        ratio = lam / largest
        status = "identifiable" if ratio >= args.threshold else "NOT identifiable from this data"
        se = math.sqrt(s2 / lam) if lam > 0 else math.inf
        print("  eigenvalue %.6e (ratio to the largest %.3e), eigenvector (%.6f, %.6f): %s; standard error along it %s"
              % (lam, ratio, v[0], v[1], status, "%.3g" % se if se < 1e6 else "unbounded"))
    # nu depends on log(lambda / mu) = (-1, 1) . (log mu, log lambda); E on the other direction.
    d_nu = np.array([-1.0, 1.0]) / math.sqrt(2)
    print("the direction of nu, (-1, 1)/sqrt(2): F-norm %.6e; of E at fixed nu, (1, 1)/sqrt(2): %.6e"
          % (d_nu @ F @ d_nu, np.array([1, 1]) @ F @ np.array([1, 1]) / 2))
    # nu = r / (2 (r + 1)), r = lambda / mu = e^t, t = log lambda - log mu = sqrt(2) (d_nu . x):
    # the standard error of t from F restricted to d_nu, then the delta method.
    r = math.exp(x[1] - x[0])
    nu = r / (2 * (r + 1))
    se_t = math.sqrt(2) * math.sqrt(s2 / (d_nu @ F @ d_nu))
    print("nu = %.5f, standard error %.4f (from s^2 F^-1 along nu's direction, delta method)"
          % (nu, se_t * r / (2 * (r + 1) ** 2)))


if __name__ == "__main__":
    main()
