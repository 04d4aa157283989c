#!/usr/bin/python3
"""The error of fitted modulus fields of study 404 against the truth.

    PYTHONPATH=build/python /usr/bin/python3 studies/404_bar_modulus_field/evaluate.py [--history] OUT [OUT ...]

OUT is the output folder of `diffipc optimize` on one of the study's problem files. The
fitted field is E = P(x) at the result's design x (summary.json `design`, mapped by the
problem's maps through diffipc.ReducedFunctional on OUT/optimal_problem.json), compared
per element with truth.json:

    relative L2 error   |E - E_true|_2 / |E_true|_2   (the elements have equal areas)
    max error           max_e |E_e - E_true_e| / E_true_e

Prints one markdown table row per OUT with summary.json's stop reason, iterations,
evaluations, rejected trials, J at the start and the end, wall time and the optimizer's
share of it. With --history, also the two errors at every design the run wrote
(OUT/design_<k>.vtu, cell data E; needs meshio).
"""
import json
import pathlib
import re
import sys

import numpy as np

import diffipc

HERE = pathlib.Path(__file__).resolve().parent


def load_truth(folder=HERE):
    truth = json.loads((pathlib.Path(folder) / "truth.json").read_text())
    return truth, np.asarray(truth["E"], dtype=float)


def field_errors(E, E_true):
    """(relative L2 error, max relative error) of a per-element field."""
    E = np.asarray(E, dtype=float)
    if E.shape != E_true.shape:
        raise ValueError(f"the field has {E.size} values, truth.json {E_true.size}")
    return (float(np.linalg.norm(E - E_true) / np.linalg.norm(E_true)),
            float((np.abs(E - E_true) / E_true).max()))


def fitted_field(out):
    """(E at the result's design, summary.json) of one optimize output folder."""
    out = pathlib.Path(out)
    summary = json.loads((out / "summary.json").read_text())
    J = diffipc.ReducedFunctional(str(out / "optimal_problem.json"))
    return np.asarray(J.parameters_of(np.asarray(summary["design"], dtype=float))), summary


def design_history(out):
    """[(iteration, E)] from the design_<k>.vtu files of an output folder."""
    import meshio
    found = []
    for path in pathlib.Path(out).glob("design_*.vtu"):
        m = re.fullmatch(r"design_(\d+)\.vtu", path.name)
        if m:
            mesh = meshio.read(path)
            found.append((int(m.group(1)), np.concatenate([np.ravel(a) for a in mesh.cell_data["E"]])))
    return sorted(found, key=lambda item: item[0])


def main(argv):
    history = "--history" in argv
    outs = [a for a in argv if a != "--history"]
    if not outs:
        raise SystemExit(__doc__)
    truth, E_true = load_truth()
    start = field_errors(np.full_like(E_true, truth["E_start"]), E_true)
    print(f"start (uniform {truth['E_start']:.6g} Pa): relative L2 error {start[0]:.4f}, max error {start[1]:.4f}")
    print("| run | stop | iterations | evaluations | rejected | J0 | J | rel. L2 error | max error | wall (s) "
          "| optimizer share |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for out in outs:
        E, s = fitted_field(out)
        l2, mx = field_errors(E, E_true)
        w = s["wall_time"]
        print(f"| {out} | {s['stop_reason']} | {s['iterations']} | {s['evaluations']} | {s['rejected']} | "
              f"{s['initial_J']:.4e} | {s['final_J']:.4e} | {l2:.4f} | {mx:.4f} | {w['total']:.1f} | "
              f"{w['optimizer'] / w['total']:.2e} |")
    if history:
        for out in outs:
            print(f"\n{out}: errors of the written designs")
            print("| iteration | rel. L2 error | max error |")
            print("| --- | --- | --- |")
            for k, E in design_history(out):
                l2, mx = field_errors(E, E_true)
                print(f"| {k} | {l2:.4f} | {mx:.4f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
