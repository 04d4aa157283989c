"""Study 407: confidence of a fit in (E, nu) from the Fisher matrix of its weighted residuals,
shared by force.py and drop.py (diffipc.identifiability's covariance s^2 F^-1 and its delta
method for E and nu)."""
import numpy as np

from diffipc.identifiability import covariance, identifiability, young_poisson


def e_nu_to_design(E, nu):
    """(log mu, log lambda) of Young's modulus and Poisson's ratio (3D)."""
    return np.log([E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))])


def report(R, F, J, x, threshold=1e-6):
    """Lines describing F's eigen-directions and, where F is regular, E and nu with their
    standard errors; and the covariance (or None)."""
    lines = []
    directions = identifiability(F, threshold)
    largest = directions[0][0]
    for lam, v, ok in directions:
        lines.append("  eigenvalue %.4e (ratio to the largest %.3e), eigenvector (%.4f, %.4f): %s"
                     % (lam, lam / largest, v[0], v[1], "identifiable" if ok else "NOT identifiable"))
    cov = covariance(R, F, J)
    (E, nu), errors = young_poisson(x, cov)
    if errors is None:
        lines.append("  F is singular: no standard errors for both parameters")
    else:
        lines.append("  E = %.4g Pa (standard error %.1f%%), nu = %.4f +- %.4f" % (E, 100 * errors[0], nu, errors[1]))
    return lines, cov
