"""Identifiability of parameters fitted to measurements (issue 13): the Gauss-Newton (Fisher)
matrix of a least-squares objective's residuals, its eigen-directions, and standard errors.

``fisher_matrix(problem, x, base_directory=None)`` takes a problem (a dict, as a problem file)
whose objective is a least-squares fit to data: a ``markers`` objective read from a ``file``
(static or with a time column), a ``reaction_force`` objective with ``targets``, or a ``sum``
of such terms (docs/objectives.md); and the design x (the problem's design variables, e.g. a
fit's summary.json ``design``). It returns the weighted residual Jacobian R (one row per
measured number: a marker coordinate at a time, a force at a state; d r / d x), F = R^T R and
the problem's J at x. Each residual is weighted as J weights it: J = 1/2 sum_i r_i^2 with r_i =
sqrt(w_i) (model - measurement)_i, w_i the term's weight times the marker's or force's weight.

Each row of R comes from the adjoint. A least-squares term restricted to one measurement with
unit weight, G = 1/2 |p - y|^2, and the same with its target moved by 1 along axis c, G_c,
differ by exactly r_c - 1/2 (the term is quadratic in the target), so grad r_c = grad G -
grad G_c, and the weighted residual's gradient is sqrt(w) times that. All
of them are the problem's constraints, evaluated from one forward run and one backward sweep
(diffipc's adjoint factorizes each step's system once for all the functionals).
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


def _least_squares_terms(objective):
    """[(weight, term)] of a least-squares objective, else ValueError."""
    kind = objective.get("type")
    if kind == "sum":
        out = []
        for i, t in enumerate(objective.get("terms", [])):
            for w, term in _least_squares_terms(t["objective"]):
                out.append((float(t.get("weight", 1.0)) * w, term))
        return out
    if (kind == "markers" and "file" in objective) or (kind == "reaction_force" and "targets" in objective):
        return [(1.0, objective)]
    raise ValueError("objective: fisher_matrix needs a least-squares fit to data: a markers objective read "
                     "from a \"file\", a reaction_force objective with \"targets\", or a sum of them")


def _measurement_weights(term, count, name):
    """Per-measurement weights from a term's "weights" or "sigma" (one number or one per entry)."""
    if "sigma" in term:
        sigma = np.broadcast_to(np.asarray(term["sigma"], dtype=float), (count,))
        return 1.0 / sigma**2
    if "weight" in term:
        return np.full(count, float(term["weight"]))
    if "weights" in term:
        w = np.asarray(term["weights"], dtype=float)
        if w.shape != (count,):
            raise ValueError(f"objective: {name}: expected {count} weights")
        return w
    return np.ones(count)


def _marker_functionals(term, base, dim, tmp, tag):
    """The single-measurement functionals of a markers file: per row (a marker, at a time for
    files with a time column), the row itself and its target moved by 1 m along each axis."""
    path = pathlib.Path(term["file"])
    rows = _marker_rows(path if path.is_absolute() else base / path)
    timed = rows.shape[1] == 2 * dim + 1
    rest = [tuple(r[:dim]) for r in rows]
    markers = list(dict.fromkeys(rest))  # markers in order of first appearance
    weights = _measurement_weights(term, len(markers), "markers")
    groups = []
    for i, row in enumerate(rows):
        functionals = []
        for c in [None] + list(range(dim)):
            shifted = row.copy()
            if c is not None:
                shifted[-dim + c] += 1.0
            f = tmp / f"{tag}_r{i}_{c}.txt"
            f.write_text(" ".join("%.17g" % v for v in shifted) + "\n")
            one = {k: v for k, v in term.items() if k not in ("weights", "sigma")}
            one["file"] = str(f)
            functionals.append(one)
        label = f"marker {markers.index(rest[i])}" + (f" at t = {row[dim]:g}" if timed else "")
        groups.append((functionals, weights[markers.index(rest[i])], [f"{label}, {'xyz'[c]}" for c in range(dim)],
                       label))
    return groups


def _force_functionals(term, scene_steps):
    """Per listed state of a reaction_force term: the state's force and its target moved by 1 N."""
    targets = term["targets"]
    steps = term.get("steps", list(range(1, scene_steps + 1)))
    weights = _measurement_weights(term, len(targets), "reaction_force")
    groups = []
    where = (f"dirichlet[{term['dirichlet']}]" if "dirichlet" in term else f"obstacle {term.get('obstacle')}")
    name = f"reaction force of {where} along {term.get('axis')}"
    for k, target, w in zip(steps, targets, weights):
        one = {key: v for key, v in term.items() if key not in ("weight", "sigma", "targets", "steps")}
        groups.append(([dict(one, targets=[target], steps=[k]), dict(one, targets=[target + 1.0], steps=[k])], w,
                       [f"{name} at step {k}"], f"{name} at step {k}"))
    return groups


def _scene_of(problem, base):
    """The problem's scene as a dict (read from its file when the problem names one)."""
    if "scenes" in problem:
        raise ValueError("scenes: fisher_matrix takes a problem with one scene (one load case)")
    scene = problem.get("scene")
    if isinstance(scene, str):
        path = pathlib.Path(scene)
        return json.loads((path if path.is_absolute() else base / path).read_text())
    if not isinstance(scene, dict):
        raise ValueError("scene: expected the scene object or the path of its file")
    return scene


def fisher_matrix(problem, x, base_directory=None, labels=None, misfits=None):
    """(R, F, J): the weighted residual Jacobian (rows: measurements, columns: design
    variables), F = R^T R, and J at the design x. ``labels``: a list that receives one name per
    row of R (e.g. "marker 3 at t = 0.01, z"). ``misfits``: a list that receives, per measured
    marker position or force, (name, |model - measurement|) in m or N, unweighted."""
    from . import ReducedFunctional  # noqa: the package's class

    base = pathlib.Path(base_directory) if base_directory is not None else pathlib.Path(".")
    p = json.loads(json.dumps(problem))
    scene = _scene_of(p, base)
    dim = int(scene.get("dimension", 3))
    steps = int(scene.get("time", {}).get("steps", 1))
    terms = [(float(p.get("weight", 1.0)) * w, term) for w, term in _least_squares_terms(p["objective"])]
    for w, _ in terms:
        if not w > 0:
            raise ValueError(f"objective: fisher_matrix needs positive term weights, got {w}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        groups = []  # (functionals, weight, row labels, name)
        for i, (w, term) in enumerate(terms):
            found = (_marker_functionals(term, base, dim, tmp, f"t{i}") if term["type"] == "markers"
                     else _force_functionals(term, steps))
            groups += [(f, w * wm, names, name) for f, wm, names, name in found]
        p["constraints"] = [{"name": f"g{g}_{j}", "objective": o, "upper": 1e30}
                            for g, (functionals, _, _, _) in enumerate(groups) for j, o in enumerate(functionals)]
        for key in ("optimizer", "output", "remesh", "checkpointing"):
            p.pop(key, None)
        rf = ReducedFunctional(p, base_directory=os.fspath(base))
        x = np.asarray(x, dtype=float)
        e = rf.evaluation(rf.parameters_of(x), True, True)
        dG = [rf.design_gradient(x, g) for g in np.asarray(e.constraint_gradients)]
    R, row = [], 0
    for functionals, w, names, name in groups:
        for c in range(1, len(functionals)):
            R.append(math.sqrt(w) * (dG[row] - dG[row + c]))
        if misfits is not None:  # the unit-weight functional G = 1/2 |model - measurement|^2
            misfits.append((name, math.sqrt(2 * max(float(e.constraint_values[row]), 0.0))))
        row += len(functionals)
        if labels is not None:
            labels += names
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


def covariance(R, F, J):
    """s^2 F^-1, the design's covariance (s^2 = 2 J / (n - k)); None where F is singular to
    round-off (condition number above 1e12)."""
    n, k = R.shape
    if np.linalg.cond(F) > 1e12:
        return None
    return 2 * J / max(n - k, 1) * np.linalg.inv(F)


def young_poisson(x, cov=None, plane_stress=False):
    """E and nu of a design x = (log mu, log lambda), and with ``cov`` (the design's covariance)
    the standard errors of log E and of nu by the delta method: ((E, nu), (se_log_E, se_nu) or
    None). 3D and 2D plane strain: E = mu (3 lambda + 2 mu) / (lambda + mu), nu = lambda /
    (2 (lambda + mu)); 2D plane stress (``plane_stress``, lambda the effective in-plane one, as the
    simulator takes it): E = 4 mu (lambda + mu) / (lambda + 2 mu), nu = lambda / (lambda + 2 mu)."""
    mu, lam = math.exp(x[0]), math.exp(x[1])
    # d log E / d (log mu, log lambda) and d nu / d (log mu, log lambda), in closed form
    if plane_stress:
        s = lam + 2 * mu
        E, nu = 4 * mu * (lam + mu) / s, lam / s
        dlogE = np.array([1 + mu / (lam + mu) - 2 * mu / s, lam / (lam + mu) - lam / s])
        dnu = np.array([-2 * lam * mu, 2 * lam * mu]) / (s * s)
    else:
        s = lam + mu
        E, nu = mu * (3 * lam + 2 * mu) / s, lam / (2 * s)
        dlogE = np.array([1 + 2 * mu / (3 * lam + 2 * mu) - mu / s, 3 * lam / (3 * lam + 2 * mu) - lam / s])
        dnu = np.array([-lam * mu, lam * mu]) / (2 * s * s)
    if cov is None:
        return (E, nu), None
    return (E, nu), (math.sqrt(dlogE @ cov @ dlogE), math.sqrt(dnu @ cov @ dnu))


def poisson_along_ratio(x, R, F, J, plane_stress=False):
    """nu at x = (log mu, log lambda) and its standard error from the direction that sets nu
    alone: nu = r / (2 (r + 1)) (plane stress: r / (r + 2)) with r = lambda / mu = e^t, t = log
    lambda - log mu = sqrt(2) (d . x), d = (-1, 1) / sqrt(2); t's standard error from s^2 / (d^T F
    d), then the delta method. For data that determine nu but not E (F singular along (1, 1))."""
    n, k = R.shape
    d = np.array([-1.0, 1.0]) / math.sqrt(2)
    se_t = math.sqrt(2) * math.sqrt(2 * J / max(n - k, 1) / (d @ F @ d))
    r = math.exp(x[1] - x[0])
    if plane_stress:
        return r / (r + 2), se_t * 2 * r / (r + 2) ** 2
    return r / (2 * (r + 1)), se_t * r / (2 * (r + 1) ** 2)


def _lame_design(problem, scene):
    """None unless the design is (log mu, log lambda) of the whole scene (two parameters, "mu"
    then "lambda", each one value per body of a one-body scene through a single exp map); else
    whether that body is in 2D plane stress."""
    p = problem.get("parameters", [])
    bodies = scene.get("bodies", [])
    if not (len(p) == 2 and [q.get("type") for q in p] == ["mu", "lambda"]
            and all(q.get("per") == "body" and q.get("maps") == [{"type": "exp"}] for q in p) and len(bodies) == 1):
        return None
    return scene.get("dimension", 3) == 2 and bodies[0].get("material", {}).get("plane") == "stress"


#: A design variable within this fraction of its bounds' range (or of max(1, |bound|) for a
#: one-sided bound) of a bound is reported as on it.
BOUND_TOLERANCE = 1e-6


def active_bounds(x, lower, upper, tolerance=BOUND_TOLERANCE):
    """Per design variable: "lo" or "hi" where x lies on (within ``tolerance`` of) its lower or
    upper bound, else None. There the fit is a constrained minimum: J's gradient need not vanish,
    the quadratic model behind s^2 F^-1 does not hold, and a standard error means little."""
    out = []
    for v, lo, hi in zip(np.asarray(x, float), np.asarray(lower, float), np.asarray(upper, float)):
        span = hi - lo if math.isfinite(lo) and math.isfinite(hi) and hi > lo else None
        side = None
        for name, b in (("lo", lo), ("hi", hi)):
            if math.isfinite(b) and abs(v - b) <= tolerance * (span if span else max(1.0, abs(b))):
                side = name
        out.append(side)
    return out


def _bound_note(sides, names=None):
    """" (at bound lo: standard error not meaningful)" for the variables on a bound."""
    hit = [(i, s) for i, s in enumerate(sides) if s]
    if not hit:
        return ""
    if names is None:
        return f" (at bound {hit[0][1]}: standard error not meaningful)"
    return " (%s at bound %s: standard error not meaningful)" % (
        ", ".join(names[i] for i, _ in hit), "/".join(dict.fromkeys(s for _, s in hit)))


def design_bounds(problem, base_directory):
    """(lower, upper) of the problem's design variables (-inf/+inf where unbounded)."""
    from . import ReducedFunctional  # noqa: the package's class

    p = {k: v for k, v in problem.items() if k not in ("optimizer", "output", "remesh", "checkpointing",
                                                          "constraints")}
    rf = ReducedFunctional(p, base_directory=os.fspath(base_directory))
    return np.asarray(rf.design_lower, float), np.asarray(rf.design_upper, float)


def report(run_directory, threshold=1e-6, printer=print):
    """Prints the identifiability report of a fit: ``diffipc optimize``'s output folder (its
    optimal_problem.json is the problem at the fit). A design variable that ended on one of its
    bounds is marked "(at bound lo: standard error not meaningful)" (or hi), and so are E and nu
    derived from it. Returns (R, F, J)."""
    directory = pathlib.Path(run_directory)
    path = directory / "optimal_problem.json"
    if not path.is_file():
        raise ValueError(f"{path}: missing (the folder of a `diffipc optimize` run)")
    problem = json.loads(path.read_text())
    x = np.array([v for q in problem["parameters"] for v in np.atleast_1d(q["initial"])], dtype=float)
    misfits = []
    R, F, J = fisher_matrix(problem, x, base_directory=directory, misfits=misfits)
    n, k = R.shape
    printer(f"fit: J = {J:.6e} from {n} weighted residuals, {k} design variables; RMS weighted residual "
            f"{math.sqrt(2 * J / n):.4g}, residual scale s = {math.sqrt(2 * J / max(n - k, 1)):.4g}")
    markers = np.array([m for name, m in misfits if name.startswith("marker")])
    if markers.size:
        printer("  markers: %d positions, distance to the measured ones RMS %.4g mm, worst %.4g mm"
                % (markers.size, 1e3 * math.sqrt(np.mean(markers**2)), 1e3 * markers.max()))
    for name, m in misfits:
        if not name.startswith("marker"):
            printer(f"  {name}: model - measurement {m:.4g} N (in magnitude)")
    directions = identifiability(F, threshold)
    largest = directions[0][0]
    for lam, v, ok in directions:
        printer("  eigenvalue %.4e (%.3e of the largest), direction (%s): %s"
                % (lam, lam / largest if largest else 0.0, ", ".join("%.4f" % c for c in v),
                   "identifiable" if ok else "NOT identifiable from these data"))
    se = standard_errors(R, F, J)
    sides = active_bounds(x, *design_bounds(problem, directory))
    printer("  design " + ", ".join("%.5g +- %s%s" % (a, "%.3g" % b if math.isfinite(b) else "inf", _bound_note([s]))
                                     for a, b, s in zip(x, se, sides)))
    plane_stress = _lame_design(problem, _scene_of(problem, directory))
    if plane_stress is not None:
        (E, nu), errors = young_poisson(x, covariance(R, F, J), plane_stress)
        flat = directions[-1][1]
        # E and nu depend on both variables: a bound on either makes their errors meaningless.
        note = _bound_note(sides, ["log mu", "log lambda"])
        if errors is not None:
            printer("  E = %.4g Pa +- %.1f%%, nu = %.4f +- %.4f%s" % (E, 100 * errors[0], nu, errors[1], note))
        elif abs(flat[0] - flat[1]) < 1e-3:
            nu, se_nu = poisson_along_ratio(x, R, F, J, plane_stress)
            printer("  nu = %.4f +- %.4f%s; E is NOT determined by these data (%.4g Pa is where this fit stopped): "
                    "the flat direction (1, 1) in (log mu, log lambda) scales E at fixed nu" % (nu, se_nu, note, E))
        else:
            printer("  E = %.4g Pa, nu = %.4f: F is singular, no standard errors" % (E, nu))
    return R, F, J


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(
        prog="python3 -m diffipc.identifiability",
        description="Identifiability and standard errors of a fit (a `diffipc optimize` output folder whose "
                    "objective is a least-squares fit to data: markers from a file, reaction forces with targets).")
    parser.add_argument("run", help="the output folder of `diffipc optimize`")
    parser.add_argument("--threshold", type=float, default=1e-6,
                        help="a direction whose eigenvalue is below this fraction of the largest is not identifiable")
    args = parser.parse_args(argv)
    try:
        report(args.run, args.threshold)
    except ValueError as e:
        raise SystemExit(f"diffipc.identifiability: {e}")


if __name__ == "__main__":
    main()
