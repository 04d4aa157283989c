"""Thread configuration seen from outside: the CLI, summary.json, libgomp's own report, Python."""
import json
import os
import re
import subprocess

from conftest import box_scene


def run(cli, *args, env=None):
    e = dict(os.environ)
    for k in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "DIFFIPC_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
              "DIFFIPC_SET_OMP_WAIT_POLICY", "DIFFIPC_REEXECUTED", "DIFFIPC_SET_OPENBLAS_CORETYPE"):
        e.pop(k, None)
    e.update(env or {})
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, env=e, timeout=300)


def pools(text):
    """Each pool's count as printed by `diffipc info`."""
    return {name: int(re.search(r"^\s+%s:\s+(\d+)" % name, text, re.M).group(1)) for name in ("TBB", "BLAS", "OpenMP")}


def test_threads_flag_reaches_every_pool(cli):
    r = run(cli, "--threads", 3, "info")
    assert r.returncode == 0, r.stderr
    assert pools(r.stdout) == {"TBB": 3, "BLAS": 3, "OpenMP": 3}
    assert "explicit: --threads" in r.stdout


def test_environment_variable_and_precedence(cli):
    r = run(cli, "info", env={"DIFFIPC_THREADS": "3"})
    assert pools(r.stdout)["TBB"] == 3 and "DIFFIPC_THREADS" in r.stdout
    r = run(cli, "--threads", 2, "info", env={"DIFFIPC_THREADS": "3"})
    assert pools(r.stdout)["TBB"] == 2
    # A user's per-library setting wins for that library.
    r = run(cli, "--threads", 3, "info", env={"OPENBLAS_NUM_THREADS": "1"})
    assert pools(r.stdout) == {"TBB": 3, "BLAS": 1, "OpenMP": 3}
    assert "OPENBLAS_NUM_THREADS=1" in r.stdout


def test_bad_thread_counts_are_refused(cli):
    r = run(cli, "info", env={"DIFFIPC_THREADS": "many"})
    assert r.returncode == 1 and "DIFFIPC_THREADS" in r.stderr
    r = run(cli, "--threads", 0, "info")
    assert r.returncode != 0


def test_libgomp_itself_sees_a_passive_wait_policy(cli):
    # libgomp prints its settings at load; the CLI re-executes itself with OMP_WAIT_POLICY=PASSIVE,
    # so the last report (the process that runs) must show a spin count of 0 (300000 when spinning).
    r = run(cli, "info", env={"OMP_DISPLAY_ENV": "VERBOSE"})
    assert r.returncode == 0
    counts = re.findall(r"GOMP_SPINCOUNT = '(\d+)'", r.stderr)
    assert counts and counts[-1] == "0", r.stderr
    assert "passive" in r.stdout
    # The user's choice is kept.
    r = run(cli, "info", env={"OMP_DISPLAY_ENV": "VERBOSE", "OMP_WAIT_POLICY": "ACTIVE"})
    counts = re.findall(r"GOMP_SPINCOUNT = '(\d+)'", r.stderr)
    assert counts and counts[-1] != "0"
    assert "the user's OMP_WAIT_POLICY" in r.stdout


def test_scene_key_and_summary(cli, tmp_path):
    s = box_scene(dim=2, steps=2)
    s.setdefault("solver", {})["threads"] = 1
    scene = tmp_path / "scene.json"
    scene.write_text(json.dumps(s))
    r = run(cli, "simulate", scene, "-o", tmp_path / "out", "-q")
    assert r.returncode == 0, r.stderr
    t = json.loads((tmp_path / "out" / "summary.json").read_text())["threads"]
    assert t["threads"] == 1 and t["tbb"] == 1 and t["source"] == "scene file"
    # --threads wins over the file.
    r = run(cli, "--threads", 2, "simulate", scene, "-o", tmp_path / "out2", "-q")
    t = json.loads((tmp_path / "out2" / "summary.json").read_text())["threads"]
    assert t["threads"] == 2 and t["source"] == "explicit"
    s["solver"]["threads"] = 0
    scene.write_text(json.dumps(s))
    r = run(cli, "simulate", scene, "-o", tmp_path / "out3")
    assert r.returncode == 1 and "solver.threads" in r.stderr


def test_python_set_threads_and_info():
    import diffipc

    info = diffipc.set_threads(2)
    assert info["threads"] == 2 and info["tbb"] == 2 and info["source"] == "explicit"
    assert diffipc.thread_info()["tbb"] == 2
    info = diffipc.set_threads(0)
    assert info["threads"] == info["cores"]["usable"]


def test_info_says_whether_a_gpu_is_usable(cli):
    """`diffipc info` ends with the GPU the "device": "gpu" scenes would run on, or why there is none."""
    r = run(cli, "info")
    assert r.returncode == 0, r.stderr
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("gpu: "), r.stdout
    assert ("runs there" in line) != ("is refused" in line), line
