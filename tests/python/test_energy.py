"""diffipc.energy (python/diffipc/energy.py), the studies' independent energy measure: its elastic
energy equals the solver's element energies (diffipc.element_energy) on a deformed state, and a
body falling freely under Newmark, which integrates a constant acceleration exactly, keeps its
mechanical energy to round-off while implicit Euler loses some."""
import json
import subprocess

import h5py
import numpy as np
import pytest

import diffipc
import diffipc.energy
from conftest import box_scene


def run(cli, tmp_path, scene, name):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / name
    r = subprocess.run([cli, "simulate", str(path), "-o", str(out), "-q"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return h5py.File(out / "trajectory.h5", "r")


@pytest.mark.parametrize("model", ["neo_hookean", "linear"])
def test_elastic_energy_matches_the_solvers_elements(cli, tmp_path, model):
    s = box_scene(dim=2, model=model, steps=3)
    s["bodies"][0]["initial_velocity"] = [0.0, 0.0]
    s["dirichlet"] = [{"body": "b", "region": {"min": [-1, -1], "max": [0, 1]}, "displacement": [0, 0]},
                      {"body": "b", "region": {"min": [0.5, -1], "max": [1, 1]}, "displacement": ["0.5*t", "0.3*t"]}]
    with run(cli, tmp_path, s, model) as f:
        X, tris, x = f["mesh/rest_positions"][:], f["mesh/elements"][:], f["positions"][-1]
        v = f["velocities"][-1]
        total = diffipc.energy.mechanical_energy(f, s)[-1]
    m = s["bodies"][0]["material"]
    mu, lam = m["E"] / (2 * (1 + m["nu"])), m["E"] * m["nu"] / ((1 + m["nu"]) * (1 - 2 * m["nu"]))
    elastic = sum(diffipc.element_energy(model, X[t], x[t], mu, lam) for t in tris)
    area = np.array([0.5 * abs(np.linalg.det(np.array([X[t[1]] - X[t[0]], X[t[2]] - X[t[0]]]))) for t in tris])
    mass = np.zeros(len(X))
    for k in range(3):
        np.add.at(mass, tris[:, k], m["density"] * area / 3)
    kinetic = 0.5 * (mass * (v ** 2).sum(axis=1)).sum()
    assert elastic > 0
    assert total == pytest.approx(elastic + kinetic, rel=1e-12)


def test_free_fall_energy_is_kept_by_newmark_and_lost_by_implicit_euler(cli, tmp_path):
    drift = {}
    for integrator in ("newmark", "implicit_euler"):
        s = box_scene(dim=2, steps=20, integrator=integrator, dt=0.01)
        s["gravity"] = [0.0, -9.81]
        s["bodies"][0]["initial_velocity"] = [0.3, 1.0]
        with run(cli, tmp_path, s, integrator) as f:
            e = diffipc.energy.mechanical_energy(f, s)
        drift[integrator] = abs(e[-1] - e[0]) / abs(e[0])
    assert drift["newmark"] < 1e-9, drift
    assert drift["implicit_euler"] > 1e-3, drift


def test_newmark_keeps_the_energy_of_a_vibrating_linear_cantilever(cli, tmp_path):
    # Newmark's average-acceleration rule conserves the energy of a linear system exactly: the
    # energy gains of study 502's bouncing box come from the barrier's nonlinearity, not the scheme.
    s = {"dimension": 2,
         "bodies": [{"name": "b", "mesh": {"box": {"min": [0, 0], "max": [1, 0.1], "cells": [20, 2]}},
                     "material": {"model": "linear", "E": 1e5, "nu": 0.3, "density": 1000},
                     "initial_velocity": [0, 0.5]}],
         "dirichlet": [{"body": "b", "region": {"min": [-1, -1], "max": [0, 1]}, "displacement": [0, 0]}],
         "time": {"integrator": "newmark", "dt": 0.002, "steps": 500}, "solver": {"residual_tolerance": 1e-11}}
    with run(cli, tmp_path, s, "vibrating") as f:
        e = diffipc.energy.mechanical_energy(f, s)
    assert np.ptp(e) < 1e-10 * e[0], (e.min(), e.max())
