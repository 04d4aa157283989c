"""Where an optimization's wall time goes, on the worked examples (studies/401-406): runs each
example's problem file with `diffipc optimize` and prints, from its summary.json, the shares of
the forward + adjoint evaluations, the parameter maps and the rest meshes' validity checks (parts
of the evaluations), the optimizer itself (its wall time, and its thread's CPU time, which does
not grow while it waits for a core), remeshing, and the rest (outputs, start-up).

    /usr/bin/python3 scripts/bench_optimizer_share.py [--cli build/cli/diffipc] [--only 401 405]
"""
import argparse
import json
import pathlib
import subprocess
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLES = [
    "401_cantilever_area/problem.json",
    "401_cantilever_area/problem_penalty.json",
    "402_throw_target/problem.json",
    "403_friction_fit/problem.json",
    "403_friction_fit/problem_ipopt.json",
    "403_friction_fit/problem_slsqp.json",
    "404_bar_modulus_field/problem.json",
    "405_bracket_contact/problem.json",
    "405_bracket_contact/problem_penalty.json",
    "406_cantilever_3d_remesh/problem.json",
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--only", nargs="*", default=[], help="study numbers to run (default: all)")
    args = parser.parse_args()
    print("| example | algorithm | iterations | wall s | s/iteration | evaluation | of it: maps | of it: validity "
          "| optimizer (wall) | optimizer (CPU) | remeshing | other |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for example in EXAMPLES:
        if args.only and not any(example.startswith(n) for n in args.only):
            continue
        with tempfile.TemporaryDirectory() as out:
            subprocess.run([args.cli, "optimize", str(ROOT / "studies" / example), "-o", out, "-q"], check=True)
            s = json.loads((pathlib.Path(out) / "summary.json").read_text())
        w = s["wall_time"]
        total = w["total"]
        remeshing = w.get("remeshing", 0.0)
        other = total - w["evaluation"] - w["optimizer"] - remeshing

        def pct(v):
            return "%.2f%%" % (100 * v / total)

        print("| %s | %s | %d | %.2f | %.4f | %s | %s | %s | %s | %s | %s | %s |" % (
            example.replace("/problem", " ").replace(".json", "").strip(), s["algorithm"], s["iterations"], total,
            total / max(1, s["iterations"]), pct(w["evaluation"]), pct(w["parametrization"]), pct(w["validity"]),
            pct(w["optimizer"]), pct(s["optimizer_cpu_seconds"]), pct(remeshing), pct(other)))


if __name__ == "__main__":
    main()
