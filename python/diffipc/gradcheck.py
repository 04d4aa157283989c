"""Finite-difference checks of derivatives, printed as a Taylor table.

For a function f with claimed gradient g at x and a direction d, the Taylor
remainders r0(h) = |f(x + h d) - f(x)| and r1(h) = |f(x + h d) - f(x) - h g.d|
converge with rates 1 and 2 when g is right (pyadjoint's convention).

check_direction gives ``diffipc gradcheck``'s verdict on one direction (the CLI's C++ check,
shape_opt/gradient_check.hpp, bound), with one-sided differences where f'' jumps (an exterior
penalty at its bound).
These work on any callable; diffipc.reduced applies them to a ReducedFunctional.
"""

import math

import numpy as np

from . import _diffipc


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


#: Relative error of a difference against the claimed slope below which a direction passes.
TOLERANCE = _diffipc.GRADIENT_CHECK_TOLERANCE
#: One-sided slopes further apart than this (relative) mean a kink of f itself.
KINK_SLOPE_GAP = _diffipc.KINK_SLOPE_GAP


def richardson_one_sided(quotients):
    """Richardson extrapolation of one-sided quotients D(h_i), h_i = h_0 / 2^i, with error c1 h + c2 h^2 + ...

    The C++ richardson_one_sided (shape_opt/gradient_check.hpp) that ``diffipc gradcheck`` uses.
    At least three quotients (else ValueError).
    """
    return _diffipc._richardson_one_sided([float(q) for q in quotients])


def check_direction(f, x, gradient, direction, step=1e-2, halvings=4, f0=None, printer=None):
    """The verdict of ``diffipc gradcheck`` on one direction (docs/problem_format.md, "gradcheck"),
    judged by the CLI's own C++ check_direction (shape_opt/gradient_check.hpp).

    j(h) = f(x + h d), slope = gradient.d. PASS: the fourth-order central difference at ``step``
    is within 1e-5 (relative) of the slope and the last rate of the second-order Taylor remainders
    |j(h) - j(0) - h slope| (h = step / 2^i, i = 0..halvings) above the floor 1e-10 |j(0)| is at
    least 1.9. Else the one-sided slopes j'(0+) and j'(0-) (Richardson-extrapolated quotients,
    richardson_one_sided): "PASS (kink)" if both agree with the slope (j'' jumps at 0, as an
    exterior penalty at its bound does, and the central difference straddles it), "NOT
    DIFFERENTIABLE" if they differ from each other by more than 1e-3 (no gradient to check),
    else "FAIL". "INCONCLUSIVE": j does not change above the floor. Returns a dict with
    ``verdict``, ``passed``, ``slope``, ``central``, ``central_error``, ``taylor`` (rows
    (h, |j(h) - j(0)|, |j(h) - j(0) - h slope|)), ``floor``, ``last_rate``, ``resolved``,
    ``one_sided`` and, when ``one_sided``, ``forward``, ``backward`` and their ``_error``s;
    ``printer`` (e.g. print) receives a summary line.
    """
    x = np.asarray(x, dtype=float)
    direction = np.asarray(direction, dtype=float)
    slope = float(np.dot(np.ravel(gradient), np.ravel(direction)))
    j0 = float(f(x)) if f0 is None else float(f0)
    r = _diffipc._check_direction(lambda h: float(f(x + h * direction)), j0, slope, float(step), int(halvings))
    if printer:
        line = f"{r['verdict']}: slope {slope:.10e}, central difference {r['central']:.10e} (relative error " \
               f"{r['central_error']:.2e})"
        if r["one_sided"]:
            line += f", one-sided {r['forward']:.10e} / {r['backward']:.10e} (relative errors " \
                    f"{r['forward_error']:.2e} / {r['backward_error']:.2e})"
        printer(line)
    return r
