"""Seeded mutations of scene, problem and mesh files for tests/python/test_fuzz.py.

A case is a copy of one seed (a study folder, or a small generated gmsh/OBJ scene)
with several mutations applied: structural ones on the parsed JSON (a value of
another kind, a deleted or unknown key, deep nesting, another enum value, an array
of another length, a NUL in a string, small and huge perturbations of numbers,
bad expressions and references), text-level ones on the JSON (truncation, inserted
bytes, duplicate keys) and line-level ones on a mesh file. Everything is a pure
function of (seed, case index): `make_case(seed, index)` gives the same files on
every machine, so a failing case is reproduced from its two numbers alone.
"""
import copy
import dataclasses
import json
import math
import pathlib
import random

ROOT = pathlib.Path(__file__).resolve().parents[2]
STUDIES = ROOT / "studies"

# Keys whose value sets the amount of work (mesh size, step count, iteration
# budgets): a case that raised one of them may legitimately run long or run out
# of the memory the fuzzer allows, as long as the value fits a 32-bit int.
SIZE_KEYS = {"steps", "cells", "segments", "layers", "cells_across", "max_iterations", "line_search_max_halvings",
             "iterations", "ccd_max_iterations", "directions", "halvings", "vtu_every", "stride", "dhat", "scale",
             "min_distance"}

# Every enum value of docs/scene_format.md, docs/problem_format.md and docs/objectives.md,
# and near misses: changing one string for another exercises combinations.
ENUMS = ["linear", "stvk", "neo_hookean", "stable_neo_hookean", "static", "implicit_euler", "bdf2", "newmark",
         "lumped", "consistent", "cholmod", "ldlt", "adaptive", "always", "strict", "permissive", "final", "sum",
         "trapezoid", "von_mises", "frobenius", "cauchy", "first_piola", "body", "element", "vertex", "group",
         "global", "all", "stride", "none", "stress_norm", "elastic_energy", "compliance", "volume",
         "kinetic_energy", "markers", "center_of_mass", "boundary_smoothness", "shape", "E", "nu", "density", "mu",
         "lambda", "initial_velocity", "initial_displacement", "prescribed", "friction", "Static", "NEO_HOOKEAN",
         " linear", "bdf2 ", "", "box", "file", "annulus", "torus", "plane", "mesh", "cpu", "gpu", "GPU"]

EXPRESSIONS = ["1/0", "sqrt(-1)", "log(0)", "t^1000", "10^400", "1e308*10", "-1e308*10", "", " ", "(((", "sin(",
               "t +", "t*", "x*y*z*t", "_pi", "_e", "nan", "inf", "1e999", "t?1:0", "t>0?1/0:0", "a=1", "t=1",
               "min()", "max(t)", "sum(t,x,y,z)", "rnd()", "sign(t)*1e30", "sin(t)" * 200, "(" * 300 + "t" + ")" * 300,
               "x\u0000y", "t;t", "\u00e9", "0x10", "1,5", "abs(-t)*1e-300", "exp(1000*t)", "exp(t)", "t/t",
               "0/0", "1e-320", "9" * 400]

WEIRD = ["", "abc", "NaN", "nan", "Infinity", "-Infinity", "inf", "1e999", "0x1p3", "true", "null", "\u00e9\u2713",
         "\U0001F600", "a\u0000b", "\u0000", "x" * 10000, True, False, None, [], {}, [1, 2, 3], [[1, 2], [3, 4]],
         {"x": 1}, [None], [""], 1e308, -1e308, 1e-300, 5e-324, -5e-324, 0, 0.0, -0.0, -1, 1, 2, 3, 0.5, 1.5,
         2 ** 31 - 1, 2 ** 31, -2 ** 31 - 1, 2 ** 32, 2 ** 53 + 1, 2 ** 63 - 1, 2 ** 63, 2 ** 64, -2 ** 63, 10 ** 30,
         -(10 ** 30), 123456789012345678901234567890, 1.7976931348623157e308, 2.2250738585072014e-308]

ENUM_GROUPS = [["linear", "stvk", "neo_hookean", "stable_neo_hookean"], ["static", "implicit_euler", "bdf2", "newmark"],
               ["lumped", "consistent"], ["cpu", "gpu"], ["cholmod", "ldlt"], ["adaptive", "always"], ["strict", "permissive"],
               ["final", "sum", "trapezoid"], ["von_mises", "frobenius"], ["cauchy", "first_piola"],
               ["body", "element", "vertex", "group", "global"], ["stride", "none"],
               ["stress_norm", "elastic_energy", "compliance", "volume", "kinetic_energy", "markers",
                "center_of_mass", "boundary_smoothness"],
               ["shape", "E", "nu", "density", "mu", "lambda", "initial_velocity", "initial_displacement",
                "prescribed", "friction"]]

NAMES = ["beam", "bar", "ring", "block", "plate", "ground", "slope", "wall", "sphere", "ghost", "", "body0",
         "body1", "a\u0000b", "x" * 300, 0, 1, 2, -1, 99, 2 ** 31, 2 ** 63, 1.5, -0.0, None, True, [0], {"body": 0}]


@dataclasses.dataclass
class Seed:
    name: str
    kind: str  # "scene" or "problem"
    main: str  # the file to run, relative to the case folder
    files: dict  # relative path -> bytes


@dataclasses.dataclass
class Case:
    seed: int
    index: int
    origin: str
    kind: str
    main: str
    files: dict
    mode: str  # "cli" or "python"
    mutations: list
    size_touched: bool  # a mutation changed a field of SIZE_KEYS (or a mesh file)
    time_touched: bool
    gradcheck_touched: bool


# ---------------------------------------------------------------------------
# Seeds


def _fmt(v):
    return repr(float(v))


def _box_triangles(nx, ny, lx, ly):
    nodes = [(i * lx / nx, j * ly / ny) for j in range(ny + 1) for i in range(nx + 1)]
    tris = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 1, a + nx + 2
            tris += [(a, b, d), (a, d, c)]
    return nodes, tris


def _box_tets(n, lx, ly, lz):
    idx = lambda i, j, k: (k * (n + 1) + j) * (n + 1) + i  # noqa: E731
    nodes = [(i * lx / n, j * ly / n, k * lz / n) for k in range(n + 1) for j in range(n + 1) for i in range(n + 1)]
    tets = []
    perms = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]
    for k in range(n):
        for j in range(n):
            for i in range(n):
                for p in perms:
                    c = [i, j, k]
                    verts = [idx(*c)]
                    for axis in p:
                        c[axis] += 1
                        verts.append(idx(*c))
                    x = [nodes[v] for v in verts]
                    e = [[x[m][q] - x[0][q] for q in range(3)] for m in (1, 2, 3)]
                    det = (e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
                           - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
                           + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]))
                    if det < 0:
                        verts[1], verts[2] = verts[2], verts[1]
                    tets.append(tuple(verts))
    return nodes, tets


def _msh22(nodes, elements, etype):
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(nodes))]
    for i, x in enumerate(nodes):
        c = list(x) + [0.0] * (3 - len(x))
        out.append(f"{i + 1} " + " ".join(_fmt(v) for v in c))
    out += ["$EndNodes", "$Elements", str(len(elements))]
    for i, e in enumerate(elements):
        out.append(f"{i + 1} {etype} 2 1 1 " + " ".join(str(v + 1) for v in e))
    out.append("$EndElements")
    return ("\n".join(out) + "\n").encode()


def _msh41(nodes, elements, etype, dim):
    n, m = len(nodes), len(elements)
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$Nodes", f"1 {n} 1 {n}", f"{dim} 1 0 {n}"]
    out += [str(i + 1) for i in range(n)]
    for x in nodes:
        c = list(x) + [0.0] * (3 - len(x))
        out.append(" ".join(_fmt(v) for v in c))
    out += ["$EndNodes", "$Elements", f"1 {m} 1 {m}", f"{dim} 1 {etype} {m}"]
    for i, e in enumerate(elements):
        out.append(f"{i + 1} " + " ".join(str(v + 1) for v in e))
    out.append("$EndElements")
    return ("\n".join(out) + "\n").encode()


def _dump(obj):
    return (json.dumps(obj, indent=1) + "\n").encode()


def _material(E=1e5):
    return {"model": "neo_hookean", "E": E, "nu": 0.3, "density": 1000}


def _generated_seeds():
    """Small scenes whose meshes are files, since the studies read only one OBJ."""
    seeds = []
    nodes, tris = _box_triangles(4, 2, 0.4, 0.2)
    scene = {"description": "generated: 2D gmsh 2.2 body falling on a plane", "dimension": 2,
             "bodies": [{"name": "block", "mesh": {"file": "block.msh"}, "material": _material(),
                         "translation": [0, 0.05], "initial_velocity": [0, -1]}],
             "obstacles": [{"name": "ground", "plane": {"point": [0, 0], "normal": [0, 1]}}],
             "contact": {"dhat": 1e-3}, "gravity": [0, -9.81],
             "time": {"integrator": "implicit_euler", "dt": 0.01, "steps": 3}, "output": {"vtu_every": 1}}
    seeds.append(Seed("gen_msh22_2d", "scene", "scene.json",
                      {"scene.json": _dump(scene), "block.msh": _msh22(nodes, tris, 2)}))

    nodes, tets = _box_tets(2, 0.3, 0.3, 0.3)
    scene = {"description": "generated: 3D gmsh 4.1 cube, clamped, under gravity", "dimension": 3,
             "bodies": [{"name": "cube", "mesh": {"file": "cube.msh"}, "material": _material(1e6)}],
             "dirichlet": [{"body": "cube", "region": {"min": [-1, -1, -1], "max": [1e-6, 1, 1]},
                            "displacement": [0, 0, "0.01*t"]}],
             "neumann": [{"body": 0, "region": {"min": [0.29, -1, -1], "max": [1, 1, 1]}, "traction": [0, "-1e3*t", 0]}],
             "gravity": [0, -9.81, 0], "time": {"integrator": "bdf2", "dt": 0.01, "steps": 3},
             "output": {"vtu_every": 1}}
    seeds.append(Seed("gen_msh41_3d", "scene", "scene.json",
                      {"scene.json": _dump(scene), "cube.msh": _msh41(nodes, tets, 4, 3)}))

    # 2D box above an OBJ polyline (v/l records), 3D box above a gmsh triangle surface.
    obj = b"# generated ground polyline\nv -1 0 0\nv 0 -0.02 0\nv 1 0 0\nl 1 2\nl 2 3\n"
    scene = {"description": "generated: 2D box on an OBJ polyline obstacle", "dimension": 2,
             "bodies": [{"name": "box", "mesh": {"box": {"min": [-0.1, 0.01], "max": [0.1, 0.1], "cells": [3, 2]}},
                         "material": _material(), "initial_velocity": [0.1, -1]}],
             "obstacles": [{"name": "ground", "mesh": {"file": "ground.obj", "scale": 1.0, "motion": ["0", "0.01*t"]},
                            "friction": {"coefficient": 0.3}}],
             "contact": {"dhat": 1e-3, "kappa": "adaptive"}, "friction": {"coefficient": 0.5, "iterations": 2},
             "gravity": [0, -9.81], "time": {"integrator": "newmark", "dt": 0.01, "steps": 3}}
    seeds.append(Seed("gen_obj_2d", "scene", "scene.json", {"scene.json": _dump(scene), "ground.obj": obj}))

    nodes, tris = _box_triangles(2, 2, 1.0, 1.0)
    surf = [(x - 0.5, 0.0, y - 0.5) for x, y in nodes]
    tris = [(a, c, b) for a, b, c in tris]
    scene = {"description": "generated: 3D box on a gmsh triangle surface obstacle", "dimension": 3,
             "bodies": [{"name": "box", "mesh": {"box": {"min": [-0.1, 0.01, -0.1], "max": [0.1, 0.1, 0.1],
                                                         "cells": [2, 1, 2]}},
                         "material": _material(), "initial_velocity": [0, -1, 0], "self_contact": False}],
             "obstacles": [{"name": "floor", "mesh": {"file": "floor.msh", "translation": [0, 0, 0]}}],
             "contact": {"dhat": 1e-3, "kappa": 1e6, "min_distance": 1e-5},
             "gravity": [0, -9.81, 0], "time": {"integrator": "implicit_euler", "dt": 0.01, "steps": 3}}
    seeds.append(Seed("gen_msh22_surface_3d", "scene", "scene.json",
                      {"scene.json": _dump(scene), "floor.msh": _msh22(surf, tris, 2)}))
    return seeds


def load_seeds():
    """The studies' scene and problem files (each with its whole folder) and the generated mesh seeds."""
    seeds = []
    for folder in sorted(STUDIES.iterdir()):
        if not folder.is_dir():
            continue
        files = {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}
        # A study whose files reference a subfolder (data/), or weigh more than 500 kB (a
        # scanned mesh), is not a seed: each case copies the folder's files and runs a
        # gradient check, hundreds of times.
        if any(p.is_dir() and p.name != "__pycache__" for p in folder.iterdir()) or sum(map(len, files.values())) > 500_000:
            continue
        for main, kind in (("scene.json", "scene"), ("problem.json", "problem")):
            if main in files:
                seeds.append(Seed(folder.name, kind, main, _lightened(files, main)))
    return seeds + _generated_seeds()


def _lightened(files, main, cells=500):
    """A problem whose inline scene meshes a box of more than `cells` cells gets a coarser box
    (the fuzzer tests input handling, and every case of it runs a gradient check), unless the
    problem names vertices by index, which a coarser mesh would renumber."""
    text = files[main].decode("utf-8", "replace")
    if main != "problem.json" or '"vertices"' in text:
        return files
    try:
        tree = json.loads(text)
    except ValueError:
        return files
    changed = False
    for body in tree.get("scene", {}).get("bodies", []) if isinstance(tree.get("scene"), dict) else []:
        box = body.get("mesh", {}).get("box") if isinstance(body.get("mesh"), dict) else None
        if not isinstance(box, dict) or not isinstance(box.get("cells"), list):
            continue
        count = 1
        for c in box["cells"]:
            count *= c
        if count > cells:
            factor = (count / cells) ** (1.0 / len(box["cells"]))
            box["cells"] = [max(1, int(c / factor)) for c in box["cells"]]
            changed = True
    if not changed:
        return files
    return {**files, main: json.dumps(tree, indent=1).encode()}


# ---------------------------------------------------------------------------
# JSON tree helpers


def _paths(node, prefix=()):
    """Every path (tuple of keys and indices) in the tree, the root included."""
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


def _get(tree, path):
    for key in path:
        tree = tree[key]
    return tree


def _set(tree, path, value):
    if not path:
        return value
    _get(tree, path[:-1])[path[-1]] = value
    return tree


def path_text(path):
    s = ""
    for key in path:
        s += f"[{key}]" if isinstance(key, int) else (f".{key}" if s else str(key))
    return s or "<root>"


def _perturb(value, rng, huge):
    if isinstance(value, bool):
        return not value
    if huge:
        choice = rng.random()
        if choice < 0.3:
            return value * rng.choice([1e3, 1e6, 1e12, 1e100, 1e300, -1e6, 1e-6, 1e-100, 1e-300])
        if choice < 0.5 and isinstance(value, int):
            return value * rng.choice([1000, 10 ** 6, 2 ** 31, 2 ** 62]) + rng.choice([0, 1, -1])
        if choice < 0.7:
            return -value if value else rng.choice([-1, 1e-300, 1e308])
        return value + rng.choice([1e15, -1e15, 1e300, -1e300, 2 ** 63])
    if isinstance(value, int):
        return value + rng.choice([-2, -1, 1, 2]) if rng.random() < 0.8 else float(value) + 1e-9
    if value == 0:
        return rng.choice([1e-15, -1e-15, 1e-300])
    return value * (1 + rng.choice([1e-15, -1e-15, 1e-9, -1e-9, 1e-3, -1e-3, 0.1, -0.1, 0.5]))


def _deep(value, depth, rng):
    for _ in range(depth):
        value = [value] if rng.random() < 0.5 else {"a": value}
    return value


class Mutator:
    def __init__(self, rng):
        self.rng = rng
        self.log = []
        self.touched = []

    def note(self, what, path):
        self.log.append(f"{what} at {path_text(path)}")
        self.touched.append(path)

    def pick(self, tree, want=None):
        paths = [p for p in _paths(tree) if want is None or want(p, _get(tree, p))]
        return self.rng.choice(paths) if paths else None

    def apply_mild(self, tree):
        """Mutations that often keep the file valid, so that the solver, not only the parser, is exercised."""
        ops = [(self.perturb_small, 5), (self.perturb_huge, 2), (self.enum_value, 3), (self.expression, 2),
               (self.duplicate_entries, 1)]
        op = self.rng.choices([o for o, _ in ops], weights=[w for _, w in ops])[0]
        return op(tree)

    def apply(self, tree):
        ops = [(self.replace_kind, 14), (self.delete_key, 8), (self.unknown_key, 4), (self.duplicate_entries, 4),
               (self.deep_nest, 3), (self.enum_value, 6), (self.resize_array, 6), (self.swap_values, 3),
               (self.nul_in_string, 3), (self.perturb_small, 8), (self.perturb_huge, 8), (self.expression, 6),
               (self.reference, 4), (self.dimension, 2), (self.copy_subtree, 3)]
        op = self.rng.choices([o for o, _ in ops], weights=[w for _, w in ops])[0]
        return op(tree)

    def replace_kind(self, tree):
        path = self.pick(tree, lambda p, v: p)
        if path is None:
            return tree
        value = self.rng.choice(WEIRD)
        self.note(f"replace by {json.dumps(value)[:40]}", path)
        return _set(tree, path, copy.deepcopy(value))

    def delete_key(self, tree):
        path = self.pick(tree, lambda p, v: p and isinstance(p[-1], str))
        if path is None:
            return tree
        del _get(tree, path[:-1])[path[-1]]
        self.note("delete key", path)
        return tree

    def unknown_key(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, dict))
        if path is None:
            return tree
        key = self.rng.choice(["colour", "Steps", "time ", "", "\u0000", "dt", "steps", "E", "x" * 200, "__proto__"])
        node = _get(tree, path)
        if key in node:
            key = key + "_"
        node[key] = copy.deepcopy(self.rng.choice(WEIRD[:30]))
        self.note(f"add key {key[:20]!r}", path + (key,))
        return tree

    def duplicate_entries(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, list) and v)
        if path is None:
            return tree
        node = _get(tree, path)
        if self.rng.random() < 0.5:
            node.append(copy.deepcopy(self.rng.choice(node)))
        else:
            node[:] = [copy.deepcopy(v) for v in node for _ in range(2)]
        self.note("duplicate entries", path)
        return tree

    def deep_nest(self, tree):
        path = self.pick(tree)
        depth = self.rng.choice([1, 2, 5, 62, 63, 64, 65, 70, 200])
        self.note(f"nest {depth} levels", path)
        return _set(tree, path, _deep(_get(tree, path), depth, self.rng))

    def enum_value(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, str) and p)
        if path is None:
            return self.replace_kind(tree)
        group = [g for g in ENUM_GROUPS if _get(tree, path) in g]
        value = self.rng.choice(group[0] if group and self.rng.random() < 0.7 else ENUMS)
        self.note(f"enum {value!r}", path)
        return _set(tree, path, value)

    def resize_array(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, list))
        if path is None:
            return tree
        node = _get(tree, path)
        r = self.rng.random()
        if r < 0.35 and node:
            del node[self.rng.randrange(len(node)):]
            what = "truncate array"
        elif r < 0.7:
            filler = node[-1] if node else 0
            node.extend(copy.deepcopy(filler) for _ in range(self.rng.choice([1, 1, 2, 100])))
            what = "extend array"
        else:
            node.append(self.rng.choice([0, 1.5, "t", None]))
            what = "append scalar"
        self.note(what, path)
        return tree

    def swap_values(self, tree):
        paths = [p for p in _paths(tree) if p]
        if len(paths) < 2:
            return tree
        a, b = self.rng.sample(paths, 2)
        if a[:len(b)] == b or b[:len(a)] == a:
            return tree
        va, vb = copy.deepcopy(_get(tree, a)), copy.deepcopy(_get(tree, b))
        _set(tree, a, vb)
        _set(tree, b, va)
        self.note(f"swap with {path_text(b)}", a)
        self.touched.append(b)
        return tree

    def nul_in_string(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, str) and p)
        if path is None:
            return tree
        s = _get(tree, path)
        i = self.rng.randrange(len(s) + 1)
        self.note("NUL in string", path)
        return _set(tree, path, s[:i] + "\u0000" + s[i:])

    def perturb_small(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, (int, float)) and not isinstance(v, bool) and p)
        if path is None:
            return tree
        self.note("perturb slightly", path)
        return _set(tree, path, _perturb(_get(tree, path), self.rng, huge=False))

    def perturb_huge(self, tree):
        path = self.pick(tree, lambda p, v: isinstance(v, (int, float)) and not isinstance(v, bool) and p)
        if path is None:
            return tree
        value = _perturb(_get(tree, path), self.rng, huge=True)
        if isinstance(value, float) and not math.isfinite(value):
            value = 1e308
        self.note("perturb hugely", path)
        return _set(tree, path, value)

    def expression(self, tree):
        keys = {"displacement", "traction", "motion"}
        path = self.pick(tree, lambda p, v: len(p) >= 2 and p[-2] in keys)
        if path is None:
            path = self.pick(tree, lambda p, v: isinstance(v, (int, float, str)) and p)
            if path is None:
                return tree
        self.note("expression", path)
        return _set(tree, path, self.rng.choice(EXPRESSIONS))

    def reference(self, tree):
        keys = {"body", "group", "vertices", "name", "file", "scene"}
        path = self.pick(tree, lambda p, v: p and p[-1] in keys)
        if path is None:
            return self.replace_kind(tree)
        if path[-1] == "file":
            value = self.rng.choice(["missing.msh", "", ".", "..", "/", "/dev/zero", "/dev/null", "scene.json",
                                     "problem.json", "a\u0000b.msh", "x" * 5000, "/proc/self/mem", "mesh.vtk",
                                     "sphere.obj", "block.msh", "cube.msh", "floor.msh", "ground.obj"])
        elif path[-1] == "scene":
            value = self.rng.choice(["scene.json", "problem.json", "missing.json", "", ".", "/dev/zero", 0, None])
        elif path[-1] == "vertices":
            value = self.rng.choice(["all", "none", [0, 0], [-1], [10 ** 9], [2 ** 31], [0.5], [], {"body": "ghost"},
                                     {"body": 99}, {"body": -1}, {}])
        else:
            value = self.rng.choice(NAMES)
        self.note(f"reference {json.dumps(value)[:40]}", path)
        return _set(tree, path, copy.deepcopy(value))

    def dimension(self, tree):
        path = self.pick(tree, lambda p, v: p and p[-1] == "dimension")
        if path is None:
            return self.replace_kind(tree)
        value = self.rng.choice([2, 3, 1, 4, 0, 2.0, 3.0000001, "3"])
        self.note(f"dimension {value!r}", path)
        return _set(tree, path, value)

    def copy_subtree(self, tree):
        """Graft a subtree in another place (a body where a material belongs, a region as a mesh)."""
        paths = [p for p in _paths(tree) if p]
        if len(paths) < 2:
            return tree
        src, dst = self.rng.sample(paths, 2)
        if dst[:len(src)] == src:
            return tree
        self.note(f"copy of {path_text(src)}", dst)
        return _set(tree, dst, copy.deepcopy(_get(tree, src)))


# ---------------------------------------------------------------------------
# Text-level mutations


def mutate_json_text(data, rng):
    """Corrupt the bytes of a JSON file; returns (bytes, description)."""
    n = len(data)
    r = rng.randrange(11)
    i = rng.randrange(n + 1)
    if r == 0:
        return data[:i], f"truncate at byte {i}"
    if r == 1:
        junk = rng.choice([b"\x00", b"\xff\xfe", b"\xc3", b"\x80", b"{", b"}", b"[", b"]", b",", b":", b'"', b"\\",
                           b"\\u", b"\\ud800", b"1e999", b"-", b"NaN", b"Infinity", b"\n", b"/*", b"//"])
        return data[:i] + junk + data[i:], f"insert {junk!r} at byte {i}"
    if r == 2:
        j = min(n, i + rng.randrange(1, 64))
        return data[:i] + data[j:], f"delete bytes {i}..{j}"
    if r == 3:
        digits = [k for k, c in enumerate(data) if chr(c).isdigit()]
        if digits:
            k = rng.choice(digits)
            new = rng.choice([b"9" * 400, b"1e999", b"-", b"e", b"00", b"0x1", b".", b"1e-400", b"18446744073709551616"])
            return data[:k] + new + data[k + 1:], f"replace digit at byte {k} by {new[:20]!r}"
        return data + b"x", "append x"
    if r == 4:
        return b"\xef\xbb\xbf" + data, "UTF-8 BOM"
    if r == 5:
        return data + rng.choice([b"x", b"{}", b"\x00", b" // c", b"\n\n"]), "trailing garbage"
    if r == 6:
        k = data.find(b"{")
        key = rng.choice([b'"dimension": 3, ', b'"time": 0, ', b'"bodies": [], ', b'"scene": {}, ',
                          b'"parameters": 7, ', b'"dimension": 2, '])
        return data[:k + 1] + key + data[k + 1:], f"duplicate key {key!r}"
    if r == 7:
        depth = rng.choice([64, 65, 1000, 100000])
        k = data.find(b":", i)
        if k < 0:
            k = data.find(b":")
        deep = b"[" * depth + b"1" + b"]" * depth + b","
        return data[:k + 1] + deep + data[k + 1:], f"insert {depth} nested arrays at byte {k + 1}"
    if r == 8:
        return b"", "empty file"
    if r == 9:
        return data.replace(b"\n", b"\r\n").replace(b" ", b"\t"), "CRLF and tabs"
    j = min(n, i + rng.randrange(1, 200))
    return data[:j] + data[i:j] * rng.choice([2, 3]) + data[j:], f"duplicate bytes {i}..{j}"


def mutate_mesh_text(data, rng):
    """Line-level corruption of an OBJ or gmsh file; returns (bytes, description)."""
    lines = data.split(b"\n")
    r = rng.randrange(10)
    i = rng.randrange(len(lines))
    if r == 0:
        k = rng.randrange(len(data) + 1)
        return data[:k], f"truncate at byte {k}"
    if r == 1:
        del lines[i]
        return b"\n".join(lines), f"delete line {i + 1}"
    if r == 2:
        lines.insert(i, lines[i])
        return b"\n".join(lines), f"duplicate line {i + 1}"
    if r in (3, 4, 5):
        numbered = [k for k, line in enumerate(lines) if any(chr(c).isdigit() for c in line)]
        if not numbered:
            return data + b"\nx\n", "append garbage"
        k = rng.choice(numbered)
        toks = lines[k].split(b" ")
        t = rng.randrange(len(toks))
        new = rng.choice([b"0", b"-1", b"1e308", b"-1e308", b"1e999", b"nan", b"inf", b"1e-300", b"2147483648",
                          b"4611686018427387904", b"18446744073709551615", b"99999", b"1.5", b"", b"x", b"\x00",
                          b"3", b"4", b"1e12", b"1e13", toks[t] + toks[t]])
        toks[t] = new
        lines[k] = b" ".join(toks)
        return b"\n".join(lines), f"line {k + 1} token {t} -> {new[:24]!r}"
    if r == 6:
        junk = rng.choice([b"garbage", b"\x00\x00", b"v 1 2", b"f 1 2 3 4 5", b"f 0 0 0", b"l 1", b"$Nodes",
                           b"$EndElements", b"$Elements\n1\n1 2 2 0 0 1 1 1\n$EndElements", b"v nan nan nan",
                           b"f -1 -2 -3", b"vn 0 0 1", b"f 1/1/1 2/2/2 3/3/3", b"\xff\xfe"])
        lines.insert(i, junk)
        return b"\n".join(lines), f"insert {junk[:24]!r} before line {i + 1}"
    if r == 7:
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines), f"swap lines {i + 1} and {j + 1}"
    if r == 8:
        return data.replace(b"\n", b"\r\n"), "CRLF"
    return b"", "empty file"


# ---------------------------------------------------------------------------
# Cases


def steps_cap(tree, kind, cap):
    """Clamp time.steps of the scene (inline scenes of a problem are left: their objectives name steps)."""
    if kind != "scene" or not isinstance(tree, dict):
        return
    t = tree.get("time")
    if isinstance(t, dict) and isinstance(t.get("steps"), int) and not isinstance(t.get("steps"), bool):
        if t["steps"] > cap:
            t["steps"] = cap


def _touches(paths, keys):
    return any(any(isinstance(k, str) and k in keys for k in p) for p in paths)


def make_case(seed, index, seeds=None, max_steps=3):
    rng = random.Random(f"diffipc-fuzz-{seed}-{index}")
    seeds = seeds or load_seeds()
    origin = rng.choice(seeds)
    files = dict(origin.files)
    mutations = []
    touched = []
    mesh_files = [f for f in files if f.endswith((".msh", ".obj"))]
    referenced = [f for f in mesh_files if f.encode() in files[origin.main]]

    tree = json.loads(files[origin.main])
    strategy = rng.random()
    mutate_mesh = referenced and strategy < 0.2
    text_level = 0.2 <= strategy < 0.35
    if mutate_mesh:
        name = rng.choice(referenced)
        data = files[name]
        for _ in range(rng.choice([1, 1, 2, 3])):
            data, what = mutate_mesh_text(data, rng)
            mutations.append(f"{name}: {what}")
        files[name] = data
    mild = not mutate_mesh and not text_level and rng.random() < 0.55
    if not mutate_mesh or rng.random() < 0.3:
        m = Mutator(rng)
        for _ in range(rng.choice([1, 1, 2, 3] if mild else [1, 2, 2, 3, 3, 4, 5])):
            tree = m.apply_mild(tree) if mild else m.apply(tree)
        mutations += [f"{origin.main}: {entry}" for entry in m.log]
        touched += m.touched
    # Clamp the steps unless a mutation wrote them (or the "time" object, or the root).
    time_touched = _touches(touched, {"steps"}) or any(p in ((), ("time",)) for p in touched)
    if not time_touched:
        steps_cap(tree, origin.kind, max_steps)
    try:
        text = (json.dumps(tree, indent=1) + "\n").encode()
    except ValueError:
        text = json.dumps(tree).encode()
    if text_level:
        for _ in range(rng.choice([1, 1, 2])):
            text, what = mutate_json_text(text, rng)
            mutations.append(f"{origin.main}: text {what}")
    files[origin.main] = text
    mode = "python" if rng.random() < 0.15 else "cli"
    return Case(seed=seed, index=index, origin=origin.name, kind=origin.kind, main=origin.main, files=files,
                mode=mode, mutations=mutations,
                size_touched=bool(mutate_mesh) or _touches(touched, SIZE_KEYS) or any(len(p) <= 1 for p in touched)
                or any(("digit" in m or "duplicate bytes" in m) for m in mutations),
                time_touched=time_touched, gradcheck_touched=_touches(touched, {"gradcheck"}))


def write_case(case, folder):
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in case.files.items():
        (folder / name).write_bytes(data)
    return folder
