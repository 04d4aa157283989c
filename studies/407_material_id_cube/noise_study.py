"""Study 407: the spread of refits to noisy data against the Fisher matrix's standard error of nu
(a parametric bootstrap).

    PYTHONPATH=build/python /usr/bin/python3 studies/407_material_id_cube/noise_study.py \
        [--repeats 8] [--seed 407] [--run output/407/lbfgsb_10_10] [--ranks N]

Noise model: independent Gaussian noise on every measured marker coordinate, with the standard
deviation of the fit's own residual (s = sqrt(2 J / (72 - 2)), 0.47 mm: the scanner's order,
and whatever the model leaves out). Each repetition takes the fitted model's marker positions
(the fit simulated; each marker carried by its barycentric coordinates in the rest mesh), adds
fresh noise and writes a marker file; the refits from the fit are one `diffipc sweep` (a point per
marker file, docs/sweep.md), over N MPI ranks with --ranks N (mpirun; docs/mpi.md). Prints the
fitted nu of each repetition, their mean and standard deviation, and the Fisher prediction.
"""
import argparse
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
import fisher  # noqa: E402  (nu's standard error)
import run_study  # noqa: E402  (the study's simulation and marker interpolation)

from diffipc.identifiability import fisher_matrix  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=8)
    parser.add_argument("--seed", type=int, default=407)
    parser.add_argument("--run", default=str(ROOT / "output" / "407" / "lbfgsb_10_10"))
    parser.add_argument("--cli", default=str(ROOT / "build" / "cli" / "diffipc"))
    parser.add_argument("--out", default=str(ROOT / "output" / "407" / "noise"))
    parser.add_argument("--ranks", type=int, default=1, help="MPI ranks for the refits (mpirun -n RANKS)")
    args = parser.parse_args()
    base = run_study.absolute(json.loads((HERE / "problem.json").read_text()))
    markers = np.loadtxt(base["objective"]["file"])
    x = np.array(json.loads((pathlib.Path(args.run) / "summary.json").read_text())["design"])
    R, F, J = fisher_matrix(json.loads((HERE / "problem.json").read_text()), x, base_directory=HERE)
    s = math.sqrt(2 * J / (R.shape[0] - R.shape[1]))
    nu_fit, se_nu = fisher.nu_and_standard_error(x, R, F, J)
    predicted = run_study.positions(base, x[0], x[1], markers)
    rng = np.random.default_rng(args.seed)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    points = []
    for k in range(args.repeats):
        noisy = predicted + rng.normal(0, s, size=predicted.shape)
        data = out / f"markers_{k}.txt"
        data.write_text("\n".join(" ".join("%.17g" % v for v in (*X, *y)) for X, y in zip(markers[:, :3], noisy)) + "\n")
        points.append({"objective.file": str(data)})
    # The refits from the fit: one sweep, a point per marker file.
    p = json.loads(json.dumps(base))
    p["parameters"][0]["initial"], p["parameters"][1]["initial"] = float(x[0]), float(x[1])
    sweep = out / "refits.json"
    sweep.write_text(json.dumps({"description": "study 407: refits to noisy marker data", "problem": p,
                                 "points": points}, indent=1))
    command = [args.cli, "sweep", str(sweep), "-o", str(out / "refits"), "-q"]
    env = dict(os.environ)
    if args.ranks > 1:
        # OpenMPI refuses root unless told (containers); the ranks share the machine's cores.
        command = [shutil.which("mpirun") or "mpirun", "-n", str(args.ranks), "--oversubscribe"] + command
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    subprocess.run(command, check=True, env=env)
    rows = json.loads((out / "refits" / "sweep.json").read_text())["runs"]
    nus = []
    for k, row in enumerate(rows):
        s_k = json.loads((out / "refits" / row["folder"] / "summary.json").read_text())
        lm, ll = s_k["design"]
        rk = math.exp(ll - lm)
        nus.append(rk / (2 * (rk + 1)))
        print("repetition %d: %s after %d iterations, nu = %.5f (rank %d)"
              % (k, s_k["stop_reason"], s_k["iterations"], nus[-1], row["rank"]))
    nus = np.array(nus)
    print("noise sigma %.3f mm per coordinate, %d repetitions (seed %d)" % (1e3 * s, args.repeats, args.seed))
    print("fit: nu = %.5f; Fisher standard error %.4f" % (nu_fit, se_nu))
    print("refits: mean nu = %.5f, standard deviation %.4f (%.2f of the Fisher prediction)"
          % (nus.mean(), nus.std(ddof=1), nus.std(ddof=1) / se_nu))


if __name__ == "__main__":
    main()
