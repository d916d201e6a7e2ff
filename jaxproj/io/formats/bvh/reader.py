"""Reading a BVH file: units (``scale=``) and ``read_bvh``, the ``"bvh"`` format's reader.

``read_bvh`` chains the steps of ``jaxproj.io.formats.bvh`` (parse, joint map, scale, forward
kinematics, Kinect joints) into a ``Recording``; ``FORMAT`` registers it (``.bvh``, or a first line
``HIERARCHY``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.io.formats.base import Format
from jaxproj.io.formats.bvh.joint_maps import JOINT_MAPS, ROOT_JOINT, resolve_joint_map
from jaxproj.io.formats.bvh.kinematics import kinect_positions
from jaxproj.io.formats.bvh.parser import BvhClip, parse_bvh
from jaxproj.io.recording import MAX_DURATION_S, Recording, check_fps, make_recording, resample
from jaxproj.io.text import Head

CMU_SCALE = (1.0 / 0.45) * 2.54 / 100.0
"""Metres per CMU skeleton unit (the ASF files' ``length 0.45``: 1 unit = 1 / 0.45 inch)."""

UNITS: dict[str, float] = {"cmu": CMU_SCALE, "m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
"""Unit names accepted by ``scale=`` (metres per file unit)."""

REFERENCE_HEIGHT_M = 1.5
"""Head-to-ankle height (m) that ``scale="auto"`` aims at when it guesses the unit of a
skeleton without a preset (an adult's ~1.7 m stature less the head top and the feet)."""


_PRESET_SCALE = {"cmu": CMU_SCALE, "cmu-mb": CMU_SCALE}

REST_FRAMES: tuple[str, ...] = ("drop", "keep")
"""``rest_frame=`` of ``read_bvh`` (CLI ``--bvh-rest-frame``): what to do with a first frame that
is the hierarchy's rest pose (``rest_pose_first``)."""

REST_TOLERANCE_DEG = 1e-4
"""A rotation channel within this many degrees of 0 counts as zero (files write 4 decimals)."""


def rest_pose_first(clip: BvhClip) -> bool:
    """Whether the clip's frame 0 is a converter's synthetic rest pose rather than motion.

    Converters that write a reference pose before the motion (the CMU releases made for
    MotionBuilder and 3ds Max insert a T-pose as frame 0 in some files) write it as every joint
    rotation 0: the hierarchy's own rest pose (its ``OFFSET``s). Frame 0 counts as such a frame
    when every rotation channel of every joint but the root is within ``REST_TOLERANCE_DEG`` of
    0 and frame 1's are finite and not all so (captured motion never holds every joint exactly at
    0; a frame 1 with a non-finite value says nothing, and frame 0 is kept). The
    root's rotation and position are not read (a converter may place the pose anywhere). The two
    bundled CMU clips (``tests/data/cmu_bvh``) start with motion: nothing is dropped there.

    Args:
      clip: the parsed file.

    Returns:
      True for a clip of at least two frames whose frame 0 is such a rest pose.
    """
    if clip.n_frames < 2:
        return False
    cols, start = [], 0
    for j, names in enumerate(clip.channels):
        if clip.parents[j] >= 0:
            cols += [start + k for k, c in enumerate(names) if c.lower().endswith("rotation")]
        start += len(names)
    if not cols:
        return False
    zero = np.abs(clip.motion[:2, cols]) <= REST_TOLERANCE_DEG
    moving = np.isfinite(clip.motion[1, cols]).all() and not zero[1].all()  # a lost frame 1: keep
    return bool(zero[0].all() and moving)


def auto_scale(clip: BvhClip, map_name: str, table: Mapping[str, str]) -> tuple[float, str]:
    """``(metres per file unit, how it was chosen)`` for ``scale="auto"`` (module docstring)."""
    if map_name in _PRESET_SCALE:
        return _PRESET_SCALE[map_name], f"cmu units ({CMU_SCALE:.6g} m)"
    lengths = np.linalg.norm(clip.offsets, axis=1)

    def chain(j: int) -> float:
        total = 0.0
        while j >= 0:
            total += float(lengths[j]) if clip.parents[j] >= 0 else 0.0
            j = int(clip.parents[j])
        return total

    height = chain(clip.index(table["Head"])) + chain(clip.index(table["AnkleLeft"]))
    if not (height > 0 and math.isfinite(height)):
        return 1.0, "m (rest pose has no height)"
    unit = min(
        (u for u in UNITS if u != "cmu"),
        key=lambda u: abs(math.log(height * UNITS[u] / REFERENCE_HEIGHT_M)),
    )
    return UNITS[unit], f"{unit} (guessed: rest pose {height:g} units head to ankle)"


def _scale(clip: BvhClip, scale: float | str, map_name: str, table: Mapping[str, str]):
    if isinstance(scale, str):
        if scale == "auto":
            return auto_scale(clip, map_name, table)
        if scale in UNITS:
            return UNITS[scale], f"{scale} (given)"
        try:
            scale = float(scale)
        except ValueError:
            raise ConfigError(
                f"bvh scale must be 'auto', a unit ({', '.join(UNITS)}) or a positive number, "
                f"got {scale!r}"
            ) from None
    value = float(scale)
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"bvh scale must be a positive finite number, got {scale!r}")
    return value, f"x {value:g} (given)"


def read_bvh(
    path: str | os.PathLike[str],
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
    scale: float | str = "auto",
    fps: float | None = None,
    *,
    data: bytes | None = None,
    rest_frame: str = "drop",
) -> Recording:
    """Read a BVH file into a ``Recording`` (``(T, 20, 3)`` float32 metres, Kinect order).

    Args:
      path: the ``.bvh`` file.
      bvh_map: ``"auto"`` (detect a preset), a preset of ``JOINT_MAPS`` (``"cmu"``,
        ``"cmu-mb"``, ``"lafan1"``, ``"mixamo"``), a JSON / TOML map file or a dict of Kinect
        joint -> BVH joint (``jaxproj.io.formats.bvh``).
      scale: ``"auto"``, a unit name of ``UNITS`` or metres per file unit.
      fps: ``None`` keeps the clip's frames (``Frame Time``); a rate resamples the clip to it.
      data: the file's bytes, if already read.
      rest_frame: ``"drop"`` (default): leave out frame 0 when it is a converter's synthetic
        rest pose (``rest_pose_first``; the recording then starts, at time 0, with the file's
        frame 1); ``"keep"``: read every frame.

    Returns:
      ``Recording`` with ``format="bvh"``, ``times`` from ``Frame Time`` (or the resampled grid)
      and ``time_source`` saying which map, scale and rate were used, and whether a rest frame
      was dropped.

    Raises:
      InputError: a malformed file or a map that does not fit it (one line, file and line).
      ConfigError: a bad ``scale``, ``fps``, ``rest_frame`` or map dict.
    """
    if fps is not None:
        check_fps(fps)
    if rest_frame not in REST_FRAMES:
        raise ConfigError(f"rest_frame must be one of {REST_FRAMES}, got {rest_frame!r}")
    clip = parse_bvh(path, data)
    dropped = rest_frame == "drop" and rest_pose_first(clip)
    if dropped:
        clip = dataclasses.replace(clip, motion=clip.motion[1:], lines=clip.lines[1:])
    map_name, table = resolve_joint_map(clip, bvh_map)
    metres, scale_note = _scale(clip, scale, map_name, table)
    positions = kinect_positions(clip, table, metres)
    times = np.arange(clip.n_frames, dtype=np.float64) * clip.frame_time
    if times[-1] > MAX_DURATION_S:
        raise InputError(
            path,
            f"the clip spans {times[-1]:g} s (more than {MAX_DURATION_S:g} s): corrupt "
            "Frame Time or Frames",
        )
    rec = make_recording(positions, None, str(path), "bvh")
    prefix = table["HipCenter"][: -len(ROOT_JOINT)] if map_name in JOINT_MAPS else ""
    if prefix:
        map_name += f" (joint names prefixed {prefix!r})"
    note = (f"BVH Frame Time {clip.frame_time:g} s ({clip.fps:.6g} fps); map {map_name}; "
            f"scale {scale_note}")  # fmt: skip
    if dropped:
        note += "; frame 0 (the hierarchy's rest pose, all rotations 0) dropped"
    rec = dataclasses.replace(rec, times=times, time_source=note, nominal_fps=clip.fps)
    if fps is not None:
        rec = resample(rec, fps)
    return rec


def sniff(head: Head) -> tuple[bool, str]:
    """A text file named ``.bvh`` or whose first line is ``HIERARCHY``."""
    line = head.first_line
    if line is None:
        return False, ""
    return head.suffix == ".bvh" or line.split()[:1] == ["HIERARCHY"], ""


def read(
    path: str | os.PathLike[str],
    data: bytes,
    fps: float | None,
    *,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
    scale: float | str = "auto",
    rest_frame: str = "drop",
    **options: Any,
) -> Recording:
    """``read_bvh`` as a format's reader (``Format.read``)."""
    return read_bvh(path, bvh_map, scale, fps, data=data, rest_frame=rest_frame)


FORMAT = Format(
    name="bvh",
    description="BVH motion capture: CMU, LAFAN1, Xsens..., mapped to the 20 Kinect joints",
    suffixes=(".bvh",),
    sniff=sniff,
    read=read,
    first_line=("HIERARCHY (BVH)", ""),
)
