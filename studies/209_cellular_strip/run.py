#!/usr/bin/env python3
"""Study 209: the cellular strip compressed to 50%, without and with friction on its self-contact.

    PYTHONPATH=build/python /usr/bin/python3 studies/209_cellular_strip/run.py [--cli build/cli/diffipc]
        [-o output/209] [--threads N] [--cases plain friction] [--summarize-only]

Runs scene.json ("plain") and scene_friction.json ("friction"), checks every committed state with
`diffipc check` (exact inversion, intersection and containment tests, independent of the solver's
contact code), and writes results.md (outcome, Newton iterations, cuts, control and relaxation
solves, valid states), force_displacement.png (the force on the top edge, per metre of depth,
against its displacement) and frames.png (the deformed strips at 0, 25 and 50% compression).

The force is recomputed from the VTU frames, not taken from the solver: at each top-edge vertex the
nodal elastic force sum_e area_e sigma_e grad N_a (Cauchy stress of the frame, shape-function
gradients on the deformed triangle) less the barrier force there.
"""
import argparse
import json
import os
import subprocess

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CASES = {"plain": "scene.json", "friction": "scene_friction.json"}
TOP = 0.044  # rest height of the top edge (m)
PUSH = 0.022  # its prescribed displacement at t = 1 (m)


def run_case(cli, out, case, threads):
    scene = os.path.join(HERE, CASES[case])
    folder = os.path.join(out, case)
    os.makedirs(folder, exist_ok=True)
    cmd = [cli] + (["--threads", str(threads)] if threads else []) + ["simulate", scene, "-o", folder, "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    open(os.path.join(folder, "log.txt"), "w").write(done.stdout + done.stderr)


def top_force(frame, top):
    """Vertical force (N/m) that the top edge exerts on the strip in a VTU frame."""
    import meshio
    m = meshio.read(frame)
    p = m.points[:, :2]
    tri = m.cells_dict["triangle"]
    sigma = m.cell_data_dict["stress"]["triangle"].reshape(-1, 3, 3)[:, :2, :2]
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    force = np.zeros_like(p)
    for i, (q, r) in enumerate(((b, c), (c, a), (a, b))):
        # grad N_i on the deformed triangle: the opposite edge (q to r) rotated by +90 degrees, over
        # twice the area (for a = 0, b = e_x, c = e_y: grad N_a = (-1, -1)).
        edge = r - q
        grad = np.stack([-edge[:, 1], edge[:, 0]], axis=1) / area2[:, None]
        np.add.at(force, tri[:, i], 0.5 * area2[:, None] * np.einsum("eij,ej->ei", sigma, grad))
    if "contact_force" in m.point_data:
        force -= m.point_data["contact_force"][:, :2]
    return -force[top, 1].sum()  # the edge pushes down: report the compressive force as positive


def summarize(out, case):
    folder = os.path.join(out, case)
    summary = json.load(open(os.path.join(folder, "summary.json")))
    with h5py.File(os.path.join(folder, "trajectory.h5"), "r") as f:
        t = f["time"][:]
        its = f["newton_iterations"][:]
        rest = f["mesh/rest_positions"][:]
        cols = {k: f[k][:] for k in ("substeps", "cuts", "control_steps", "relaxation_steps") if k in f}
    top = np.flatnonzero(rest[:, 1] >= TOP - 1e-9)
    base = np.flatnonzero(rest[:, 1] <= 1e-9)
    frames = [os.path.join(folder, f"frame_{k}.vtu") for k in range(len(t))]
    force = [top_force(frame, top) for frame in frames]
    # Equilibrium: the base carries the same force (no gravity); the largest relative mismatch.
    balance = max(abs(f + top_force(frame, base)) / max(abs(f), 1e-300) for f, frame in zip(force[1:], frames[1:]))
    check = subprocess.run([ARGS.cli, "check", folder, "--scene", os.path.join(HERE, CASES[case]), "-q"],
                           capture_output=True, text=True)
    valid = check.stdout.strip().splitlines()[-1] if check.stdout.strip() else check.stderr.strip()
    return dict(t=t, its=its, force=np.array(force), balance=balance, summary=summary, check=valid, **cols)


def main(argv=None):
    global ARGS
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default="build/cli/diffipc")
    p.add_argument("-o", "--output", default="output/209")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    p.add_argument("--summarize-only", action="store_true", help="do not run; summarize the case folders")
    ARGS = a = p.parse_args(argv)
    if not a.summarize_only:
        for case in a.cases:
            run_case(a.cli, a.output, case, a.threads)
    rows, results = [], {}
    for case in a.cases:
        s = results[case] = summarize(a.output, case)
        steps = len(s["t"]) - 1
        total = lambda k: int(sum(s.get(k, [0])))
        rows.append(f"| {case} | {s['summary']['status']} | {steps} | {100 * PUSH * s['t'][-1] / TOP:.1f}% | "
                    f"{int(s['its'].sum())} | {np.median(s['its']):.0f} | {total('substeps')} | {total('cuts')} | "
                    f"{total('control_steps')} | {total('relaxation_steps')} | {s['force'].max():.1f} | {s['balance']:.1e} | "
                    f"{s['summary']['wall_time']['total']:.0f} | {s['check']} |")
        print(rows[-1], flush=True)
    with open(os.path.join(a.output, "results.md"), "w") as f:
        f.write("| case | status | steps | compression | Newton its | median its / step | sub-steps | cuts | "
                "control solves | relaxation solves | peak force (N/m) | top/base force mismatch | wall time (s) | "
                "diffipc check |\n|" + " --- |" * 14 + "\n" + "\n".join(rows) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for case, s in results.items():
        ax.plot(PUSH * s["t"] * 1e3, s["force"], "o-", ms=3, label=case)
    ax.set_xlabel("top edge displacement (mm)")
    ax.set_ylabel("force on the top edge (N per m of depth)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(a.output, "force_displacement.png"), dpi=120)
    import meshio
    fig, axes = plt.subplots(len(results), 3, figsize=(12, 2.6 * len(results)), squeeze=False)
    for row, (case, s) in zip(axes, results.items()):
        n = len(s["t"]) - 1
        for ax, k in zip(row, (0, n // 2, n)):
            m = meshio.read(os.path.join(a.output, case, f"frame_{k}.vtu"))
            ax.triplot(m.points[:, 0], m.points[:, 1], m.cells_dict["triangle"], lw=0.15)
            ax.set_aspect("equal")
            ax.set_title(f"{case}, {100 * PUSH * s['t'][k] / TOP:.0f}%", fontsize=9)
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(a.output, "frames.png"), dpi=60)


if __name__ == "__main__":
    main()
