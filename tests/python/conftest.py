import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture
def root():
    return ROOT


@pytest.fixture
def cli():
    path = os.environ.get("DIFFIPC_CLI", str(ROOT / "build" / "cli" / "diffipc"))
    if not os.path.exists(path):
        pytest.fail(f"diffipc CLI not found at {path}; build first or set DIFFIPC_CLI")
    return path


def box_scene(dim=2, model="neo_hookean", E=1e5, nu=0.3, steps=3, integrator="implicit_euler", dt=0.01):
    hi = [0.5, 0.2] if dim == 2 else [0.5, 0.2, 0.2]
    cells = [4, 2] if dim == 2 else [3, 1, 1]
    return {
        "dimension": dim,
        "bodies": [{"name": "b", "mesh": {"box": {"min": [0.0] * dim, "max": hi, "cells": cells}},
                    "material": {"model": model, "E": E, "nu": nu, "density": 1000.0}}],
        "time": {"integrator": integrator, "dt": dt, "steps": steps},
        "solver": {"residual_tolerance": 1e-10},
    }


def load_script(path):
    """A study's script (studies/NNN/run.py, ...) as a module, to call its functions."""
    import importlib.util
    path = pathlib.Path(path)
    spec = importlib.util.spec_from_file_location(f"{path.parent.name}_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
