"""gradcheck at a kink of J'' (docs/problem_format.md, "gradcheck"): an exterior penalty of a
constraint that is active at the start is only C^1, so a central difference straddling it is off by
O(h) although the adjoint is right. The shipped penalty problems must pass; a wrong gradient,
at a kink or not, must still fail; and diffipc.gradcheck.check_direction (the CLI's C++ check, bound)
gives the CLI's numbers and verdict on the CLI's own direction."""
import math
import os
import re
import subprocess

import numpy as np
import pytest

from conftest import ROOT
from diffipc.gradcheck import check_direction, richardson_one_sided

PENALTY_PROBLEMS = [
    "studies/401_cantilever_area/problem_penalty.json",
    "studies/405_bracket_contact/problem_penalty.json",
    "studies/405_bracket_contact/problem_penalty_1e12.json",
]


def gradcheck(cli, problem, perturb=None, *args):
    env = dict(os.environ)
    env.pop("DIFFIPC_GRADCHECK_PERTURB", None)
    if perturb is not None:
        env["DIFFIPC_GRADCHECK_PERTURB"] = str(perturb)
    return subprocess.run([cli, "gradcheck", str(ROOT / problem), *args], capture_output=True, text=True,
                          timeout=600, env=env)


@pytest.mark.parametrize("problem", PENALTY_PROBLEMS, ids=lambda p: p.split("/")[1] + "_" + p.split("/")[2])
def test_penalty_problem_at_its_bound_passes_at_a_kink(cli, problem):
    # Before: exit 4, the central difference 1e-4 relative off while the Taylor rate was 2.00.
    r = gradcheck(cli, problem)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "gradcheck passed" in r.stdout
    assert "PASS at a kink" in r.stdout  # said as such, not as a plain pass
    assert "one-sided differences" in r.stdout


# Every shipped problem file passes (studies/*/problem.json: tests/python/test_gradcheck.py); these are
# the other variants of the studies and the tutorials' problems, each under a second here.
SHIPPED = sorted(str(p.relative_to(ROOT)) for p in
                 [*ROOT.glob("studies/*/problem_*.json"), *ROOT.glob("docs/tutorial/**/problem*.json")]
                 if str(p.relative_to(ROOT)) not in PENALTY_PROBLEMS)


def test_the_shipped_problem_files_are_found():
    assert len(SHIPPED) >= 10 and "docs/tutorial/problem.json" in SHIPPED


@pytest.mark.parametrize("problem", SHIPPED)
def test_every_other_shipped_problem_passes_gradcheck(cli, problem):
    r = gradcheck(cli, problem)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "gradcheck passed" in r.stdout


@pytest.mark.parametrize("problem,error", [
    ("studies/401_cantilever_area/problem_penalty.json", 1e-3),  # at the kink
    ("studies/401_cantilever_area/problem_penalty.json", 1e-4),
    ("studies/301_beam_shape_stress/problem.json", 1e-4),  # smooth
])
def test_a_wrong_gradient_still_fails(cli, problem, error):
    r = gradcheck(cli, problem, error, "--directions", "1")
    assert r.returncode == 4, r.stdout + r.stderr
    assert "gradcheck FAILED" in r.stdout and "PASS" not in r.stdout
    assert f"multiplied by 1 + {error:g}" in r.stdout


def test_a_bad_perturbation_names_the_variable(cli):
    r = gradcheck(cli, "studies/301_beam_shape_stress/problem.json", "1e-4x")
    assert r.returncode == 1 and "DIFFIPC_GRADCHECK_PERTURB" in r.stderr, r.stderr


def smooth(x):
    return 2 * math.exp(0.3 * x[0]) + math.sin(x[0])


SLOPE = 1.6  # smooth'(0)


def penalized(x):
    return smooth(x) + 50 * max(0.0, x[0]) ** 2


@pytest.mark.parametrize("f,slope,verdict", [
    (smooth, SLOPE, "PASS"),
    (smooth, SLOPE * (1 + 1e-3), "FAIL"),
    (penalized, SLOPE, "PASS (kink)"),
    (penalized, SLOPE * (1 + 1e-4), "FAIL"),
    (lambda x: smooth(x) + 3 * abs(x[0]), SLOPE, "NOT DIFFERENTIABLE"),
    (lambda x: 4.0, 0.0, "INCONCLUSIVE"),
])
def test_python_check_direction_verdicts(f, slope, verdict):
    r = check_direction(f, [0.0], [slope], [1.0], step=0.1, halvings=4)
    assert r["verdict"] == verdict, r
    assert r["passed"] == verdict.startswith("PASS")
    if verdict == "PASS (kink)":
        assert r["central_error"] > 1e-2 and r["forward_error"] < 1e-8 and r["backward_error"] < 1e-8


def test_richardson_removes_first_and_second_order_terms():
    d = [1.5 + 7 * h - 40 * h * h for h in (0.1, 0.05, 0.025, 0.0125)]
    assert richardson_one_sided(d) == pytest.approx(1.5, abs=1e-13)
    with pytest.raises(ValueError):
        richardson_one_sided([1, 2])


def mt19937_uniform(seed, count):
    """``count`` draws of std::uniform_real_distribution<double>(-1, 1) over std::mt19937(seed), as
    libstdc++ makes them (generate_canonical: two 32-bit outputs g1 + g2 2^32, over 2^64): the
    directions of `diffipc gradcheck` (cli/gradcheck.cpp) before their scales."""
    key = np.empty(624, dtype=np.uint32)
    key[0] = seed
    for i in range(1, 624):  # std::mt19937's seeding (numpy's legacy seeding is the same)
        prev = int(key[i - 1])
        key[i] = (1812433253 * (prev ^ (prev >> 30)) + i) & 0xFFFFFFFF
    bits = np.random.MT19937()
    bits.state = {"bit_generator": "MT19937", "state": {"key": key, "pos": 624}}
    raw = bits.random_raw(2 * count)
    out = []
    for k in range(count):
        u = (float(raw[2 * k]) + float(raw[2 * k + 1]) * 4294967296.0) / 18446744073709551616.0
        out.append(min(u, math.nextafter(1.0, 0.0)) * 2.0 - 1.0)
    return np.array(out)


def test_python_check_agrees_with_the_cli_on_401_penalty(cli):
    # The CLI's first direction, redrawn here: the same slope, differences and verdict, from the
    # output of `diffipc gradcheck` itself.
    import diffipc

    r = gradcheck(cli, PENALTY_PROBLEMS[0], None, "--directions", "1")
    assert r.returncode == 0, r.stdout + r.stderr
    number = r"([-+0-9.e]+)"
    head = re.search(rf"direction 1: dJ.dp adjoint {number}, central difference {number}", r.stdout)
    sides = re.search(rf"one-sided differences .*: forward {number} .*backward {number} ", r.stdout)
    assert head and sides and "PASS at a kink" in r.stdout, r.stdout
    cli_slope, cli_central = float(head[1]), float(head[2])
    cli_forward, cli_backward = float(sides[1]), float(sides[2])

    J = diffipc.ReducedFunctional(str(ROOT / PENALTY_PROBLEMS[0]))
    p = J.parameters_of(J.design_initial)  # where the CLI checks
    J0, g = J.value_and_gradient(p)
    settings = J.check_settings
    d = mt19937_uniform(settings["seed"], J.size) * J.scales
    assert float(g @ d) == pytest.approx(cli_slope, rel=1e-9), "not the CLI's direction"
    c = check_direction(J, p, g, d, step=settings["step"], halvings=settings["halvings"], f0=J0)
    assert c["verdict"] == "PASS (kink)", c
    assert c["central"] == pytest.approx(cli_central, rel=1e-7)
    assert c["forward"] == pytest.approx(cli_forward, rel=1e-7)
    assert c["backward"] == pytest.approx(cli_backward, rel=1e-7)
