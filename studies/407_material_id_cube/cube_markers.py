"""Study 407: the markers' simulated positions, computed independently of the markers objective.

Each marker's rest position is located once in the rest mesh (the tetrahedron in which all its
barycentric coordinates are largest) and carried to a deformed mesh by those coordinates; each
evaluation then costs one diffipc.simulate. Used by run_study.py (residuals), noise_study.py,
force.py, models.py, plots.py and drop.py.
"""
import json

import numpy as np

import diffipc
from diffipc.identifiability import young_poisson


class Markers:
    """The markers (rows rest x y z, measured x y z) located in a scene's rest mesh."""

    def __init__(self, scene, markers):
        sc = diffipc.scene(scene)
        self.scene, self.measured = scene, markers[:, 3:]
        self.rest = np.asarray(sc.rest_positions)
        tets = np.asarray(sc.elements)
        a = self.rest[tets[:, 0]]
        inv = np.linalg.inv(np.stack([self.rest[tets[:, i]] - a for i in (1, 2, 3)], axis=2))
        self.tets, self.weights = [], []
        for X in markers[:, :3]:
            b = np.einsum("eij,ej->ei", inv, X - a)
            w = np.concatenate([1 - b.sum(1, keepdims=True), b], axis=1)
            e = np.argmax(w.min(1))
            self.tets.append(tets[e])
            self.weights.append(w[e])
        self.tets, self.weights = np.array(self.tets), np.array(self.weights)

    def simulate(self, E, nu):
        """The deformed mesh vertices (m) with material (E, nu)."""
        scene = json.loads(json.dumps(self.scene))
        scene["bodies"][0]["material"].update(E=E, nu=nu)
        _, tr = diffipc.simulate(scene)
        if tr["final_status"] != "CONVERGED":
            raise RuntimeError(f"E = {E:g}, nu = {nu:g}: {tr['final_status']} {tr['failure_message']}")
        return tr["positions"][-1]

    def carry(self, deformed):
        """The markers' deformed positions (m)."""
        return np.einsum("mi,mic->mc", self.weights, deformed[self.tets])

    def positions(self, log_mu, log_lambda):
        """The markers' simulated positions (m) for the design (log mu, log lambda)."""
        return self.carry(self.simulate(*young_poisson([log_mu, log_lambda])[0]))

    def objective(self, E, nu):
        """J = 1/2 sum of squared marker distances (m^2)."""
        return 0.5 * np.sum((self.carry(self.simulate(E, nu)) - self.measured) ** 2)
