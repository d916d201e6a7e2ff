"""Checks every exported trajectory shares: JSON-scalar ``meta`` and strictly increasing times.

Used by the motion files (``jaxproj.io.motion_files``: NPZ, CSV) and by each robot's own export
(``Robot.exports``, e.g. ``jaxproj.robots.nao_h25.naoqi``), so they live below both. Both raise
``ConfigError``; ``load_motion`` reports it as an ``InputError`` naming the file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from jaxproj.errors import ConfigError

MetaValue = str | int | float | bool
"""A ``Motion.meta`` value: a JSON scalar."""


def check_meta(meta: object) -> dict[str, MetaValue]:
    """A plain ``dict`` of JSON scalars (numpy scalars turned into Python ones), or ConfigError."""
    if not isinstance(meta, Mapping):
        raise ConfigError(f"meta must be a mapping of str to scalars, got {type(meta).__name__}")
    out: dict[str, MetaValue] = {}
    for key, value in meta.items():
        if not isinstance(key, str):
            raise ConfigError(f"meta keys must be str, got {key!r}")
        if isinstance(value, np.generic):
            value = value.item()
        if not isinstance(value, (str, int, float, bool)):
            raise ConfigError(
                f"meta[{key!r}] must be a str, int, float or bool, got {type(value).__name__}"
            )
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(f"meta[{key!r}] must be finite, got {value}")
        out[key] = value
    return out


def check_times(times: np.ndarray, what: str = "times") -> None:
    """ConfigError unless ``(T,)`` ``times`` are finite and strictly increasing."""
    if not np.isfinite(times).all():
        raise ConfigError(f"{what} must be finite")
    steps = np.diff(times)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise ConfigError(
            f"{what} must increase strictly: frame {i} at {float(times[i])!r} follows "
            f"{float(times[i - 1])!r}"
        )
