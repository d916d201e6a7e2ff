"""NAOqi JSON: the NAO's own trajectory document (``Robot.exports[".json"]`` of the NAO H25).

The document is exactly the arguments of NAOqi's
``ALMotion.angleInterpolation(names, angleLists, timeLists, isAbsolute)``:
``{"names": [...], "angleLists": [[...], ...], "timeLists": [[...], ...], "isAbsolute": true}``,
one angle list and one time list per joint name, plus a ``"jaxproj"`` block (the motion's
``meta`` and ``t0``, ``lead_in_s``, ``joints``, ``invalid_frames``, and ``confidence``, one
number per frame, when the motion has one) that NAOqi never sees.
Times are ``times - times[0] + lead_in``: NAOqi wants strictly increasing times > 0, and the
lead-in (default 1 s) gives the robot time to move from wherever it stands to the first pose.
By default only the ``"upper"`` joints are written (``UPPER_JOINTS``: NAOqi's Head, LArm and
RArm chains), since a standing NAO's legs belong to its own balance / posture control;
``joints="body"`` writes every joint. Reading fills joints the file does not name with the
standing posture and restores the original times from ``t0`` / ``lead_in_s``.

``jaxproj.io.motion_files`` (``save_motion`` / ``load_motion`` of a ``.json`` path) calls
``EXPORT``; the functions take the ``Robot`` (the NAO) for its joint names and posture.
``save_motion`` hands them angles already held ``motion_files.EXPORT_MARGIN`` (2e-4 rad) inside
every joint's range and inside the head envelope, so a strict URDF-limit check passes; the
angles are otherwise the motion's, so a ``jaxproj retarget`` output keeps its speed limits
(``jaxproj.motion.feasible``: the rated speeds by default).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.robots.base import Export
from jaxproj.robots.export import check_meta, check_times

if TYPE_CHECKING:
    from jaxproj.robots.base import Robot

UPPER_JOINTS: tuple[str, ...] = (
    "HeadYaw", "HeadPitch",
    "LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll", "LWristYaw", "LHand",
    "RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll", "RWristYaw", "RHand",
)  # fmt: skip
"""NAOqi's Head, LArm and RArm chains, in ``robot.JOINT_NAMES`` order (``joints="upper"``)."""

DEFAULT_LEAD_IN_S = 1.0
"""Seconds before the first pose in NAOqi JSON (the robot moves there from where it stands)."""

RESERVED_META = ("t0", "lead_in_s", "joints", "invalid_frames", "confidence")
"""Keys of the ``"jaxproj"`` block that a motion's ``meta`` may not use."""

_JSON_KEYS = ("names", "angleLists", "timeLists", "isAbsolute")


def joint_sets(robot: Robot) -> dict[str, tuple[str, ...]]:
    """Named joint selections of ``save_motion(..., joints=)``: ``"upper"``, ``"body"``."""
    return {"upper": UPPER_JOINTS, "body": robot.joint_names}


def resolve_joints(robot: Robot, joints: str | Sequence[str]) -> tuple[str, ...]:
    """``"upper"`` / ``"body"`` (``joint_sets``) or a sequence of joint names -> names.

    Raises:
      ConfigError: an unknown set or joint name, a repeated name, or no name at all.
    """
    sets = joint_sets(robot)
    if isinstance(joints, str):
        if joints not in sets:
            raise ConfigError(
                f"joints must be one of {sorted(sets)} or a sequence of joint names, got {joints!r}"
            )
        return sets[joints]
    names = tuple(joints)
    unknown = [n for n in names if not robot.has_joint(n)]
    if unknown:
        raise ConfigError(f"unknown joint names {unknown}; valid names: {robot.joint_names}")
    if not names or len(set(names)) != len(names):
        raise ConfigError(f"joints must name each joint once and at least one, got {names}")
    return names


def check_options(
    robot: Robot, joints: str | Sequence[str], lead_in: float | None
) -> tuple[tuple[str, ...], str | list[str], float]:
    """Validated ``(names, label, lead_in)`` of ``save_motion``'s ``joints`` / ``lead_in``
    (``lead_in=None``: ``DEFAULT_LEAD_IN_S``)."""
    names = resolve_joints(robot, joints)
    lead = DEFAULT_LEAD_IN_S if lead_in is None else float(lead_in)
    if not (math.isfinite(lead) and lead > 0):
        raise ConfigError(f"lead_in must be a finite number of seconds > 0, got {lead_in!r}")
    label: str | list[str] = joints if isinstance(joints, str) else list(names)
    return names, label, lead


def document(
    robot: Robot,
    angles: np.ndarray,
    times: np.ndarray,
    valid: np.ndarray,
    meta: Mapping[str, Any],
    options: tuple[tuple[str, ...], str | list[str], float],
    confidence: np.ndarray | None = None,
) -> dict[str, Any]:
    """The NAOqi ``angleInterpolation`` arguments plus the ``jaxproj`` block.

    Args:
      robot: the NAO (joint names).
      angles: ``(T, n_joints)`` float32 rad; times: ``(T,)`` float64 s; valid: ``(T,)`` bool.
      confidence: optional ``(T,)`` float32 per-frame confidence (written to the block).
      meta: the motion's meta (no ``RESERVED_META`` key).
      options: ``check_options(...)``.
    """
    names, label, lead_in = options
    clash = sorted(set(meta) & set(RESERVED_META))
    if clash:
        raise ConfigError(f"meta keys {clash} are reserved in the JSON 'jaxproj' block")
    shifted = times - times[0] + lead_in
    if not (np.diff(shifted) > 0).all() or not shifted[0] > 0:
        raise ConfigError(
            "times are too close together to stay strictly increasing once shifted to start at "
            f"lead_in={lead_in} s"
        )
    time_list = shifted.tolist()
    return {
        "names": list(names),
        "angleLists": [angles[:, robot.index(n)].astype(np.float64).tolist() for n in names],
        "timeLists": [list(time_list) for _ in names],
        "isAbsolute": True,
        "jaxproj": {
            **meta,
            "t0": float(times[0]),
            "lead_in_s": lead_in,
            "joints": label,
            "invalid_frames": np.flatnonzero(~valid).tolist(),
            **({} if confidence is None else {"confidence": _exact(confidence)}),
        },
    }


def _exact(values: np.ndarray) -> list[float]:
    """float32 values as JSON numbers that read back to the same float32 bits."""
    return [float(v) for v in np.asarray(values, np.float32).tolist()]


def write(
    robot: Robot,
    angles: np.ndarray,
    times: np.ndarray,
    valid: np.ndarray,
    meta: Mapping[str, Any],
    options: tuple[tuple[str, ...], str | list[str], float],
    confidence: np.ndarray | None = None,
) -> str:
    """The document (``document``) as JSON text."""
    doc = document(robot, angles, times, valid, meta, options, confidence)
    return json.dumps(doc, allow_nan=False)


def _number_list(path: Path, what: str, value: object) -> np.ndarray:
    """A JSON list of numbers (or one number) -> float64 array; InputError otherwise."""
    items = value if isinstance(value, list) else [value]
    for x in items:
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise InputError(path, f"{what} must hold numbers, found {json.dumps(x)[:40]}")
    arr = np.array(items, dtype=np.float64)
    if not np.isfinite(arr).all():
        raise InputError(path, f"{what} must be finite")
    return arr


def read(
    robot: Robot, path: Path
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any], np.ndarray | None]:
    """Read a NAOqi JSON document.

    Returns:
      ``(angles (T, n_joints) float32, times (T,) float64, valid (T,) bool, meta, confidence
      (T,) float32 or None)``: joints the file does not name at the standing posture; times
      restored with ``t0`` / ``lead_in_s`` of the ``"jaxproj"`` block when present (else NAOqi's
      times as they are); frames valid except the block's ``invalid_frames``; the block's
      ``confidence`` when present.

    Raises:
      InputError: the file is unreadable or malformed (names the file and the problem).
      ConfigError: unknown or repeated joint names, times not strictly increasing (the caller,
        ``load_motion``, reports these as ``InputError`` naming the file).
    """
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except UnicodeDecodeError:
        raise InputError(path, "not a UTF-8 text file") from None
    except json.JSONDecodeError as e:
        raise InputError(path, f"not valid JSON: {e}") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}") from None
    if not isinstance(doc, dict):
        raise InputError(path, "expected a JSON object with keys " + ", ".join(_JSON_KEYS))
    missing = [k for k in _JSON_KEYS if k not in doc]
    if missing:
        raise InputError(path, f"missing keys {missing} (NAOqi angleInterpolation arguments)")
    names = doc["names"]
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise InputError(path, "names must be a non-empty list of joint names")
    if doc["isAbsolute"] is not True:
        raise InputError(path, "isAbsolute must be true (relative angles do not make a motion)")
    angle_lists, time_lists = doc["angleLists"], doc["timeLists"]
    if not isinstance(angle_lists, list) or len(angle_lists) != len(names):
        raise InputError(path, f"angleLists must be a list of {len(names)} lists, one per name")
    if not isinstance(time_lists, list) or not time_lists:
        raise InputError(path, "timeLists must be a list of time lists, one per name")
    shared = not isinstance(time_lists[0], list)  # NAOqi also takes one list for every joint
    if not shared and len(time_lists) != len(names):
        raise InputError(path, f"timeLists must hold {len(names)} lists, one per name")
    times = _number_list(path, "timeLists", time_lists if shared else time_lists[0])
    if len(times) < 1:
        raise InputError(path, "no frames (empty time lists)")
    columns = np.empty((len(times), len(names)), dtype=np.float32)
    for j, name in enumerate(names):
        angles_j = _number_list(path, f"angleLists[{j}] ({name})", angle_lists[j])
        if len(angles_j) != len(times):
            raise InputError(
                path,
                f"angleLists[{j}] ({name}) has {len(angles_j)} angles for {len(times)} times",
            )
        if not shared:
            times_j = _number_list(path, f"timeLists[{j}] ({name})", time_lists[j])
            if times_j.shape != times.shape or (times_j != times).any():
                raise InputError(
                    path,
                    f"timeLists[{j}] ({name}) differs from timeLists[0]: jaxproj motions "
                    "share one time base",
                )
        columns[:, j] = angles_j
    check_times(times, "timeLists")
    angles = robot.from_columns(names, columns)
    block = doc.get("jaxproj", {})
    if not isinstance(block, dict):
        raise InputError(path, "the 'jaxproj' block must be a JSON object")
    valid = np.ones(len(times), dtype=bool)
    if "t0" in block or "lead_in_s" in block:
        t0 = _number_list(path, "jaxproj.t0", block.get("t0", 0.0))
        lead = _number_list(path, "jaxproj.lead_in_s", block.get("lead_in_s", 0.0))
        if t0.shape != (1,) or lead.shape != (1,):
            raise InputError(path, "jaxproj.t0 and jaxproj.lead_in_s must be numbers")
        times = times - lead[0] + t0[0]
    invalid = block.get("invalid_frames", [])
    if not isinstance(invalid, list) or not all(
        isinstance(i, int) and not isinstance(i, bool) and 0 <= i < len(times) for i in invalid
    ):
        raise InputError(path, f"jaxproj.invalid_frames must list frame indices < {len(times)}")
    valid[invalid] = False
    conf = None
    if "confidence" in block:
        conf = _number_list(path, "jaxproj.confidence", block["confidence"]).astype(np.float32)
        if conf.shape != (len(times),):
            raise InputError(path, f"jaxproj.confidence must list {len(times)} numbers")
    meta = {k: v for k, v in block.items() if k not in RESERVED_META}
    try:
        meta = check_meta(meta)
    except ConfigError as e:
        raise InputError(path, f"jaxproj block: {e}") from None
    return angles, times, valid, meta, conf


EXPORT = Export(name="naoqi", suffix=".json", check=check_options, write=write, read=read)
"""The NAO's export hook (``NAO_H25.exports[".json"]``)."""
