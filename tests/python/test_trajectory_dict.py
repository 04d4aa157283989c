"""The trajectory dict of a periodic cell (docs/python.md): `macro_gradient` and `macro_stress`,
[T, d, d] per step, the same numbers as trajectory.h5's datasets of the same run; absent for a
scene that is not periodic, as in trajectory.h5."""
import numpy as np
import pytest

import diffipc
from conftest import box_scene


def periodic_cell():
    # A cell compressed by 20% along x over 4 static steps, G_yy free, the shear held.
    return {"dimension": 2,
            "bodies": [{"name": "cell", "mesh": {"box": {"min": [0, 0], "max": [1, 1], "cells": [4, 4]}},
                        "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
            "periodic": {"gradient": [["-0.2*t", 0], [0, None]]},
            "time": {"integrator": "static", "dt": 0.25, "steps": 4},
            "solver": {"residual_tolerance": 1e-10}}


def test_a_periodic_cells_dict_holds_its_macro_quantities_as_the_hdf5_file(tmp_path):
    h5py = pytest.importorskip("h5py")
    sim, tr = diffipc.simulate(periodic_cell())
    assert tr["final_status"] == "CONVERGED"
    G, P = tr["macro_gradient"], tr["macro_stress"]
    assert G.shape == P.shape == (4, 2, 2) and G.dtype == P.dtype == np.float64
    # the prescribed entries, row-major [k, i, j] = G_ij after step k + 1
    np.testing.assert_allclose(G[:, 0, 0], -0.05 * np.arange(1, 5), rtol=0, atol=1e-15)
    assert np.all(G[:, 0, 1] == 0) and np.all(G[:, 1, 0] == 0)
    assert G[-1, 1, 1] > 0.01  # the free lateral component expands
    assert np.all(P[:, 0, 0] < 0)  # compressive
    assert np.abs(P[:, 1, 1]).max() < 1e-6 * np.abs(P[:, 0, 0]).max()  # free: no stress along it
    sim.write_hdf5(str(tmp_path / "trajectory.h5"))
    with h5py.File(tmp_path / "trajectory.h5") as f:
        np.testing.assert_array_equal(G, f["macro_gradient"][:])
        np.testing.assert_array_equal(P, f["macro_stress"][:])
    # trajectory() gives the same as run()
    again = sim.trajectory()
    np.testing.assert_array_equal(again["macro_gradient"], G)
    np.testing.assert_array_equal(again["macro_stress"], P)


def test_a_scene_that_is_not_periodic_has_no_macro_keys(tmp_path):
    h5py = pytest.importorskip("h5py")
    sim, tr = diffipc.simulate(box_scene(dim=2, steps=2))
    assert "macro_gradient" not in tr and "macro_stress" not in tr
    sim.write_hdf5(str(tmp_path / "trajectory.h5"))
    with h5py.File(tmp_path / "trajectory.h5") as f:
        assert "macro_gradient" not in f and "macro_stress" not in f
