"""Mechanical energy of a stored run, computed from its trajectory.h5 alone (independently of the
solver): kinetic energy with the lumped P1 masses, elastic energy of 2D neo-Hookean or linear
elements, and the work potential of gravity. The studies use it for energy drift."""
import numpy as np


def _element_energy_density(model, F, mu, lam):
    J = np.linalg.det(F)
    if model == "neo_hookean":
        with np.errstate(invalid="ignore", divide="ignore"):
            logJ = np.log(J)
        psi = mu / 2 * (np.einsum("eij,eij->e", F, F) - 2) - mu * logJ + lam / 2 * logJ ** 2
        return np.where(J > 0, psi, np.inf)
    if model == "linear":
        eps = 0.5 * (F + np.transpose(F, (0, 2, 1))) - np.eye(2)
        tr = np.trace(eps, axis1=1, axis2=2)
        return mu * np.einsum("eij,eij->e", eps, eps) + lam / 2 * tr ** 2
    raise ValueError(f"energy: material model '{model}' is not supported here (2D neo_hookean or linear)")


def mechanical_energy(f, scene):
    """Per stored state (initial state first): kinetic + elastic + gravitational energy of the
    bodies (J, per unit thickness: 2D scenes only, plane strain). `f` an open trajectory.h5,
    `scene` the scene dict it was run from (materials and gravity); +inf for an inverted element."""
    if scene["dimension"] != 2:
        raise ValueError("energy: 2D scenes only")
    X = f["mesh/rest_positions"][:]
    tris = f["mesh/elements"][:]
    eb = f["mesh/element_body"][:]
    x, v = f["positions"][:], f["velocities"][:]
    mats = [b["material"] for b in scene["bodies"]]
    E = np.array([mats[b]["E"] for b in eb])
    nu = np.array([mats[b]["nu"] for b in eb])
    rho = np.array([mats[b]["density"] for b in eb])
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    models = {mats[b]["model"] for b in set(eb.tolist())}
    if len(models) != 1:
        raise ValueError("energy: one material model per scene")
    model = models.pop()
    Dm = np.stack([X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]], axis=2)
    area = 0.5 * np.abs(np.linalg.det(Dm))
    Dm_inv = np.linalg.inv(Dm)
    mass = np.zeros(len(X))
    for k in range(3):
        np.add.at(mass, tris[:, k], rho * area / 3)
    body = f["mesh/body"][:] < len(scene["bodies"])
    g = np.array(scene.get("gravity", [0.0, 0.0]), float)
    out = np.empty(x.shape[0])
    for s in range(x.shape[0]):
        Ds = np.stack([x[s, tris[:, 1]] - x[s, tris[:, 0]], x[s, tris[:, 2]] - x[s, tris[:, 0]]], axis=2)
        psi = _element_energy_density(model, Ds @ Dm_inv, mu, lam)
        kinetic = 0.5 * (mass[body] * (v[s, body] ** 2).sum(axis=1)).sum()
        out[s] = kinetic + (area * psi).sum() - (mass[body] * (x[s, body] @ g)).sum()
    return out
