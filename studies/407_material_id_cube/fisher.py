"""Study 407: the Gauss-Newton (Fisher) matrix of the marker residuals at a fit, its eigenvalues
and eigenvectors, and which parameter directions the data determine.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/fisher.py \
        [--run output/407/lbfgsb_10_10] [--threshold 1e-6]

F = sum_i grad r_i grad r_i^T over the 72 residual components r = p_m - y_m (marker m,
coordinate c), with respect to the design (log mu, log lambda), by
diffipc.identifiability.fisher_matrix: each grad r_i from the adjoint (the markers objective of
marker m alone, G_m = 1/2 |p_m - y_m|^2, and the same with its target moved by 1 m along c,
F_mc, differ by exactly r_mc; all 96 are evaluated from one forward run, one adjoint each;
forward sensitivities would take 2 linearized solves per step, but the toolkit has adjoints).
A direction whose eigenvalue is below `threshold` times the largest is reported as not
identifiable from this data.
"""
import argparse
import json
import math
import pathlib

import numpy as np

from diffipc.identifiability import fisher_matrix, identifiability, poisson_along_ratio

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def nu_and_standard_error(x, R, F, J):
    """nu at the design x = (log mu, log lambda) and its standard error from the direction that
    sets nu (diffipc.identifiability.poisson_along_ratio: s^2 F^-1 restricted to (-1, 1) / sqrt(2),
    s^2 = 2 J / (n - k), then the delta method)."""
    return poisson_along_ratio(x, R, F, J)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", default=str(ROOT / "output" / "407" / "lbfgsb_10_10"),
                        help="a run's output folder (its summary.json design is the point); run_study.py writes it")
    parser.add_argument("--threshold", type=float, default=1e-6)
    args = parser.parse_args()
    problem = json.loads((HERE / "problem.json").read_text())
    x = np.array(json.loads((pathlib.Path(args.run) / "summary.json").read_text())["design"])
    # d r_i / d (log mu, log lambda), 72 x 2 (diffipc.identifiability: one adjoint per residual)
    R, F, J = fisher_matrix(problem, x, base_directory=HERE)
    n, k = R.shape
    s2 = 2 * J / (n - k)  # residual variance per coordinate (m^2)
    print("design (log mu, log lambda) = (%.4f, %.4f); J = %.6e m^2; residual sigma = %.3f mm"
          % (x[0], x[1], J, 1e3 * math.sqrt(s2)))
    print("Fisher (Gauss-Newton) matrix J^T J, per (log mu, log lambda):")
    print("  [[%.6e, %.6e], [%.6e, %.6e]]" % (F[0, 0], F[0, 1], F[1, 0], F[1, 1]))
    largest = max(lam for lam, _, _ in identifiability(F, args.threshold))
    for lam, v, identifiable in identifiability(F, args.threshold):
        ratio = lam / largest
        status = "identifiable" if identifiable else "NOT identifiable from this data"
        se = math.sqrt(s2 / lam) if lam > 0 else math.inf
        print("  eigenvalue %.6e (ratio to the largest %.3e), eigenvector (%.6f, %.6f): %s; standard error along it %s"
              % (lam, ratio, v[0], v[1], status, "%.3g" % se if se < 1e6 else "unbounded"))
    # nu depends on log(lambda / mu) = (-1, 1) . (log mu, log lambda); E on the other direction.
    d_nu = np.array([-1.0, 1.0]) / math.sqrt(2)
    print("the direction of nu, (-1, 1)/sqrt(2): F-norm %.6e; of E at fixed nu, (1, 1)/sqrt(2): %.6e"
          % (d_nu @ F @ d_nu, np.array([1, 1]) @ F @ np.array([1, 1]) / 2))
    nu, se_nu = nu_and_standard_error(x, R, F, J)
    print("nu = %.5f, standard error %.4f (from s^2 F^-1 along nu's direction, delta method)"
          % (nu, se_nu))


if __name__ == "__main__":
    main()
