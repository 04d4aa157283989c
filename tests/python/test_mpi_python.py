"""diffipc.ReducedFunctional(problem, comm=MPI.COMM_WORLD) under mpirun (issue 18): every rank gets the serial
evaluation's J, gradient and constraints bit for bit, and the serial evaluation's error (type and message) where
load cases fail, whatever the number of ranks. Skipped with a message without mpi4py or mpirun."""
import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import diffipc
from test_mpi_runs import ENV, MPIEXEC, rejecting_rings

#: Evaluated in this order by every rank: a good point, one where cases 1, 2 and 3 fail with different messages
#: (serial: case 1's), a good point again (the ranks are still in step after a failure), p with a NaN.
POINTS = {"start": [3.0, 0.5], "failing": [8.0, 0.5], "again": [2.5, 0.25], "nan": [float("nan"), 0.5]}

SCRIPT = textwrap.dedent("""
    import json, sys
    from mpi4py import MPI
    import diffipc
    from test_mpi_python import record

    problem, points, out = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), sys.argv[3]
    comm = MPI.COMM_WORLD
    J = diffipc.ReducedFunctional(problem, comm=comm)
    results = {name: record(J, p) for name, p in points.items()}
    results["distribution"] = J.distribution
    json.dump(results, open(f"{out}/rank{comm.Get_rank()}.json", "w"))
""")


def record(J, p):
    """The evaluation at p as hex bits, or its error's type and message."""
    try:
        e = J.evaluation(np.array(p), gradient=True, constraints=True)
    except Exception as error:
        return {"error": type(error).__name__, "message": str(error)}
    return {"value": e.value.hex(), "gradient": [g.hex() for g in e.gradient],
            "constraints": [g.hex() for g in e.constraint_values],
            "constraint_gradients": [g.hex() for g in e.constraint_gradients.ravel()]}


@pytest.fixture(scope="module")
def mpi_python():
    python = "/usr/bin/python3"
    probe = subprocess.run([python, "-c", "import mpi4py"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip("mpi4py is not installed (python3-mpi4py): the Python MPI runs are not tested")
    if not MPIEXEC:
        pytest.skip("no mpirun on the PATH (openmpi-bin) and DIFFIPC_MPIEXEC unset: the Python MPI runs are not tested")
    return python


def test_collective_evaluations_are_the_serial_ones(mpi_python, tmp_path):
    problem = rejecting_rings()
    problem["constraints"] = [{"name": "energy", "objective": {"type": "elastic_energy", "time": "final"},
                               "lower": 0.0, "case": 1}]
    J = diffipc.ReducedFunctional(problem)
    serial = {name: record(J, p) for name, p in POINTS.items()}
    # The points do what they are there for.
    assert "value" in serial["start"] and "value" in serial["again"]
    assert serial["failing"]["error"] == "AdjointError"
    assert "after 30 Newton iterations" in serial["failing"]["message"]  # case 1's (case 2 stops after 32)
    assert serial["nan"]["error"] == "InputError" and "parameters[0]" in serial["nan"]["message"]
    (tmp_path / "problem.json").write_text(json.dumps(problem))
    (tmp_path / "points.json").write_text(json.dumps(POINTS))
    (tmp_path / "script.py").write_text(SCRIPT)
    env = dict(ENV, PYTHONPATH=os.pathsep.join(sys.path))
    for ranks in (1, 2, 3, 4):
        out = tmp_path / f"ranks{ranks}"
        out.mkdir()
        result = subprocess.run([MPIEXEC, "-n", str(ranks), mpi_python, str(tmp_path / "script.py"),
                                 str(tmp_path / "problem.json"), str(tmp_path / "points.json"), str(out)],
                                capture_output=True, text=True, env=env, timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
        for rank in range(ranks):
            got = json.loads((out / f"rank{rank}.json").read_text())
            distribution = got.pop("distribution")
            assert got == serial, (ranks, rank)
            assert distribution["ranks"] == ranks and distribution["rank"] == rank
            assert distribution["evaluations"] == 3  # the NaN point is refused before any case runs
        # Rank 0 saw every case of the three evaluations; the last assignment is the longest-processing-time
        # rule on the seconds each case took the evaluation before (checked here by a rule of its own).
        distribution = json.loads((out / "rank0.json").read_text())["distribution"]
        assert sum(distribution["cases"]) == 3 * 4
        costs = distribution["assignment_costs"]
        assert len(costs) == 4 and all(c > 0 for c in costs)
        assert distribution["assignment"] == longest_first(costs, ranks)


def longest_first(costs, ranks):
    """Cases by decreasing cost (ties: lower case first), each to the least loaded rank (ties: lower rank)."""
    load, owner = [0.0] * ranks, [0] * len(costs)
    for c in sorted(range(len(costs)), key=lambda c: (-costs[c], c)):
        owner[c] = min(range(ranks), key=lambda r: (load[r], r))
        load[owner[c]] += costs[c]
    return owner


def test_a_communicator_that_is_not_one_is_refused():
    with pytest.raises(TypeError, match="mpi4py communicator"):
        diffipc.ReducedFunctional(rejecting_rings(), comm=object())
