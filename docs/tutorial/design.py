"""The tutorial's bracket (problem.json) as functions of its 8 design variables x, for
optimizers called from Python (docs/tutorial_optimization.md, step 4).

One forward run and one adjoint sweep per new x give J, the rest area g and both gradients
(J.evaluation with constraints=True); the result is kept for the last x, because scipy and
diffipc.minimize ask for the objective and the constraint at the same point one after the
other. J and g are scaled as `diffipc optimize` scales them (J / |J(x0)|, the area margin
relative to its bound), so that the optimizers' tolerances mean the same as in the CLI run.
"""
import pathlib

import numpy as np

import diffipc

PROBLEM = pathlib.Path(__file__).resolve().parent / "problem.json"


class BracketDesign:
    def __init__(self, problem=PROBLEM):
        self.J = diffipc.ReducedFunctional(str(problem))
        self.x0 = self.J.design_initial                        # 8 zeros: the scene's own shape
        self.bounds = list(zip(self.J.design_lower, self.J.design_upper))   # [(-0.1, 0.1)] * 8
        self.area_bound = self.J.constraints[0]["bound"]       # 0.08 m^2 ("upper")
        self._x, self._values = None, None
        self.J0 = self.values(self.x0)[0]

    def values(self, x):
        """J, dJ/dx, area, d area/dx at x (one forward and one adjoint run per new x)."""
        x = np.asarray(x, dtype=float)
        if self._x is None or not np.array_equal(x, self._x):
            p = self.J.parameters_of(x)                        # x -> rest positions (insert, ffd)
            e = self.J.evaluation(p, gradient=True, constraints=True)
            self._values = (e.value, self.J.design_gradient(x, e.gradient),
                            e.constraint_values[0], self.J.design_gradient(x, e.constraint_gradients[0]))
            self._x = x.copy()
        return self._values

    def objective(self, x):
        """(J / J0, its gradient): what scipy's jac=True and diffipc.minimize take."""
        value, gradient, _, _ = self.values(x)
        return value / self.J0, gradient / self.J0

    def area_margin(self, x):
        """(0.08 - area) / 0.08 >= 0: scipy's sign of an inequality."""
        return (self.area_bound - self.values(x)[2]) / self.area_bound

    def area_margin_jacobian(self, x):
        return -self.values(x)[3] / self.area_bound

    def constraints(self):
        return [{"type": "ineq", "fun": self.area_margin, "jac": self.area_margin_jacobian}]
