"""A problem's load cases evaluated apart (ReducedFunctional.evaluation_of_case) and added in case order
(ReducedFunctional.sum_shares) give evaluation()'s bits, whatever order computed them: what a distributed
evaluation over ranks stands on (shape_opt/reduced_functional.hpp, evaluate_case and add_share)."""
import copy
import json

import numpy as np
import pytest

import diffipc
from conftest import ROOT


def three_walls():
    """Study 304's ring thrown at a wall, three load cases (the wall at three distances, three weights) that
    share the two initial-velocity parameters, and a constraint on the second case."""
    case = json.loads((ROOT / "studies" / "304_ring_wall_velocity" / "problem.json").read_text())
    scenes = []
    for weight, wall in ((1.0, 0.11), (0.5, 0.115), (0.25, 0.12)):
        scene = copy.deepcopy(case["scene"])
        scene["obstacles"][0]["plane"]["point"] = [wall, 0]
        scenes.append({"scene": scene, "objective": case["objective"], "weight": weight})
    return {"scenes": scenes, "parameters": case["parameters"],
            "constraints": [{"name": "energy", "objective": {"type": "elastic_energy", "time": "final"},
                             "lower": 0.0, "case": 1}]}


def test_shares_in_case_order_are_the_evaluation():
    J = diffipc.ReducedFunctional(three_walls())
    assert J.load_cases == 3
    p = np.array([2.9, 0.6])
    whole = J.evaluation(p, gradient=True, constraints=True)
    # Computed out of order (as ranks would), added in case order.
    shares = {c: J.evaluation_of_case(c, p, gradient=True, constraints=True) for c in (2, 0, 1)}
    total = diffipc.ReducedFunctional.sum_shares([shares[c] for c in range(3)])
    assert total.value == whole.value
    np.testing.assert_array_equal(total.gradient, whole.gradient)
    np.testing.assert_array_equal(total.constraint_values, whole.constraint_values)
    np.testing.assert_array_equal(total.constraint_gradients, whole.constraint_gradients)
    # The cases differ (else the test could not tell their shares apart), and the constraint's row is
    # the second case's alone.
    values = [shares[c].value for c in range(3)]
    assert len(set(values)) == 3 and all(v > 0 for v in values)
    assert all(np.any(shares[c].gradient != shares[0].gradient) for c in (1, 2))
    assert shares[1].constraint_values[0] > 0
    assert shares[0].constraint_values[0] == 0 and shares[2].constraint_values[0] == 0
    assert not shares[0].constraint_gradients.any() and not shares[2].constraint_gradients.any()
    # A share is its case's weighted objective: the second case alone, weight 1, is twice its share.
    alone = three_walls()
    alone["scenes"] = [dict(alone["scenes"][1], weight=1.0)]
    alone["constraints"][0]["case"] = 0
    single = diffipc.ReducedFunctional(alone).evaluation(p, gradient=True, constraints=True)
    assert shares[1].value == pytest.approx(0.5 * single.value, rel=1e-14)
    np.testing.assert_allclose(shares[1].gradient, 0.5 * single.gradient, rtol=1e-13)
    # Without the gradient: values only, the same sum.
    values_only = [J.evaluation_of_case(c, p, gradient=False) for c in range(3)]
    assert diffipc.ReducedFunctional.sum_shares(values_only).value == J.evaluation(p, gradient=False).value


def test_a_case_out_of_range_or_a_bad_p_is_refused():
    J = diffipc.ReducedFunctional(three_walls())
    with pytest.raises(IndexError, match="load case 3 of 3"):
        J.evaluation_of_case(3, np.array([2.9, 0.6]))
    with pytest.raises(ValueError, match="parameters"):
        J.evaluation_of_case(0, np.array([2.9, np.nan]))
