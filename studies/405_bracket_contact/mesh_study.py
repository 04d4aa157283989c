"""How the figures of study 405 depend on the girder's mesh: the start (h = 0) and a written
design (the `design` of a run's summary.json) on box meshes of 40 x 6, 120 x 18 and 240 x 36
cells. For each it evaluates the objective of `problem.json` with the box's cells changed
(`diffipc.ReducedFunctional`), writes that mesh's rest design as a VTU and hands it to
`check_design.py`, which simulates it again and reports the contact and the element
stresses. The design variables (the FFD control values) mean the same on every mesh.

    PYTHONPATH=build/python /usr/bin/python3 studies/405_bracket_contact/mesh_study.py \
        output/405/summary.json [--cli build/cli/diffipc]
"""
import argparse
import importlib.util
import json
import pathlib
import sys
import tempfile

import meshio
import numpy as np

import diffipc

STUDY = pathlib.Path(__file__).resolve().parent
MESHES = ([40, 6], [120, 18], [240, 36])


def check_design_module():
    spec = importlib.util.spec_from_file_location("check_design_405", STUDY / "check_design.py")
    module = importlib.util.module_from_spec(spec)
    sys.dont_write_bytecode = True  # no __pycache__ in the study folder
    spec.loader.exec_module(module)
    return module


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("summary", help="summary.json of a run of problem.json (its design)")
    parser.add_argument("--cli", default="build/cli/diffipc")
    args = parser.parse_args()
    design = json.loads(pathlib.Path(args.summary).read_text())["design"]
    check = check_design_module().check
    print("cells    design  triangles  J                  max von Mises (Pa), at      over roller  elsewhere"
          "  roller's share of the p-norm sum  min gap (mm)  pairs  contact vertices")
    with tempfile.TemporaryDirectory() as tmp:
        for cells in MESHES:
            problem = json.loads((STUDY / "problem.json").read_text())
            problem["scene"]["bodies"][0]["mesh"]["box"]["cells"] = cells
            problem_path = pathlib.Path(tmp) / f"problem_{cells[0]}x{cells[1]}.json"
            problem["scene"]["obstacles"][0]["mesh"]["file"] = str(STUDY / "roller.obj")
            problem_path.write_text(json.dumps(problem))
            scene = diffipc.scene(problem["scene"], base_directory=str(STUDY))
            J = diffipc.ReducedFunctional(problem, base_directory=str(STUDY))
            nb = int((np.asarray(scene.vertex_body) == 0).sum())
            triangles = np.asarray(scene.elements)
            for name, x in (("start", [0.0] * len(design)), ("design", design)):
                value, _ = J.evaluate(J.parameters_of(x), gradient=False)
                rest = np.asarray(J.parameters_of(x)).reshape(-1, 2)[:nb]
                vtu = pathlib.Path(tmp) / f"{cells[0]}x{cells[1]}_{name}.vtu"
                meshio.write(vtu, meshio.Mesh(np.hstack([rest, np.zeros((nb, 1))]), [("triangle", triangles)]))
                r = check(problem_path, vtu, args.cli)
                if r.get("status") != "CONVERGED":
                    sys.exit(f"{cells} {name}: the re-simulation did not converge: {r}")
                share = f"{100 * r['p_norm_sum_share_over_roller']:.2g}%"
                print(f"{cells[0]:>3} x {cells[1]:<3} {name:<7} {len(triangles):>9}  {value:<17.2f}  "
                      f"{r['max_von_mises']:>8.0f} ({r['max_von_mises_at'][0]:.3f}, {r['max_von_mises_at'][1]:.3f})"
                      f"  {r['max_von_mises_over_roller']:>11.0f}  {r['max_von_mises_off_roller']:>9.0f}"
                      f"  {share:>32}  {1e3 * r['min_gap']:>12.3f}"
                      f"  {r['active_contacts']:>5}  {len(r['contact_x'])}")


if __name__ == "__main__":
    main()
