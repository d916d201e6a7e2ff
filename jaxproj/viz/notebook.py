"""What the notebooks in ``notebooks/`` share: the run mode, the library stamp, the results file.

* ``fast_mode()``: ``JAXPROJ_FAST=1`` in the environment selects each notebook's smaller settings
  (the tests run them so); anything else runs the full settings that the committed outputs come
  from.
* ``library_stamp()``: a hash of the library's code and data, i.e. of every file of the
  ``jaxproj`` package that ``pip install`` installs (``*.py`` sources, ``py.typed``, the MJCF in
  ``assets/``, the bundled data and their notes in ``data/``), path and content. A notebook prints
  it in its first cell (``header``); ``tests/test_notebooks.py`` compares the stamp a committed
  notebook printed with the stamp of the code it sits beside, so outputs computed by other code
  fail the tests until the notebooks are executed again (``python notebooks/execute.py``). It
  changes with any change to those files, comments included: stale means "not computed by this
  code", not "known to be different".
* ``save_results(name, results, **arrays)``: with ``JAXPROJ_NOTEBOOK_RESULTS`` set to a folder,
  a notebook writes its key results there (``name.json`` and, given arrays, ``name.npz``) for the
  tests to check; without it, nothing is written.
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

FAST_ENV = "JAXPROJ_FAST"
"""Environment variable: ``1`` selects the notebooks' fast settings."""

RESULTS_ENV = "JAXPROJ_NOTEBOOK_RESULTS"
"""Environment variable: a folder the notebooks write their key results to (tests)."""

STAMP_PATTERNS: tuple[str, ...] = ("**/*.py", "py.typed", "assets/*.xml", "data/*.npz",
                                   "data/*.md", "data/*.txt")  # fmt: skip
"""The package files the stamp covers, relative to the package folder: what ``pip install``
installs (``pyproject.toml``: the packages' modules plus ``package-data``)."""

STAMP_LENGTH = 16
"""Hex digits of the stamp (64 bits of the SHA-256)."""


def fast_mode() -> bool:
    """Whether ``JAXPROJ_FAST`` asks for the fast settings (``1``, ``true`` or ``yes``)."""
    return os.environ.get(FAST_ENV, "").strip().lower() in ("1", "true", "yes")


def stamp_files(root: str | os.PathLike[str] | None = None) -> list[Path]:
    """The files ``library_stamp`` hashes, sorted by path (``root``: the package folder, by
    default that of the imported ``jaxproj``)."""
    base = Path(__file__).parents[1] if root is None else Path(root)
    files = {p for pattern in STAMP_PATTERNS for p in base.glob(pattern) if p.is_file()}
    return sorted((p for p in files if "__pycache__" not in p.parts),
                  key=lambda p: p.relative_to(base).as_posix())  # fmt: skip


def library_stamp(root: str | os.PathLike[str] | None = None) -> str:
    """Hash (``STAMP_LENGTH`` hex digits of a SHA-256) of the package's code and data: each file
    of ``stamp_files(root)`` contributes its path relative to ``root`` and its bytes."""
    base = Path(__file__).parents[1] if root is None else Path(root)
    h = hashlib.sha256()
    for p in stamp_files(base):
        data = p.read_bytes()
        h.update(p.relative_to(base).as_posix().encode() + b"\0")
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:STAMP_LENGTH]


def header(fast: bool | None = None) -> str:
    """The first line a notebook prints: library version and stamp, run mode, JAX and MuJoCo
    versions and the device. ``tests/test_notebooks.py`` reads the stamp and the mode from it."""
    import jax
    import mujoco

    import jaxproj

    fast = fast_mode() if fast is None else fast
    mode = f"fast ({FAST_ENV}=1)" if fast else "full"
    dev = jax.devices()[0]
    return (
        f"jaxproj {jaxproj.__version__} | library stamp {library_stamp()} | mode: {mode} | "
        f"jax {jax.__version__} on {dev.platform} ({os.cpu_count()} CPU cores) | mujoco "
        f"{mujoco.__version__} | Python {platform.python_version()}"
    )


@functools.cache
def render_backend() -> str:
    """``"mujoco"`` where MuJoCo's offscreen renderer can be created (an OpenGL context:
    ``MUJOCO_GL=egl`` / ``osmesa`` or a display), else ``"matplotlib"``; decided once, quietly
    (``render``'s ``"auto"`` backend says so on stderr at every call)."""
    from jaxproj.io.motion_files import Motion
    from jaxproj.robots.nao_h25 import robot
    from jaxproj.viz import render

    standing = Motion(robot.STANDING_POSTURE[None], np.zeros(1), np.ones(1, bool))
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
        np.savez(out / f"{name}.npz", **{k: np.asarray(v) for k, v in arrays.items()})
    return out / f"{name}.json"


__all__ = ["FAST_ENV", "RESULTS_ENV", "fast_mode", "header", "library_stamp", "render_backend",
           "save_results", "stamp_files"]  # fmt: skip
