"""Finite-difference checks of derivatives, printed as a Taylor table.

For a function f with claimed gradient g at x and a direction d, the Taylor
remainders r0(h) = |f(x + h d) - f(x)| and r1(h) = |f(x + h d) - f(x) - h g.d|
converge with rates 1 and 2 when g is right (pyadjoint's convention).

These work on any callable; diffipc.reduced applies them to a ReducedFunctional.
"""

import math

import numpy as np


def convergence_rates(remainders, steps):
    """Observed orders log(r[k-1] / r[k]) / log(h[k-1] / h[k]); NaN where a remainder is 0."""
    return [
        math.log(remainders[k - 1] / remainders[k]) / math.log(steps[k - 1] / steps[k])
        if remainders[k] > 0 and remainders[k - 1] > 0
        else float("nan")
        for k in range(1, len(steps))
    ]


def taylor_test(f, x, gradient, direction, steps=(1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4), printer=print, f0=None):
    """Return (r0, r1, rates0, rates1) and print the table.

    ``f0`` is f(x) if already known (saves one evaluation).
    """
    x = np.asarray(x, dtype=float)
    direction = np.asarray(direction, dtype=float)
    f0 = f(x) if f0 is None else f0
    slope = float(np.dot(np.ravel(gradient), np.ravel(direction)))
    r0, r1 = [], []
    for h in steps:
        fh = f(x + h * direction)
        r0.append(abs(fh - f0))
        r1.append(abs(fh - f0 - h * slope))
    rates0 = convergence_rates(r0, steps)
    rates1 = convergence_rates(r1, steps)
    if printer:
        printer(f"{'h':>10} {'|f(x+hd)-f(x)|':>18} {'rate':>6} {'|...-h g.d|':>14} {'rate':>6}")
        for k, h in enumerate(steps):
            a = f"{rates0[k - 1]:6.2f}" if k else "      "
            b = f"{rates1[k - 1]:6.2f}" if k else "      "
            printer(f"{h:10.3e} {r0[k]:18.6e} {a} {r1[k]:14.6e} {b}")
    return r0, r1, rates0, rates1


def central_difference_check(f, x, gradient, direction, h):
    """Relative error between g.d and the central difference of f along d."""
    x = np.asarray(x, dtype=float)
    fd = (f(x + h * direction) - f(x - h * direction)) / (2 * h)
    an = float(np.dot(np.ravel(gradient), np.ravel(direction)))
    return abs(fd - an) / max(abs(an), 1e-300)


def random_directions(size, count, seed=1, scales=None):
    """``count`` directions with entries uniform in [-1, 1] (times ``scales``), reproducible by ``seed``."""
    rng = np.random.default_rng(seed)
    scales = np.ones(size) if scales is None else np.asarray(scales, dtype=float)
    return [rng.uniform(-1.0, 1.0, size) * scales for _ in range(count)]


def central_difference_errors(f, x, gradient, directions=2, h=1e-3, seed=1, scales=None):
    """Relative errors of g.d against central differences at step h along random directions d.

    ``directions`` is a count (drawn by random_directions with ``seed`` and ``scales``)
    or a list of directions. Returns a numpy array, one relative error per direction.
    """
    x = np.asarray(x, dtype=float)
    if isinstance(directions, int):
        directions = random_directions(x.size, directions, seed, scales)
    return np.array([central_difference_check(f, x, gradient, np.asarray(d, dtype=float), h) for d in directions])
