"""Step 4a of docs/tutorial_optimization.md: the bracket optimized by scipy's SLSQP on
diffipc.ReducedFunctional (bounds and the area constraint)."""
import scipy.optimize

from design import BracketDesign

d = BracketDesign()
result = scipy.optimize.minimize(d.objective, d.x0, jac=True, method="SLSQP", bounds=d.bounds,
                                 constraints=d.constraints(), options={"maxiter": 100, "ftol": 1e-12})
J, _, area, _ = d.values(result.x)
print(f"SLSQP: {result.message} after {result.nit} iterations ({result.nfev} evaluations)")
print(f"J {d.J0:.6f} -> {J:.6f}, area {area:.12f} (bound {d.area_bound})")
print("x =", result.x.round(6))
