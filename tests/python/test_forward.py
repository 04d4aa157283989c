import json

import numpy as np
import pytest

import diffipc
from diffipc.gradcheck import taylor_test, central_difference_check
from conftest import box_scene


def test_free_fall_from_dict_matches_closed_form():
    s = box_scene(dim=3, steps=8)
    s["gravity"] = [0.0, -9.81, 0.5]
    s["bodies"][0]["initial_velocity"] = [1.0, 0.0, 0.0]
    sim, tr = diffipc.simulate(s)
    assert tr["final_status"] == "CONVERGED"
    T = 8
    X = tr["positions"][0]
    assert tr["positions"].shape == (T + 1, X.shape[0], 3)
    assert tr["time"].shape == (T + 1,)
    assert tr["status"].shape == (T,) and (tr["status"] == 0).all()
    h, g, v0 = 0.01, np.array([0.0, -9.81, 0.5]), np.array([1.0, 0.0, 0.0])
    for n in range(1, T + 1):
        expected = X + n * h * v0 + h * h * g * n * (n + 1) / 2
        np.testing.assert_allclose(tr["positions"][n], expected, rtol=0, atol=1e-9 * np.abs(expected - X).max())


def test_scene_from_path(root):
    sc = diffipc.scene(root / "studies" / "102_bar_2d" / "scene.json")
    assert sc.dimension == 2
    assert sc.num_elements == 2 * 40 * 4
    assert sc.rest_positions.shape == (sc.num_vertices, 2)
    assert sc.elements.shape == (sc.num_elements, 3)


def test_simulate_a_dict_with_relative_mesh_paths(root):
    # Before: diffipc.simulate(dict) had no base_directory (a TypeError), so a dict scene with
    # a relative obstacle mesh could only run from the mesh's own directory; and
    # scene(path, base_directory=...) ignored the argument without a word.
    study = root / "studies" / "205_plate_on_sphere"
    s = json.loads((study / "scene.json").read_text())
    s["time"]["steps"] = 1
    s["bodies"][0]["mesh"]["box"]["cells"] = [4, 1, 4]
    del s["output"]
    with pytest.raises(ValueError, match="obstacles\\[0\\].mesh.file"):
        diffipc.simulate(s, base_directory=root)
    sim, tr = diffipc.simulate(s, base_directory=study)
    assert tr["final_status"] == "CONVERGED" and tr["positions"].shape[0] == 2
    with pytest.raises(TypeError, match="base_directory"):
        diffipc.scene(study / "scene.json", base_directory=study)


def test_step_by_step_and_trajectory():
    sim = diffipc.Simulator(diffipc.scene(box_scene(steps=2)))
    assert sim.step() == "CONVERGED"
    assert sim.steps_done == 1
    assert sim.step() == "CONVERGED"
    tr = sim.trajectory()
    assert tr["positions"].shape[0] == 3
    assert np.isfinite(tr["residual"]).all()


@pytest.mark.parametrize("mutate, field", [
    (lambda s: s["bodies"][0]["material"].__setitem__("nu", 0.7), "bodies[0].material.nu"),
    (lambda s: s["time"].__setitem__("dt", -1.0), "time.dt"),
    (lambda s: s.__setitem__("unknown", 1), "unknown"),
    (lambda s: s["bodies"][0]["material"].__setitem__("E", float("nan")), "NaN"),
])
def test_bad_dict_raises_value_error_naming_the_field(mutate, field):
    s = box_scene()
    mutate(s)
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        diffipc.scene(s)


def test_per_element_materials_change_the_result():
    s = box_scene(dim=2, steps=1, integrator="static", dt=1.0)
    s["gravity"] = [0.0, -9.81]
    s["dirichlet"] = [{"body": 0, "region": {"min": [-1, -1], "max": [0, 1]}, "displacement": [0, 0]}]
    base = diffipc.Simulator(diffipc.scene(s))
    tr0 = base.run()
    soft = diffipc.Simulator(diffipc.scene(s))
    ne = diffipc.scene(s).num_elements
    soft.set_element_materials(np.full(ne, 1e4), np.full(ne, 0.3))
    tr1 = soft.run()
    sag0 = tr0["positions"][-1][:, 1].min()
    sag1 = tr1["positions"][-1][:, 1].min()
    assert sag1 < sag0  # softer beam sags more
    with pytest.raises(ValueError):
        soft.set_element_materials(np.full(ne, 1e4), np.full(ne, 0.3))  # after the first step


@pytest.mark.parametrize("model", ["linear", "stvk", "neo_hookean", "stable_neo_hookean"])
@pytest.mark.parametrize("dim", [2, 3])
def test_element_derivatives_taylor(model, dim):
    rng = np.random.default_rng(42)
    rest = np.vstack([np.zeros(dim), np.eye(dim)]) * 0.1 + 0.01 * rng.standard_normal((dim + 1, dim))
    F = np.eye(dim) + 0.3 * rng.standard_normal((dim, dim))
    if np.linalg.det(F) <= 0.2:
        F = np.eye(dim) * 1.2
    deformed = rest @ F.T
    mu, lam = diffipc.lame_parameters(1e6, 0.3)
    x = deformed.ravel()

    def energy(v):
        return diffipc.element_energy(model, rest, v.reshape(dim + 1, dim), mu, lam)

    def grad(v):
        return diffipc.element_gradient(model, rest, v.reshape(dim + 1, dim), mu, lam)

    d = rng.standard_normal(x.size) * 0.01
    _, r1, _, rates1 = taylor_test(energy, x, grad(x), d, printer=None)
    assert min(rates1) > 1.9, rates1
    H = diffipc.element_hessian(model, rest, deformed, mu, lam)
    # Hessian: the gradient's Taylor remainder, component-wise through a random projection.
    w = rng.standard_normal(x.size)
    _, r1h, _, rates_h = taylor_test(lambda v: float(w @ grad(v)), x, H @ w, d, printer=None)
    if model == "linear":  # the gradient is affine: the remainder is round-off only
        assert max(r1h) < 1e-9 * abs(float(w @ H @ d))
    else:
        assert min(rates_h) > 1.9, rates_h
    assert central_difference_check(energy, x, grad(x), d, 1e-4) < 1e-6
    Hp = diffipc.element_hessian(model, rest, deformed, mu, lam, project_to_psd=True)
    assert np.linalg.eigvalsh(Hp).min() > -1e-8 * np.abs(Hp).max()


def test_taylor_test_detects_a_wrong_gradient():
    f = lambda v: float(np.sum(v ** 3))
    x = np.array([0.3, -0.2, 0.5])
    d = np.array([1.0, 0.5, -0.25])
    _, _, _, good = taylor_test(f, x, 3 * x ** 2, d, printer=None)
    _, _, _, bad = taylor_test(f, x, 3 * x ** 2 * 1.1, d, printer=None)
    assert min(good) > 1.9
    assert max(bad) < 1.5


def test_meshio_export():
    meshio = pytest.importorskip("meshio")
    sc = diffipc.scene(box_scene(dim=3))
    m = diffipc.to_meshio(sc)
    assert isinstance(m, meshio.Mesh)
    assert m.cells[0].data.shape == (sc.num_elements, 4)


def test_contact_trajectory_arrays(root):
    """The ring pile from a dict: contact arrays in the trajectory, bodies above the plane."""
    s = json.loads((root / "studies" / "204_ring_pile" / "scene.json").read_text())
    for b in s["bodies"]:
        b["mesh"]["annulus"].update({"segments": 16, "layers": 1})
    s["time"]["steps"] = 40
    sim, tr = diffipc.simulate(s)
    assert tr["final_status"] == "CONVERGED"
    assert tr["active_contacts"].shape == (40,) and tr["active_contacts"].max() > 0
    assert np.all(tr["kappa"] > 0)
    # Every body vertex above the ground plane (y = 0) at every step; the plane's
    # point is the one vertex with body index 3 (#bodies + 0).
    body = np.asarray(diffipc.scene(s).vertex_body)
    assert np.all(tr["positions"][:, body < 3, 1] > 0)


def test_set_initial_state_from_python():
    s = box_scene(dim=2, steps=2)
    sim = diffipc.Simulator(diffipc.scene(s))
    x0 = np.asarray(diffipc.scene(s).rest_positions)
    v0 = np.zeros_like(x0)
    v0[:, 0] = 0.25
    sim.set_initial_state(x0, v0)
    tr = sim.run()
    assert tr["final_status"] == "CONVERGED"
    np.testing.assert_allclose(tr["velocities"][0][:, 0], 0.25)
    with pytest.raises(Exception, match="initial_state"):
        sim.set_initial_state(x0, v0)  # after a step
