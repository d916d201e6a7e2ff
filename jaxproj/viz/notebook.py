"""What the notebooks in ``notebooks/`` share: the run mode, the header line, the results file.

* ``fast_mode()``: ``JAXPROJ_FAST=1`` in the environment selects each notebook's smaller settings
  (the tests run them so); anything else runs the full settings that the committed outputs come
  from.
* ``header()``: the first line a notebook prints: the ``jaxproj`` version, the run mode and the
  machine. Committed outputs are tied to a release: ``notebooks/execute.py`` records the version
  and a hash of the notebook's code cells in its metadata, and
  ``tests/integration/test_notebooks.py`` checks that the hash matches the cells and the version
  is the current one. A library edit between releases does not stale the notebooks (the tests
  still execute all four in fast mode and check their results); cutting a release includes
  ``python notebooks/execute.py``.
* ``save_results(name, results, **arrays)``: with ``JAXPROJ_NOTEBOOK_RESULTS`` set to a folder,
  a notebook writes its key results there (``name.json`` and, given arrays, ``name.npz``) for the
  tests to check; without it, nothing is written.
"""

from __future__ import annotations

import functools
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from jaxproj._internal.atomic import write_npz

FAST_ENV = "JAXPROJ_FAST"
"""Environment variable: ``1`` selects the notebooks' fast settings."""

RESULTS_ENV = "JAXPROJ_NOTEBOOK_RESULTS"
"""Environment variable: a folder the notebooks write their key results to (tests)."""


def fast_mode() -> bool:
    """Whether ``JAXPROJ_FAST`` asks for the fast settings (``1``, ``true`` or ``yes``)."""
    return os.environ.get(FAST_ENV, "").strip().lower() in ("1", "true", "yes")


def header(fast: bool | None = None) -> str:
    """The first line a notebook prints: library version, run mode, JAX and MuJoCo versions and
    the device. ``tests/integration/test_notebooks.py`` reads the version and the mode from it."""
    import jax
    import mujoco

    import jaxproj

    fast = fast_mode() if fast is None else fast
    mode = f"fast ({FAST_ENV}=1)" if fast else "full"
    dev = jax.devices()[0]
    return (
        f"jaxproj {jaxproj.__version__} | mode: {mode} | "
        f"jax {jax.__version__} on {dev.platform} ({os.cpu_count()} CPU cores) | mujoco "
        f"{mujoco.__version__} | Python {platform.python_version()}"
    )


@functools.cache
def render_backend() -> str:
    """``"mujoco"`` where MuJoCo's offscreen renderer can be created (an OpenGL context:
    ``MUJOCO_GL=egl`` / ``osmesa`` or a display), else ``"matplotlib"``; decided once, quietly
    (``render``'s ``"auto"`` backend says so on stderr at every call)."""
    from jaxproj import robots
    from jaxproj.io.motion_files import Motion
    from jaxproj.viz import render

    robot = robots.get()  # the default robot: any robot's MJCF tells whether OpenGL works
    standing = Motion(robot.standing[None], np.zeros(1), np.ones(1, bool), robot=robot)
    try:
        render.render_frames(standing, backend="mujoco", size=(32, 32))
    except render.RenderError:
        return "matplotlib"
    return "mujoco"


def save_results(name: str, results: dict[str, Any], **arrays: Any) -> Path | None:
    """Write ``results`` (JSON-ready after ``report.to_jsonable``) to ``$JAXPROJ_NOTEBOOK_RESULTS/
    name.json`` and ``arrays`` to ``name.npz`` when that variable is set; returns the JSON path,
    or ``None`` (and writes nothing) when it is not."""
    from jaxproj.viz import report

    folder = os.environ.get(RESULTS_ENV)
    if not folder:
        return None
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    report.write_json(out / f"{name}.json", results)
    if arrays:
        write_npz(out / f"{name}.npz", {k: np.asarray(v) for k, v in arrays.items()})
    return out / f"{name}.json"


__all__ = ["FAST_ENV", "RESULTS_ENV", "fast_mode", "header", "render_backend", "save_results"]
