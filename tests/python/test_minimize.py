"""diffipc.minimize against scipy.optimize.minimize on the same analytic problems, with each
method; plus the conventions (constraint signs, bounds, callback, invalid points, errors)."""
import numpy as np
import pytest
from scipy.optimize import Bounds, LinearConstraint, NonlinearConstraint
from scipy.optimize import minimize as scipy_minimize

import diffipc

ALL = ["lbfgsb", "lbfgs", "ipopt", "mma", "ccsaq", "slsqp"]
BOUNDED = ["lbfgsb", "ipopt", "mma", "ccsaq", "slsqp"]
TIGHT = {"gtol": 1e-10, "relative_gradient_tolerance": 0, "maxiter": 20000}


def rosen(x):
    """2D Rosenbrock with its gradient (scipy's jac=True form)."""
    a, b = x
    r = b - a * a
    return 100 * r * r + (1 - a) ** 2, np.array([-400 * a * r - 2 * (1 - a), 200 * r])


def scipy_rosen(bounds=None):
    # Tight L-BFGS-B: its x is within ~1e-7 of the minimum.
    return scipy_minimize(rosen, [-1.2, 1], jac=True, method="L-BFGS-B", bounds=bounds,
                          options={"gtol": 1e-12, "ftol": 1e-16, "maxiter": 10000})


# Both reach the minimum (1, 1); they agree to 1e-6 (diffipc stops at gradient 1e-10, ~1e-9 away).
@pytest.mark.parametrize("method", ALL)
def test_rosenbrock_agrees_with_scipy(method):
    ours = diffipc.minimize(rosen, [-1.2, 1], method=method, options=TIGHT)
    ref = scipy_rosen()
    assert ours.success, ours.message
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(ours.x, [1, 1], atol=1e-6)
    assert ours.fun == pytest.approx(rosen(ours.x)[0])


# x0 <= 0.5 is active at the minimum (0.5, 0.25); agreement to 1e-6.
@pytest.mark.parametrize("method", BOUNDED)
def test_rosenbrock_with_active_bound_agrees_with_scipy(method):
    bounds = [(-5, 0.5), (None, None)]
    ours = diffipc.minimize(rosen, [-1.2, 1], method=method, bounds=bounds, options=TIGHT)
    ref = scipy_rosen(bounds)
    np.testing.assert_allclose(ours.x, ref.x, atol=1e-6)
    np.testing.assert_allclose(ours.x, [0.5, 0.25], atol=1e-6)


def sphere_to(a):
    a = np.asarray(a, dtype=float)
    return lambda x: (float(np.sum((x - a) ** 2)), 2 * (x - a))


A = np.array([[1.0, 1.0, 1.0], [-1.0, 0.0, 1.0]])
QUAD = sphere_to([1, 2, 3])
# scipy's sign: "ineq" is fun(x) >= 0. x0 + x1 + x2 = 3 and x2 - x0 <= 1, i.e. 1 - (x2 - x0) >= 0.
EQ = {"type": "eq", "fun": lambda x: A[0] @ x - 3, "jac": lambda x: A[0]}
INEQ = {"type": "ineq", "fun": lambda x: 1 - A[1] @ x, "jac": lambda x: -A[1]}
SUM_INEQ = {"type": "ineq", "fun": lambda x: 3 - A[0] @ x, "jac": lambda x: -A[0]}
QUAD_OPT = np.array([0.5, 1.0, 1.5])  # both constraints active, multipliers (2, 1) > 0
BOX = [(-5, 5)] * 3  # inactive; MMA and CCSAQ need finite bounds for their asymptotes
CONSTRAINED_OPTIONS = dict(TIGHT, xtol=1e-12, ctol=1e-9)


# scipy's trust-constr stops its barrier problems early: on these problems it lands 1e-6 to
# 2e-5 from the KKT point (measured), so it is compared to 5e-5; SLSQP to 1e-6.
TRUST_ATOL = 5e-5


def scipy_both(fun, x0, constraints, bounds, trust_constraints):
    """scipy's SLSQP and trust-constr (with the exact Hessian 2 I of these objectives) on the same problem."""
    slsqp = scipy_minimize(fun, x0, jac=True, method="SLSQP", bounds=bounds, constraints=constraints,
                           options={"ftol": 1e-14, "maxiter": 1000})
    trust = scipy_minimize(fun, x0, jac=True, hess=lambda x: 2 * np.eye(len(x)), method="trust-constr",
                           bounds=Bounds(*zip(*bounds)),
                           constraints=trust_constraints,
                           options={"gtol": 1e-12, "xtol": 1e-14, "barrier_tol": 1e-12, "maxiter": 5000})
    return slsqp, trust


# Linear equality and inequality (MMA/CCSAQ: the equality as an inequality, same optimum):
# diffipc and scipy SLSQP agree to 1e-6 (trust-constr: TRUST_ATOL), and match the KKT point (1e-6).
@pytest.mark.parametrize("method", ["ipopt", "slsqp", "mma", "ccsaq"])
def test_linear_constraints_agree_with_scipy(method):
    constraints = [EQ, INEQ] if method in ("ipopt", "slsqp") else [SUM_INEQ, INEQ]
    ours = diffipc.minimize(QUAD, np.zeros(3), method=method, bounds=BOX, constraints=constraints,
                            options=CONSTRAINED_OPTIONS)
    slsqp, trust = scipy_both(QUAD, np.zeros(3), constraints, BOX,
                              [LinearConstraint(A[0], 3, 3), LinearConstraint(A[1], -np.inf, 1)])
    np.testing.assert_allclose(ours.x, QUAD_OPT, atol=1e-6)
    np.testing.assert_allclose(ours.x, slsqp.x, atol=1e-6)
    np.testing.assert_allclose(ours.x, trust.x, atol=TRUST_ATOL)
    assert ours.maxcv <= 1e-9


# The bound x0 <= 0.5 and the circle x0^2 + x1^2 <= 2 are both active at (0.5, sqrt(1.75)),
# with positive multipliers (KKT, see test_optimizer.cpp); agreement with scipy's SLSQP to 1e-6
# (trust-constr: TRUST_ATOL).
@pytest.mark.parametrize("method", ["ipopt", "slsqp", "mma", "ccsaq"])
def test_bound_and_nonlinear_constraint_agree_with_scipy(method):
    fun = sphere_to([2, 2])
    circle = {"type": "ineq", "fun": lambda x: 2 - x @ x, "jac": lambda x: -2 * x}
    bounds = [(-5, 0.5), (-5, 5)]
    ours = diffipc.minimize(fun, [0.25, 0.5], method=method, bounds=bounds, constraints=[circle],
                            options=CONSTRAINED_OPTIONS)
    slsqp, trust = scipy_both(fun, [0.25, 0.5], [circle], bounds,
                              [NonlinearConstraint(lambda x: x @ x, -np.inf, 2, jac=lambda x: 2 * x[None, :],
                                                   hess=lambda x, v: 2 * v[0] * np.eye(2))])
    expected = [0.5, np.sqrt(1.75)]
    np.testing.assert_allclose(ours.x, expected, atol=1e-6)
    np.testing.assert_allclose(ours.x, slsqp.x, atol=1e-6)
    np.testing.assert_allclose(ours.x, trust.x, atol=TRUST_ATOL)


def test_scipy_constraint_objects_and_bounds():
    """LinearConstraint / NonlinearConstraint / Bounds give the same optimum as the dicts (1e-6)."""
    ours = diffipc.minimize(QUAD, np.zeros(3), method="ipopt", bounds=Bounds(-5, 5),
                            constraints=[LinearConstraint(A, [3, -np.inf], [3, 1])], options=CONSTRAINED_OPTIONS)
    np.testing.assert_allclose(ours.x, QUAD_OPT, atol=1e-6)
    nonlinear = NonlinearConstraint(lambda x: A @ x, [3, -np.inf], [3, 1], jac=lambda x: A)
    ours = diffipc.minimize(QUAD, np.zeros(3), method="slsqp", constraints=nonlinear, options=CONSTRAINED_OPTIONS)
    np.testing.assert_allclose(ours.x, QUAD_OPT, atol=1e-6)


def validity_problem():
    """Minimum (28/15, 8/15) inside x0 > 1.5, declared invalid (fun returns None there)."""
    seen = []

    def fun(x):
        if x[0] > 1.5:
            return None
        seen.append(x.copy())
        f = (x[0] - 2) ** 2 + (x[1] - 1) ** 2 + 0.5 * x[0] * x[1]
        return f, np.array([2 * (x[0] - 2) + 0.5 * x[1], 2 * (x[1] - 1) + 0.5 * x[0]])

    return fun, seen


# Invalid points are rejected, never reported: every callback point is valid and the run ends
# within 1e-3 of the boundary x0 = 1.5, at a valid point.
@pytest.mark.parametrize("method", ALL)
def test_invalid_points(method):
    fun, _ = validity_problem()
    points = []
    r = diffipc.minimize(fun, [0, 0], method=method, callback=lambda xk: points.append(xk.copy()),
                         options=dict(TIGHT, maxiter=500, xtol=1e-12))
    assert all(p[0] <= 1.5 for p in points)
    assert 1.5 - 1e-3 < r.x[0] <= 1.5, r.message
    assert r.nrejected > 0
    assert np.isfinite(r.fun)


def test_max_valid_step_avoids_rejections():
    fun, _ = validity_problem()

    def max_valid_step(x, dx):
        return 1.0 if dx[0] <= 0 or x[0] + dx[0] <= 1.5 else (1.5 - x[0]) / dx[0]

    r = diffipc.minimize(fun, [0, 0], method="lbfgsb", max_valid_step=max_valid_step, options={"xtol": 1e-12})
    assert r.nrejected == 0
    assert 1.5 - 1e-3 < r.x[0] <= 1.5


def test_callback_forms_and_stop():
    seen = []

    def with_result(intermediate_result):  # scipy's newer form: an OptimizeResult
        seen.append(intermediate_result.iteration)
        assert intermediate_result.fun == pytest.approx(rosen(intermediate_result.x)[0])
        if intermediate_result.iteration == 3:
            raise StopIteration

    r = diffipc.minimize(rosen, [-1.2, 1], callback=with_result)
    assert r.reason == "user_stop" and not r.success
    assert seen == [0, 1, 2, 3]

    points = []

    def with_x(xk):  # scipy's older form: x; returning True stops (as in trust-constr)
        points.append(xk.copy())
        return len(points) == 5

    r = diffipc.minimize(rosen, [-1.2, 1], method="ipopt", callback=with_x)
    assert r.reason == "user_stop" and r.nit == 4
    np.testing.assert_array_equal(points[0], [-1.2, 1])


def test_iteration_budget_and_library_options():
    r = diffipc.minimize(rosen, [-1.2, 1], options={"maxiter": 5})
    assert r.reason == "iteration_budget" and r.nit == 5 and not r.success
    r = diffipc.minimize(rosen, [-1.2, 1], method="ipopt", options={"max_iter": 3, "mu_strategy": "adaptive"})
    assert r.reason == "iteration_budget" and r.nit == 3
    with pytest.raises(ValueError, match="optimizer.options.mu_strategy"):
        diffipc.minimize(rosen, [-1.2, 1], method="ipopt", options={"mu_strategy": "fast"})
    with pytest.raises(ValueError, match="optimizer.options.inner_maxeval"):
        diffipc.minimize(rosen, [-1.2, 1], method="slsqp", options={"inner_maxeval": 5})
    r = diffipc.minimize(rosen, [-1.2, 1], method="mma", options={"inner_maxeval": 5, "maxeval": 30})
    assert r.nfev <= 30


def test_errors():
    with pytest.raises(ValueError, match="optimizer.algorithm.*use ipopt, mma, ccsaq or slsqp"):
        diffipc.minimize(QUAD, np.zeros(3), constraints=[EQ])
    with pytest.raises(ValueError, match="optimizer.algorithm"):
        diffipc.minimize(QUAD, np.zeros(3), method="mma", constraints=[EQ])
    with pytest.raises(ValueError, match="optimizer.x0"):
        diffipc.minimize(rosen, [-1.2, 1], bounds=[(0, 1), (0, 2)])
    with pytest.raises(ValueError, match="optimizer.lower"):
        diffipc.minimize(rosen, [0.5, 1], bounds=[(1, 0), (0, 2)])
    with pytest.raises(ValueError, match="method"):
        diffipc.minimize(rosen, [0, 0], method="bfgs")
    with pytest.raises(ValueError, match="gradient"):
        diffipc.minimize(lambda x: (0.0, np.zeros(3)), [0, 0])
    with pytest.raises(ValueError, match="jac"):
        diffipc.minimize(QUAD, np.zeros(3), method="slsqp", constraints=[{"type": "eq", "fun": lambda x: x[0]}])


def test_exceptions_propagate():
    calls = []

    def failing(x):
        calls.append(1)
        if len(calls) == 4:
            raise KeyError("from fun")
        return rosen(x)

    def failing_callback(xk):
        raise ArithmeticError("from the callback")

    for method in ALL:
        calls.clear()
        with pytest.raises(KeyError, match="from fun"):
            diffipc.minimize(failing, [-1.2, 1], method=method)
        with pytest.raises(ArithmeticError, match="from the callback"):
            diffipc.minimize(rosen, [-1.2, 1], method=method, callback=failing_callback)


def test_invalid_start():
    r = diffipc.minimize(lambda x: None, [0.0, 0.0])
    assert r.reason == "invalid_start" and r.fun is None and r.nfev == 1
