"""Finite-difference checks of derivatives, printed as a Taylor table.

For a function f with claimed gradient g at x and a direction d, the Taylor
remainders r0(h) = |f(x + h d) - f(x)| and r1(h) = |f(x + h d) - f(x) - h g.d|
converge with rates 1 and 2 when g is right (pyadjoint's convention).
"""

import math

import numpy as np


def taylor_test(f, x, gradient, direction, steps=(1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4), printer=print):
    """Return (r0, r1, rates0, rates1) and print the table."""
    x = np.asarray(x, dtype=float)
    direction = np.asarray(direction, dtype=float)
    f0 = f(x)
    slope = float(np.dot(np.ravel(gradient), np.ravel(direction)))
    r0, r1 = [], []
    for h in steps:
        fh = f(x + h * direction)
        r0.append(abs(fh - f0))
        r1.append(abs(fh - f0 - h * slope))
    rates0 = [math.log(r0[k - 1] / r0[k]) / math.log(steps[k - 1] / steps[k]) if r0[k] > 0 and r0[k - 1] > 0 else float("nan") for k in range(1, len(steps))]
    rates1 = [math.log(r1[k - 1] / r1[k]) / math.log(steps[k - 1] / steps[k]) if r1[k] > 0 and r1[k - 1] > 0 else float("nan") for k in range(1, len(steps))]
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
