"""Study 501 (studies/501_scene_work): only the work a scene needs. Every example scene runs one
step through the CLI and its summary.json's per-potential counts are checked against what the
scene's JSON needs; the check itself is shown to catch each kind of needless (or missing) work."""
import copy
import json
import os

import pytest

from conftest import ROOT, box_scene, load_script

STUDY = ROOT / "studies" / "501_scene_work"


study = load_script(STUDY / "run.py")


def test_every_example_scene_runs_only_what_it_needs(cli, tmp_path):
    table = tmp_path / "table.md"
    rc = study.main(["--cli", cli, "-o", str(tmp_path / "runs"), "--steps", "1", "--table", str(table)])
    assert rc == 0, "a scene or a problem ran work it does not need (see the VIOLATION lines above)"
    text = table.read_text()
    scenes = study.example_scenes()
    assert len(scenes) >= 15
    for path in scenes:
        assert f"`{os.path.relpath(path, ROOT)}`" in text, path
    rows = (tmp_path / "table.csv").read_text().splitlines()
    assert rows[0].startswith("scene,potential")
    assert any(",friction," in r for r in rows) and any(",inertia," in r for r in rows)


def run(cli, tmp_path, scene, name):
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps(scene))
    rel, summary = study.run_scene(cli, str(path), str(tmp_path / "runs"), None, 0)
    return summary


def test_the_check_catches_needless_and_missing_work(cli, tmp_path):
    # A dynamic box without loads or contact: inertia and elasticity only.
    scene = box_scene(dim=2, steps=1)
    summary = run(cli, tmp_path, scene, "plain")
    assert study.check("plain", scene, summary) == []
    assert set(k for k, v in summary["potentials"].items() if study.evaluations(v) > 0) == {"inertia", "elastic"}

    def violations(edit):
        s = copy.deepcopy(summary)
        edit(s)
        return study.check("plain", scene, s)

    zero = {"values": 0, "gradients": 0, "hessians": 0, "step_bounds": 0, "time": 0.0}
    ran = {"values": 3, "gradients": 2, "hessians": 1, "step_bounds": 1, "time": 1e-4}
    # External forces evaluated without gravity or tractions.
    assert any("external_force" in m for m in violations(lambda s: s["potentials"].update(external_force=ran)))
    # Listed but never evaluated is fine (a term the problem holds and skips).
    assert violations(lambda s: s["potentials"].update(external_force=zero)) == []
    # Friction or contact work in a scene without contact.
    assert any("friction" in m for m in violations(lambda s: s["potentials"].update(friction=ran)))
    assert any("contact" in m for m in violations(lambda s: s["wall_time"].update(broad_phase=0.01)))
    # Inertia missing from a dynamic scene, elasticity missing, an unknown term.
    assert any("inertia" in m for m in violations(lambda s: s["potentials"].update(inertia=zero)))
    assert any("elastic" in m for m in violations(lambda s: s["potentials"].pop("elastic")))
    assert any("unknown" in m for m in violations(lambda s: s["potentials"].update(penalty=ran)))


def test_static_scene_skips_inertia_and_zero_friction_builds_nothing(cli, tmp_path):
    # Static: no inertia. Contact with friction coefficient 0 everywhere: no friction term at all.
    scene = box_scene(dim=2, steps=1, integrator="static")
    scene["bodies"][0]["mesh"]["box"]["min"] = [0.0, 0.01]
    scene["obstacles"] = [{"name": "floor", "plane": {"point": [0, 0], "normal": [0, 1]}}]
    scene["friction"] = {"coefficient": 0.0}
    scene["gravity"] = [0, -9.81]
    scene["dirichlet"] = [{"body": "b", "region": {"min": [-1, -1], "max": [0, 1]}, "displacement": [0, None]}]
    summary = run(cli, tmp_path, scene, "static")
    assert summary["status"] == "CONVERGED"
    assert study.check("static", scene, summary) == []
    assert "inertia" not in summary["potentials"] and "friction" not in summary["potentials"]
    assert study.evaluations(summary["potentials"]["contact"]) > 0
    # The same scene with a positive coefficient on the floor: friction runs.
    scene["obstacles"][0]["friction"] = {"coefficient": 0.5}
    scene["bodies"][0]["friction"] = {"coefficient": 0.5}
    summary = run(cli, tmp_path, scene, "static_friction")
    assert study.check("static_friction", scene, summary) == []
    assert study.evaluations(summary["potentials"]["friction"]) > 0


def test_the_adjoint_computes_only_the_blocks_its_parameters_read(tmp_path):
    # Two examples here (the study's run covers all of them): a shape and a material problem.
    for name, block in (("301_beam_shape_stress", "rest_positions"), ("302_bar_youngs_markers", "lame")):
        types, needed, computed, forward, adjoint = study.adjoint_work(str(ROOT / "studies" / name / "problem.json"))
        assert needed == computed == [block], (name, types, computed)
        assert forward > 0 and adjoint > 0
    # The check names an extra or a missing block.
    assert study.check_adjoint("p", ["E"], ["lame"], ["lame"]) == []
    assert "rest_positions" in study.check_adjoint("p", ["E"], ["lame"], ["lame", "rest_positions"])[0]
    assert "did not compute ['lame']" in study.check_adjoint("p", ["E"], ["lame"], [])[0]
