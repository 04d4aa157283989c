"""`mpirun -n N diffipc optimize|gradcheck` (issue 18): the load cases spread over N ranks give the serial
run's J, gradient and optimizer trajectory bit for bit (rank 0 adds the cases' shares in case order, as the
serial run does), a failing case is the serial run's rejection, and a killed rank ends the job with a message.

Runs with OpenMPI's mpirun (DIFFIPC_MPIEXEC, else the one on the PATH), oversubscribed; skipped with a message
when diffipc was built without MPI. The serial runs are the same binary without mpirun."""
import copy
import json
import os
import shutil
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from conftest import ROOT

MPIEXEC = os.environ.get("DIFFIPC_MPIEXEC") or shutil.which("mpirun")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", DIFFIPC_THREADS="1")
RANKS = (1, 2, 3, 4)


@pytest.fixture(scope="module")
def mpi_cli():
    path = os.environ.get("DIFFIPC_CLI", str(ROOT / "build" / "cli" / "diffipc"))
    if not os.path.exists(path):
        pytest.fail(f"diffipc CLI not found at {path}; build first or set DIFFIPC_CLI")
    info = subprocess.run([path, "info"], capture_output=True, text=True, env=ENV).stdout
    if "mpi: built with MPI" not in info:
        pytest.skip("diffipc was built without MPI (DIFFIPC_MPI=OFF or no libopenmpi-dev): the MPI runs are not tested")
    if not MPIEXEC:
        pytest.skip("no mpirun on the PATH (openmpi-bin) and DIFFIPC_MPIEXEC unset: the MPI runs are not tested")
    return path


def run(cli, args, ranks=0, timeout=300):
    """diffipc ARGS alone (ranks 0) or under mpirun -n RANKS."""
    command = ([MPIEXEC, "-n", str(ranks)] if ranks else []) + [cli] + args
    return subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=timeout)


def ring_walls(cases=4, algorithm="ipopt", iterations=3):
    """Study 304's ring thrown at a wall: load cases with the wall at different distances and different weights,
    the two initial-velocity parameters shared, a constraint on case 1 (Ipopt: a true constraint)."""
    base = json.loads((ROOT / "studies" / "304_ring_wall_velocity" / "problem.json").read_text())
    scenes = []
    for c in range(cases):
        scene = copy.deepcopy(base["scene"])
        scene["obstacles"][0]["plane"]["point"] = [0.11 + 0.005 * c, 0]
        scenes.append({"scene": scene, "objective": base["objective"], "weight": 1.0 / (1 + c)})
    return {"scenes": scenes, "parameters": base["parameters"],
            "constraints": [{"name": "energy", "objective": {"type": "elastic_energy", "time": "final"},
                             "lower": 0.0, "case": 1}],
            "optimizer": {"algorithm": algorithm, "max_iterations": iterations},
            "gradcheck": {"directions": 1, "seed": 3, "step": 0.01, "halvings": 2}}


def hammered_bars(iterations=3):
    """Study 404's bar (Young's modulus per element through a filter and exp, 160 parameters) hit by the
    hammer at three speeds and for three lengths of time (cases of different cost), L-BFGS-B."""
    base = json.loads((ROOT / "studies" / "404_bar_modulus_field" / "problem.json").read_text())
    scenes = []
    for c, (speed, steps) in enumerate(((1.0, 50), (0.8, 30), (1.2, 40))):
        scene = copy.deepcopy(base["scene"])
        scene["obstacles"][0]["plane"]["motion"] = [f"{speed} * (t < 0.05 ? t : 0.1 - t)", "0"]
        scene["time"]["steps"] = steps
        objective = copy.deepcopy(base["objective"])
        keep = [k for k, s in enumerate(objective["steps"]) if s <= steps]
        objective["steps"] = [objective["steps"][k] for k in keep]
        objective["targets"] = [objective["targets"][k] for k in keep]
        scenes.append({"scene": scene, "objective": objective, "weight": [1.0, 0.5, 0.7][c]})
    return {"scenes": scenes, "parameters": base["parameters"],
            "optimizer": {"algorithm": "lbfgsb", "max_iterations": iterations},
            "gradcheck": {"directions": 1, "seed": 5, "step": 0.1, "halvings": 2}}


def rejecting_rings():
    """ring_walls pushed to bounce back far (L-BFGS-B, no constraint), with Newton's iterations per step capped
    at 30 in case 1 and 32 in case 2 (so that their failures read differently): the start needs at most 20 per
    step in every case and the accepted iterates at most 17, while the line search's first trial point (about
    2.0 m/s) needs 45 in case 2, so that trial point fails and is rejected, and the run goes on (a failing case
    midway, as in serial). The margins of 10 iterations and more on either side keep round-off (another BLAS
    kernel, another element kernel) from deciding it."""
    problem = ring_walls(algorithm="lbfgsb", iterations=15)
    del problem["constraints"]
    for case in problem["scenes"]:
        case["objective"] = dict(case["objective"], targets=[[[-0.1, 0.03], [-0.3, 0.03]]])
    problem["scenes"][1]["scene"]["solver"]["max_iterations"] = 30
    problem["scenes"][2]["scene"]["solver"]["max_iterations"] = 32
    return problem


PROBLEMS = {"ring_walls": ring_walls, "hammered_bars": hammered_bars, "rejecting_rings": rejecting_rings}


def history(directory):
    """Every dataset of history.h5 but the times, and summary.json's outcome."""
    with h5py.File(directory / "history.h5", "r", swmr=True) as f:
        data = {k: f[k][()] for k in f.keys() if not k.endswith("seconds")}
    summary = json.loads((directory / "summary.json").read_text())
    keep = ("stop_reason", "message", "iterations", "evaluations", "rejected", "initial_J", "final_J",
            "max_violation", "design", "last_rejection")
    return data, {k: summary.get(k) for k in keep}


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("name", sorted(PROBLEMS))
def test_optimize_over_ranks_is_the_serial_run_bit_for_bit(mpi_cli, tmp_path, name):
    problem = tmp_path / f"{name}.json"
    problem.write_text(json.dumps(PROBLEMS[name]()))
    serial = run(mpi_cli, ["optimize", str(problem), "-o", str(tmp_path / "serial"), "-q"])
    assert serial.returncode == 0, serial.stderr
    data, outcome = history(tmp_path / "serial")
    assert len(data["J"]) >= 3 and outcome["iterations"] >= 2  # the optimizer moved: a trajectory to compare
    assert data["J"][-1] < data["J"][0]
    if name == "rejecting_rings":  # trial points rejected midway, and iterations after them
        assert outcome["rejected"] >= 1 and "NEWTON_EXHAUSTED" in outcome["last_rejection"]
        assert outcome["iterations"] >= 4 and outcome["stop_reason"] != "invalid_start"
    for ranks in RANKS:
        out = tmp_path / f"ranks{ranks}"
        result = run(mpi_cli, ["optimize", str(problem), "-o", str(out), "-q"], ranks)
        assert result.returncode == 0, result.stderr
        other, other_outcome = history(out)
        assert other_outcome == outcome, ranks
        assert sorted(other) == sorted(data)
        for key in data:
            assert same_bits(other[key], data[key]), (ranks, key)
        processes = json.loads((out / "summary.json").read_text())["processes"]
        assert processes["ranks"] == ranks
        cases = len(json.loads(problem.read_text())["scenes"])
        evaluated = [r["load_cases_evaluated"] for r in processes["per_rank"]]
        assert sum(evaluated) == cases * processes["evaluations"]
        # Every rank evaluated cases when there are as many cases as ranks or more.
        assert all(e > 0 for e in evaluated) == (ranks <= cases)


def gradcheck_lines(text):
    """gradcheck's report without its times."""
    return [line.split("   forward")[0] for line in text.splitlines()]


@pytest.mark.parametrize("name", ["hammered_bars", "ring_walls"])
def test_gradcheck_over_ranks_is_the_serial_one(mpi_cli, tmp_path, name):
    problem = tmp_path / f"{name}.json"
    problem.write_text(json.dumps(PROBLEMS[name]()))
    serial = run(mpi_cli, ["gradcheck", str(problem)])
    assert serial.returncode == 0, serial.stdout + serial.stderr
    assert "gradcheck passed" in serial.stdout
    for ranks in RANKS:
        result = run(mpi_cli, ["gradcheck", str(problem)], ranks)
        assert result.returncode == 0, result.stdout + result.stderr
        assert gradcheck_lines(result.stdout) == gradcheck_lines(serial.stdout), ranks


def failing_cases():
    """Cases 1 and 2 of four cannot take their first step (Newton gets 1 and 2 iterations): they fail
    with different messages, and serial runs report case 1's, the first."""
    problem = ring_walls()
    for c, iterations in ((1, 1), (2, 2)):
        problem["scenes"][c]["scene"]["solver"]["max_iterations"] = iterations
    return problem


def own_lines(stderr):
    """diffipc's lines of stderr (mpirun and its libraries may add lines of their own)."""
    return [line for line in stderr.splitlines() if line.startswith("diffipc")]


def test_a_failing_case_is_reported_as_in_the_serial_run(mpi_cli, tmp_path):
    problem = tmp_path / "failing.json"
    problem.write_text(json.dumps(failing_cases()))
    serial_gradcheck = run(mpi_cli, ["gradcheck", str(problem)])
    assert serial_gradcheck.returncode == 2, serial_gradcheck.stdout + serial_gradcheck.stderr
    serial = run(mpi_cli, ["optimize", str(problem), "-o", str(tmp_path / "serial"), "-q"])
    assert serial.returncode == 2
    # Case 1's failure (1 Newton iteration), not case 2's.
    assert "NEWTON_EXHAUSTED after 1 Newton iterations" in serial.stderr, serial.stderr
    summary = json.loads((tmp_path / "serial" / "summary.json").read_text())
    for ranks in RANKS:
        result = run(mpi_cli, ["gradcheck", str(problem)], ranks)
        assert (result.returncode, own_lines(result.stderr)) == (2, own_lines(serial_gradcheck.stderr)), ranks
        out = tmp_path / f"ranks{ranks}"
        result = run(mpi_cli, ["optimize", str(problem), "-o", str(out), "-q"], ranks)
        assert result.returncode == 2
        assert own_lines(result.stderr) == own_lines(serial.stderr)
        other = json.loads((out / "summary.json").read_text())
        for key in ("stop_reason", "message", "last_rejection", "rejected"):
            assert other.get(key) == summary.get(key), (ranks, key)


def rank_process(rank, marker):
    """The pid of the diffipc process of `rank` whose command line names `marker` (from /proc, not from diffipc)."""
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            command = open(f"/proc/{entry}/cmdline", "rb").read().split(b"\0")
            environment = open(f"/proc/{entry}/environ", "rb").read().split(b"\0")
        except OSError:
            continue
        if command and command[0].endswith(b"diffipc") and marker.encode() in command and \
                f"OMPI_COMM_WORLD_RANK={rank}".encode() in environment:
            return int(entry)
    return None


def start_optimize(cli, problem, ranks, tmp_path):
    """mpirun -n RANKS diffipc optimize PROBLEM in the background: the job and its output folder."""
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(problem))
    out = tmp_path / "run"
    job = subprocess.Popen([MPIEXEC, "-n", str(ranks), cli, "optimize", str(path), "-o", str(out), "-q"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    return job, out


def test_a_rank_killed_while_rank_0_waits_is_named_with_its_cases(mpi_cli, tmp_path):
    """Two ranks, case 0 a few steps (rank 0's, round robin) and case 1 long (rank 1's): a second into the first
    evaluation rank 0 is waiting for case 1 when rank 1 is killed, and says so."""
    problem = ring_walls(cases=2, algorithm="lbfgsb", iterations=20)
    del problem["constraints"]
    fast, slow = problem["scenes"]
    fast["scene"]["time"]["steps"] = 4
    fast["objective"] = dict(fast["objective"], steps=[4])
    slow["scene"]["time"].update(steps=3000, dt=0.08 / 3000)
    slow["objective"] = dict(slow["objective"], steps=[3000])
    job, out = start_optimize(mpi_cli, problem, 2, tmp_path)
    try:
        deadline = time.time() + 60
        while not (out / "initial_problem.json").exists() and time.time() < deadline:
            assert job.poll() is None, job.communicate()
            time.sleep(0.02)
        time.sleep(1.0)
        assert not (out / "history.csv").exists() or len((out / "history.csv").read_text().splitlines()) <= 1
        victim = rank_process(1, str(out))
        assert victim is not None
        os.kill(victim, signal.SIGKILL)
        _, stderr = job.communicate(timeout=60)
    finally:
        if job.poll() is None:
            job.kill()
    assert job.returncode != 0
    assert "rank 0 was stopped while it waited for the load cases of rank 1: load case 1 " in stderr, stderr
    assert "process rank 1 " in stderr, stderr  # mpirun's line about the rank that ended


def test_help_and_usage_errors_under_mpirun_end_every_rank(mpi_cli):
    """Rank 0 answers and ends; the serving ranks must not wait for it (a hang before the review's mend)."""
    for args, code in ((["--help"], 0), (["nosuchcommand"], 1), (["optimize", "/no/such/problem.json"], 1)):
        result = run(mpi_cli, args, ranks=3, timeout=60)
        assert result.returncode == code, (args, result.stdout, result.stderr)
    result = subprocess.run([MPIEXEC, "-n", "2", mpi_cli, "optimize", "x.json"], capture_output=True, text=True,
                            timeout=60, env=dict(ENV, DIFFIPC_THREADS="abc"))
    assert result.returncode == 1 and "DIFFIPC_THREADS" in result.stderr


def test_a_killed_rank_ends_the_job_with_a_message_and_the_history_resumes(mpi_cli, tmp_path):
    problem = ring_walls(cases=4, iterations=400)
    for case in problem["scenes"]:  # slower cases: the kill lands inside an evaluation
        case["scene"]["time"].update(steps=40, dt=0.002)
        case["scene"]["bodies"][0]["mesh"]["annulus"].update(segments=96, layers=4)
    job, out = start_optimize(mpi_cli, problem, 3, tmp_path)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            csv = out / "history.csv"
            if csv.exists() and len(csv.read_text().splitlines()) >= 4:
                break
            assert job.poll() is None, job.communicate()
            time.sleep(0.05)
        victim = rank_process(2, str(out))
        assert victim is not None
        os.kill(victim, signal.SIGKILL)
        killed_at = time.time()
        stdout, stderr = job.communicate(timeout=60)  # bounded: the job ends, it does not hang
    finally:
        if job.poll() is None:
            job.kill()
    assert time.time() - killed_at < 60
    assert job.returncode != 0
    assert "rank 2" in stderr  # mpirun names the rank that died ...
    # ... and rank 0 the cases it was waiting for (rank 2 holds cases 2 or 1 and 3 by the assignment), unless the
    # kill came between two evaluations, when rank 0 is not waiting.
    waiting = [line for line in stderr.splitlines() if "waited for the load cases" in line]
    assert all("rank 2: load case" in line for line in waiting)
    # The history written so far is readable, and the run resumes from it (here without mpirun).
    with h5py.File(out / "history.h5", "r", swmr=True) as f:
        iterations = f["iteration"][()]
        assert len(iterations) >= 3 and np.all(np.diff(iterations) == 1)
    resumed = run(mpi_cli, ["optimize", "--resume", str(out), "--max-iterations", str(len(iterations) + 2), "-q"])
    assert resumed.returncode == 0, resumed.stderr
    with h5py.File(out / "history.h5", "r") as f:
        assert len(f["iteration"][()]) > len(iterations)


def test_a_sweep_over_ranks_is_the_serial_sweep(mpi_cli, tmp_path):
    """diffipc sweep under mpirun: run k on rank k mod N, the table written by rank 0 with the serial values."""
    spec = {"problem": ring_walls(cases=2), "run": "evaluate",
            "grid": {"scenes[0].weight": [0.5, 1.0, 2.0], "scenes[1].weight": [0.25, 0.75]}}
    path = tmp_path / "sweep.json"
    path.write_text(json.dumps(spec))
    serial = run(mpi_cli, ["sweep", str(path), "-o", str(tmp_path / "serial"), "-q"])
    assert serial.returncode == 0, serial.stderr
    expected = json.loads((tmp_path / "serial" / "sweep.json").read_text())["runs"]
    assert len(expected) == 6 and len({r["J"] for r in expected}) == 6
    for ranks in (2, 3, 4):
        out = tmp_path / f"ranks{ranks}"
        result = run(mpi_cli, ["sweep", str(path), "-o", str(out), "-q"], ranks)
        assert result.returncode == 0, result.stderr
        rows = json.loads((out / "sweep.json").read_text())["runs"]
        assert [r["rank"] for r in rows] == [k % ranks for k in range(6)]
        times = ("rank", "seconds", "forward_seconds", "adjoint_seconds")
        assert [{k: v for k, v in r.items() if k not in times} for r in rows] == \
            [{k: v for k, v in r.items() if k not in times} for r in expected]


def test_a_remeshed_problem_travels_to_the_ranks(mpi_cli, tmp_path):
    """test_optimize_remesh.py's beam with two load cases (two tip loads) remeshes once in 12 Ipopt iterations;
    rank 0 sends the remeshed problem (its new mesh file in the run's folder) to the other ranks, and the run is
    the serial run bit for bit before and after the remesh."""
    from test_optimize_remesh import beam
    problem = beam(iterations=12)
    scene, objective = problem.pop("scene"), problem.pop("objective")
    lighter = json.loads(json.dumps(scene))
    lighter["neumann"][0]["traction"] = [0, "-2e4*t"]
    problem["scenes"] = [{"scene": scene, "objective": objective},
                         {"scene": lighter, "objective": objective, "weight": 0.5}]
    problem["constraints"][0]["case"] = 0
    path = tmp_path / "beam.json"
    path.write_text(json.dumps(problem))
    serial = run(mpi_cli, ["optimize", str(path), "-o", str(tmp_path / "serial"), "-q"])
    assert serial.returncode == 0, serial.stderr
    data, outcome = history(tmp_path / "serial")
    remeshes = json.loads((tmp_path / "serial" / "summary.json").read_text())["remeshes"]
    assert len(remeshes) == 1 and 0 < remeshes[0]["iteration"] < outcome["iterations"]
    for ranks in (2, 3):
        out = tmp_path / f"ranks{ranks}"
        result = run(mpi_cli, ["optimize", str(path), "-o", str(out), "-q"], ranks)
        assert result.returncode == 0, result.stderr
        other, other_outcome = history(out)
        assert other_outcome == outcome
        for key in data:
            assert same_bits(other[key], data[key]), (ranks, key)
        summary = json.loads((out / "summary.json").read_text())
        assert [r["iteration"] for r in summary["remeshes"]] == [remeshes[0]["iteration"]]
        # Rank 1 evaluated a case at every evaluation, after the remesh too, and loaded both problems.
        rank1 = summary["processes"]["per_rank"][1]
        assert rank1["load_cases_evaluated"] == summary["processes"]["evaluations"]
        assert rank1["seconds_loading_problems"] > 0
