#!/usr/bin/env python3
"""Study 502: error against run time. Reference cases with exact answers, each run through
`diffipc simulate` while one knob at a time is varied from a base setting; the error against the
exact answer and the wall time of every run go to a CSV, one log-log figure per case (error
against time, a curve per knob, points labelled by value, the Pareto front over all runs) and a
markdown table of observed convergence orders.

    PYTHONPATH=build/python /usr/bin/python3 studies/502_error_vs_time/run.py [--cli build/cli/diffipc]
        [-o output/502] [--full] [--cases free_fall uniaxial cantilever slope stopping rolling hertz bounce] [--jobs 2]
        [--results studies/502_error_vs_time]

Cases (the error of each is defined in its docstring below and in the README):
  free_fall   a box falling under gravity, 2D and 3D, knob dt per integrator (exact: y0 - g t^2 / 2)
  uniaxial    a bar of each material stretched 20% by an end traction (static), 2D and 3D, knobs
              the Newton tolerance and the mesh (exact: the material's uniaxial stress equations,
              solved here)
  cantilever  a cantilever's tip deflection under its weight (static, neo-Hookean), 2D and 3D,
              knobs mesh size and Newton tolerance (reference: Richardson extrapolation)
  slope       a block sliding down a 30 degree slope, mu = 0.2 (exact: v = g (sin - mu cos) t),
              knobs dt, eps_v, dhat, kappa, friction iterations, and the penalty baseline's stiffness
  stopping    a block sliding on flat ground at 1 m/s with mu = 0.5 (exact stopping distance
              v0^2 / (2 mu g)), knobs dt, eps_v, dhat, and the penalty baseline's stiffness
  rolling     a thick ring rolling down a 30 degree slope without slipping (a = g sin / (1 + k)),
              knobs dt, eps_v, the polygon's segments, mu
  bounce      a soft box bouncing on a frictionless plane for 1 s: energy drift per bounce, knob dt per
              integrator (implicit Euler, BDF2, Newmark)
  hertz       a half cylinder pressed onto a plane (Hertz's contact half-width), knobs the mesh size
              at the contact, dhat, both together, and the penalty baseline's stiffness

The runs are one `diffipc sweep` (docs/sweep.md), each run single-threaded (--threads 1); --jobs N deals
them to N MPI ranks (mpirun -n N diffipc sweep, docs/mpi.md; without mpirun, one after the other).
"""
import argparse
import copy
import json
import math
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

import diffipc.energy
import diffipc.studies

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
G = 9.81


# ---------------------------------------------------------------- cases


def box(dim, lo, hi, cells, E=1e7, nu=0.3, model="neo_hookean", name="body"):
    return {"name": name, "mesh": {"box": {"min": lo, "max": hi, "cells": cells}},
            "material": {"model": model, "E": E, "nu": nu, "density": 1000.0}}


def body_mean(f, key, step=-1):
    body = f["mesh/body"][:] == 0
    return f[key][step, body, :].mean(axis=0)


def free_fall(dim, integrator, dt):
    """Error: |mean vertical displacement at T - (-g T^2/2)| / (g T^2/2), T = 0.4 s (the body does
    not deform: every vertex falls alike)."""
    T = 0.4
    hi = [0.1] * dim
    scene = {"dimension": dim, "bodies": [box(dim, [0.0] * dim, hi, [2] * dim)],
             "gravity": [0.0, -G] + [0.0] * (dim - 2),
             "time": {"integrator": integrator, "dt": dt, "steps": int(round(T / dt))},
             "solver": {"residual_tolerance": 1e-10}}

    def error(f, folder=None):
        y = body_mean(f, "positions")[1] - body_mean(f, "positions", 0)[1]
        exact = -0.5 * G * T * T
        return abs(y - exact) / abs(exact)
    return scene, error


UNIAXIAL_E, UNIAXIAL_NU, UNIAXIAL_T = 1e6, 0.3, 2e5
MATERIALS = ("linear", "stvk", "neo_hookean", "stable_neo_hookean")


def uniaxial_stretches(model, dim, E=UNIAXIAL_E, nu=UNIAXIAL_NU, T=UNIAXIAL_T):
    """The principal stretches (a along the load, b lateral) of a bar under the nominal traction T
    with free lateral faces: the roots of P11(a, b) = T and P22(a, b) = 0 for each model's first
    Piola-Kirchhoff stress (docs/math.md), solved here by scipy, independently of the solver."""
    from scipy.optimize import fsolve
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    lat = dim - 1

    def residual(z):
        a, b = z
        J = a * b ** lat
        if model == "linear":
            e1, e2 = a - 1, b - 1
            tr = e1 + lat * e2
            P = (2 * mu * e1 + lam * tr, 2 * mu * e2 + lam * tr)
        elif model == "stvk":
            E1, E2 = (a * a - 1) / 2, (b * b - 1) / 2
            tr = E1 + lat * E2
            P = (a * (2 * mu * E1 + lam * tr), b * (2 * mu * E2 + lam * tr))
        elif model == "neo_hookean":
            P = (mu * (a - 1 / a) + lam * math.log(J) / a, mu * (b - 1 / b) + lam * math.log(J) / b)
        else:  # stable neo-Hookean (Smith et al. 2018): P = mu F + (lambda' (J - 1) - mu) cof F
            c = (lam + mu) * (J - 1) - mu
            P = (mu * a + c * J / a, mu * b + c * J / b)
        return [P[0] - T, P[1]]
    import warnings
    with warnings.catch_warnings():  # fsolve warns when it cannot improve a root already at round-off
        warnings.simplefilter("ignore", RuntimeWarning)
        z = fsolve(residual, [1 + T / E, 1 - nu * T / E], xtol=1e-14)
    # Accept only a root: the stresses' residual at round-off of the traction.
    if not np.all(np.abs(residual(z)) < 1e-9 * T):
        raise RuntimeError(f"uniaxial closed form for {model}: no root found (residual {residual(z)})")
    return z


def uniaxial(dim, model, tolerance=1e-10, refine=1):
    """A 2 m x 0.5 m (x 0.5 m) bar (4 r x 2 r (x r) cells, E = 1e6 Pa, nu = 0.3) held on rollers at
    x = 0 and pulled by a nominal traction of 2e5 Pa at x = 2 m in three static load steps. P1
    represents the homogeneous stretch exactly, so the error is the solver's alone. Error: the
    largest deviation of a vertex from (a X, b Y, b Z) over the stretch a L - L (relative)."""
    L, W, T = 2.0, 0.5, UNIAXIAL_T
    cells = [4 * refine, 2 * refine] if dim == 2 else [4 * refine, refine, refine]
    body = box(dim, [0.0] * dim, [L] + [W] * (dim - 1), cells, E=UNIAXIAL_E, nu=UNIAXIAL_NU, model=model)

    def region(lo, hi):
        return {"min": lo, "max": hi}
    origin = [0.0] * dim
    dirichlet = [{"body": 0, "region": region([0.0] + [-1.0] * (dim - 1), [0.0] + [5.0] * (dim - 1)),
                  "displacement": [0.0] + [None] * (dim - 1)},
                 {"body": 0, "region": region(origin, origin), "displacement": [None] + [0.0] * (dim - 1)}]
    if dim == 3:  # no spin about the bar's axis
        corner = [0.0, W, 0.0]
        dirichlet.append({"body": 0, "region": region(corner, corner), "displacement": [None, None, 0.0]})
    scene = {"dimension": dim, "bodies": [body], "dirichlet": dirichlet,
             "neumann": [{"body": 0, "region": region([L] + [-1.0] * (dim - 1), [L] + [5.0] * (dim - 1)),
                          "traction": [f"{T}*t/3"] + [0] * (dim - 1)}],
             "time": {"integrator": "static", "dt": 1.0, "steps": 3},
             "solver": {"residual_tolerance": tolerance}}
    a, b = uniaxial_stretches(model, dim)

    def error(f, folder=None):
        X = f["mesh/rest_positions"][:]
        x = f["positions"][-1]
        exact = X * np.array([a] + [b] * (dim - 1))
        return np.abs(x - exact).max() / (abs(a - 1) * L), f"stretches a = {a:.6f}, b = {b:.6f}"
    return scene, error


def cantilever(dim, refine, tolerance=1e-10):
    """Tip deflection w (mean vertical displacement of the free end's vertices) of a 0.5 m x 0.1 m
    (x 0.1 m) neo-Hookean cantilever (E = 1e8 Pa) under its weight, static; cells 5 r x r (x r). The
    error is against the Richardson extrapolation of the three finest meshes (after the sweep)."""
    L, H = 0.5, 0.1
    cells = [5 * refine] + [refine] * (dim - 1)
    scene = {"dimension": dim, "bodies": [box(dim, [0.0] * dim, [L] + [H] * (dim - 1), cells, E=1e8)],
             "gravity": [0.0, -G] + [0.0] * (dim - 2),
             "dirichlet": [{"body": 0, "region": {"min": [-1.0] * dim, "max": [0.0] + [1.0] * (dim - 1)},
                            "displacement": [0.0] * dim}],
             "time": {"integrator": "static", "dt": 1.0, "steps": 1},
             "solver": {"residual_tolerance": tolerance}}

    def deflection(f, folder=None):
        X = f["mesh/rest_positions"][:]
        x = f["positions"][-1]
        tip = np.abs(X[:, 0] - L) < 1e-9
        return -(x[tip, 1] - X[tip, 1]).mean()
    return scene, deflection


def block(theta, mu, v0, dt, eps_v, dhat, kappa, iterations, penalty, T):
    """A 0.1 m x 0.05 m block (8 x 4 cells, E = 1e7 Pa) on a plane tilted by theta degrees, its
    lowest side 1.05 dhat above it (just outside the contact layer: it settles in without being
    thrown off), sliding down the slope at v0."""
    b = box(2, [0.0, 1.05 * dhat], [0.1, 0.05 + 1.05 * dhat], [8, 4])
    b["rotation"] = [-theta]
    th = math.radians(theta)
    b["initial_velocity"] = [v0 * math.cos(th), -v0 * math.sin(th)]
    return {"dimension": 2, "bodies": [b], "gravity": [0.0, -G],
            "obstacles": [{"name": "ground", "plane": {"point": [0, 0], "normal": [math.sin(th), math.cos(th)]}}],
            "contact": contact_block(dhat, kappa, penalty),
            "friction": {"coefficient": mu, "eps_v": eps_v, "iterations": iterations},
            "time": {"integrator": "implicit_euler", "dt": dt, "steps": int(round(T / dt))},
            "solver": {"residual_tolerance": 1e-8}}


def slope(dt=5e-4, eps_v=1e-3, dhat=2e-4, kappa="adaptive", iterations=5, penalty=None):
    """A block sliding down a 30 degree slope from rest, mu = 0.2: a = g (sin 30 - 0.2 cos 30) =
    3.207 m/s^2. Error: |s(T) - a T^2/2| / (a T^2/2), s the mean displacement along the slope at
    T = 0.3 s."""
    T, mu = 0.3, 0.2
    scene = block(30.0, mu, 0.0, dt, eps_v, dhat, kappa, iterations, penalty, T)
    th = math.radians(30.0)
    a = G * (math.sin(th) - mu * math.cos(th))
    down = np.array([math.cos(th), -math.sin(th)])

    def error(f, folder=None):
        s = (body_mean(f, "positions") - body_mean(f, "positions", 0)) @ down
        return abs(s - 0.5 * a * T * T) / (0.5 * a * T * T)
    return scene, error


def stopping(dt=5e-4, eps_v=1e-3, dhat=2e-4, kappa="adaptive", penalty=None):
    """A block sliding on flat ground at v0 = 1 m/s with mu = 0.5 stops after d = v0^2 / (2 mu g) =
    0.1019 m (at t = 0.204 s). Error: |x(T) - d| / d, x the mean horizontal displacement at T = 0.3 s."""
    T, mu, v0 = 0.3, 0.5, 1.0
    scene = block(0.0, mu, v0, dt, eps_v, dhat, kappa, 5, penalty, T)
    d = v0 * v0 / (2 * mu * G)

    def error(f, folder=None):
        x = body_mean(f, "positions")[0] - body_mean(f, "positions", 0)[0]
        return abs(x - d) / d
    return scene, error


def rolling(dt=5e-4, eps_v=1e-3, segments=48, mu=0.5):
    """A thick ring (annulus, radii 0.05 and 0.025 m, 3 layers, E = 1e8 Pa: nearly rigid) released on
    a 30 degree slope with mu = 0.5 rolls without slipping (mu above tan 30 k / (1 + k) = 0.22,
    k = I / (m R^2) = (1 + 0.5^2) / 2): its centre accelerates at a = g sin 30 / (1 + k) = 3.019 m/s^2.
    Error: |s(T) - a T^2 / 2| / (a T^2 / 2), s the displacement of the mass centre (the lumped-mass
    average of the vertices) along the slope, T = 0.3 s. The ring is a polygon of `segments` sides."""
    T, th, R, r = 0.3, math.radians(30.0), 0.05, 0.025
    k = (1 + (r / R) ** 2) / 2
    a = G * math.sin(th) / (1 + k)
    gap = 1.05e-4
    centre = [(R + gap) * math.sin(th), (R + gap) * math.cos(th)]  # R + gap from the slope, along its normal
    ring = {"name": "ring", "mesh": {"annulus": {"center": centre, "inner_radius": r, "outer_radius": R,
                                                 "segments": segments, "layers": 3}},
            "material": {"model": "neo_hookean", "E": 1e8, "nu": 0.3, "density": 1000.0}}
    scene = {"dimension": 2, "bodies": [ring], "gravity": [0.0, -G],
             "obstacles": [{"name": "slope", "plane": {"point": [0, 0], "normal": [math.sin(th), math.cos(th)]}}],
             "contact": {"dhat": 1e-4}, "friction": {"coefficient": mu, "eps_v": eps_v, "iterations": 3},
             "time": {"integrator": "implicit_euler", "dt": dt, "steps": int(round(T / dt))},
             "solver": {"residual_tolerance": 1e-8}}
    down = np.array([math.cos(th), -math.sin(th)])

    def error(f, folder=None):
        X, tris = f["mesh/rest_positions"][:], f["mesh/elements"][:]
        area = 0.5 * np.abs(np.cross(X[tris[:, 1]] - X[tris[:, 0]], X[tris[:, 2]] - X[tris[:, 0]]))
        mass = np.zeros(len(X))
        for j in range(3):
            np.add.at(mass, tris[:, j], area / 3)
        x = f["positions"][:]
        c = (mass[:, None] * x).sum(axis=1) / mass.sum()
        s_end = (c[-1] - c[0]) @ down
        return abs(s_end - 0.5 * a * T * T) / (0.5 * a * T * T)
    return scene, error


def bounce(integrator, dt):
    """A soft box (0.1 m x 0.05 m, 8 x 4 cells, E = 1e5 Pa, 5 kg/m) dropped from 5 cm onto a
    frictionless plane, for 1 s. E is the kinetic + elastic + gravitational energy computed from the
    stored states (diffipc.energy; the barrier's is not counted: it is 0 out of contact). The error is
    the first bounce's energy change relative to the bouncing energy, |E(after) - E(0)| / (E(0) -
    E_rest), E(after) at the first state out of contact after the first contact, E_rest = E(0) - m g
    0.05 m (the box at rest on the plane). An elastic bounce keeps it: the exact error is 0."""
    T = 1.0
    scene = {"dimension": 2, "bodies": [box(2, [0.0, 0.05], [0.1, 0.1], [8, 4], E=1e5)], "gravity": [0.0, -G],
             "obstacles": [{"name": "ground", "plane": {"point": [0, 0], "normal": [0, 1]}}],
             "contact": {"dhat": 1e-4},
             "time": {"integrator": integrator, "dt": dt, "steps": int(round(T / dt))},
             "solver": {"residual_tolerance": 1e-8}}

    def error(f, folder=None):
        e = diffipc.energy.mechanical_energy(f, scene)
        touching = np.concatenate([[False], f["active_contacts"][:] > 0])  # per state, the initial one first
        starts = np.flatnonzero(touching[1:] & ~touching[:-1]) + 1
        ends = np.flatnonzero(~touching[1:] & touching[:-1]) + 1  # first free state after an episode
        # At rest on the plane the box is 5 cm lower (its 5 kg/m, the contact layer neglected): the
        # bouncing energy is E(0) - E_rest = m g 0.05 m.
        rest = e[0] - 1000.0 * 0.1 * 0.05 * G * 0.05
        if len(ends) == 0:
            return float("nan"), "never left the plane"
        first = (e[ends[0]] - e[0]) / (e[0] - rest)
        note = (f"{len(starts)} contact episodes; the first bounce changes the bouncing energy by {100 * first:+.2f}%; "
                f"energy {e[0]:.4g} -> {e[-1]:.4g} J/m at 1 s (at rest: {rest:.4g})")
        return abs(first), note
    return scene, error


HERTZ_R, HERTZ_E, HERTZ_NU, HERTZ_DEPTH = 0.1, 1e7, 0.3, 5e-4


def half_disk_mesh(h_contact, path):
    """The lower half of a disk of radius R centred at (0, R), meshed by gmsh with triangles of size
    h_contact + 0.2 r at distance r from its lowest point (at most 1 cm); a vertex at the centre
    of its flat top edge. Written as gmsh 2.2 ASCII."""
    import gmsh
    R = HERTZ_R
    gmsh.initialize(["hertz", "-v", "2"])
    try:
        gmsh.model.add("half_disk")
        occ = gmsh.model.occ
        disk = occ.addDisk(0, R, 0, R, R)
        upper = occ.addRectangle(-R, R, 0, 2 * R, R)
        half, _ = occ.cut([(2, disk)], [(2, upper)])
        centre = occ.addPoint(0, R, 0)
        occ.fragment(half, [(0, centre)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getEntities(2)], 1)
        field = gmsh.model.mesh.field
        field.add("MathEval", 1)
        field.setString(1, "F", f"{h_contact}+0.2*sqrt(x*x+y*y)")
        field.setAsBackgroundMesh(1)
        for option in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints", "Mesh.MeshSizeFromCurvature"):
            gmsh.option.setNumber(option, 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.01)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.model.mesh.generate(2)
        gmsh.write(path)
    finally:
        gmsh.finalize()


def hertz(mesh, dhat, penalty=None):
    """A half cylinder (radius 0.1 m, neo-Hookean, E = 1e7 Pa, nu = 0.3, plane strain) pressed
    0.5 mm onto a rigid plane by its flat top edge (static, 4 load steps). Hertz's line contact:
    half-width a_H = sqrt(4 F R / (pi E*)), E* = E / (1 - nu^2), peak pressure p0 = 2 F / (pi a_H),
    F the measured force per unit length. The contact half-width is measured from the nodal contact
    forces f_i at x_i as a = 2 sqrt(sum f_i (x_i - xbar)^2 / sum f_i), exact for Hertz's elliptical
    pressure (its second moment is a^2 / 4). Error: |a - a_H| / a_H."""
    R, g0 = HERTZ_R, 0.5 * dhat
    top = R + g0
    scene = {"dimension": 2,
             "bodies": [{"name": "cylinder", "mesh": {"file": mesh}, "translation": [0.0, g0],
                         "material": {"model": "neo_hookean", "E": HERTZ_E, "nu": HERTZ_NU, "density": 1000.0}}],
             "obstacles": [{"name": "floor", "plane": {"point": [0, 0], "normal": [0, 1]}}],
             "contact": contact_block(dhat, "adaptive", penalty),
             "dirichlet": [{"body": 0, "region": {"min": [-1, top], "max": [1, top]},
                            "displacement": [None, f"-{HERTZ_DEPTH}*t"]},
                           {"body": 0, "region": {"min": [0, top], "max": [0, top]}, "displacement": [0, None]}],
             "time": {"integrator": "static", "dt": 0.25, "steps": 4},
             "solver": {"residual_tolerance": 1e-8}, "output": {"vtu_every": 4}}

    def error(f, folder):
        import meshio
        frame = meshio.read(os.path.join(folder, "frame_4.vtu"))
        force, x = frame.point_data["contact_force"][:, 1], frame.points[:, 0]
        on = force > 0
        F = force[on].sum()
        xbar = (force[on] * x[on]).sum() / F
        a = 2 * math.sqrt((force[on] * (x[on] - xbar) ** 2).sum() / F)
        a_h = math.sqrt(4 * F * R / (math.pi * HERTZ_E / (1 - HERTZ_NU ** 2)))
        # The peak pressure from the force of the vertex nearest the centre over its share of the surface.
        xs, fs = x[on][np.argsort(x[on])], force[on][np.argsort(x[on])]
        c = int(np.argmin(np.abs(xs - xbar)))
        share = (xs[min(c + 1, len(xs) - 1)] - xs[max(c - 1, 0)]) / 2
        p0 = 2 * F / (math.pi * a_h)
        note = (f"F = {F:.5g} N/m, a = {a * 1e3:.4f} mm, a_H = {a_h * 1e3:.4f} mm, {int(on.sum())} vertices in "
                f"contact, centre pressure {fs[c] / share:.4g} Pa against p0 = {p0:.4g} Pa")
        return abs(a - a_h) / a_h, note
    return scene, error


def contact_block(dhat, kappa, penalty):
    if penalty is not None:
        return {"dhat": dhat, "model": "penalty", "penalty_stiffness": penalty}
    return {"dhat": dhat, "kappa": kappa}


def sweeps(full):
    """(case, variant, knob, value, builder): one knob varied at a time from the base setting."""
    dts = [0.05, 0.025, 0.0125, 0.00625, 0.003125] + ([0.0015625, 0.00078125] if full else [])
    out = []
    for dim in (2, 3):
        for integ in ("implicit_euler", "bdf2", "newmark"):
            for dt in dts:
                out.append(("free_fall", f"{dim}D {integ}", "dt", dt, lambda d=dim, i=integ, t=dt: free_fall(d, i, t)))
    for dim in (2, 3):
        for model in MATERIALS:
            for tol in (1e-2, 1e-4, 1e-6, 1e-8, 1e-10):
                out.append(("uniaxial", f"{dim}D {model}", "residual tolerance", tol,
                            lambda d=dim, m=model, t=tol: uniaxial(d, m, t)))
            for r in (1, 2, 4):
                out.append(("uniaxial", f"{dim}D {model}", "cells (x 4 along the bar)", r,
                            lambda d=dim, m=model, r=r: uniaxial(d, m, 1e-10, r)))
    refines = {2: [1, 2, 4, 8, 16, 32] + ([64, 128] if full else []), 3: [1, 2, 4, 8, 16]}
    for dim in (2, 3):
        for r in refines[dim]:
            out.append(("cantilever", f"{dim}D", "cells across", r, lambda d=dim, r=r: cantilever(d, r)))
        for tol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
            out.append(("cantilever", f"{dim}D", "residual tolerance", tol,
                        lambda d=dim, t=tol: cantilever(d, refines[d][-2], t)))
    for knob, values in (("dt", [2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]), ("eps_v", [1e-1, 1e-2, 1e-3, 1e-4]),
                         ("segments", [24, 48, 96]), ("mu", [0.3, 0.5, 1.0])):
        for v in values:
            out.append(("rolling", "IPC", knob, v, lambda k=knob, v=v: rolling(**{k: v})))
    for integ in ("implicit_euler", "bdf2", "newmark"):
        for dt in [2e-3, 1e-3, 5e-4, 2.5e-4] + ([1.25e-4] if full else []):
            out.append(("bounce", integ, "dt", dt, lambda i=integ, t=dt: bounce(i, t)))
    k_penalty = [1e3, 1e4, 1e5, 1e6, 1e7] + ([1e8] if full else [])
    for case, fn, extra in (("slope", slope, {"friction iterations": [1, 2, 5, 10]}), ("stopping", stopping, {})):
        knobs = {"dt": [0.008, 0.004, 0.002, 0.001, 0.0005, 0.00025] + ([0.000125] if full else []),
                 "eps_v": [1e-1, 1e-2, 1e-3, 1e-4, 1e-5],
                 "dhat": [2e-3, 1e-3, 5e-4, 2e-4, 1e-4],
                 "kappa": [1e3, 1e5, 1e7, "adaptive"],
                 "penalty stiffness": k_penalty, **extra}
        arg = {"dt": "dt", "eps_v": "eps_v", "dhat": "dhat", "kappa": "kappa",
               "penalty stiffness": "penalty", "friction iterations": "iterations"}
        for knob, values in knobs.items():
            for v in values:
                out.append((case, "IPC" if knob != "penalty stiffness" else "penalty", knob, v,
                            lambda f=fn, k=arg[knob], v=v: f(**{k: v})))
    return out


def hertz_sweeps(out, full):
    """The Hertz case's runs; its meshes are made here, before the runs start."""
    meshes = [2e-3, 1e-3, 5e-4, 2.5e-4] + ([1.25e-4] if full else [])
    joint = [(2e-3, 8e-4), (1e-3, 4e-4), (5e-4, 2e-4), (2.5e-4, 1e-4)] + ([(1.25e-4, 5e-5)] if full else [])
    folder = os.path.join(out, "meshes")
    os.makedirs(folder, exist_ok=True)
    path = {}
    for h in sorted(set(meshes) | {h for h, _ in joint}):
        path[h] = os.path.abspath(os.path.join(folder, f"half_disk_{h:g}.msh"))
        if not os.path.exists(path[h]):
            half_disk_mesh(h, path[h])
    fine = 2.5e-4
    runs = [("hertz", "IPC", "contact mesh size (dhat 1e-4)", h, lambda h=h: hertz(path[h], 1e-4)) for h in meshes]
    runs += [("hertz", "IPC", "dhat (mesh 2.5e-4)", d, lambda d=d: hertz(path[fine], d))
             for d in [4e-4, 2e-4, 1e-4, 5e-5, 2.5e-5]]
    runs += [("hertz", "IPC", "mesh size and dhat together (value: mesh)", h, lambda h=h, d=d: hertz(path[h], d))
             for h, d in joint]
    runs += [("hertz", "penalty", "penalty stiffness (mesh 2.5e-4, dhat 1e-4)", k,
              lambda k=k: hertz(path[fine], 1e-4, penalty=k)) for k in [1e8, 1e9, 1e10, 1e11]]
    return runs


# ---------------------------------------------------------------- running


def run_all(cli, out, todo, ranks):
    """Every run of `todo` as one `diffipc sweep` (docs/sweep.md): a point per scene, each run single-threaded;
    with ranks > 1 under mpirun (docs/mpi.md), the runs dealt to the ranks. The rows, with the errors measured."""
    built = [entry[-1]() for entry in todo]
    scenes = []
    for scene, _ in built:
        scene = copy.deepcopy(scene)
        scene.setdefault("output", {}).setdefault("vtu_every", 0)  # frames only where a case asks for them
        scenes.append(scene)
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "sweep.json")
    with open(path, "w") as f:
        json.dump({"description": "study 502: the reference cases' runs", "scene": scenes[0],
                   "points": [{"": scene} for scene in scenes]}, f)
    folder = os.path.join(out, "runs")
    shutil.rmtree(folder, ignore_errors=True)  # fresh runs: the times are what the study measures
    command = [cli, "--threads", "1", "sweep", path, "-o", folder, "-q"]
    env = dict(os.environ)
    if ranks > 1:
        # OpenMPI refuses root unless told (containers); more ranks than cores need --oversubscribe.
        command = [shutil.which("mpirun") or "mpirun", "-n", str(ranks), "--oversubscribe"] + command
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    if done.returncode not in (0, 2):  # 2: some runs failed (their rows say so; the study reports them)
        raise SystemExit(f"{' '.join(command)}: exit code {done.returncode}\n{done.stdout}{done.stderr}")
    with open(os.path.join(folder, "sweep.json")) as f:
        table = json.load(f)["runs"]
    return [row_of(os.path.join(folder, r["folder"]), r["exit_code"], entry[:4], scene, measure)
            for r, entry, (scene, measure) in zip(table, todo, built)]


def row_of(folder, exit_code, what, scene, measure):
    case, variant, knob, value = what
    summary = json.load(open(os.path.join(folder, "summary.json")))
    row = dict(case=case, variant=variant, knob=knob, value=value, status=summary["status"],
               steps=summary["steps_committed"], newton=summary["counts"]["newton_iterations"],
               time=summary["wall_time"]["total"], measured=float("nan"), error=float("nan"),
               min_gap=float("nan"), note="", folder=os.path.relpath(folder, ROOT))
    if exit_code == 0:
        with h5py.File(os.path.join(folder, "trajectory.h5"), "r") as f:
            measured = measure(f, folder)
            if isinstance(measured, tuple):
                measured, row["note"] = measured
            row["measured"] = float(measured)
            if scene.get("obstacles"):
                row["min_gap"] = float(signed_gap(f, scene))
    return row


def signed_gap(f, scene):
    """The smallest signed distance of a body vertex to the plane obstacle over all committed
    states, from the positions alone (negative: the body is behind the plane)."""
    plane = scene["obstacles"][0]["plane"]
    n = np.array(plane["normal"], float)
    n /= np.linalg.norm(n)
    body = f["mesh/body"][:] == 0
    return ((f["positions"][:, body, :] - np.array(plane["point"])) @ n).min()


def finish_errors(rows):
    """The cantilever's error against its Richardson-extrapolated reference; the others measured
    their error directly. Returns the references {variant: (w_ref, observed order)}."""
    refs = {}
    for r in rows:
        if r["case"] != "cantilever":
            r["error"] = r["measured"]
    for variant in sorted({r["variant"] for r in rows if r["case"] == "cantilever"}):
        mesh = sorted((r for r in rows if r["case"] == "cantilever" and r["variant"] == variant
                       and r["knob"] == "cells across" and r["status"] == "CONVERGED"), key=lambda r: r["value"])
        if len(mesh) < 3:
            continue
        w1, w2, w3 = (m["measured"] for m in mesh[-3:])
        p = math.log2(abs(w1 - w2) / abs(w2 - w3))
        w_ref = w3 + (w3 - w2) / (2 ** p - 1)
        refs[variant] = (w_ref, p)
        for r in rows:
            if r["case"] == "cantilever" and r["variant"] == variant:
                if r["knob"] == "cells across":
                    r["error"] = abs(r["measured"] - w_ref) / abs(w_ref)
                else:
                    # The solver's error: against the same mesh at the default sweep's tolerance 1e-10.
                    same = next(m for m in mesh if m["value"] == mesh[-2]["value"])
                    r["error"] = abs(r["measured"] - same["measured"]) / abs(same["measured"])
    return refs


def observed_order(points):
    """Least-squares slope of log(error) against log(knob) over the points with a finite, positive error."""
    pts = [(v, e) for v, e in points if e > 0 and math.isfinite(e)]
    if len(pts) < 2:
        return float("nan")
    x = np.log([p[0] for p in pts])
    y = np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


# ---------------------------------------------------------------- outputs


def pareto(points):
    """The points (time, error) not dominated by a faster and more accurate one, by time."""
    front, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            front.append((t, e))
            best = e
    return front


def plot_case(case, rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 5.5))
    groups = sorted({(r["variant"], r["knob"]) for r in rows})
    # Past the colour cycle's 10 colours: a colour per variant, a line style per knob.
    variants = sorted({v for v, _ in groups})
    knobs = sorted({k for _, k in groups})
    many = len(groups) > 10
    cmap = plt.get_cmap("tab10" if len(variants) <= 10 else "tab20")
    for variant, knob in groups:
        pts = [r for r in rows if (r["variant"], r["knob"]) == (variant, knob) and r["error"] > 0
               and math.isfinite(r["error"])]
        if not pts:
            continue
        label = f"{variant}: {knob}" if case in ("free_fall", "uniaxial", "cantilever", "bounce") else knob
        if variant == "penalty":
            label = "penalty: stiffness (N/m)"
        style = dict(color=cmap(variants.index(variant)), ls=["-", "--", ":", "-."][knobs.index(knob) % 4]) if many else {}
        line, = ax.plot([r["time"] for r in pts], [r["error"] for r in pts], "o", ms=4, label=label,
                        **({"ls": "-"} | style))
        for r in pts:
            ax.annotate(f"{r['value']:g}" if not isinstance(r["value"], str) else r["value"], (r["time"], r["error"]),
                        fontsize=6, color=line.get_color(), xytext=(3, 2), textcoords="offset points")
    allpts = [(r["time"], r["error"]) for r in rows if r["error"] > 0 and math.isfinite(r["error"])]
    front = pareto(allpts)
    if front:
        ax.plot(*zip(*front), "k--", lw=1, label="Pareto front (all runs)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the run (s)")
    ax.set_ylabel("relative error")
    ax.set_title(f"{case}: error against run time, one knob varied at a time")
    ax.legend(fontsize=7, loc="best")
    ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


EXPECTED = {("free_fall", "implicit_euler"): 1.0, ("free_fall", "bdf2"): 2.0, ("cantilever", "cells across"): -2.0,
            ("slope", "dt"): 1.0, ("stopping", "dt"): 1.0}


def orders_table(rows, refs):
    """Observed orders: the slope of log(error) against log(knob) (for meshes, against h ~ 1/cells,
    over the three finest: the coarse ones lock in bending); error range for exact schemes."""
    lines = ["| case | variant | knob | values | errors | observed order | expected |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for case, variant, knob in sorted({(r["case"], r["variant"], r["knob"]) for r in rows}):
        pts = sorted((r["value"], r["error"]) for r in rows
                     if (r["case"], r["variant"], r["knob"]) == (case, variant, knob) and not isinstance(r["value"], str))
        values = ", ".join(f"{v:g}" for v, _ in pts)
        errors = f"{min(e for _, e in pts):.1e} .. {max(e for _, e in pts):.1e}"
        fit = pts
        if knob == "cells across":
            fit = [(1.0 / v, e) for v, e in pts[-3:]]
        expected = next((f"{abs(o):g}" for (c, k), o in EXPECTED.items()
                         if c == case and (k == knob or k in variant) and (knob in ("dt", "cells across"))), "")
        order = f"{observed_order(fit):.2f}" if expected else "—"
        if case == "free_fall" and "newmark" in variant:
            expected, order = "exact (error at round-off)", "—"
        if case == "uniaxial" and knob.startswith("cells"):
            expected, order = "exact: P1 represents the homogeneous stretch (error at the solver's tolerance)", "—"
        lines.append(f"| {case} | {variant} | {knob} | {values} | {errors} | {order} | {expected} |")
    text = "\n".join(lines) + "\n"
    for variant, (w, p) in sorted(refs.items()):
        text += (f"\nCantilever {variant}: Richardson reference tip deflection {w * 1e3:.5f} mm from the three finest "
                 f"meshes, their observed order {p:.2f}.\n")
    return text


def penalty_table(rows):
    lines = ["| case | contact | setting | status | relative error | min signed gap (m) | Newton | time (s) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for case in ("slope", "stopping"):
        base = [r for r in rows if r["case"] == case and r["knob"] == "dhat" and r["value"] == 2e-4]
        pen = sorted((r for r in rows if r["case"] == case and r["variant"] == "penalty"), key=lambda r: r["value"])
        for r in base + pen:
            setting = "adaptive kappa, dhat 2e-4" if r["variant"] == "IPC" else f"k = {r['value']:g} N/m, dhat 2e-4"
            lines.append(f"| {case} | {r['variant']} | {setting} | {r['status']} | {r['error']:.2e} | "
                         f"{r['min_gap']:.2e} | {r['newton']} | {r['time']:.3f} |")
        ok = [r for r in pen if r["status"] == "CONVERGED" and r["min_gap"] > 0]
        if ok:
            best = min(ok, key=lambda r: r["error"])
            lines.append(f"| {case} | penalty, best in the sweep | k = {best['value']:g} N/m | | {best['error']:.2e} | "
                         f"{best['min_gap']:.2e} | {best['newton']} | {best['time']:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default=os.environ.get("DIFFIPC_CLI", os.path.join(ROOT, "build", "cli", "diffipc")))
    p.add_argument("-o", "--output", default=os.path.join(ROOT, "output", "502"))
    p.add_argument("--full", action="store_true", help="finer time steps and meshes")
    p.add_argument("--cases", nargs="*",
                   default=["free_fall", "uniaxial", "cantilever", "slope", "stopping", "rolling", "hertz", "bounce"])
    p.add_argument("--jobs", type=int, default=2,
                   help="runs at once: MPI ranks of one diffipc sweep (mpirun; 1: the sweep alone)")
    p.add_argument("--results", default=None, help="write results.md, results.csv and the figures here")
    a = p.parse_args(argv)
    output = os.path.abspath(a.output)
    todo = [s for s in sweeps(a.full) if s[0] in a.cases]
    if "hertz" in a.cases:
        todo += hertz_sweeps(output, a.full)
    ranks = a.jobs if a.jobs > 1 and shutil.which("mpirun") else 1
    rows = run_all(a.cli, output, todo, ranks)
    refs = finish_errors(rows)
    if not a.results:
        for r in rows:
            print(r)
        return rows
    os.makedirs(a.results, exist_ok=True)
    diffipc.studies.write_csv(os.path.join(a.results, "results.csv"), rows)
    text = diffipc.studies.provenance(ROOT, __file__, sys.argv[1:] if argv is None else argv)
    text += f"\n{len(rows)} runs, each single-threaded, {ranks} at a time (one diffipc sweep over {ranks} MPI ranks).\n"
    for case in a.cases:
        png = f"{case}.png"
        plot_case(case, [r for r in rows if r["case"] == case], os.path.join(a.results, png))
        text += f"\n![{case}: error against run time]({png})\n"
    text += "\n### Observed orders\n\n" + orders_table(rows, refs)
    table = diffipc.studies.markdown_table
    bo = [r for r in rows if r["case"] == "bounce"]
    if bo:
        text += "\n### Bouncing box: energy per integrator\n\n" + table(
            ["integrator", "dt", "status", "first bounce's error", "measured"],
            [[r["variant"], f"{r['value']:g}", r["status"], f"{r['error']:.2e}", r["note"]] for r in bo])
    hz = [r for r in rows if r["case"] == "hertz"]
    if hz:
        text += "\n### Hertz contact of a half cylinder\n\n" + table(
            ["contact", "knob", "value", "error of a", "time (s)", "measured"],
            [[r["variant"], r["knob"], f"{r['value']:g}", f"{r['error']:.2e}", f"{r['time']:.3f}", r["note"]]
             for r in hz])
    if any(r["variant"] == "penalty" for r in rows):
        text += "\n### IPC and the penalty baseline\n\n" + penalty_table(rows)
    failed = [r for r in rows if r["status"] != "CONVERGED"]
    text += f"\n{len(failed)} of {len(rows)} runs did not converge"
    text += (": " + "; ".join(f"{r['case']} {r['variant']} {r['knob']} = {r['value']}: {r['status']}" for r in failed)
             if failed else ".") + "\n"
    open(os.path.join(a.results, "results.md"), "w").write(text)
    return rows


if __name__ == "__main__":
    main()
