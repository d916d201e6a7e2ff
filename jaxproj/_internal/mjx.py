"""``mujoco.mjx``, imported without its "Failed to import warp" notice.

MuJoCo MJX 3.x tries the optional NVIDIA Warp backend when it is imported and *prints* (to
stdout) ``Failed to import warp: No module named 'warp'`` and the same for ``mujoco_warp`` when
Warp is not installed. jaxproj uses MJX's JAX implementation (``impl="jax"``) only, so on a
machine without Warp that notice is expected and reads like an error. ``import_mjx`` drops
exactly those two lines; anything else MJX prints (a Warp that is installed but broken, say)
still reaches stdout, and an import that fails still raises.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys
from types import ModuleType

_NOTICE = re.compile(r"Failed to import (warp|mujoco_warp): No module named 'warp'")


def drop_warp_notice(text: str) -> str:
    """``text`` without the lines of MJX's notice that Warp is not installed."""
    lines = text.splitlines(keepends=True)
    return "".join(line for line in lines if not _NOTICE.fullmatch(line.rstrip("\r\n")))


def import_mjx() -> ModuleType:
    """``mujoco.mjx`` (imported once per process; later imports print nothing anyway)."""
    if "mujoco.mjx" in sys.modules:
        return sys.modules["mujoco.mjx"]
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            from mujoco import mjx
    finally:
        rest = drop_warp_notice(printed.getvalue())
        if rest:
            sys.stdout.write(rest)
    return mjx
