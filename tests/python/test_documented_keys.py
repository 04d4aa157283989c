"""Every key the scene and problem readers accept is documented, and every documented key is accepted.

No list of keys is kept here. The keys the code accepts at an object are read from the code
itself: the readers refuse an unknown key with a message that lists the keys allowed at that
place (`bodies[0].material.zzz: unknown field (allowed here: model, E, ...)`), so each case
adds a probe key at one object of a valid file, runs `diffipc validate` (or `optimize`, for
the problem's `output`, which only it reads) and parses that list. The documented keys are
the first column of the table that follows a `<!-- keys: NAME -->` marker in docs/.
"""

import copy
import json
import os
import re
import subprocess

import pytest

from conftest import ROOT

PROBE = "zz_probe_key"
DOCS = ("scene_format.md", "problem_format.md", "optimization.md", "remeshing.md")
MARKER = re.compile(r"<!--\s*keys:\s*(\S+)\s*-->")
KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


# --- the documented keys -------------------------------------------------------------------


def _cells(line):
    return [c.strip() for c in line.strip().strip("|").split("|")]


def documented_tables(docs_dir=ROOT / "docs"):
    """{marker name: (file, set of keys)} of every marked key table in DOCS."""
    tables = {}
    for name in DOCS:
        lines = (docs_dir / name).read_text().splitlines()
        for i, line in enumerate(lines):
            m = MARKER.search(line)
            if not m:
                continue
            where = f"docs/{name}:{i + 1}"
            assert m.group(1) not in tables, f"{where}: key table '{m.group(1)}' is marked twice"
            j = i + 1
            while j < len(lines) and not lines[j].strip():
                j += 1
            assert j + 1 < len(lines) and lines[j].lstrip().startswith("|"), \
                f"{where}: the marker '{m.group(0)}' is not followed by a table"
            assert _cells(lines[j])[0] == "key", \
                f"{where}: the table after '{m.group(0)}' has no 'key' first column: {lines[j]}"
            assert set(_cells(lines[j + 1])[0]) <= set("-: "), f"docs/{name}:{j + 2}: not a table's rule"
            keys = set()
            for k in range(j + 2, len(lines)):
                if not lines[k].lstrip().startswith("|"):
                    break
                first = _cells(lines[k])[0]
                names = re.findall(r"`([^`]*)`", first)
                assert names, f"docs/{name}:{k + 1}: a key row without a `key` in its first cell: {lines[k]}"
                for n in names:
                    assert KEY.fullmatch(n), f"docs/{name}:{k + 1}: '{n}' in the key column is not a key name"
                    assert n not in keys, f"docs/{name}:{k + 1}: '{n}' is documented twice in one table"
                    keys.add(n)
            tables[m.group(1)] = (f"docs/{name}", keys)
    return tables


# --- the accepted keys ---------------------------------------------------------------------

OBJ_2D = "v 0 0 0\nv 1 0 0\nl 1 2\n"
MSH_2D = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
3
1 0 0 0
2 1 0 0
3 0 1 0
$EndNodes
$Elements
1
1 2 2 0 1 1 2 3
$EndElements
"""


def scene_2d():
    """Every object of a 2D scene, each with a valid value."""
    box = lambda lo, hi: {"min": lo, "max": hi}
    return {
        "description": "every object of a 2D scene",
        "dimension": 2,
        "bodies": [
            {"name": "block", "mesh": {"box": {"min": [0, 0], "max": [1, 0.5], "cells": [2, 1]}},
             "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000, "plane": "strain"},
             "friction": {"coefficient": 0.2}, "self_contact": False},
            {"name": "ring", "mesh": {"annulus": {"center": [3, 1], "inner_radius": 0.4, "outer_radius": 0.5,
                                                  "segments": 12}},
             "material": {"model": "linear", "E": 1e5, "nu": 0.3, "density": 1000}},
            {"name": "tri", "mesh": {"file": "tri.msh"}, "translation": [5, 0],
             "material": {"model": "linear", "E": 1e5, "nu": 0.3, "density": 1000}},
        ],
        "gravity": [0, -9.81],
        "dirichlet": [{"body": "block", "region": box([-1, -1], [0, 1]), "displacement": [0, 0]}],
        "neumann": [{"body": "block", "region": box([0.99, -1], [2, 1]), "traction": [0, "-1e3*t"]}],
        "time": {"integrator": "static", "dt": 0.5, "steps": 2, "adaptive": {"cut": 0.5}},
        "mass": "lumped",
        "solver": {"residual_tolerance": 1e-8},
        "output": {"directory": "out", "vtu_every": 0},
        "contact": {"dhat": 1e-3},
        "friction": {"coefficient": 0.1},
        "obstacles": [
            {"name": "floor", "plane": {"point": [0, -1], "normal": [0, 1]}, "friction": {"coefficient": 0.3}},
            {"name": "line", "mesh": {"file": "line.obj", "translation": [0, -2]}},
        ],
        "device": "cpu",
    }


def scene_3d():
    return {
        "dimension": 3,
        "bodies": [{"mesh": {"torus": {"major_radius": 1, "half_width": 0.2, "segments": 8}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
        "time": {"integrator": "implicit_euler", "dt": 0.01, "steps": 1},
    }


def scene_periodic():
    return {
        "dimension": 2,
        "bodies": [{"mesh": {"box": {"min": [0, 0], "max": [1, 1], "cells": [2, 2]}},
                    "material": {"model": "neo_hookean", "E": 1e5, "nu": 0.3, "density": 1000}}],
        "time": {"integrator": "static", "dt": 1, "steps": 1},
        "periodic": {"box": {"min": [0, 0], "max": [1, 1]}, "gradient": [["-0.01*t", 0], [0, None]]},
    }


def problem():
    """Every object of a problem file with one load case, each with a valid value."""
    scene = {
        "dimension": 2,
        "bodies": [{"name": "beam", "mesh": {"box": {"min": [0, 0], "max": [1, 0.2], "cells": [4, 1]}},
                    "material": {"model": "neo_hookean", "E": 1e6, "nu": 0.3, "density": 1000}}],
        "dirichlet": [{"body": "beam", "region": {"min": [-1, -1], "max": [1e-6, 1]}, "displacement": [0, 0]}],
        "neumann": [{"body": "beam", "region": {"min": [0.99, -1], "max": [2, 1]}, "traction": [0, "-1e3*t"]}],
        "time": {"integrator": "static", "dt": 0.5, "steps": 2},
    }
    return {
        "description": "every object of a problem",
        "scene": scene,
        "objective": {"type": "compliance", "time": "final"},
        "weight": 1,
        "parameters": [{"type": "E", "per": "body", "lower": 1e5, "upper": 1e7},
                       {"type": "shape", "vertices": {"body": "beam"}, "components": [1]}],
        "gradcheck": {"directions": 1},
        "checkpointing": {"stride": 1},
        "constraints": [{"name": "area", "objective": {"type": "volume", "configuration": "rest"}, "upper": 1}],
        "optimizer": {"max_iterations": 1, "final_taylor_check": {"step": 0.01}},
        "output": {"design_every": 0},
        "threads": 1,
    }


def problem_cases():
    p = problem()
    case = {"description": "the only case", "scene": p.pop("scene"), "objective": p.pop("objective"),
            "weight": p.pop("weight")}
    p["scenes"] = [case]
    p["constraints"][0]["case"] = 0
    return p


# (object path, doc table, base document, command). An object the base lacks is created as {}:
# every reader checks its keys before it reads a value, so the probe is refused first.
CASES = [
    ("", "scene", scene_2d, "validate"),
    ("bodies[0]", "body", scene_2d, "validate"),
    ("bodies[0].material", "material", scene_2d, "validate"),
    ("bodies[0].mesh", "mesh", scene_2d, "validate"),  # the box form
    ("bodies[2].mesh", "mesh", scene_2d, "validate"),  # the file form
    ("bodies[0].mesh.box", "mesh.box", scene_2d, "validate"),
    ("bodies[1].mesh.annulus", "mesh.annulus", scene_2d, "validate"),
    ("bodies[0].mesh.torus", "mesh.torus", scene_3d, "validate"),
    ("bodies[0].friction", "local_friction", scene_2d, "validate"),
    ("dirichlet[0]", "dirichlet", scene_2d, "validate"),
    ("dirichlet[0].region", "region", scene_2d, "validate"),
    ("neumann[0]", "neumann", scene_2d, "validate"),
    ("neumann[0].region", "region", scene_2d, "validate"),
    ("time", "time", scene_2d, "validate"),
    ("time.adaptive", "time.adaptive", scene_2d, "validate"),
    ("solver", "solver", scene_2d, "validate"),
    ("output", "output", scene_2d, "validate"),
    ("contact", "contact", scene_2d, "validate"),
    ("friction", "friction", scene_2d, "validate"),
    ("obstacles[0]", "obstacle", scene_2d, "validate"),
    ("obstacles[0].plane", "obstacle.plane", scene_2d, "validate"),
    ("obstacles[1].mesh", "obstacle.mesh", scene_2d, "validate"),
    ("obstacles[0].friction", "local_friction", scene_2d, "validate"),
    ("periodic", "periodic", scene_periodic, "validate"),
    ("periodic.box", "region", scene_periodic, "validate"),
    ("", "problem", problem, "validate"),
    ("scenes[0]", "problem.scenes", problem_cases, "validate"),
    ("parameters[0]", "problem.parameter", problem, "validate"),  # an E entry
    ("parameters[1]", "problem.parameter", problem, "validate"),  # a shape entry: the same keys
    ("parameters[1].vertices", "problem.parameter.vertices", problem, "validate"),
    ("constraints[0]", "problem.constraint", problem, "validate"),
    ("gradcheck", "problem.gradcheck", problem, "validate"),
    ("checkpointing", "problem.checkpointing", problem, "validate"),
    ("remesh", "problem.remesh", problem, "validate"),
    ("optimizer", "problem.optimizer", problem, "validate"),
    ("optimizer.final_taylor_check", "problem.optimizer.final_taylor_check", problem, "validate"),
    ("output", "problem.output", problem, "optimize"),
]


def _steps(path):
    return [int(s) if s.isdigit() else s for s in re.findall(r"[^.\[\]]+", path)]


def with_probe(document, path):
    doc = copy.deepcopy(document)
    node = doc
    for step in _steps(path):
        if isinstance(step, str) and step not in node:
            node[step] = {}
        node = node[step]
    assert isinstance(node, dict), f"{path} is not an object in the base document"
    node[PROBE] = 1
    return doc


def write_base(tmp_path, document):
    (tmp_path / "tri.msh").write_text(MSH_2D)
    (tmp_path / "line.obj").write_text(OBJ_2D)
    f = tmp_path / "input.json"
    f.write_text(json.dumps(document))
    return f


def run(cli, command, path, tmp_path):
    args = [os.path.abspath(cli), command, str(path)]
    if command == "optimize":
        args += ["-q", "-o", str(tmp_path / "opt")]
    return subprocess.run(args, capture_output=True, text=True, cwd=tmp_path, timeout=300)


def accepted_keys(cli, tmp_path, base, path, command):
    """The keys the code accepts at `path`, from its refusal of a probe key there."""
    r = run(cli, command, write_base(tmp_path, with_probe(base(), path)), tmp_path)
    where = f"{path}.{PROBE}" if path else PROBE
    m = re.search(re.escape(where) + r": unknown field \((?:allowed here|expected):? ([^)]*)\)", r.stderr)
    assert r.returncode != 0 and m, (
        f"'diffipc {command}' did not refuse the unknown key {where} with the list of allowed keys "
        f"(exit {r.returncode}): {r.stderr.strip() or r.stdout.strip()[-400:]}")
    return {k.strip() for k in m.group(1).split(",")} - {""}


# --- the tests -----------------------------------------------------------------------------


@pytest.mark.parametrize("base", [scene_2d, scene_3d, scene_periodic, problem, problem_cases],
                         ids=lambda b: b.__name__)
def test_base_documents_are_valid(cli, tmp_path, base):
    """The probes start from valid files, so a refusal is the probe's."""
    r = run(cli, "validate", write_base(tmp_path, base()), tmp_path)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("path,table,base,command", CASES, ids=[f"{c[1]}@{c[0] or 'root'}" for c in CASES])
def test_documented_keys_match_code(cli, tmp_path, path, table, base, command):
    tables = documented_tables()
    if table not in tables:
        pytest.fail(f"no key table '<!-- keys: {table} -->' in docs/ ({', '.join(DOCS)}): "
                    f"the keys of {base.__name__}'s {path or 'top level'} are not documented")
    doc, documented = tables[table]
    code = accepted_keys(cli, tmp_path, base, path, command)
    only_code, only_docs = sorted(code - documented), sorted(documented - code)
    if only_code or only_docs:
        pytest.fail(f"{base.__name__}: {path or 'top level'} (table '{table}' in {doc}):\n"
                    f"  accepted by the code but not documented: {only_code}\n"
                    f"  documented but refused by the code: {only_docs}")


def test_every_key_table_is_checked():
    """A marked table that no case compares would be a second, unchecked list."""
    unchecked = set(documented_tables()) - {c[1] for c in CASES}
    assert not unchecked, f"key tables no case checks: {sorted(unchecked)}"


def test_a_key_table_is_parsed(tmp_path):
    """The parser reads every key of a row (several per row too) and stops at the table's end."""
    docs = tmp_path / "docs"
    docs.mkdir()
    for name in DOCS:
        (docs / name).write_text("")
    (docs / "scene_format.md").write_text(
        "text\n<!-- keys: demo -->\n\n| key | meaning |\n| --- | --- |\n| `a` | x `not_a_key` |\n"
        "| `b`, `c` | y |\n\n| `d` | another table |\n")
    assert documented_tables(docs) == {"demo": ("docs/scene_format.md", {"a", "b", "c"})}
