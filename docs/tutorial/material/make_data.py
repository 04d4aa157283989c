"""The tutorial's measurements (docs/tutorial_material_fit.md), made by the simulator: the
sample of problem.json with E = 2.5e5 Pa and nu = 0.42, nine markers on its face x = 0.02 m
(some at mesh vertices, some inside faces) carried to the deformed mesh, plus Gaussian noise of
0.02 mm per coordinate (seed 1); and the top plate's force at full compression with 1% noise.

    PYTHONPATH=build/python /usr/bin/python3 docs/tutorial/material/make_data.py

Writes markers.txt next to this file and prints the force, which problem_force.json holds.
Your own data come from your scanner and your testing machine instead.
"""
import json
import pathlib

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent
E, NU, SIGMA = 2.5e5, 0.42, 2e-5


def main():
    problem = json.loads((HERE / "problem.json").read_text())
    scene = problem["scene"]
    scene["bodies"][0]["material"].update(E=E, nu=NU)
    sc = diffipc.scene(scene)
    rest, tets = np.asarray(sc.rest_positions), np.asarray(sc.elements)
    _, tr = diffipc.simulate(scene)
    deformed = tr["positions"][-1]
    markers = np.array([[0.02, y, z] for z in (0.004, 0.01, 0.016) for y in (0.004, 0.01, 0.016)])
    rng = np.random.default_rng(1)
    lines = ["# rest x y z, measured x y z (m): the face x = 0.02 m, synthetic (make_data.py)"]
    for X in markers:
        a = rest[tets[:, 0]]
        inv = np.linalg.inv(np.stack([rest[tets[:, i]] - a for i in (1, 2, 3)], axis=2))
        b = np.einsum("eij,ej->ei", inv, X - a)
        w = np.concatenate([1 - b.sum(1, keepdims=True), b], axis=1)
        e = np.argmax(w.min(1))
        x = w[e] @ deformed[tets[e]] + rng.normal(0, SIGMA, 3)
        lines.append("%.4f %.4f %.4f  %.8f %.8f %.8f" % (*X, *x))
    (HERE / "markers.txt").write_text("\n".join(lines) + "\n")
    p = json.loads(json.dumps(problem))
    p["objective"] = {"type": "reaction_force", "dirichlet": 1, "axis": "z", "time": "final"}
    p.pop("optimizer")
    rf = diffipc.ReducedFunctional(p, base_directory=str(HERE))
    force = rf(rf.parameters_of(np.log([E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))])))
    print("top plate force: %.6f N, with 1%% noise: %.4f N" % (force, force * (1 + 0.01 * rng.normal())))


if __name__ == "__main__":
    main()
