"""diffipc.minimize: the C++ optimizers (projected L-BFGS(-B), Ipopt, NLopt's MMA, CCSAQ and
SLSQP) with scipy.optimize.minimize's conventions where they fit. See docs (Optimizers).

Differences from scipy, on purpose:

* ``fun(x)`` returns ``(f, gradient)`` (scipy's ``jac=True``); there are no finite differences.
  It may return ``None`` for a point where it cannot be evaluated (an invalid design, a failed
  forward solve): the optimizer rejects that point and steps back.
* Constraints are dicts ``{"type": "ineq" | "eq", "fun": c, "jac": dc}`` as in scipy, where
  "ineq" means ``fun(x) >= 0`` (scipy's sign). The C++ side uses ``c(x) <= 0``; the conversion
  (``-fun``, ``-jac``) happens here. scipy's ``LinearConstraint`` and ``NonlinearConstraint``
  (with a callable ``jac``) are accepted too. A constraint's ``fun`` is called once at ``x0``
  to learn its size.
* ``max_valid_step(x, dx)`` (optional): the largest t in (0, 1] such that x + s dx is valid for
  every s in [0, t]; the L-BFGS methods bound their trial steps by it.
"""

import inspect

import numpy as np

from ._diffipc import _minimize, registered_optimizer_algorithms

__all__ = ["minimize", "OptimizeResult"]


class OptimizeResult(dict):
    """The result, a dict with attribute access like scipy.optimize.OptimizeResult: x, fun, jac,
    success, status, reason, message, nit, nfev, njev, nrejected, maxcv, evaluation_seconds,
    optimizer_seconds."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    __setattr__ = dict.__setitem__
    __delattr__ = dict.__delitem__

    def __repr__(self):
        return "OptimizeResult(" + ", ".join(f"{k}={v!r}" for k, v in self.items()) + ")"


# scipy's option names, mapped to diffipc's settings; any other name goes to the library as it
# is (Ipopt's options, NLopt's maxeval, xtol_rel, ftol_abs, stopval, inner_maxeval, ...).
_ALIASES = {
    "maxiter": "max_iterations",
    "gtol": "gradient_tolerance",
    "ftol": "f_tolerance",
    "xtol": "x_tolerance",
    "maxcor": "lbfgs_memory",
    "maxtime": "max_seconds",
    "ctol": "constraint_tolerance",
}

# The C++ table of algorithms (shape_opt/optimizer/optimizer.cpp), not a list of our own.
_METHODS = {a["name"]: a["name"] for a in registered_optimizer_algorithms()}

_SUCCESS = ("gradient_tolerance", "x_tolerance", "f_tolerance")


def _method(method):
    key = str(method).lower().replace("-", "").replace("_", "")
    if key not in _METHODS:
        raise ValueError(f"method: unknown method {method!r} (known: {', '.join(sorted(_METHODS))})")
    return _METHODS[key]


def _bounds(bounds, n):
    """(lower, upper) arrays of n, or (None, None)."""
    if bounds is None:
        return None, None
    if hasattr(bounds, "lb") and hasattr(bounds, "ub"):  # scipy.optimize.Bounds
        lower = np.broadcast_to(np.asarray(bounds.lb, dtype=float), (n,)).copy()
        upper = np.broadcast_to(np.asarray(bounds.ub, dtype=float), (n,)).copy()
        return lower, upper
    pairs = list(bounds)
    if len(pairs) != n:
        raise ValueError(f"bounds: {len(pairs)} pairs for {n} variables")
    lower = np.array([-np.inf if lo is None else float(lo) for lo, _ in pairs])
    upper = np.array([np.inf if hi is None else float(hi) for _, hi in pairs])
    return lower, upper


def _rows(value, n, what):
    """A constraint's Jacobian as an m by n array."""
    a = np.atleast_2d(np.asarray(value, dtype=float))
    if a.ndim != 2 or a.shape[1] != n:
        raise ValueError(f"{what}: the Jacobian has shape {np.shape(value)}, expected (m, {n})")
    return a


def _constraint_blocks(constraints, x0):
    """Each constraint as (kind, g, dg, m) with kind "ineq" (g <= 0) or "eq" (g == 0), in diffipc's sign."""
    if isinstance(constraints, dict) or not isinstance(constraints, (list, tuple)):
        constraints = [constraints]
    n = x0.size
    blocks = []
    for i, con in enumerate(constraints):
        what = f"constraints[{i}]"
        if isinstance(con, dict):
            kind = con.get("type")
            if kind not in ("ineq", "eq"):
                raise ValueError(f"{what}: 'type' must be 'ineq' or 'eq', not {kind!r}")
            fun, jac, args = con.get("fun"), con.get("jac"), tuple(con.get("args", ()))
            if not callable(fun) or not callable(jac):
                raise ValueError(f"{what}: give 'fun' and 'jac' as callables (diffipc takes no finite differences)")
            sign = -1.0 if kind == "ineq" else 1.0  # scipy: fun >= 0; diffipc: c <= 0
            g = (lambda x, fun=fun, args=args, sign=sign: sign * np.atleast_1d(np.asarray(fun(x, *args), dtype=float)))
            dg = (lambda x, jac=jac, args=args, sign=sign, what=what: sign * _rows(jac(x, *args), n, what))
            m = g(x0).size
            blocks.append((kind, g, dg, m))
        elif hasattr(con, "A") and hasattr(con, "lb"):  # scipy LinearConstraint
            A = np.atleast_2d(np.asarray(con.A.toarray() if hasattr(con.A, "toarray") else con.A, dtype=float))
            blocks.extend(_two_sided(lambda x, A=A: A @ x, lambda x, A=A: A, con.lb, con.ub, A.shape[0], what))
        elif hasattr(con, "fun") and hasattr(con, "lb"):  # scipy NonlinearConstraint
            if not callable(getattr(con, "jac", None)):
                raise ValueError(f"{what}: NonlinearConstraint needs a callable jac (diffipc takes no finite differences)")
            fun, jac = con.fun, con.jac
            m = np.atleast_1d(np.asarray(fun(x0), dtype=float)).size
            blocks.extend(_two_sided(lambda x: np.atleast_1d(np.asarray(fun(x), dtype=float)),
                                     lambda x: _rows(jac(x), n, what), con.lb, con.ub, m, what))
        else:
            raise ValueError(f"{what}: not a constraint dict, LinearConstraint or NonlinearConstraint")
    return blocks


def _two_sided(g, dg, lb, ub, m, what):
    """lb <= g(x) <= ub as diffipc blocks: equalities where lb == ub, else lb - g <= 0, g - ub <= 0."""
    lb = np.broadcast_to(np.asarray(lb, dtype=float), (m,))
    ub = np.broadcast_to(np.asarray(ub, dtype=float), (m,))
    eq = lb == ub
    lo = ~eq & np.isfinite(lb)
    hi = ~eq & np.isfinite(ub)
    blocks = []
    if eq.any():
        blocks.append(("eq", lambda x: g(x)[eq] - lb[eq], lambda x: dg(x)[eq], int(eq.sum())))
    if lo.any():
        blocks.append(("ineq", lambda x: lb[lo] - g(x)[lo], lambda x: -dg(x)[lo], int(lo.sum())))
    if hi.any():
        blocks.append(("ineq", lambda x: g(x)[hi] - ub[hi], lambda x: dg(x)[hi], int(hi.sum())))
    return blocks


def _callback(callback):
    """The low-level callback: info dict -> False to stop. scipy's two forms: callback(xk), or
    callback(intermediate_result) when its one parameter has that name; it stops the run by
    raising StopIteration or returning True."""
    if callback is None:
        return None
    try:
        params = list(inspect.signature(callback).parameters)
    except (TypeError, ValueError):
        params = []
    wants_result = params == ["intermediate_result"]

    def call(info):
        try:
            stop = callback(OptimizeResult(info) if wants_result else info["x"])
        except StopIteration:
            return False
        return stop is not True

    return call


def minimize(fun, x0, method="lbfgsb", bounds=None, constraints=(), callback=None, options=None,
             max_valid_step=None):
    """Minimize fun(x) -> (f, gradient) (or None at an invalid point) from x0.

    method: "lbfgsb" (default; bounds only), "lbfgs" (no bounds), "ipopt", "mma", "ccsaq" (bounds
    and inequalities) or "slsqp"; case and "-" ignored ("L-BFGS-B" works).
    bounds: a sequence of (lo, hi) with None for no bound, or a scipy.optimize.Bounds.
    constraints: scipy-style dicts {"type": "ineq" (fun(x) >= 0) | "eq" (fun(x) == 0), "fun",
    "jac", "args"}, LinearConstraint or NonlinearConstraint (callable jac).
    callback: callback(xk) or callback(intermediate_result) at the start and at each iteration;
    raise StopIteration or return True to stop (reason "user_stop").
    options: diffipc's settings (max_iterations, gradient_tolerance, relative_gradient_tolerance,
    x_tolerance, f_tolerance, max_seconds, constraint_tolerance, lbfgs_memory) or scipy's names
    (maxiter, gtol, ftol, xtol, maxcor, maxtime, ctol); any other name is passed to the library
    (Ipopt options; NLopt's maxeval, xtol_rel, ftol_abs, stopval, inner_maxeval, ...).
    max_valid_step(x, dx): see the module's docstring.

    Returns an OptimizeResult; success is True when a tolerance stopped the run at a feasible
    point. Bad input raises ValueError naming the field; an exception raised by fun, a
    constraint or the callback ends the run and propagates.
    """
    x0 = np.array(x0, dtype=float).ravel()
    n = x0.size
    method = _method(method)
    lower, upper = _bounds(bounds, n)
    blocks = _constraint_blocks(constraints, x0)
    ineq = [b for b in blocks if b[0] == "ineq"]
    eq = [b for b in blocks if b[0] == "eq"]
    n_ineq = sum(b[3] for b in ineq)
    n_eq = sum(b[3] for b in eq)

    settings = {}
    for key, value in dict(options or {}).items():
        settings[_ALIASES.get(key, key)] = value

    def stack(group, x):
        if not group:
            return None, None
        return (np.concatenate([b[1](x) for b in group]), np.vstack([b[2](x) for b in group]))

    def combined(x):
        r = fun(x)
        if r is None:
            return None
        try:
            f, g = r
        except (TypeError, ValueError):
            raise ValueError("fun(x) must return (f, gradient) or None") from None
        c, dc = stack(ineq, x)
        h, dh = stack(eq, x)
        return (f, g, c, dc, h, dh)

    raw = _minimize(combined, x0, method, lower, upper, n_ineq, n_eq, settings, _callback(callback),
                    max_valid_step)
    result = OptimizeResult(raw)
    result["success"] = result["reason"] in _SUCCESS
    result["njev"] = result["nfev"]
    result["method"] = method
    return result
