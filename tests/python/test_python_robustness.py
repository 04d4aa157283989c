"""The Python module under misuse: wrong shapes, Ctrl-C, two threads on one Simulator.

Before these fixes: energy() of a wrongly shaped array segfaulted or returned a number,
run() could not be interrupted, and a second thread using a Simulator during run() crashed.
"""
import _thread
import threading
import time

import numpy as np
import pytest

import diffipc
from conftest import box_scene


def long_simulator(steps=20000):
    s = box_scene(dim=2, steps=steps)
    s["bodies"][0]["mesh"]["box"]["cells"] = [20, 8]
    s["gravity"] = [0.0, -9.81]
    s["time"]["dt"] = 1e-3
    return diffipc.Simulator(diffipc.scene(s))


def test_energy_and_initial_state_check_shapes():
    sim = diffipc.Simulator(diffipc.scene(box_scene(dim=3, steps=1)))
    x = sim.positions
    assert np.isfinite(sim.energy(x))
    for bad in (x.T, x[:-1], x.ravel(), np.zeros((x.shape[0], 2)), np.full_like(x, np.nan)):
        with pytest.raises(ValueError, match="positions"):
            sim.energy(bad)
    with pytest.raises(ValueError, match="velocities"):
        sim.set_initial_state(x, np.zeros((x.shape[0], 2)))


def test_keyboard_interrupt_stops_run_after_a_step():
    sim = long_simulator()
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        sim.run()
    timer.join()
    done = sim.steps_done
    assert 0 < done < 20000
    tr = sim.trajectory()
    assert tr["positions"].shape[0] == done + 1
    assert np.isfinite(tr["positions"]).all()
    assert sim.step() == "CONVERGED"  # the simulator is still usable
    assert sim.steps_done == done + 1


def test_a_second_thread_is_refused_while_run_is_going():
    sim = long_simulator(steps=3000)
    errors = []
    started = threading.Event()

    def runner():
        started.set()
        try:
            sim.run()
        except Exception as e:  # pragma: no cover - reported below
            errors.append(e)

    worker = threading.Thread(target=runner)
    worker.start()
    started.wait()
    refused = 0
    deadline = time.time() + 30
    while worker.is_alive() and time.time() < deadline:
        try:
            sim.step()
        except RuntimeError as e:
            assert "another thread" in str(e)
            refused += 1
        time.sleep(0.01)
    worker.join()
    assert not errors
    assert refused > 0
    assert sim.steps_done >= 3000


def test_an_inverted_initial_state_fails_with_its_reason():
    # No contact: before, the failure said INVALID_INITIAL_STATE and nothing about why.
    sim = diffipc.Simulator(diffipc.scene(box_scene(dim=2, steps=2)))
    x = sim.positions.copy()
    x[:, 0] *= -1.0  # mirrored: every element inverted
    sim.set_initial_state(x, np.zeros_like(x))
    assert sim.step() == "INVALID_INITIAL_STATE"
    message = sim.trajectory()["failure_message"]
    assert "INVALID_INITIAL_STATE" in message and "inverted" in message, message


def test_a_file_with_bytes_that_are_not_utf8_gives_a_message(root, tmp_path):
    # Before: ValueError("") (found by the fuzz test): the parser's message quoted the invalid
    # byte, and the text could not become a Python str. The CLI printed the raw byte and
    # nlohmann's "[json.exception.parse_error.101]" tag.
    text = (root / "studies" / "302_bar_youngs_markers" / "problem.json").read_bytes()
    at = text.index(b'"objective"') + 1
    bad = tmp_path / "problem.json"
    bad.write_bytes(text[:at] + b"\xc3" + text[at:])  # a key with an ill-formed UTF-8 byte
    with pytest.raises(ValueError) as info:
        diffipc.ReducedFunctional(str(bad))
    message = str(info.value)
    assert message.startswith(str(bad) + ": invalid JSON: ") and "?" in message, message
    assert "json.exception" not in message
    with pytest.raises(ValueError, match="invalid JSON"):
        diffipc.scene(str(bad))
