"""Identifiability of parameters fitted to markers (issue 13): the Gauss-Newton (Fisher) matrix
of a markers objective's residuals, its eigen-directions, and standard errors.

``fisher_matrix(problem, x, base_directory=None)`` takes a problem (a dict, as a problem file)
whose objective is a markers objective read from a file (docs/objectives.md), and the design x
(the problem's design variables, e.g. a fit's summary.json ``design``). It returns the residual
Jacobian R (one row per marker coordinate, d r / d x), F = R^T R and the problem's J at x.

Each row of R comes from the adjoint: the markers objective of one marker, G_m = 1/2 |p_m -
y_m|^2, and the same with the target moved by 1 m along axis c, F_mc, differ by exactly the
residual component r_mc = (p_m - y_m)_c (the objective is quadratic in the target), so
grad r_mc = grad G_m - grad F_mc. All of them are the problem's constraints, evaluated from one
forward run with one adjoint solve each.
"""
import json
import math
import os
import pathlib
import tempfile

import numpy as np


def _marker_rows(path):
    rows = []
    for line in pathlib.Path(path).read_text().splitlines():
        line = line.split("#", 1)[0].replace(",", " ").replace(";", " ").replace("\t", " ")
        if line.strip():
            rows.append([float(v) for v in line.split()])
    return np.array(rows)


def fisher_matrix(problem, x, base_directory=None):
    """(R, F, J): the residual Jacobian (rows: marker coordinates, columns: design variables),
    F = R^T R, and J at the design x. Static marker files only (one measured state)."""
    from . import ReducedFunctional  # noqa: the package's class

    base = pathlib.Path(base_directory) if base_directory is not None else pathlib.Path(".")
    p = json.loads(json.dumps(problem))
    objective = p["objective"]
    if objective.get("type") != "markers" or "file" not in objective:
        raise ValueError("objective: fisher_matrix needs a markers objective read from a \"file\"")
    marker_file = pathlib.Path(objective["file"])
    if not marker_file.is_absolute():
        marker_file = base / marker_file
    rows = _marker_rows(marker_file)
    dim = rows.shape[1] // 2
    if rows.shape[1] != 2 * dim:
        raise ValueError(f"{marker_file}: fisher_matrix reads files without a time column")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        constraints = []
        for m, row in enumerate(rows):
            for c in [None] + list(range(dim)):
                shifted = row.copy()
                if c is not None:
                    shifted[dim + c] += 1.0
                f = tmp / f"m{m}_{c}.txt"
                f.write_text(" ".join("%.17g" % v for v in shifted) + "\n")
                marker = dict(objective)
                marker["file"] = str(f)
                marker.pop("weights", None)
                marker.pop("sigma", None)
                constraints.append({"name": f"m{m}_{c}", "objective": marker, "upper": 1e30})
        p["constraints"] = constraints
        for key in ("optimizer", "output", "remesh"):
            p.pop(key, None)
        rf = ReducedFunctional(p, base_directory=os.fspath(base))
        x = np.asarray(x, dtype=float)
        e = rf.evaluation(rf.parameters_of(x), True, True)
        dG = np.array([rf.design_gradient(x, g) for g in np.asarray(e.constraint_gradients)])
    R = []
    for m in range(len(rows)):
        for c in range(dim):
            R.append(dG[(dim + 1) * m] - dG[(dim + 1) * m + 1 + c])
    R = np.array(R)
    return R, R.T @ R, e.value


def identifiability(F, threshold=1e-6):
    """Eigen-directions of F, largest first: a list of (eigenvalue, eigenvector, identifiable),
    identifiable when the eigenvalue is at least `threshold` times the largest."""
    values, vectors = np.linalg.eigh(F)
    largest = values.max()
    out = []
    for lam, v in sorted(zip(values, vectors.T), key=lambda t: -t[0]):
        v = v if v[-1] > 0 or (v[-1] == 0 and v.sum() >= 0) else -v
        out.append((float(lam), v, bool(largest > 0 and lam >= threshold * largest)))
    return out


def standard_errors(R, F, J):
    """Standard errors of the design variables from s^2 F^-1, s^2 = 2 J / (n - k) (the residual
    variance per coordinate); inf where F is singular along a variable."""
    n, k = R.shape
    s2 = 2 * J / max(n - k, 1)
    try:
        cov = s2 * np.linalg.inv(F)
        if not np.all(np.isfinite(cov)) or np.linalg.cond(F) > 1e12:
            raise np.linalg.LinAlgError
        return np.sqrt(np.abs(np.diag(cov)))
    except np.linalg.LinAlgError:
        return np.full(k, math.inf)
