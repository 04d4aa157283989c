"""diffipc.plot: PNG figures of a ``diffipc optimize`` output directory (docs/python.md).

Four figures, each from what the run wrote (docs/optimization.md, "Output"):

* ``convergence.png``: J, its relative distance to the final J, the gradient norm and the
  step norm per iteration (``history.csv``);
* ``constraints.png``: each constraint's value g against its bound (the bounds from
  ``optimal_problem.json``) and its relative violation as the optimizer measures it;
* ``objective_over_time.png``: the objective's per-state values f_k (a per-state objective)
  or per-step contributions (``markers``, ``center_of_mass``) over the run, at the initial
  and at the optimal design. These are not in the output: they are recomputed with
  ``diffipc.ReducedFunctional`` on the problem truncated after each step, and the value at
  the horizon is checked against the J the run wrote before anything is drawn;
* ``design.png``: the initial and the optimal design side by side (design_0.vtu and
  design_final.vtu), coloured per element by the von Mises stress at the final load, one colour
  scale for both (2D: the filled rest mesh; 3D: its boundary surface). The stresses come from
  the scene re-simulated on each design's rest mesh (:func:`design_states`).

From the shell: ``python3 -m diffipc.plot DIR [--problem FILE] [--refine N]``. From Python:
``plot_run(DIR)``, or ``plot_convergence``, ``plot_constraints``,
``plot_objective_over_time``, ``plot_design`` for one figure; each returns a :class:`Plot` (``path``,
``figure``, ``data``: the arrays it drew). Matplotlib's Agg canvas is used directly (no
pyplot, no display). A missing or malformed directory or file raises ValueError naming it.
"""

import argparse
import copy
import csv
import json
import os
import sys

import numpy as np

__all__ = [
    "Plot",
    "OptimizationRun",
    "read_run",
    "violations",
    "objective_over_time",
    "plot_convergence",
    "plot_constraints",
    "plot_objective_over_time",
    "design_states",
    "plot_design",
    "plot_run",
    "main",
]

#: history.csv's columns before and after the constraints' (docs/optimization.md, "Output").
HEAD_COLUMNS = ("iteration", "J")
TAIL_COLUMNS = ("gradient_norm", "step_norm", "evaluations", "rejected", "evaluation_seconds",
                "optimizer_seconds", "wall_seconds")

#: Objectives that measure one state (docs/objectives.md, "Per-state objectives and `time`"),
#: with the unit of f for the axis label.
PER_STATE = {"stress_norm": "Pa", "elastic_energy": "J", "compliance": "J", "volume": "m^d",  # d: dimension
             "kinetic_energy": "J", "reaction_force": "N"}
#: Objectives that compare listed states with targets: one contribution per listed state
#: (``reaction_force`` is one of these when it has ``targets``, else a per-state objective).
TRACKING = {"markers": "m^2", "center_of_mass": "m^2", "reaction_force": "N^2"}


def _is_tracking(objective):
    """Does this objective compare listed states with targets?"""
    name = objective.get("type")
    return name in TRACKING and (name != "reaction_force" or "targets" in objective)

#: Relative tolerance of the check that the recomputed objective reproduces the run's J.
REPRODUCTION_TOLERANCE = 1e-8


class Plot:
    """One written figure: ``path`` (the PNG), ``figure`` (matplotlib Figure) and ``data``
    (dict of the numpy arrays drawn, by name)."""

    def __init__(self, path, figure, data):
        self.path = path
        self.figure = figure
        self.data = data

    def __repr__(self):
        return f"Plot({self.path!r}, data keys {sorted(self.data)})"


class OptimizationRun:
    """What ``diffipc optimize -o DIR`` wrote, read by :func:`read_run`.

    ``directory``; ``history``: dict column name -> numpy array (one entry per row of
    history.csv, row 0 the start); ``columns``: the CSV's column names in order;
    ``constraint_names``: the constraint columns; ``summary``: summary.json as a dict;
    ``problem``: optimal_problem.json as a dict (None if the file is absent);
    ``constraints``: per constraint, a dict ``name``, ``kind`` (``"upper"``, ``"lower"``,
    ``"equals"``) and ``bound`` (from ``problem``; empty without constraints);
    ``constraint_tolerance``: the optimizer's relative tolerance (default 1e-6).
    """

    def __init__(self, directory, columns, history, summary, problem):
        self.directory = directory
        self.columns = columns
        self.history = history
        self.summary = summary
        self.problem = problem
        self.constraint_names = columns[len(HEAD_COLUMNS):len(columns) - len(TAIL_COLUMNS)]
        self.constraints = _constraint_bounds(directory, self.constraint_names, problem)
        optimizer = (problem or {}).get("optimizer") or {}
        self.constraint_tolerance = float(optimizer.get("constraint_tolerance", 1e-6))


def _read_json(path):
    if not os.path.isfile(path):
        raise ValueError(f"{path}: missing (is the directory the output of `diffipc optimize -o DIR`?)")
    try:
        with open(path) as f:
            value = json.load(f)
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: not readable as JSON ({e})") from None
    if not isinstance(value, dict):
        raise ValueError(f"{path}: expected a JSON object")
    return value


def _read_history(path):
    if not os.path.isfile(path):
        raise ValueError(f"{path}: missing (is the directory the output of `diffipc optimize -o DIR`?)")
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise ValueError(f"{path}: not readable as CSV ({e})") from None
    if not rows:
        raise ValueError(f"{path}: empty (no header)")
    columns = [c.strip() for c in rows[0]]
    n_head, n_tail = len(HEAD_COLUMNS), len(TAIL_COLUMNS)
    if (len(columns) < n_head + n_tail or tuple(columns[:n_head]) != HEAD_COLUMNS
            or tuple(columns[len(columns) - n_tail:]) != TAIL_COLUMNS):
        raise ValueError(f"{path}: header {','.join(columns)!r} is not iteration,J,<constraints...>,"
                         + ",".join(TAIL_COLUMNS))
    if len(set(columns)) != len(columns):
        raise ValueError(f"{path}: a column name appears twice in the header")
    if len(rows) < 2:
        raise ValueError(f"{path}: no iteration rows (the start, iteration 0, is always written)")
    values = np.empty((len(rows) - 1, len(columns)))
    for i, row in enumerate(rows[1:]):
        line = i + 2
        if len(row) != len(columns):
            raise ValueError(f"{path} line {line}: {len(row)} values, the header has {len(columns)}")
        for j, text in enumerate(row):
            try:
                values[i, j] = float(text)
            except ValueError:
                raise ValueError(f"{path} line {line}: column '{columns[j]}': not a number: {text!r}") from None
    iterations = values[:, 0]
    if iterations[0] != 0 or np.any(np.diff(iterations) != 1):
        raise ValueError(f"{path}: column 'iteration' must count 0, 1, 2, ... (got {iterations[:5].tolist()}...)")
    return columns, {c: values[:, j].copy() for j, c in enumerate(columns)}


def _constraint_bounds(directory, names, problem):
    if not names:
        return []
    path = os.path.join(directory, "optimal_problem.json")
    if problem is None:
        raise ValueError(f"{path}: missing; history.csv has constraint columns "
                         f"({', '.join(names)}) whose bounds are in it")
    entries = problem.get("constraints")
    if not isinstance(entries, list) or len(entries) != len(names):
        raise ValueError(f"{path}: constraints: expected {len(names)} entries (history.csv's columns "
                         f"{', '.join(names)}), got {entries!r:.200}")
    out = []
    for i, (entry, column) in enumerate(zip(entries, names)):
        field = f"{path}: constraints[{i}]"
        if not isinstance(entry, dict):
            raise ValueError(f"{field}: expected an object")
        name = entry.get("name", f"constraint {i}")
        if name != column:
            raise ValueError(f"{field}.name: '{name}' is not history.csv's column '{column}'")
        kinds = [k for k in ("upper", "lower", "equals") if k in entry]
        if len(kinds) != 1 or isinstance(entry[kinds[0]], bool) or not isinstance(entry[kinds[0]], (int, float)):
            raise ValueError(f"{field}: expected exactly one numeric 'upper', 'lower' or 'equals'")
        out.append({"name": name, "kind": kinds[0], "bound": float(entry[kinds[0]])})
    return out


def read_run(directory):
    """Read an optimization output directory (history.csv, summary.json, optimal_problem.json
    if present) into an :class:`OptimizationRun`. ValueError names a missing or malformed file."""
    directory = os.fspath(directory)
    if not os.path.isdir(directory):
        raise ValueError(f"{directory}: not a directory (expected the output of `diffipc optimize -o DIR`)")
    columns, history = _read_history(os.path.join(directory, "history.csv"))
    summary = _read_json(os.path.join(directory, "summary.json"))
    problem_path = os.path.join(directory, "optimal_problem.json")
    problem = _read_json(problem_path) if os.path.exists(problem_path) else None
    return OptimizationRun(directory, columns, history, summary, problem)


def violations(values, kind, bound):
    """Relative violation of g (array) against its bound, as the optimizer sees it
    (docs/optimization.md): upper max(0, (g - b) / |b|), lower max(0, (b - g) / |b|),
    equals |g - b| / |b|, with |b| replaced by 1 for b = 0."""
    g = np.asarray(values, dtype=float)
    scale = abs(bound) if bound != 0 else 1.0
    if kind == "upper":
        return np.maximum(0.0, (g - bound) / scale)
    if kind == "lower":
        return np.maximum(0.0, (bound - g) / scale)
    if kind == "equals":
        return np.abs(g - bound) / scale
    raise ValueError(f"constraint kind: expected 'upper', 'lower' or 'equals', got {kind!r}")


# ---------------------------------------------------------------------------------------------
# Figures


def _figure(rows, height=2.6):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, 0.6 + height * rows), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.subplots(rows, 1, squeeze=False)[:, 0]
    return figure, list(axes)


def _save(figure, path):
    try:
        figure.savefig(path, dpi=110)
    except OSError as e:
        raise ValueError(f"{path}: cannot write the figure ({e})") from None
    return path


def _integer_ticks(ax):
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _positive(x, y):
    """The points with y > 0 (a log axis cannot show the others)."""
    keep = np.asarray(y) > 0
    return np.asarray(x)[keep], np.asarray(y)[keep]


def _title(run):
    s = run.summary
    parts = [os.path.basename(os.path.normpath(run.directory))]
    if "algorithm" in s:
        parts.append(str(s["algorithm"]))
    if "stop_reason" in s:
        parts.append(f"stop: {s['stop_reason']}")
    return ", ".join(parts)


def plot_convergence(directory, path=None):
    """convergence.png (or ``path``): J per iteration (a log axis when J > 0 spans more than a
    decade), |J - J_final| / |J_final| (log), and the gradient and step norms (log; the
    gradient norm is that of J / |J(x0)|, docs/optimization.md). Points a log axis cannot show
    (zeros) are left out. Returns a :class:`Plot`; ``data`` holds ``iteration``, ``J``,
    ``relative_gap``, ``gradient_norm``, ``step_norm`` as read from history.csv."""
    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    h = run.history
    it, J = h["iteration"], h["J"]
    final = J[-1]
    gap = np.abs(J - final) / (abs(final) if final != 0 else 1.0)
    figure, (ax_j, ax_gap, ax_norm) = _figure(3)
    ax_j.plot(it, J, "o-", ms=3, color="C0", label="J")
    if np.all(J > 0) and J.max() > 10 * J.min():
        ax_j.set_yscale("log")
    ax_j.set_ylabel("J")
    ax_j.set_title(_title(run))
    if "initial_J" in run.summary and "final_J" in run.summary:
        ax_j.text(0.99, 0.95, f"J {run.summary['initial_J']:.6g} -> {run.summary['final_J']:.6g}",
                  transform=ax_j.transAxes, ha="right", va="top")
    x, y = _positive(it, gap)
    ax_gap.semilogy(x, y, "o-", ms=3, color="C1")
    ax_gap.set_ylabel("|J - J_final| / |J_final|")
    x, y = _positive(it, h["gradient_norm"])
    ax_norm.semilogy(x, y, "o-", ms=3, color="C2", label="gradient norm (J / |J(x0)|)")
    x, y = _positive(it, h["step_norm"])
    ax_norm.semilogy(x, y, "s-", ms=3, color="C3", label="step norm")
    ax_norm.set_ylabel("norm")
    ax_norm.legend(loc="best")
    ax_norm.set_xlabel("iteration")
    for ax in (ax_j, ax_gap, ax_norm):
        ax.grid(True, which="both", alpha=0.3)
        _integer_ticks(ax)
    path = path or os.path.join(run.directory, "convergence.png")
    data = {"iteration": it, "J": J, "relative_gap": gap, "gradient_norm": h["gradient_norm"],
            "step_norm": h["step_norm"]}
    return Plot(_save(figure, path), figure, data)


def plot_constraints(directory, path=None):
    """constraints.png (or ``path``): per constraint, g per iteration with its bound, and all
    constraints' relative violations (:func:`violations`) on a symmetric-log axis that is linear
    below the optimizer's ``constraint_tolerance`` (drawn dashed), so that 0 (feasible) shows.
    ValueError if the run has no constraints. Returns a :class:`Plot`; ``data`` holds
    ``iteration``, and per constraint name its values and ``<name> violation``."""
    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    if not run.constraints:
        raise ValueError(f"{os.path.join(run.directory, 'history.csv')}: the run has no constraints")
    it = run.history["iteration"]
    figure, axes = _figure(len(run.constraints) + 1)
    data = {"iteration": it}
    symbol = {"upper": "<=", "lower": ">=", "equals": "=="}
    for ax, c in zip(axes, run.constraints):
        g = run.history[c["name"]]
        ax.plot(it, g, "o-", ms=3, color="C0", label=f"{c['name']} (g)")
        ax.axhline(c["bound"], color="k", ls="--", lw=1, label=f"bound: g {symbol[c['kind']]} {c['bound']:.6g}")
        ax.set_ylabel(c["name"])
        ax.legend(loc="best")
        ax.grid(True, alpha=0.3)
        _integer_ticks(ax)
        data[c["name"]] = g
    axes[0].set_title(_title(run))
    ax = axes[-1]
    tol = run.constraint_tolerance
    for i, c in enumerate(run.constraints):
        v = violations(run.history[c["name"]], c["kind"], c["bound"])
        ax.plot(it, v, "o-", ms=3, color=f"C{i}", label=f"{c['name']}")
        data[f"{c['name']} violation"] = v
    if tol > 0:
        ax.set_yscale("symlog", linthresh=tol)
        ax.axhline(tol, color="k", ls="--", lw=1, label=f"constraint_tolerance {tol:g}")
    ax.set_ylim(bottom=0)
    ax.set_ylabel("relative violation")
    ax.set_xlabel("iteration")
    ax.legend(loc="best")
    ax.grid(True, which="both", alpha=0.3)
    _integer_ticks(ax)
    path = path or os.path.join(run.directory, "constraints.png")
    return Plot(_save(figure, path), figure, data)


# ---------------------------------------------------------------------------------------------
# Objective over time


def _resolve_problem(run, problem):
    if problem is None:
        problem = run.summary.get("problem")
        if not isinstance(problem, str):
            raise ValueError(f"{os.path.join(run.directory, 'summary.json')}: no 'problem' path; pass the "
                             "problem file the run started from (problem= or --problem)")
        if not os.path.isfile(problem):
            raise ValueError(f"{problem}: the run's problem file (summary.json 'problem', relative to the "
                             "directory the run was started in) is not found from here; pass it "
                             "(problem= or --problem)")
    elif not os.path.isfile(os.fspath(problem)):
        raise ValueError(f"{os.fspath(problem)}: problem file not found")
    return os.fspath(problem)


def _scene_and_base(run, problem):
    """The optimal problem's scene as a dict, and the directory its relative paths refer to."""
    path = os.path.join(run.directory, "optimal_problem.json")
    if "scenes" in problem:
        raise ValueError(f"{path}: scenes: the objective over time is drawn for one load case; "
                         "a problem with several (`scenes`) is not supported")
    scene = problem.get("scene")
    if isinstance(scene, dict):
        return copy.deepcopy(scene), os.path.abspath(run.directory)
    if isinstance(scene, str):
        scene_path = scene if os.path.isabs(scene) else os.path.join(run.directory, scene)
        return _read_json(scene_path), os.path.dirname(os.path.abspath(scene_path))
    raise ValueError(f"{path}: scene: expected a path or an object")


def _fix_adaptive_kappa(scene, base):
    """The reduced functional fixes an adaptive barrier stiffness at the value a nominal run of
    the whole scene reaches (docs/problem_format.md); a truncated scene's own nominal run would
    reach less, so the full run's value is written into the truncated scenes."""
    contact = scene.get("contact")
    if contact is None and "obstacles" not in scene:
        return
    if isinstance(contact, dict) and not isinstance(contact.get("kappa", "adaptive"), str):
        return  # a fixed stiffness
    import diffipc

    _, tr = diffipc.simulate(scene, base_directory=base)
    if tr["final_status"] != "CONVERGED" or "kappa" not in tr or len(tr["kappa"]) == 0:
        raise ValueError(f"scene: the nominal run for the adaptive barrier stiffness ended with "
                         f"{tr['final_status']}")
    scene.setdefault("contact", {})["kappa"] = float(np.max(tr["kappa"]))


def _evaluate(problem, base, designs):
    import diffipc

    J = diffipc.ReducedFunctional(problem, base_directory=base)
    return [float(J.evaluate(J.parameters_of(np.asarray(x, dtype=float)), gradient=False)[0]) for x in designs]


def _aggregate(objective, values, contributions):
    """J from the per-state values (k = 1..T) where docs/objectives.md's aggregation needs no
    more than those; None otherwise (an initial state is needed)."""
    if contributions:
        return float(np.sum(values))
    time = objective.get("time", "final")
    if objective.get("include_initial"):
        return None
    if time == "final":
        return float(values[-1])
    if time == "sum":
        return float(np.sum(values))
    if isinstance(time, dict) and "max_p" in time:
        p = float(time["max_p"])
        v = np.maximum(np.asarray(values, dtype=float), 0.0)
        return float(np.sum(v**p) ** (1.0 / p))
    return None


def objective_over_time(directory, problem=None, refine=1):
    """The objective over the run's states at the initial and the optimal design.

    For a per-state objective (stress_norm, elastic_energy, compliance, volume,
    kinetic_energy, reaction_force without targets; docs/objectives.md) it gives f_k, the
    value at state k = 1..T, whatever the objective's ``time`` aggregation; for ``markers``,
    ``center_of_mass`` and ``reaction_force`` with targets the
    contribution of each listed state (their sum is J). Each value is J of the optimal problem
    (optimal_problem.json) with the scene truncated after step k and the objective restricted
    to state k, evaluated by ``diffipc.ReducedFunctional`` (forward only): T runs of 1..T steps
    per design. State 0 is not drawn for per-state objectives (a scene has at least one step).

    The initial design is the start of ``problem`` (default: summary.json's ``problem``, a
    path relative to where the run started), the optimal one summary.json's ``design``. Where
    the aggregation can be recomputed from the drawn values (``final``, ``sum`` and ``max_p``
    without the initial state; the sum of contributions), it must reproduce history.csv's
    first J and summary.json's final_J within 1e-8 relative, else RuntimeError.

    ``refine`` n > 1 (per-state objectives of a ``static`` scene only) also draws the states at
    dt / n: the same loads on a finer pseudo-time grid, n T (n T + 1) / 2 steps per design;
    ``fine_difference`` is the largest relative difference between the refined path at the
    problem's times and the problem's own states (equilibria at the same loads: round-off and
    solver tolerance, unless the load path picks another equilibrium).

    Returns a dict: ``kind`` (``"per_state"`` or ``"contributions"``), ``objective`` (its
    type), ``unit``, ``time`` (t_k, s), ``steps`` (k), ``initial`` and ``optimal`` (the values),
    ``check`` (``{"initial": (recomputed, written), "optimal": (...)}`` or None), and with
    ``refine`` also ``fine_time``, ``fine_initial``, ``fine_optimal``, ``fine_difference``.
    """
    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    import diffipc

    if run.problem is None:
        raise ValueError(f"{os.path.join(run.directory, 'optimal_problem.json')}: missing")
    summary_path = os.path.join(run.directory, "summary.json")
    if not isinstance(run.summary.get("design"), list):
        raise ValueError(f"{summary_path}: design: missing (the optimal design variables)")
    x_optimal = np.asarray(run.summary["design"], dtype=float)
    start = diffipc.ReducedFunctional(_resolve_problem(run, problem))
    x_initial = start.design_initial
    if x_initial.shape != x_optimal.shape:
        raise ValueError(f"{summary_path}: design has {x_optimal.size} variables, the problem "
                         f"{x_initial.size}: not the problem this run started from")
    refine = int(refine)
    if refine < 1:
        raise ValueError(f"refine: must be at least 1, got {refine}")

    base_problem = {k: copy.deepcopy(v) for k, v in run.problem.items()
                    if k not in ("constraints", "optimizer", "output", "gradcheck", "checkpointing",
                                 "description")}
    for i, entry in enumerate(base_problem.get("parameters", [])):
        if isinstance(entry, dict) and entry.get("type") == "prescribed":
            raise ValueError(f"parameters[{i}]: a `prescribed` block has one row per step; the objective "
                             "over time is not drawn for it")
    scene, base = _scene_and_base(run, base_problem)
    _fix_adaptive_kappa(scene, base)
    objective = base_problem.get("objective")
    if not isinstance(objective, dict) or not isinstance(objective.get("type"), str):
        raise ValueError(f"{os.path.join(run.directory, 'optimal_problem.json')}: objective: expected an object")
    kind_name = objective["type"]
    try:
        T = int(scene["time"]["steps"])
        dt = float(scene["time"]["dt"])
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"{os.path.join(run.directory, 'optimal_problem.json')}: scene.time: expected "
                         "'steps' and 'dt'") from None

    def truncated(steps, objective_k, step_dt=None):
        q = copy.deepcopy(base_problem)
        q["scene"] = copy.deepcopy(scene)
        q["scene"]["time"]["steps"] = int(steps)
        if step_dt is not None:
            q["scene"]["time"]["dt"] = step_dt
        q["objective"] = objective_k
        return q

    designs = (x_initial, x_optimal)
    out = {"objective": kind_name}
    if kind_name in PER_STATE and not _is_tracking(objective):
        per_state = {k: v for k, v in objective.items() if k not in ("time", "include_initial")}
        per_state["time"] = "final"
        steps = np.arange(1, T + 1)
        values = np.array([_evaluate(truncated(k, per_state), base, designs) for k in steps])
        unit = PER_STATE[kind_name].replace("^d", f"^{scene.get('dimension', 3)}")
        out.update(kind="per_state", unit=unit, steps=steps, time=steps * dt)
        if refine > 1:
            if scene["time"].get("integrator") != "static":
                raise ValueError(f"refine: a smaller dt changes a dynamic scene's solution; only a "
                                 f"`static` scene is refined (this one: {scene['time'].get('integrator')})")
            fine = np.arange(1, refine * T + 1)
            fine_values = np.array([_evaluate(truncated(j, per_state, dt / refine), base, designs) for j in fine])
            out.update(fine_time=fine * dt / refine, fine_initial=fine_values[:, 0], fine_optimal=fine_values[:, 1])
            # The refined path passes through the problem's load levels: how far from its states.
            at_problem_states = fine_values[refine - 1::refine]
            out["fine_difference"] = float(np.max(np.abs(at_problem_states - values)
                                                  / np.maximum(np.abs(values), 1e-300)))
        contributions = False
    elif _is_tracking(objective):
        if refine > 1:
            raise ValueError(f"refine: applies to per-state objectives, not to '{kind_name}' (its targets "
                             "are given at the listed states)")
        targets = objective.get("targets")
        listed = objective.get("steps", list(range(1, T + 1)))
        if not isinstance(targets, list) or not isinstance(listed, list) or len(targets) != len(listed):
            raise ValueError(f"objective: {kind_name}: expected one target entry per listed state")
        rows = []
        for k, target in zip(listed, targets):
            restricted = dict(objective, steps=[int(k)], targets=[target])
            rows.append(_evaluate(truncated(max(int(k), 1), restricted), base, designs))
        values = np.array(rows, dtype=float).reshape(len(listed), 2)
        steps = np.asarray(listed, dtype=int)
        out.update(kind="contributions", unit=TRACKING[kind_name], steps=steps, time=steps * dt)
        contributions = True
    else:
        raise ValueError(f"objective: type '{kind_name}' has no per-state curve here (drawn for "
                         f"{', '.join(sorted(PER_STATE) + sorted(TRACKING))})")
    out["initial"], out["optimal"] = values[:, 0], values[:, 1]

    written = (float(run.history["J"][0]), float(run.summary.get("final_J", float("nan"))))
    recomputed = (_aggregate(objective, out["initial"], contributions),
                  _aggregate(objective, out["optimal"], contributions))
    if recomputed[0] is None:
        out["check"] = None
    else:
        out["check"] = {"initial": (recomputed[0], written[0]), "optimal": (recomputed[1], written[1])}
        for name, (again, value) in out["check"].items():
            if not abs(again - value) <= REPRODUCTION_TOLERANCE * max(abs(value), 1e-300):
                raise RuntimeError(f"objective over time: the {name} design's J recomputed from the drawn "
                                   f"states is {again!r}, the run wrote {value!r}: the curve would not be "
                                   "this run's (another problem file? pass the one the run started from)")
    return out


def plot_objective_over_time(directory, path=None, problem=None, refine=1, curve=None):
    """objective_over_time.png (or ``path``) from :func:`objective_over_time` (``curve``: its
    result, if already computed): the values at the initial and the optimal design against
    t_k. Returns a :class:`Plot` whose ``data`` is that result."""
    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    c = curve if curve is not None else objective_over_time(run, problem=problem, refine=refine)
    figure, (ax,) = _figure(1, height=3.6)
    if "fine_time" in c:
        ax.plot(c["fine_time"], c["fine_initial"], "-", color="C0", lw=1, label=f"initial design, dt / {refine}")
        ax.plot(c["fine_time"], c["fine_optimal"], "-", color="C3", lw=1, label=f"optimal design, dt / {refine}")
    style = ("o", "s") if "fine_time" in c else ("o-", "s-")
    ax.plot(c["time"], c["initial"], style[0], color="C0", lw=0.8, label="initial design, the problem's states")
    ax.plot(c["time"], c["optimal"], style[1], color="C3", lw=0.8, label="optimal design, the problem's states")
    name = c["objective"]
    if c["kind"] == "per_state":
        ax.set_ylabel(f"{name} f_k ({c['unit']})")
        title = f"{name} at each state (J: time = {json.dumps(run.problem['objective'].get('time', 'final'))})"
    else:
        ax.set_ylabel(f"{name}: contribution of state k ({c['unit']})")
        title = f"{name}: each listed state's share of J"
    if c.get("check"):
        (a0, w0), (a1, w1) = c["check"]["initial"], c["check"]["optimal"]
        title += f"\nJ from these states: {a0:.6g} -> {a1:.6g}; the run wrote {w0:.6g} -> {w1:.6g}"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("t (s)" + ("; static: the loads' pseudo-time" if "fine_time" in c else ""))
    ax.legend(loc="best")
    ax.grid(True, alpha=0.3)
    path = path or os.path.join(run.directory, "objective_over_time.png")
    return Plot(_save(figure, path), figure, c)


# ---------------------------------------------------------------------------------------------
# The design

#: Parameter types whose design the re-simulation of :func:`design_states` reproduces: the rest
#: mesh and the per-element material of the design VTU.
DESIGN_TYPES = ("shape", "E", "nu", "mu", "lambda")
#: Relative tolerance of the check that the re-simulated design reproduces the run's J (the
#: renumbered mesh assembles in another order: round-off and the solver's tolerance).
DESIGN_TOLERANCE = 1e-6
#: Keys of an optimal problem that an evaluation of its objective does not need.
_NOT_FOR_EVALUATION = ("constraints", "optimizer", "output", "gradcheck", "checkpointing", "description", "remesh",
                       "parameters", "scene")


def _read_design(path):
    """(points #V by d, elements, cell data dict) of a design VTU written by diffipc optimize."""
    if not os.path.isfile(path):
        raise ValueError(f"{path}: missing (the run writes design_0.vtu with output.design_every >= 1, "
                         "design_final.vtu at its end)")
    import meshio

    try:
        m = meshio.read(path)
    except Exception as e:  # meshio raises its own ReadError and others
        raise ValueError(f"{path}: not readable as VTU ({e})") from None
    kinds = {c.type: c.data for c in m.cells}
    if "triangle" in kinds:
        d, cells = 2, np.asarray(kinds["triangle"], dtype=int)
    elif "tetra" in kinds:
        d, cells = 3, np.asarray(kinds["tetra"], dtype=int)
    else:
        raise ValueError(f"{path}: no triangles or tetrahedra")
    data = {k: np.asarray(v[0], dtype=float).ravel() for k, v in m.cell_data.items()}
    return np.asarray(m.points, dtype=float)[:, :d], cells, data


def _write_msh22(path, points, cells):
    """A gmsh 2.2 ASCII mesh of P1 triangles (2D) or tetrahedra (3D)."""
    d = points.shape[1]
    kind = 2 if d == 2 else 4
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % len(points))
        for i, p in enumerate(points):
            z = p[2] if d == 3 else 0.0
            f.write("%d %.17g %.17g %.17g\n" % (i + 1, p[0], p[1], z))
        f.write("$EndNodes\n$Elements\n%d\n" % len(cells))
        for i, c in enumerate(cells):
            f.write("%d %d 2 1 1 %s\n" % (i + 1, kind, " ".join(str(v + 1) for v in c)))
        f.write("$EndElements\n")


def design_states(directory):
    """The initial and the optimal design (design_0.vtu, design_final.vtu) re-simulated: for each,
    the optimal problem's scene with each body's mesh replaced by the design's rest mesh (the
    scene's regions then select on the design's rest positions) and the design's per-element E
    and nu (or mu and lambda) set (an adaptive barrier stiffness fixed as in
    :func:`objective_over_time`), run to its last step. Returns a dict ``initial``, ``optimal``,
    each a dict ``rest``, ``deformed`` (#V by d, the scene's body vertices), ``elements``,
    ``von_mises`` (Pa, per element at the final state: ``Simulator.element_von_mises``, the VTU
    frames' ``von_mises``), ``time`` (the final state's, s) and ``J`` ((recomputed, written)): the
    problem's objective evaluated on the re-simulated scene must reproduce the J the run wrote for
    that design (history.csv's first, summary.json's final_J) within 1e-6 relative, which it does
    only if the scene selects on the design's mesh what the run's selected. ValueError names what cannot be re-simulated: a problem
    with several load cases, parameter types other than shape, E, nu, mu, lambda (the design VTU
    does not hold them), a design file that is missing, a run that does not converge, or a J that
    is not reproduced."""
    import tempfile

    import diffipc

    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    problem_path = os.path.join(run.directory, "optimal_problem.json")
    if run.problem is None:
        raise ValueError(f"{problem_path}: missing")
    for i, entry in enumerate(run.problem.get("parameters", [])):
        kind = entry.get("type") if isinstance(entry, dict) else None
        if kind not in DESIGN_TYPES:
            raise ValueError(f"{problem_path}: parameters[{i}]: a '{kind}' design is not re-simulated for the "
                             f"drawing (drawn: {', '.join(DESIGN_TYPES)})")
    scene, base = _scene_and_base(run, run.problem)
    _fix_adaptive_kappa(scene, base)  # as the reduced functional and objective_over_time fix it
    bodies = scene.get("bodies", [])
    written_J = {"initial": float(run.history["J"][0]),
                 "optimal": float(run.summary.get("final_J", run.history["J"][-1]))}
    out = {}
    for name, file in (("initial", "design_0.vtu"), ("optimal", "design_final.vtu")):
        path = os.path.join(run.directory, file)
        points, cells, data = _read_design(path)
        d = points.shape[1]
        body_of = data.get("body", np.zeros(len(cells))).astype(int)
        if body_of.max(initial=0) >= len(bodies):
            raise ValueError(f"{path}: body index {body_of.max()} but the scene has {len(bodies)} bodies")
        order = np.argsort(body_of, kind="stable")  # the scene numbers elements body by body
        s = copy.deepcopy(scene)
        with tempfile.TemporaryDirectory() as tmp:
            for b, body in enumerate(s["bodies"]):
                mine = cells[body_of == b]
                used = np.unique(mine)
                local = np.full(len(points), -1)
                local[used] = np.arange(len(used))
                msh = os.path.join(tmp, f"body{b}.msh")
                _write_msh22(msh, points[used], local[mine])
                body["mesh"] = {"file": msh}
                for key in ("translation", "scale", "rotation"):
                    body.pop(key, None)  # the design's positions are the world's
            sc = diffipc.scene(s, base_directory=base)
            rest = np.asarray(sc.rest_positions, dtype=float)
            elements = np.asarray(sc.elements, dtype=int)
            if len(elements) != len(cells):
                raise RuntimeError(f"{path}: the re-meshed scene has {len(elements)} elements, the design "
                                   f"{len(cells)}")
            # The gmsh reader renumbers vertices, not elements: element k must be the design's
            # element order[k] (the same centroid).
            if not np.allclose(rest[elements].mean(axis=1), points[cells[order]].mean(axis=1), rtol=0,
                               atol=1e-9 * max(1.0, np.abs(points).max())):
                raise RuntimeError(f"{path}: the re-meshed scene's elements are not the design's")
            E = np.empty(len(cells))
            nu = np.empty(len(cells))
            plane = np.zeros(len(cells), dtype=bool)
            element_body = body_of[order]
            for k, e in enumerate(order):
                material = bodies[element_body[k]].get("material", {})
                plane[k] = d == 2 and material.get("plane") == "stress"
                if not ("mu" in data and "lambda" in data):
                    E[k] = data["E"][e] if "E" in data else float(material["E"])
                    nu[k] = data["nu"][e] if "nu" in data else float(material["nu"])
            if "mu" in data and "lambda" in data:
                for flag in (False, True):  # the C++ inverse of the Lame parameters, per plane kind
                    mine = plane == flag
                    if mine.any():
                        E[mine], nu[mine] = diffipc.young_poisson_of_lame(
                            data["mu"][order[mine]], data["lambda"][order[mine]], plane_stress=flag)
            sim = diffipc.Simulator(sc)
            sim.set_element_materials(E, nu)
            tr = sim.run()
            if tr["final_status"] != "CONVERGED":
                raise ValueError(f"{path}: the scene re-simulated on this design ended with {tr['final_status']} "
                                 f"at step {tr['failed_step']}: {tr['failure_message']}")
            # The run's J again, on this scene: its regions and lists must pick what the run's did.
            q = {k: v for k, v in run.problem.items() if k not in _NOT_FOR_EVALUATION}
            q["scene"] = s
            q["parameters"] = [{"type": "E", "per": "element", "initial": E.tolist()},
                               {"type": "nu", "per": "element", "initial": nu.tolist()}]
            rf = diffipc.ReducedFunctional(q, base_directory=base)
            again = float(rf.evaluate(rf.parameters_of(rf.design_initial), gradient=False)[0])
        written = written_J[name]
        if not abs(again - written) <= DESIGN_TOLERANCE * max(abs(written), 1e-300):
            raise ValueError(f"{path}: J of the scene re-simulated on this design is {again!r}, the run wrote "
                             f"{written!r}: the drawing would not show the run's state (the scene's regions or "
                             "vertex lists select differently on the design's mesh)")
        nv = len(rest)
        final = np.asarray(tr["positions"][-1], dtype=float)
        out[name] = {"rest": rest, "deformed": final[:nv], "elements": elements, "time": float(tr["time"][-1]),
                     "J": (again, written), "von_mises": np.asarray(sim.element_von_mises(final))}
    return out


def _boundary_faces(elements):
    """(faces #F by 3, the tetrahedron of each) of the faces that belong to one tetrahedron."""
    owner = {}
    for t, tet in enumerate(elements):
        for face in ((tet[1], tet[2], tet[3]), (tet[0], tet[3], tet[2]), (tet[0], tet[1], tet[3]),
                     (tet[0], tet[2], tet[1])):
            key = tuple(sorted(face))
            owner[key] = None if key in owner else (face, t)
    kept = [v for v in owner.values() if v is not None]
    return np.array([f for f, _ in kept], dtype=int).reshape(-1, 3), np.array([t for _, t in kept], dtype=int)


def plot_design(directory, path=None, states=None):
    """design.png (or ``path``): the initial and the optimal design side by side, each element
    coloured by its von Mises stress at the final load (:func:`design_states`; ``states``: its
    result, if already computed) on ONE colour scale, 0 to the larger maximum, with one colour
    bar; titles with each design's J (history.csv's first J, summary.json's final_J). 2D: the
    filled rest mesh; 3D: its boundary surface seen from matplotlib's default view (the faces
    turned towards it), each face coloured as its tetrahedron. Returns a
    :class:`Plot` whose ``data`` holds ``initial_von_mises``, ``optimal_von_mises`` (Pa per
    element), ``norm`` ((vmin, vmax) of the shared scale), ``J`` ((initial, optimal)) and
    ``check`` (per design, J recomputed on the re-simulated scene and the J the run wrote)."""
    run = directory if isinstance(directory, OptimizationRun) else read_run(directory)
    st = states if states is not None else design_states(run)
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    d = st["initial"]["rest"].shape[1]
    top = max(float(st[k]["von_mises"].max()) for k in ("initial", "optimal"))
    norm = Normalize(vmin=0.0, vmax=top if top > 0 else 1.0)
    cmap = matplotlib.colormaps["viridis"]
    J = (float(run.history["J"][0]), float(run.summary.get("final_J", run.history["J"][-1])))
    lo = np.min([st[k]["rest"].min(axis=0) for k in ("initial", "optimal")], axis=0)
    hi = np.max([st[k]["rest"].max(axis=0) for k in ("initial", "optimal")], axis=0)
    span = hi - lo
    if d == 2:
        aspect = span[1] / max(span[0], 1e-300)
        figure = Figure(figsize=(11.0, min(max(2.2 + 4.6 * aspect, 3.2), 8.0)), layout="constrained")
    else:
        figure = Figure(figsize=(11.0, 6.0), layout="constrained")
    FigureCanvasAgg(figure)
    axes = []
    mappables = []
    for i, (key, label) in enumerate((("initial", "initial design"), ("optimal", "optimal design"))):
        s = st[key]
        if d == 2:
            ax = figure.add_subplot(1, 2, i + 1)
            m = ax.tripcolor(s["rest"][:, 0], s["rest"][:, 1], s["elements"], facecolors=s["von_mises"],
                             norm=norm, cmap=cmap, edgecolors="face", linewidth=0.2)
            ax.set_aspect("equal")
            margin = 0.03 * span.max()
            ax.set_xlim(lo[0] - margin, hi[0] + margin)
            ax.set_ylim(lo[1] - margin, hi[1] + margin)
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
        else:
            from mpl_toolkits.mplot3d.art3d import Poly3DCollection

            ax = figure.add_subplot(1, 2, i + 1, projection="3d")
            faces, owner = _boundary_faces(s["elements"])
            # Matplotlib paints polygons back to front by their centres, which large triangles on
            # the far side of the body can get wrong: only the faces turned towards the viewer
            # are drawn (all that shows of a convex body).
            corners = s["rest"][faces]
            normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            elev, azim = np.radians(ax.elev), np.radians(ax.azim)
            eye = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
            front = normals @ eye > 0
            m = Poly3DCollection(corners[front], cmap=cmap, norm=norm, edgecolors="none")
            m.set_array(s["von_mises"][owner[front]])
            ax.add_collection3d(m)
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            ax.set_zlim(lo[2], hi[2])
            ax.set_box_aspect(tuple(np.maximum(span, 1e-3 * span.max())))
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
            ax.set_zlabel("z (m)")
        ax.set_title(f"{label}: J = {J[i]:.6g}\nlargest von Mises {s['von_mises'].max():.4g} Pa", fontsize=10)
        axes.append(ax)
        mappables.append(m)
    bar = figure.colorbar(mappables[0], ax=axes, location="bottom", shrink=0.6, aspect=40)
    bar.set_label(f"von Mises stress at the final load (t = {st['optimal']['time']:.4g} s), Pa; one scale for both")
    figure.suptitle(_title(run) + " (rest designs)", fontsize=10)
    path = path or os.path.join(run.directory, "design.png")
    data = {"initial_von_mises": st["initial"]["von_mises"], "optimal_von_mises": st["optimal"]["von_mises"],
            "norm": (norm.vmin, norm.vmax), "J": J, "check": {k: st[k]["J"] for k in ("initial", "optimal")}}
    return Plot(_save(figure, path), figure, data)


def plot_run(directory, problem=None, refine=1, objective=True, printer=None):
    """Every figure of a run into the directory: convergence.png, constraints.png (with
    constraints), objective_over_time.png (unless ``objective`` is False), design.png. A figure
    that does not apply (no constraints; an objective without a per-state curve; the start
    problem not found; no design files or a design that is not re-simulated) is skipped with a
    line to ``printer`` (e.g. print) saying why. Returns the list of :class:`Plot`."""
    say = printer or (lambda _line: None)
    run = read_run(directory)
    plots = [plot_convergence(run)]
    if run.constraints:
        plots.append(plot_constraints(run))
    else:
        say("constraints.png: not written (the run has no constraints)")
    if objective:
        try:
            plots.append(plot_objective_over_time(run, problem=problem, refine=refine))
        except ValueError as e:
            say(f"objective_over_time.png: not written ({e})")
    try:
        plots.append(plot_design(run))
    except ValueError as e:
        say(f"design.png: not written ({e})")
    return plots


def main(argv=None):
    """``python3 -m diffipc.plot DIR [--problem FILE] [--refine N] [--no-objective]``."""
    parser = argparse.ArgumentParser(
        prog="python3 -m diffipc.plot",
        description="PNG figures of a `diffipc optimize -o DIR` output directory, written into DIR.")
    parser.add_argument("directory", help="the optimization's output directory")
    parser.add_argument("--problem", help="the problem file the run started from (default: summary.json's)")
    parser.add_argument("--refine", type=int, default=1,
                        help="also draw a static scene's per-state objective at dt / N (default 1: off)")
    parser.add_argument("--no-objective", action="store_true", help="skip the objective over time")
    args = parser.parse_args(argv)
    try:
        plots = plot_run(args.directory, problem=args.problem, refine=args.refine,
                         objective=not args.no_objective, printer=print)
    except (ValueError, RuntimeError) as e:
        raise SystemExit(f"diffipc.plot: {e}") from None
    for p in plots:
        print(p.path)
        check = p.data.get("check") if isinstance(p.data, dict) else None
        if check:
            rel = [abs(a - w) / max(abs(w), 1e-300) for a, w in check.values()]
            print(f"  J recomputed from the drawn states: initial {check['initial'][0]:.10g}, optimal "
                  f"{check['optimal'][0]:.10g}; relative difference to the run's J: {max(rel):.1e}")
        if isinstance(p.data, dict) and "fine_difference" in p.data:
            print(f"  the path at dt / {args.refine} against the problem's states: largest relative "
                  f"difference {p.data['fine_difference']:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
