"""diffipc: differentiable Incremental Potential Contact elastodynamics.

Load a scene (file path or dict), run it, get the trajectory as numpy arrays;
load a problem (docs/problem_format.md) as a ReducedFunctional for J(p) and its
adjoint gradient dJ/dp, checked by taylor_test and finite_difference_check.
Bad input raises ValueError naming the field; a gradient that cannot be
computed raises AdjointError (a RuntimeError). diffipc.plot draws PNG figures of a
`diffipc optimize` output directory. See docs/python.md.
"""

import json
import os


def _prepare_openmp():
    """libgomp (loaded with the extension, through SuiteSparse) reads OMP_WAIT_POLICY once,
    when it is loaded: ask its idle threads to sleep rather than spin against TBB and
    OpenBLAS (forward/common/threads.hpp), unless the user chose, or it is loaded already."""
    if os.environ.get("OMP_WAIT_POLICY") or os.environ.get("GOMP_SPINCOUNT"):
        return
    try:
        with open("/proc/self/maps") as maps:
            if "libgomp" in maps.read():
                return
    except OSError:
        return
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
    os.environ["DIFFIPC_SET_OMP_WAIT_POLICY"] = "1"


_prepare_openmp()

from ._diffipc import (  # noqa: E402,F401
    AdjointError,
    Evaluation,
    InputError,
    Scene,
    Simulator,
    element_energy,
    element_gradient,
    element_hessian,
    lame_parameters,
    load_scene,
    young_poisson_of_lame,
    registered_optimizer_algorithms,
    _scene_from_json_text,
    _thread_info,
)
from ._diffipc import set_threads as _set_threads  # noqa: E402
from .reduced import ReducedFunctional, finite_difference_check, taylor_test  # noqa: E402,F401
from .optimize import OptimizeResult, minimize  # noqa: E402,F401
from . import microstructure  # noqa: E402,F401


def __getattr__(name):
    # diffipc.plot (matplotlib) is imported on first use: `import diffipc` stays light, and
    # `python3 -m diffipc.plot` does not find the module imported before it runs.
    if name == "plot":
        import importlib

        return importlib.import_module(".plot", __name__)
    raise AttributeError(f"module 'diffipc' has no attribute '{name}'")


def set_threads(count):
    """Use `count` threads in TBB, OpenBLAS and OpenMP (0: the cores this process may use,
    CPU affinity and cgroup quota respected). Wins over DIFFIPC_THREADS and the files'
    `threads` keys; a user's OPENBLAS_NUM_THREADS / OMP_NUM_THREADS still win for their
    library. Returns thread_info()."""
    return json.loads(_set_threads(int(count)))


def thread_info():
    """The effective thread configuration: the count and where it came from, the usable
    cores, and each pool's setting read back from TBB, OpenBLAS and OpenMP."""
    return json.loads(_thread_info())


def scene(source, base_directory=None):
    """Return a validated Scene from a path to a JSON file or from a dict.

    Relative mesh paths in a dict are resolved against ``base_directory``
    (default: the current directory); a file's are relative to the file, so
    ``base_directory`` with a path or a Scene is a TypeError.
    """
    if base_directory is not None and not isinstance(source, dict):
        raise TypeError("base_directory applies to a scene dict; a file's mesh paths are relative to the file")
    if isinstance(source, Scene):
        return source
    if isinstance(source, (str, os.PathLike)):
        return load_scene(os.fspath(source))
    if isinstance(source, dict):
        try:
            text = json.dumps(source, allow_nan=False)
        except ValueError as e:
            raise ValueError(f"<dict>: scene contains a NaN or infinite number ({e})") from None
        except TypeError as e:
            raise ValueError(f"<dict>: scene is not JSON-serializable ({e})") from None
        return _scene_from_json_text(text, os.fspath(base_directory or os.getcwd()))
    raise TypeError("scene source must be a path, a dict or a Scene")


def simulate(source, progress=None, base_directory=None):
    """Run a scene (a path, a dict or a Scene) to its end (or its first failed step); returns
    (simulator, trajectory dict). ``base_directory``: as in :func:`scene`, for a dict."""
    sim = Simulator(scene(source, base_directory))
    trajectory = sim.run(progress) if progress else sim.run()
    return sim, trajectory


def to_meshio(sim_or_scene, positions=None):
    """A meshio.Mesh of the scene's elements at the given #V by dim positions (rest by default)."""
    import meshio
    import numpy as np

    sc = sim_or_scene
    if isinstance(sim_or_scene, Simulator):
        raise TypeError("pass the Scene; positions come from the trajectory")
    points = np.asarray(positions if positions is not None else sc.rest_positions, dtype=float)
    cell_type = "triangle" if sc.dimension == 2 else "tetra"
    return meshio.Mesh(points, [(cell_type, np.asarray(sc.elements))])
