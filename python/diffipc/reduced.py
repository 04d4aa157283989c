"""The reduced functional of a problem file (docs/problem_format.md) from Python.

p -> J(p) with its adjoint gradient dJ/dp, cached for the last p, and the two
checks a user runs on it: a pyadjoint-style Taylor test and central differences
in random directions. See docs/python.md.
"""

import os

import numpy as np

from . import _diffipc
from ._diffipc import AdjointError  # noqa: F401
from .gradcheck import central_difference_errors
from .gradcheck import taylor_test as taylor_table

#: pyadjoint's steps: h = 0.01 * 2^-i, i = 0..3.
TAYLOR_STEPS = tuple(0.01 * 2.0**-i for i in range(4))


class ReducedFunctional(_diffipc.ReducedFunctional):
    """J(p) and dJ/dp of a problem, from a file path or from a dict.

    ``ReducedFunctional("problem.json")`` or ``ReducedFunctional(problem_dict,
    base_directory=...)`` (scene and mesh paths in the dict are relative to
    ``base_directory``, default the current directory). ``device="gpu"`` runs
    every load case's simulations and adjoint solves on the GPU, replacing the
    scenes' ``"device"`` (``"cpu"`` the CPU; ``""``, the default: theirs). Bad input raises
    ValueError naming the field; a failed forward step or a gradient that cannot
    be computed raises AdjointError and returns nothing.

    ``comm=MPI.COMM_WORLD`` (mpi4py) spreads the load cases over the ranks: every
    evaluation is then collective, called by every rank with the same p, and gives
    every rank the serial evaluation's bits (diffipc/mpi.py; ``distribution``
    has the ranks' times). ``evaluation_of_case`` stays local.

    ``J(p)``, ``J.gradient(p)`` and ``J.value_and_gradient(p)`` share one cached
    evaluation: asking for the gradient at the p just evaluated runs only what
    is missing. ``evaluate(p, gradient=True)`` (no cache) and ``size``,
    ``initial``, ``scales``, ``layout``, ``check_settings`` come from the
    compiled class.
    """

    def __init__(self, problem, base_directory=None, device="", comm=None):
        if not isinstance(device, str):
            raise TypeError('device must be "cpu", "gpu" or "" (the scenes\' own)')
        if isinstance(problem, dict):
            super().__init__(problem, None if base_directory is None else os.fspath(base_directory), device)
        elif isinstance(problem, (str, os.PathLike)):
            if base_directory is not None:
                raise TypeError("base_directory applies to a problem dict; a file's scenes are relative to the file")
            super().__init__(os.fspath(problem), device)
        else:
            raise TypeError("problem must be a path to a JSON problem file or a dict")
        #: With ``comm`` (an mpi4py communicator): the diffipc.mpi.MpiCommunicator that spreads the load cases.
        self.communicator = None
        if comm is not None:
            from .mpi import MpiCommunicator

            self.communicator = MpiCommunicator(comm)
            _diffipc._distribute(self, self.communicator)
        self._last = None  # (p, J, dJ/dp or None) of the last successful evaluation
        #: Seconds and counts summed over this object's evaluations (cache hits excluded).
        self.timings = {"forward": 0.0, "adjoint": 0.0, "evaluations": 0, "gradients": 0}

    @property
    def distribution(self):
        """With comm: the ranks, this rank, the evaluations, the wall seconds in them, per rank its seconds in
        its load cases and their count (filled on rank 0 only: the other ranks' lists stay zero), and the last
        assignment of cases to ranks with the costs it was made by (rank 0); else None."""
        return _diffipc._distribution_times(self)

    def _cached(self, p, gradient):
        p = np.array(p, dtype=float)  # a copy: the caller may change p afterwards
        last = self._last
        if last is not None and last[0].shape == p.shape and np.array_equal(last[0], p):
            if not gradient or last[2] is not None:
                return last[1], last[2]
        e = self.evaluation(p, gradient)
        self.timings["forward"] += e.forward_time
        self.timings["adjoint"] += e.adjoint_time
        self.timings["evaluations"] += 1
        self.timings["gradients"] += int(gradient)
        self._last = (p, e.value, e.gradient)
        return e.value, e.gradient

    def __call__(self, p):
        """J(p)."""
        return self._cached(p, False)[0]

    def gradient(self, p):
        """dJ/dp (a new numpy array)."""
        return self._cached(p, True)[1].copy()

    def value_and_gradient(self, p):
        """(J(p), dJ/dp)."""
        value, g = self._cached(p, True)
        return value, g.copy()


def _value_and_gradient(J, p, dJdp):
    if dJdp is not None:
        return J(p), np.asarray(dJdp, dtype=float)
    if not hasattr(J, "value_and_gradient"):
        raise TypeError("pass dJdp, or a J with value_and_gradient (a ReducedFunctional)")
    return J.value_and_gradient(p)


def taylor_test(J, p, dp, dJdp=None, printer=None):
    """pyadjoint's Taylor test: the smallest observed order of the second-order remainder.

    Remainders |J(p + h dp) - J(p) - h dJdp.dp| for h = 0.01 * 2^-i, i = 0..3,
    and their rates log2(r_{i-1} / r_i); a right gradient gives rates near 2
    (a wrong one near 1). ``J`` is a ReducedFunctional or any callable p -> float
    with ``dJdp`` given; ``printer`` (e.g. print) receives the table. Returns NaN
    if a remainder is exactly 0, so that a check ``rate >= 1.9`` fails.
    """
    p = np.asarray(p, dtype=float)
    J0, g = _value_and_gradient(J, p, dJdp)
    _, _, _, rates = taylor_table(J, p, g, dp, steps=TAYLOR_STEPS, printer=printer, f0=J0)
    return float(np.min(rates))


def finite_difference_check(J, p=None, directions=None, seed=None, h=1e-3, dJdp=None):
    """Relative errors of dJ/dp . d against central differences (J(p + h d) - J(p - h d)) / 2h.

    The directions d have entries uniform in [-1, 1] times ``J.scales`` (a typical
    magnitude per variable), drawn with a fixed ``seed``; ``directions`` and
    ``seed`` default to the problem file's "gradcheck" settings, ``p`` to
    ``J.initial``. ``directions`` may also be a list of arrays. Returns a numpy
    array, one relative error per direction.
    """
    p = J.initial if p is None else np.asarray(p, dtype=float)
    settings = J.check_settings
    directions = settings["directions"] if directions is None else directions
    seed = settings["seed"] if seed is None else seed
    _, g = _value_and_gradient(J, p, dJdp)
    return central_difference_errors(J, p, g, directions, h, seed, J.scales)
