"""Seeded mutation fuzzing of scene, problem and mesh files through the CLI and the Python module.

Each case copies one seed (a study folder under studies/, or a small generated
gmsh/OBJ scene, see fuzz_mutations.py), mutates it and runs it:
`diffipc validate` and `diffipc simulate` for a scene, `diffipc gradcheck
--directions 1` for a problem, or (some cases) diffipc.scene / Simulator.run /
ReducedFunctional in a subprocess. The contract checked is README.md's exit codes:

- validate: 0 or 1; simulate: 0, 1 or 2 (a step failed); gradcheck: 0, 1, 2 (a
  forward step failed) or 4 (a direction failed); never a signal, never 3
  (internal error), never a hang;
- on exit 1, stderr is one line "diffipc: error: ..." naming a field or a file,
  without a leaked library exception;
- on exit 0 (and 2, for the committed steps), summary.json, trajectory.h5 and the
  VTU frames hold finite numbers only (min_distance may be +inf, "none close");
- validate and simulate agree on whether the scene is bad input.

A case that raised a size (mesh cells or segments, steps, iteration budgets,
gradcheck directions or halvings) may need more than the fuzzer grants: there a
timeout, or an allocation failure under the memory limit, is reported as
tolerated and does not fail the test. Unless a mutation wrote it, a scene's
time.steps is clamped to 3 (problems keep theirs: their objectives name steps),
so a clean case takes well under a second. Environment:

    DIFFIPC_FUZZ_CASES=3000   number of cases (default 500)
    DIFFIPC_FUZZ_SEED=7       campaign seed (default 1: the default run is the same every time)
    DIFFIPC_FUZZ_ONLY=12,40   run only these case indices (to reproduce)
    DIFFIPC_FUZZ_JOBS=2       cases run in parallel (default 2)
    DIFFIPC_FUZZ_TIMEOUT=60   CPU seconds per command (a hang that spins); a command that sleeps
                              is stopped at 10 times that in wall time. CPU time, not wall time,
                              so that a busy machine does not turn a slow case into a "hang"
    DIFFIPC_FUZZ_MEMORY_MB=4096  address-space limit per command
    DIFFIPC_FUZZ_OUT=DIR      where failing cases are saved (default $TMPDIR/diffipc_fuzz/seed_<seed>)

Every failing case is saved with its mutated files, repro.sh and result.txt, and
all failures are listed at the end, grouped by class.
"""
import collections
import concurrent.futures
import json
import os
import pathlib
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

import fuzz_mutations as fm

CASES = int(os.environ.get("DIFFIPC_FUZZ_CASES", "500"))
SEED = int(os.environ.get("DIFFIPC_FUZZ_SEED", "1"))
JOBS = int(os.environ.get("DIFFIPC_FUZZ_JOBS", "2"))
TIMEOUT = float(os.environ.get("DIFFIPC_FUZZ_TIMEOUT", "60"))
MEMORY_BYTES = int(os.environ.get("DIFFIPC_FUZZ_MEMORY_MB", "4096")) << 20
ONLY = [int(i) for i in os.environ.get("DIFFIPC_FUZZ_ONLY", "").replace(",", " ").split()]
OUT = pathlib.Path(os.environ.get("DIFFIPC_FUZZ_OUT", pathlib.Path(tempfile.gettempdir()) / "diffipc_fuzz"
                                  / f"seed_{SEED}"))

ENV = dict(os.environ, DIFFIPC_THREADS="1", OMP_WAIT_POLICY="PASSIVE")

# Run in a subprocess for the Python-module cases: exit 0 clean, 1 ValueError, 2 a
# failed step or AdjointError, 3 another exception, 5 a non-finite number came back.
DRIVER = r'''
import json, os, sys
import numpy as np
import diffipc

kind, path, use_dict = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
base = os.path.dirname(os.path.abspath(path))
source = path
if use_dict:
    try:
        with open(path, "rb") as f:
            tree = json.loads(f.read())
    except Exception:
        tree = None
    if isinstance(tree, dict):
        source = tree


def nonfinite(name, value):
    a = np.asarray(value)
    if a.dtype.kind != "f":
        return []
    ok = ~np.isnan(a) & (a > -np.inf) if name.endswith("min_distance") else np.isfinite(a)
    return [] if ok.all() else [name]


try:
    if kind == "scene":
        sc = diffipc.scene(source, base_directory=base) if isinstance(source, dict) else diffipc.scene(source)
        sim = diffipc.Simulator(sc)
        tr = sim.run()
        bad = [n for k, v in tr.items() for n in nonfinite(k, v)]
        json.loads(sim.summary(), parse_constant=lambda c: bad.append("summary " + c))
        status = tr.get("final_status")
        print(json.dumps({"status": str(status), "nonfinite": bad}))
        sys.exit(5 if bad else (0 if status == "CONVERGED" else 2))
    else:
        J = (diffipc.ReducedFunctional(source, base_directory=base) if isinstance(source, dict)
             else diffipc.ReducedFunctional(source))
        p = J.initial
        value, gradient = J.value_and_gradient(p)
        bad = nonfinite("initial", p) + nonfinite("J", value) + nonfinite("gradient", gradient)
        print(json.dumps({"J": repr(value), "nonfinite": bad}))
        sys.exit(5 if bad else 0)
except diffipc.AdjointError as e:
    print(f"AdjointError: {e}", file=sys.stderr)
    sys.exit(2)
except ValueError as e:
    print(str(e), file=sys.stderr)
    sys.exit(1)
except Exception as e:
    print(f"{type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(3)
'''

LEAKS = re.compile(r"json\.exception|std::|basic_string|what\(\)|terminate called|bad_alloc|stoi|stod|"
                   r"vector::|out_of_range|invalid_argument|length_error|Traceback|pybind11|H5[A-Z]|HDF5-DIAG")
NONFINITE_TEXT = re.compile(r"(?i)(?<![\w.])[-+]?(nan|inf|infinity)(?![\w])")


def _names_field_or_file(msg, case, case_dir):
    """The message starts with "FIELD: " or "FILE: " (a path, not a sentence), or quotes a file of the case."""
    if any(name in msg for name in list(case.files) + [str(case_dir)]):
        return True
    prefix, sep, _ = msg.partition(": ")
    return bool(sep and prefix and not re.search(r"\s\S+\s", prefix) and not prefix.startswith(" "))


class Outcome:
    def __init__(self, name, argv, rc, stdout, stderr, seconds, timed_out=False):
        self.name, self.argv, self.rc = name, argv, rc
        self.stdout, self.stderr, self.seconds, self.timed_out = stdout, stderr, seconds, timed_out


def _limits(cpu_seconds):
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_BYTES, MEMORY_BYTES))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    # The hang detector counts the command's CPU time (SIGXCPU at the limit, SIGKILL 5 s later), which
    # other work on the machine does not stretch as it stretches wall time.
    cpu = int(cpu_seconds) + 1
    resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 5))


def _out_of_cpu_time(rc):
    return rc in (-signal.SIGXCPU, -signal.SIGKILL)


def _run(name, argv, cwd, timeout=None):
    t0 = time.monotonic()
    try:
        cpu_seconds = timeout or TIMEOUT
        p = subprocess.run(argv, cwd=cwd, capture_output=True, timeout=max(10 * cpu_seconds, 60), env=ENV,
                           preexec_fn=lambda: _limits(cpu_seconds))
        return Outcome(name, argv, p.returncode, p.stdout.decode(errors="replace"),
                       p.stderr.decode(errors="replace"), time.monotonic() - t0,
                       timed_out=_out_of_cpu_time(p.returncode))
    except subprocess.TimeoutExpired as e:
        out = (e.stdout or b"").decode(errors="replace")
        err = (e.stderr or b"").decode(errors="replace")
        return Outcome(name, argv, None, out, err, time.monotonic() - t0, timed_out=True)


def _shape(text, case_dir):
    """A message reduced to its shape, to group failures by cause."""
    text = text.replace(str(case_dir), "<dir>")
    text = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", text)
    text = re.sub(r"[-+]?\d+(\.\d+)?([eE][-+]?\d+)?", "N", text)
    return text[:140]


def _cut_at_nul(msg, case):
    """A message that stops right after a field path or an opening quote, for an input with a NUL in
    a key or a string: the C string of the message ended at the NUL."""
    # Inputs only: a study folder's figures (PNG) hold NUL bytes that no message reads.
    inputs = [data for name, data in case.files.items() if not name.endswith(".png")]
    if not any(b"\\u0000" in data or b"\x00" in data for data in inputs):
        return False
    last = msg.split(": ")[-1].strip()
    quotes = re.sub(r"(?<=\w)'(?=\w)", "", msg).count("'")  # not the apostrophe of Poisson's
    return quotes % 2 == 1 or not last or bool(re.fullmatch(r"\S*[.\[/]", last))


def _allowed_parse_error(text):
    """JSON syntax errors are reported as "invalid JSON: " + nlohmann's message, by design (json_input.cpp)."""
    return re.sub(r"invalid JSON: \[json\.exception\.parse_error\.\d+\]", "invalid JSON:", text)


def _first_line(text):
    lines = [line for line in text.splitlines() if line.strip()]
    return lines[0] if lines else ""


class Checker:
    def __init__(self, case, case_dir):
        self.case, self.dir = case, case_dir
        self.issues = []  # (class, detail): each fails the test
        self.tolerated = []  # (class, detail): reported, not failed

    def issue(self, cls, detail=""):
        self.issues.append((cls, detail))

    def exit_code(self, o, allowed):
        """Returns True if the outcome may be inspected further."""
        # A case that raised a mesh size, a step count or an iteration budget may ask for more
        # time or memory than the fuzzer gives: a timeout or an allocation failure there is
        # reported as tolerated. Everywhere else it is a failure, and so is a signal always.
        if o.timed_out:
            if self.case.size_touched:
                self.tolerated.append((f"timeout (a size field was changed): {o.name}", f"> {TIMEOUT:.0f} CPU s"))
            else:
                self.issue(f"timeout: {o.name}", f"> {TIMEOUT:.0f} CPU s")
            return False
        if o.rc < 0:
            name = signal.Signals(-o.rc).name if -o.rc in signal.Signals._value2member_map_ else str(-o.rc)
            note = " (a size field was changed: check without the memory limit)" if self.case.size_touched else ""
            self.issue(f"crash {name}: {o.name}{note}", o.stderr[-2000:])
            return False
        if o.rc == 3 and self.case.size_touched and re.search(r"bad_alloc|MemoryError", o.stderr):
            self.tolerated.append((f"out of memory under the {MEMORY_BYTES >> 20} MiB limit (a size field was "
                                   f"changed): {o.name}: {_shape(_first_line(o.stderr), self.dir)}", o.stderr[-500:]))
            return False
        if o.rc == 3:
            self.issue(f"exit 3: {o.name}: {_shape(_first_line(o.stderr), self.dir)}", o.stderr[-2000:])
            return False
        if o.rc not in allowed:
            self.issue(f"exit {o.rc}: {o.name}: {_shape(_first_line(o.stderr), self.dir)}", o.stderr[-2000:])
            return False
        return True

    def input_error(self, o, prefix="diffipc: error: "):
        lines = [line for line in o.stderr.splitlines() if line.strip()]
        if len(lines) != 1:
            self.issue(f"exit 1 with {min(len(lines), 3)}{'+' if len(lines) > 3 else ''} stderr lines: {o.name}",
                       o.stderr[-2000:])
            if not lines:
                return
        line = lines[0]
        if not line.startswith(prefix):
            self.issue(f"exit 1 without {prefix.strip()!r}: {o.name}", line[:500])
            return
        msg = line[len(prefix):]
        if _cut_at_nul(msg, self.case):
            self.issue(f"exit 1 message cut at a NUL of the input: {o.name}", line[:500])
        elif not _names_field_or_file(msg, self.case, self.dir):
            self.issue(f"exit 1 message names no field or file: {o.name}: {_shape(msg, self.dir)}", line[:500])
        m = LEAKS.search(_allowed_parse_error(line))
        if m:
            self.issue(f"exit 1 leaks {m.group(0)!r}: {o.name}: {_shape(msg, self.dir)}", line[:500])

    def outputs(self, out, expect_converged):
        summary = out / "summary.json"
        if not summary.exists():
            self.issue("no summary.json", str(out))
            return
        constants = []
        try:
            data = json.loads(summary.read_text(), parse_constant=lambda c: constants.append(c) or 0.0)
        except ValueError as e:
            self.issue("summary.json is not JSON", str(e))
            return
        if constants:
            self.issue("summary.json holds NaN/Infinity", " ".join(constants))
        nulls = [k for k, v in _walk(data) if v is None and not k.endswith("min_distance")]
        if nulls:
            self.issue("summary.json holds null numbers (non-finite): " + ",".join(sorted(set(nulls))[:4]))
        bad = [k for k, v in _walk(data) if isinstance(v, float) and not np.isfinite(v)]
        if bad:
            self.issue("summary.json non-finite: " + ",".join(bad[:4]))
        status = data.get("status")
        if expect_converged:
            if status != "CONVERGED" or data.get("steps_committed") != data.get("steps_requested"):
                self.issue("exit 0 but summary.json says not converged",
                           f"{status} {data.get('steps_committed')}/{data.get('steps_requested')}")
        elif status in ("CONVERGED", "RUNNING"):
            self.issue(f"exit 2 but summary.json status {status}")
        h5 = out / "trajectory.h5"
        if h5.exists():
            self.hdf5(h5)
        elif self._wants_hdf5():
            self.issue("no trajectory.h5")
        for vtu in sorted(out.glob("*.vtu")) + sorted(out.glob("*.pvd")):
            self.vtu(vtu)

    def _wants_hdf5(self):
        try:
            tree = json.loads(self.case.files[self.case.main])
            return tree.get("output", {}).get("hdf5", True) is True
        except Exception:
            return True

    def hdf5(self, path):
        import h5py

        try:
            with h5py.File(path, "r") as f:
                names = []
                f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
                for name in names:
                    ds = f[name]
                    if ds.dtype.kind != "f":
                        continue
                    a = ds[()]
                    ok = (~np.isnan(a) & (a > -np.inf)) if name.endswith("min_distance") else np.isfinite(a)
                    if not np.all(ok):
                        self.issue(f"trajectory.h5 non-finite: {name}", f"{np.size(a) - np.count_nonzero(ok)} values")
        except OSError as e:
            self.issue("trajectory.h5 unreadable", str(e)[:300])

    def vtu(self, path):
        text = path.read_text(errors="replace")
        for m in re.finditer(r'<DataArray[^>]*Name="([^"]*)"[^>]*>(.*?)</DataArray>|<DataArray[^>]*>(.*?)</DataArray>',
                             text, re.S):
            name = m.group(1) or "Points"
            body = m.group(2) if m.group(1) else m.group(3)
            if NONFINITE_TEXT.search(body):
                self.issue(f"{path.suffix} non-finite: {name}", path.name)
                return
        for t in re.findall(r'timestep="([^"]*)"', text):
            if NONFINITE_TEXT.search(t):
                self.issue("trajectory.pvd non-finite timestep", t)
                return


def _walk(node, prefix=""):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _walk(v, f"{prefix}.{k}" if prefix else k)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _walk(v, f"{prefix}[{i}]")
    else:
        yield prefix, node


def run_case(case, cli, work_root, python_ok):
    case_dir = fm.write_case(case, work_root / f"case_{case.index}")
    check = Checker(case, case_dir)
    outcomes = []
    main = case.main
    mode = case.mode if python_ok else "cli"
    if mode == "python":
        (case_dir / "driver.py").write_text(DRIVER)
        use_dict = "1" if case.index % 2 == 0 else "0"
        o = _run("python", [sys.executable, "driver.py", case.kind, main, use_dict], case_dir)
        outcomes.append(o)
        if check.exit_code(o, {0, 1, 2, 5}):
            if o.rc == 5:
                check.issue("python: non-finite result", o.stdout[-500:])
            elif o.rc == 1:
                lines = [line for line in o.stderr.splitlines() if line.strip()]
                msg = lines[0] if lines else ""
                if _cut_at_nul(msg, case):
                    check.issue("python: ValueError message cut at a NUL of the input", msg[:500])
                elif not _names_field_or_file(msg, case, case_dir):
                    check.issue(f"python: ValueError names no field or file: {_shape(msg, case_dir)}", msg[:500])
                m = LEAKS.search(_allowed_parse_error(o.stderr))
                if m:
                    check.issue(f"python: ValueError leaks {m.group(0)!r}: {_shape(msg, case_dir)}", msg[:500])
    elif case.kind == "scene":
        v = _run("validate", [cli, "validate", main], case_dir)
        outcomes.append(v)
        if check.exit_code(v, {0, 1}) and v.rc == 1:
            check.input_error(v)
        s = _run("simulate", [cli, "simulate", main, "-o", "out", "-q"], case_dir)
        outcomes.append(s)
        if check.exit_code(s, {0, 1, 2}):
            if s.rc == 1:
                check.input_error(s)
            else:
                if s.rc == 2 and len([x for x in s.stderr.splitlines() if x.strip()]) > 3:
                    check.issue("simulate exit 2 with many stderr lines", s.stderr[-1000:])
                check.outputs(case_dir / "out", expect_converged=s.rc == 0)
        if not v.timed_out and not s.timed_out and v.rc in (0, 1) and s.rc in (0, 1, 2):
            if v.rc == 0 and s.rc == 1:
                check.issue(f"validate accepts, simulate exit 1: {_shape(_first_line(s.stderr), case_dir)}",
                            s.stderr[-500:])
            # A scene whose initial state is invalid is refused by validate and, documented in
            # docs/scene_format.md, run by simulate to a step 1 that fails with INVALID_INITIAL_STATE.
            invalid_start = (v.rc == 1 and s.rc == 2 and "initial state is invalid" in v.stderr
                             and "INVALID_INITIAL_STATE" in s.stderr)
            if v.rc == 1 and s.rc != 1 and not invalid_start:
                check.issue(f"validate exit 1, simulate exit {s.rc}: {_shape(_first_line(v.stderr), case_dir)}",
                            v.stderr[-500:])
    else:
        argv = [cli, "gradcheck", main] + ([] if case.gradcheck_touched else ["--directions", "1"])
        g = _run("gradcheck", argv, case_dir)
        outcomes.append(g)
        if check.exit_code(g, {0, 1, 2, 4}):
            if g.rc == 1:
                check.input_error(g)
            elif g.rc == 2:
                if len([x for x in g.stderr.splitlines() if x.strip()]) > 3:
                    check.issue("gradcheck exit 2 with many stderr lines", g.stderr[-1000:])
            elif NONFINITE_TEXT.search(g.stdout):
                line = next(x for x in g.stdout.splitlines() if NONFINITE_TEXT.search(x))
                check.issue(f"gradcheck exit {g.rc} prints a non-finite number", line[:300])
    return check, outcomes, case_dir


def save_failure(case, check, outcomes, cli):
    folder = OUT / f"case_{case.index}"
    shutil.rmtree(folder, ignore_errors=True)
    fm.write_case(case, folder)
    lines = ["#!/bin/sh", f"# diffipc fuzz seed {case.seed} case {case.index} ({case.origin}, {case.kind})",
             'cd "$(dirname "$0")"', f"ulimit -t {int(TIMEOUT) + 1}  # the fuzzer's limit: CPU seconds"]
    for o in outcomes:
        if o.name == "python":
            (folder / "driver.py").write_text(DRIVER)
            lines.append(f"PYTHONPATH={os.environ.get('PYTHONPATH', '')} timeout -s KILL {10 * TIMEOUT:.0f} "
                         f"{' '.join(o.argv)}; echo \"exit $?\"")
        else:
            # SIGKILL: a step that never ends ignores SIGTERM (the CLI finishes the current step first).
            lines.append(" ".join([f"timeout -s KILL {10 * TIMEOUT:.0f}", "\"${DIFFIPC_CLI:-%s}\"" % cli] + o.argv[1:])
                         + "; echo \"exit $?\"")
    (folder / "repro.sh").write_text("\n".join(lines) + "\n")
    report = [f"seed {case.seed} case {case.index}: {case.origin} {case.kind} via {case.mode}",
              "mutations:"] + [f"  {m}" for m in case.mutations] + ["issues:"]
    report += [f"  {cls}\n    {detail[:1500]}" for cls, detail in check.issues]
    report += [f"  tolerated: {cls}\n    {detail[:1500]}" for cls, detail in check.tolerated]
    for o in outcomes:
        report += [f"$ {' '.join(map(str, o.argv))}",
                   f"  exit {o.rc}{' (timed out)' if o.timed_out else ''} in {o.seconds:.2f} s",
                   "  stderr: " + o.stderr[-3000:].replace("\n", "\n          "),
                   "  stdout (tail): " + o.stdout[-1500:].replace("\n", "\n          ")]
    (folder / "result.txt").write_text("\n".join(report) + "\n")
    return folder


def _python_module_ok():
    r = subprocess.run([sys.executable, "-c", "import diffipc"], capture_output=True, env=ENV)
    return r.returncode == 0


def test_fuzz(cli, tmp_path):
    seeds = fm.load_seeds()
    indices = ONLY or list(range(CASES))
    python_ok = _python_module_ok()
    if not python_ok:
        print("note: diffipc is not importable (set PYTHONPATH); the Python-module cases run through the CLI")
    t0 = time.monotonic()

    def one(i):
        case = fm.make_case(SEED, i, seeds)
        check, outcomes, case_dir = run_case(case, cli, tmp_path, python_ok)
        saved = save_failure(case, check, outcomes, cli) if check.issues or check.tolerated else None
        shutil.rmtree(case_dir, ignore_errors=True)
        return case, check, outcomes, saved

    results = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, JOBS)) as pool:
        for r in pool.map(one, indices):
            results.append(r)
    elapsed = time.monotonic() - t0

    classes = collections.OrderedDict()
    tolerated = collections.OrderedDict()
    for case, check, _, saved in results:
        for cls, _ in check.issues:
            classes.setdefault(cls, []).append((case.index, saved))
        for cls, _ in check.tolerated:
            tolerated.setdefault(cls, []).append((case.index, saved))
    exit_codes = collections.Counter()
    for case, _, outcomes, _ in results:
        for o in outcomes:
            exit_codes[f"{o.name}:{'timeout' if o.timed_out else o.rc}"] += 1
    slowest = max(results, key=lambda r: sum(o.seconds for o in r[2]))
    report = [f"diffipc fuzz: seed {SEED}, {len(results)} cases in {elapsed:.1f} s ({JOBS} jobs); exit codes "
              + ", ".join(f"{k} x{v}" for k, v in sorted(exit_codes.items())),
              f"slowest case {slowest[0].index}: {sum(o.seconds for o in slowest[2]):.1f} s"]
    failing = [r for r in results if r[1].issues]
    if tolerated:
        report.append(f"tolerated (inputs that ask for much work; not failures), saved under {OUT}:")
        for cls, hits in sorted(tolerated.items(), key=lambda kv: -len(kv[1])):
            report.append(f"  [{len(hits)}] {cls}: cases " + ", ".join(str(i) for i, _ in hits[:8]))
    if failing:
        report.append(f"{len(failing)} failing cases in {len(classes)} classes (saved under {OUT}):")
        for cls, hits in sorted(classes.items(), key=lambda kv: -len(kv[1])):
            cases = ", ".join(str(i) for i, _ in hits[:8]) + (" ..." if len(hits) > 8 else "")
            report.append(f"  [{len(hits)}] {cls}\n        cases {cases}; e.g. {hits[0][1]}/result.txt")
        report.append(f"reproduce one: DIFFIPC_FUZZ_SEED={SEED} DIFFIPC_FUZZ_ONLY=<case> pytest test_fuzz.py, "
                      "or sh <saved case>/repro.sh")
    text = "\n".join(report)
    print(text)
    if failing or tolerated:
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / "summary.txt").write_text(text + "\n")
    if failing:
        pytest.fail(text, pytrace=False)


def test_unmutated_seeds_run_clean(cli, tmp_path):
    """Every seed, unmutated (steps clamped), passes the same checks with exit 0: a seed that
    stopped being valid would leave the fuzzer testing the parser only."""
    python_ok = _python_module_ok()
    bad = []
    for i, s in enumerate(fm.load_seeds()):
        for mode in ("cli", "python") if python_ok else ("cli",):
            files = dict(s.files)
            tree = json.loads(files[s.main])
            fm.steps_cap(tree, s.kind, 3)
            files[s.main] = json.dumps(tree).encode()
            case = fm.Case(seed=SEED, index=2 * i + (mode == "python"), origin=s.name, kind=s.kind, main=s.main,
                           files=files, mode=mode, mutations=[], size_touched=False, time_touched=False,
                           gradcheck_touched=False)
            check, outcomes, _ = run_case(case, cli, tmp_path, python_ok)
            if check.issues or any(o.rc != 0 for o in outcomes):
                bad.append(f"{s.name} ({mode}): {[(o.name, o.rc, o.stderr[-300:]) for o in outcomes]} "
                           f"{check.issues}")
    assert not bad, "\n".join(bad)


def test_a_command_that_spins_is_a_timeout_and_one_that_waits_is_not(tmp_path):
    """The hang detector: CPU time past the limit is a timeout; wall time spent waiting (as on a busy
    machine) is not."""
    spin = _run("spin", [sys.executable, "-c", "while True: pass"], tmp_path, timeout=1)
    assert spin.timed_out, (spin.rc, spin.stderr)
    wait = _run("wait", [sys.executable, "-c", "import time; time.sleep(3)"], tmp_path, timeout=1)
    assert not wait.timed_out and wait.rc == 0, (wait.rc, wait.stderr)
