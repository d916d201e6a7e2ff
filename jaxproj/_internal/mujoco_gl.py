"""Import MuJoCo whatever ``MUJOCO_GL`` says: a rendering back-end that cannot load must not take
the physics (and every command) down with it.

``import mujoco`` loads the OpenGL back-end that ``MUJOCO_GL`` names, and only an ``ImportError``
of it is caught by MuJoCo itself. ``MUJOCO_GL=osmesa`` on a machine without libOSMesa fails inside
PyOpenGL with ``AttributeError: 'NoneType' object has no attribute 'glGetError'``, an unknown
value with ``RuntimeError``: the whole package, jaxproj with it, then fails to import (even
``jaxproj info`` died with that traceback). Importing this module imports MuJoCo
(``import_mujoco``), and ``jaxproj/__init__.py`` imports it first of all. Where the back-end of
``MUJOCO_GL`` fails, MuJoCo is imported again with rendering disabled, the environment restored,
and one line kept saying what failed (``gl_failure``): ``jaxproj info`` reports it, and the
renderer (``jaxproj.viz.render``) raises it as a one-line ``RenderError`` (or, for
``backend="auto"``, draws with matplotlib).
"""

from __future__ import annotations

import os
import sys
from types import ModuleType

from jaxproj._internal.environ import restore_environ, saved_environ

_DISABLED = ("disable", "disabled", "off", "false", "0")
"""``MUJOCO_GL`` values that load no OpenGL back-end (MuJoCo's ``gl_context``)."""

_NEEDS = {
    "osmesa": "libOSMesa (e.g. apt install libosmesa6)",
    "egl": "libEGL and a GPU driver or Mesa",
}
"""What each headless back-end loads, for the message."""

_failure: list[str] = []
"""The back-end failure of the first import, if any (one line)."""


def _forget(prefixes: tuple[str, ...]) -> None:
    """Drop half-imported pure-Python modules (a failed import leaves its finished submodules
    in ``sys.modules``) so that the second import runs them again; MuJoCo's compiled
    extensions stay (they loaded, and cannot be loaded twice)."""
    for name in list(sys.modules):
        if name.startswith(prefixes) and not name.startswith("mujoco._"):
            del sys.modules[name]


def import_mujoco() -> ModuleType:
    """``mujoco``, imported; a failed ``MUJOCO_GL`` back-end is recorded (``gl_failure``) and
    MuJoCo imported without rendering. Any other import failure propagates."""
    if "mujoco" in sys.modules:
        return sys.modules["mujoco"]
    gl = os.environ.get("MUJOCO_GL", "")
    saved = saved_environ(("MUJOCO_GL", "PYOPENGL_PLATFORM"))
    try:
        import mujoco
    except Exception as e:  # AttributeError (PyOpenGL without its library), RuntimeError, ...
        if gl.strip().lower() in ("", *_DISABLED):
            raise  # not the rendering back-end: a broken installation
        text = " ".join(str(e).split())
        needs = _NEEDS.get(gl.strip().lower())
        hint = f"; it needs {needs}" if needs else ""
        _failure.append(
            f"MUJOCO_GL={gl}: MuJoCo's OpenGL back-end cannot load ({type(e).__name__}: "
            f"{text}{hint})"
        )
        _forget(("mujoco", "OpenGL"))
        os.environ["MUJOCO_GL"] = "disable"
        try:
            import mujoco
        finally:
            restore_environ(saved)
    return mujoco


def gl_failure() -> str | None:
    """What made the ``MUJOCO_GL`` back-end fail when MuJoCo was imported (one line), or
    ``None``: rendering with MuJoCo is then unavailable in this process."""
    return _failure[0] if _failure else None


import_mujoco()  # on import: before any other jaxproj module imports mujoco
