"""Study 407, the whole study by one command: the fits, the Fisher matrix, the load cell and the
drop test (what would make E identifiable), the noise study, the model comparison and the
figures; every part's printed result is collected in results.md.

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/run_all.py \
        [--out output/407] [--repeats 6] [--drop-fit] [--grid-e 4] [--grid-nu 7]

About 7 to 8 minutes on 2 cores with the defaults. --repeats sets the noise study's refits (8 in
the README's record), --drop-fit also fits the drop test (about 2.5 more minutes), --grid-e and
--grid-nu the landscape's grid (5 x 9 in the README's figure). Writes into --out: results.md,
markers.png, landscape.png (and .csv), convergence.png, and each part's runs in subfolders.
"""
import argparse
import os
import pathlib
import subprocess
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def markdown(text):
    """A part's printed output as markdown: its tables (runs of lines starting with "|") as they
    are, every other run of lines in a code block."""
    out, block = [], []
    for line in text.rstrip().splitlines() + [""]:
        if block and (line.startswith("|") != block[0].startswith("|") or not line):
            out += (block if block[0].startswith("|") else ["```"] + block + ["```"]) + [""]
            block = []
        if line:
            block.append(line)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407"))
    parser.add_argument("--repeats", type=int, default=6, help="refits of the noise study")
    parser.add_argument("--drop-fit", action="store_true", help="also fit the drop test's markers")
    parser.add_argument("--grid-e", type=int, default=4)
    parser.add_argument("--grid-nu", type=int, default=7)
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cli = ["--cli", args.cli]
    parts = [
        ("The fit from three far-off starts (L-BFGS-B) and with Ipopt", "run_study.py", cli + ["--out", str(out)]),
        ("Identifiability: the Fisher matrix of the marker residuals at the first fit", "fisher.py",
         ["--run", str(out / "lbfgsb_10_10")]),
        ("With a load cell: markers and the top plate's force (synthetic reading)", "force.py",
         cli + ["--out", str(out / "force")]),
        ("With a transient experiment: a synthetic drop test", "drop.py",
         cli + ["--out", str(out / "drop")] + ([] if args.drop_fit else ["--no-fit"])),
        ("Confidence checked by refits to noisy data", "noise_study.py",
         cli + ["--run", str(out / "lbfgsb_10_10"), "--out", str(out / "noise"), "--repeats", str(args.repeats)]),
        ("Sensitivity to the material model", "models.py", cli + ["--out", str(out / "models")]),
        ("Figures", "plots.py", ["--out", str(out), "--grid-e", str(args.grid_e), "--grid-nu", str(args.grid_nu)]),
    ]
    env = dict(os.environ)
    report = ["# Study 407: results", "",
              "Written by `studies/407_material_id_cube/run_all.py` (README.md there explains each part).", ""]
    start = time.time()
    for title, script, extra in parts:
        t0 = time.time()
        print(f"== {title} ({script})", flush=True)
        r = subprocess.run([sys.executable, str(HERE / script)] + extra, capture_output=True, text=True, env=env)
        sys.stdout.write(r.stdout)
        if r.returncode != 0:
            sys.stderr.write(r.stderr)
            raise SystemExit(f"run_all: {script} failed (exit {r.returncode})")
        report += [f"## {title}", "", f"`{script}`, {time.time() - t0:.0f} s.", ""] + markdown(r.stdout)
        (out / "results.md").write_text("\n".join(report) + "\n")
    total = time.time() - start
    report += [f"Whole study: {total:.0f} s."]
    (out / "results.md").write_text("\n".join(report) + "\n")
    print(f"== done in {total:.0f} s; wrote {out / 'results.md'}")


if __name__ == "__main__":
    main()
