"""Step 4b of docs/tutorial_optimization.md: the bracket optimized by diffipc.minimize (the
optimizers of `diffipc optimize`) with a callback that prints each iteration."""
import diffipc

from design import BracketDesign

d = BracketDesign()


def callback(intermediate_result):
    r = intermediate_result          # iteration, x, fun (J / J0), gradient_norm, step_norm, nfev, ...
    J, _, area, _ = d.values(r.x)
    print(f"  {r.iteration:3d}  J {J:.6f}  area {area:.8f}  |grad| {r.gradient_norm:.2e}  evaluations {r.nfev}")
    # return True (or raise StopIteration) here to stop the run: result.reason is then "user_stop"


result = diffipc.minimize(d.objective, d.x0, method="ipopt", bounds=d.bounds, constraints=d.constraints(),
                          callback=callback, options={"maxiter": 50})
print(f"{result.reason}: {result.message}; {result.nit} iterations, {result.nfev} evaluations")
print(f"J {d.J0:.6f} -> {d.values(result.x)[0]:.6f}, largest constraint violation {result.maxcv:.1e}")
print("x =", result.x.round(6))
