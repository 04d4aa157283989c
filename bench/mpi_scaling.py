"""Load cases over MPI ranks (issue 18): parallel efficiency and the time split of `mpirun -n N diffipc optimize`.

    /usr/bin/python3 bench/mpi_scaling.py [--cli build/cli/diffipc] [--ranks 1,2,4,8] [--cases 8,16,32]
        [--threads 1] [--iterations 3] [--size small|medium] [--repeat 1] [--placement "--bind-to none"]
        [--out output/bench_mpi]

A problem of C equal load cases (study 304's ring thrown at a wall; the cases differ only in their weight, so
they cost the same) is optimized for a fixed number of iterations with N ranks of T threads each. From each
run's summary.json ("processes") and history:
  eval       rank 0's wall time per evaluation (s): what the optimizer waits for
  compute    the busiest rank's time in its load cases per evaluation, and the ranks' mean
  loading    the ranks' time loading the problem rank 0 sends (once per run, spread over its evaluations)
  overhead   eval - the busiest rank's compute + loading: messages, adding the shares, rank 0's checks
  idle       the ranks' mean time per evaluation in neither: imbalance + overhead
  case s     one load case's mean seconds in this run
  speedup    eval(1 rank) / eval(N); efficiency = speedup / N (of the evaluations; the optimizer's own time is
             rank 0's alone), the product of core speed (case s with 1 rank / case s with N) and distribution
             (the rest: balance, overhead, waiting)
and a model  eval(N, C) = ceil(C / N) t_case + o(N), t_case from the 1-rank run, o(N) fitted as a + b log2(N)
to the measured overheads, with its prediction for a 1000-core cluster. It prints the table and writes it as CSV.
"""
import argparse
import csv
import json
import math
import os
import pathlib
import shutil
import subprocess
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def problem(cases, size, iterations):
    base = json.loads((ROOT / "studies" / "304_ring_wall_velocity" / "problem.json").read_text())
    scene = base["scene"]
    if size == "medium":  # the same 0.08 s of the throw, finer in space and time
        scene["bodies"][0]["mesh"]["annulus"].update(segments=128, layers=4)
        scene["time"].update(steps=48, dt=0.08 / 48)
    base["objective"]["steps"] = [scene["time"]["steps"]]
    return {"scenes": [{"scene": scene, "objective": base["objective"], "weight": 1.0 + 0.01 * c}
                       for c in range(cases)],
            "parameters": base["parameters"],
            "optimizer": {"algorithm": "lbfgsb", "max_iterations": iterations}}


def measure(cli, mpirun, ranks, threads, path, out, placement=("--bind-to", "none")):
    if out.exists():
        shutil.rmtree(out)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", DIFFIPC_THREADS=str(threads))
    command = [mpirun, "-n", str(ranks), *placement, cli, "optimize", str(path), "-o", str(out), "-q"]
    start = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{result.stdout}{result.stderr}")
    summary = json.loads((out / "summary.json").read_text())
    p = summary["processes"]
    evaluations = p["evaluations"]
    compute = [r["seconds_in_load_cases"] / evaluations for r in p["per_rank"]]
    loading = [r["seconds_loading_problems"] / evaluations for r in p["per_rank"]]
    busy = [c + l for c, l in zip(compute, loading)]
    eval_time = p["evaluation_wall_seconds"] / evaluations
    return {"ranks": ranks, "threads": threads, "evaluations": evaluations, "iterations": summary["iterations"],
            "command_wall": wall, "eval": eval_time, "compute_max": max(compute),
            "compute_mean": sum(compute) / len(compute), "loading_max": max(loading),
            "overhead": eval_time - max(busy), "idle": eval_time - sum(busy) / len(busy),
            "case_seconds": sum(compute) / sum(r["load_cases_evaluated"] for r in p["per_rank"]) * evaluations,
            "optimizer": summary["wall_time"]["optimizer"] / max(1, summary["iterations"]),
            "final_J": summary["final_J"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    parser.add_argument("--ranks", default="1,2,4,8")
    parser.add_argument("--cases", default="8")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--size", choices=("small", "medium"), default="medium")
    parser.add_argument("--out", default=str(ROOT / "output" / "bench_mpi"))
    parser.add_argument("--repeat", type=int, default=1, help="runs per configuration; the fastest is kept")
    parser.add_argument("--placement", default="--bind-to none",
                        help="mpirun's options that place the ranks (e.g. \"--bind-to core --cpu-set 0,2,4,6\")")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"{os.cpu_count()} cores; {args.threads} thread(s) per rank; problem size {args.size}; "
          f"{args.iterations} L-BFGS-B iterations")
    header = ("cases", "ranks", "evals", "eval s", "compute max", "compute mean", "loading max", "overhead", "idle",
              "case s", "speedup", "efficiency", "core speed", "distribution", "command s")
    print(" ".join(f"{h:>12}" for h in header))
    for cases in [int(c) for c in args.cases.split(",")]:
        path = out / f"problem_{cases}.json"
        path.write_text(json.dumps(problem(cases, args.size, args.iterations)))
        reference = None
        for ranks in [int(r) for r in args.ranks.split(",")]:
            runs = [measure(args.cli, args.mpirun, ranks, args.threads, path, out / f"run_{cases}_{ranks}",
                            args.placement.split()) for _ in range(args.repeat)]
            m = min(runs, key=lambda r: r["eval"])
            m["cases"] = cases
            m["repeats"] = [round(r["eval"], 4) for r in runs]
            if reference is None:
                reference = m
            if m["final_J"] != reference["final_J"]:
                raise SystemExit(f"{ranks} ranks ended at J = {m['final_J']!r}, 1 rank at {reference['final_J']!r}")
            m["speedup"] = reference["eval"] * reference["ranks"] / m["eval"]
            m["efficiency"] = m["speedup"] / m["ranks"]
            # efficiency = core speed x distribution: a case's time alone on the machine against with N ranks
            # busy, times the ranks' mean busy share of the evaluation (balance, overhead, waiting).
            m["core_speed"] = reference["case_seconds"] / m["case_seconds"]
            m["distribution"] = m["efficiency"] / m["core_speed"]
            rows.append(m)
            print(" ".join(f"{v:>12}" if isinstance(v, int) else f"{v:>12.4f}" for v in (
                cases, ranks, m["evaluations"], m["eval"], m["compute_max"], m["compute_mean"], m["loading_max"],
                m["overhead"], m["idle"], m["case_seconds"], m["speedup"], m["efficiency"], m["core_speed"],
                m["distribution"], m["command_wall"])))
    with open(out / "mpi_scaling.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    # The model: eval(N, C) = ceil(C / N) t_case + o(N); o(N) = a + b log2(N) fitted to the overheads.
    single = [r for r in rows if r["ranks"] == 1]
    t_case = sum(r["compute_max"] / r["cases"] for r in single) / max(1, len(single))
    points = [(math.log2(r["ranks"]), r["overhead"]) for r in rows]
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    b = sum((x - mx) * (y - my) for x, y in points) / sxx if sxx > 0 else 0.0
    a = my - b * mx
    print(f"\nmodel: eval(N, C) = ceil(C / N) * {t_case:.4f} s + ({a:.5f} + {b:.5f} log2 N) s")
    for r in rows:
        predicted = math.ceil(r["cases"] / r["ranks"]) * t_case + a + b * math.log2(r["ranks"])
        print(f"  C = {r['cases']:3d}, N = {r['ranks']:3d}: measured {r['eval']:.4f} s, model {predicted:.4f} s")
    for cases, ranks in ((32, 32), (1000, 1000), (32, 1000)):
        used = min(cases, ranks)
        t = math.ceil(cases / ranks) * t_case + a + b * math.log2(ranks)
        print(f"  prediction C = {cases}, N = {ranks}: eval {t:.4f} s, efficiency {cases * t_case / (ranks * t):.3f}"
              f" ({used} ranks busy)")
    print(f"wrote {out / 'mpi_scaling.csv'}")


if __name__ == "__main__":
    main()
