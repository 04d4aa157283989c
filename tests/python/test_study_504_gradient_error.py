"""Study 504 (studies/504_gradient_error): the gradient's error against the forward tolerance and
the time step on three adjoint examples, and the checkpointed adjoint's memory and cost."""
import math

import pytest

from conftest import ROOT, load_script

STUDY = ROOT / "studies" / "504_gradient_error"


study = load_script(STUDY / "run.py")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    out = tmp_path_factory.mktemp("s504")
    rows, checkpoints = study.main(["--results", str(out)])
    return rows, checkpoints, out


def test_gradient_converges_at_first_order_in_dt_where_the_motion_is_smooth(result):
    rows, _, _ = result
    for example in study.ORDER_EXPECTED:
        pts = sorted(((r["value"], r["error"]) for r in rows if r["example"] == example and r["knob"] == "dt"),
                     reverse=True)
        assert all(a[1] > b[1] for a, b in zip(pts, pts[1:])), (example, pts)
        assert 0.85 < study.observed_order(pts) < 1.3, (example, pts)


def test_gradient_error_falls_with_the_forward_tolerance(result):
    rows, _, _ = result
    for example in study.EXAMPLES:
        pts = sorted(((r["value"], r["error"]) for r in rows
                      if r["example"] == example and r["knob"] == "residual tolerance"), reverse=True)
        errors = [e for _, e in pts]
        # Tightening the forward tolerance never makes the gradient worse, and at 1e-10 it is within
        # 1e-7 of the 1e-12 reference.
        assert all(b <= a * (1 + 1e-6) for a, b in zip(errors, errors[1:])), (example, pts)
        assert errors[-1] < 1e-7, (example, pts)


def test_checkpointed_gradient_equals_the_full_memory_one_within_its_bound(result):
    _, checkpoints, out = result
    full, rest = checkpoints[0], checkpoints[1:]
    steps = full["steps"]
    for c in rest:
        s = int(str(c["stride"]).split()[0])
        assert c["difference"] < 1e-10, c
        assert c["peak_records"] <= math.ceil(steps / s) - 1 + s, c
        if s > 1:
            assert c["peak_records"] < steps and c["recomputed"] > 0, c
    assert (out / "gradient_error.png").exists() and "Command: `" in (out / "results.md").read_text()
