"""Robot-motion files: a NAO joint trajectory (``Motion``) saved as NPZ, CSV or NAOqi JSON.

``save_motion(path, motion)`` picks the format from the extension; ``load_motion(path)`` reads any
of the three back:

- ``.npz`` (lossless, everything): ``angles`` ``(T, 26)`` float32 rad, ``times`` ``(T,)`` float64
  s, ``valid`` ``(T,)`` bool, ``joint_names`` ``(26,)`` str (``robot.JOINT_NAMES``),
  ``positions`` ``(T, 20, 3)`` float32 m (only when the motion has them) and ``meta`` (a 0-d str
  array holding a JSON object). ``load_motion`` also reads the ``.npz`` of ``jaxproj retarget``
  (no ``times``: frames are taken ``1 / DEFAULT_FPS`` s apart; its ``method`` / ``smoothed``
  become ``meta``).
- ``.csv``: a plain CSV, header ``time,<the 26 joint names in JOINT_NAMES order>``, one row per
  frame, times in s and angles in rad, written so that parsing each value with ``float`` gives
  the float32 angle bit-exactly and the float64 time exactly. There is no validity column:
  loading a CSV marks every frame valid (and it has no positions and no meta).
- ``.json``: exactly the arguments of NAOqi's
  ``ALMotion.angleInterpolation(names, angleLists, timeLists, isAbsolute)``:
  ``{"names": [...], "angleLists": [[...], ...], "timeLists": [[...], ...], "isAbsolute": true}``,
  one angle list and one time list per joint name, plus a ``"jaxproj"`` block (the motion's
  ``meta`` and ``t0``, ``lead_in_s``, ``joints``, ``invalid_frames``) that NAOqi never sees.
  Times are ``times - times[0] + lead_in``: NAOqi wants strictly increasing times > 0, and the
  lead-in (default 1 s) gives the robot time to move from wherever it stands to the first pose.
  By default only the ``"upper"`` joints are written (``UPPER_JOINTS``: NAOqi's Head, LArm and
  RArm chains), since a standing NAO's legs belong to its own balance / posture control;
  ``joints="body"`` writes all 26. Loading fills joints the file does not name with
  ``robot.STANDING_POSTURE`` and restores the original times from ``t0`` / ``lead_in_s``.

Every write is atomic (a temporary file in the same folder, then ``os.replace``): a failed write
never leaves a half-written file. Bad files raise ``InputError`` naming the file and the problem.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jaxproj._internal.atomic import atomic_write
from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import N_JOINTS as N_HUMAN_JOINTS
from jaxproj.robots.nao_h25 import robot

MetaValue = str | int | float | bool
"""A ``Motion.meta`` value: a JSON scalar."""

FORMATS: tuple[str, ...] = (".npz", ".csv", ".json")
"""File extensions ``save_motion`` / ``load_motion`` accept."""

UPPER_JOINTS: tuple[str, ...] = (
    "HeadYaw", "HeadPitch",
    "LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll", "LWristYaw", "LHand",
    "RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll", "RWristYaw", "RHand",
)  # fmt: skip
"""NAOqi's Head, LArm and RArm chains, in ``robot.JOINT_NAMES`` order (``joints="upper"``)."""

JOINT_SETS: dict[str, tuple[str, ...]] = {"upper": UPPER_JOINTS, "body": robot.JOINT_NAMES}
"""Named joint selections of ``save_motion(..., joints=)``."""

DEFAULT_FPS = 15.0
"""Frame rate assumed where a file has no times (``jaxproj retarget`` output; MSR Action3D rate)
and for a one-frame motion without ``meta["fps"]``."""

DEFAULT_LEAD_IN_S = 1.0
"""Seconds before the first pose in NAOqi JSON (the robot moves there from where it stands)."""

_JSON_KEYS = ("names", "angleLists", "timeLists", "isAbsolute")
_RESERVED_META = ("t0", "lead_in_s", "joints", "invalid_frames")


# --- the motion ------------------------------------------------------------------------------


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _check_meta(meta: object) -> dict[str, MetaValue]:
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


@dataclass(frozen=True, eq=False)
class Motion:
    """A NAO joint trajectory, with the human motion it came from (optional).

    The arrays are copied into read-only arrays of the stated dtypes when constructed
    (``eq=False``: motions compare by identity; compare the arrays themselves).

    Attributes:
      angles: ``(T, 26)`` float32 rad, ``robot.JOINT_NAMES`` order, all finite; ``T >= 1``.
      times: ``(T,)`` float64 s, finite and strictly increasing (may start at any ``t0``).
      valid: ``(T,)`` bool; ``False`` where the input frame was invalid and its angles were filled.
      positions: ``(T, 20, 3)`` float32 human joints, Kinect SDK order, m (for rendering; may hold
        non-finite values at invalid frames), or ``None``.
      meta: JSON scalars describing the motion, e.g. ``method``, ``smoothed``, ``feasible``,
        ``source``, ``fps``.

    Raises:
      ConfigError: a wrong shape or dtype, a non-finite angle, times not finite and strictly
        increasing, or a meta value that is not a finite JSON scalar.
    """

    angles: np.ndarray
    times: np.ndarray
    valid: np.ndarray
    positions: np.ndarray | None = None
    meta: Mapping[str, MetaValue] = field(default_factory=dict)

    def __post_init__(self) -> None:
        angles = np.asarray(self.angles)
        if angles.dtype.kind not in "fiu" or angles.ndim != 2 or angles.shape[1] != robot.N_JOINTS:
            raise ConfigError(
                f"angles must be a real (T, {robot.N_JOINTS}) array, got {angles.dtype} "
                f"{angles.shape}"
            )
        n = angles.shape[0]
        if n < 1:
            raise ConfigError("a motion needs at least one frame")
        angles = np.array(angles, dtype=np.float32)
        if not np.isfinite(angles).all():
            bad = int(np.flatnonzero(~np.isfinite(angles).all(axis=1))[0])
            raise ConfigError(f"angles must be finite (float32); frame {bad} is not")
        times = np.asarray(self.times)
        if times.dtype.kind not in "fiu" or times.shape != (n,):
            raise ConfigError(f"times must be a real ({n},) array, got {times.dtype} {times.shape}")
        times = np.array(times, dtype=np.float64)
        if not np.isfinite(times).all():
            raise ConfigError("times must be finite")
        steps = np.diff(times)
        if (steps <= 0).any():
            i = int(np.flatnonzero(steps <= 0)[0]) + 1
            raise ConfigError(
                f"times must increase strictly: frame {i} at {float(times[i])!r} s follows "
                f"{float(times[i - 1])!r} s"
            )
        valid = np.asarray(self.valid)
        if valid.dtype != np.bool_ or valid.shape != (n,):
            raise ConfigError(f"valid must be a bool ({n},) array, got {valid.dtype} {valid.shape}")
        positions = self.positions
        if positions is not None:
            positions = np.asarray(positions)
            want = (n, N_HUMAN_JOINTS, 3)
            if positions.dtype.kind not in "fiu" or positions.shape != want:
                raise ConfigError(
                    f"positions must be a real {want} array or None, got {positions.dtype} "
                    f"{positions.shape}"
                )
            positions = _frozen(np.array(positions, dtype=np.float32))
        object.__setattr__(self, "angles", _frozen(angles))
        object.__setattr__(self, "times", _frozen(times))
        object.__setattr__(self, "valid", _frozen(np.array(valid)))
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "meta", _check_meta(self.meta))

    @property
    def n_frames(self) -> int:
        """``T``, the number of frames."""
        return int(self.angles.shape[0])

    @property
    def fps(self) -> float:
        """Frame rate, Hz: ``1 / median(diff(times))``; for one frame ``meta["fps"]`` if it is a
        positive number, else ``DEFAULT_FPS``."""
        if self.n_frames >= 2:
            return float(1.0 / np.median(np.diff(self.times)))
        fps = self.meta.get("fps")
        if isinstance(fps, (int, float)) and not isinstance(fps, bool) and fps > 0:
            return float(fps)
        return DEFAULT_FPS


def resolve_joints(joints: str | Sequence[str]) -> tuple[str, ...]:
    """``"upper"`` / ``"body"`` (see ``JOINT_SETS``) or a sequence of joint names -> names.

    Raises:
      ConfigError: an unknown set or joint name, a repeated name, or no name at all.
    """
    if isinstance(joints, str):
        if joints not in JOINT_SETS:
            raise ConfigError(
                f"joints must be one of {sorted(JOINT_SETS)} or a sequence of joint names, "
                f"got {joints!r}"
            )
        return JOINT_SETS[joints]
    names = tuple(joints)
    unknown = [n for n in names if n not in robot.IDX]
    if unknown:
        raise ConfigError(f"unknown joint names {unknown}; valid names: {robot.JOINT_NAMES}")
    if not names or len(set(names)) != len(names):
        raise ConfigError(f"joints must name each joint once and at least one, got {names}")
    return names


def _check_format(path: Path) -> str:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise ConfigError(
            f"{path}: unsupported motion file extension {path.suffix!r}; use one of "
            f"{', '.join(FORMATS)}"
        )
    return ext


# --- writing ---------------------------------------------------------------------------------


def save_motion(
    path: str | os.PathLike[str],
    motion: Motion,
    *,
    joints: str | Sequence[str] = "upper",
    lead_in: float = DEFAULT_LEAD_IN_S,
) -> Path:
    """Write ``motion`` to ``path``; the format follows the extension (module docstring).

    Args:
      path: ``.npz``, ``.csv`` or ``.json``; the folder is created if missing.
      motion: the motion.
      joints: JSON only: which joints to write, ``"upper"`` (default, ``UPPER_JOINTS``),
        ``"body"`` (all 26) or a sequence of names (written in that order). NPZ and CSV always
        hold all 26.
      lead_in: JSON only: seconds before the first pose (> 0); NAOqi times are
        ``times - times[0] + lead_in``.

    Returns:
      ``path`` as a ``Path``.

    Raises:
      ConfigError: an unsupported extension, bad ``joints`` / ``lead_in``, a meta key the JSON
        block reserves (``t0``, ``lead_in_s``, ``joints``, ``invalid_frames``).
      InputError: the file cannot be written (nothing is left behind).
    """
    path = Path(path)
    ext = _check_format(path)
    if not isinstance(motion, Motion):
        raise ConfigError(f"motion must be a jaxproj.io.motion_files.Motion, got {type(motion).__name__}")
    names = resolve_joints(joints)
    lead = float(lead_in)
    if not (math.isfinite(lead) and lead > 0):
        raise ConfigError(f"lead_in must be a finite number of seconds > 0, got {lead_in!r}")
    if ext == ".npz":
        return atomic_write(path, lambda tmp: _write_npz(tmp, motion))
    if ext == ".csv":
        return atomic_write(path, lambda tmp: _write_csv(tmp, motion))
    clash = sorted(set(motion.meta) & set(_RESERVED_META))
    if clash:
        raise ConfigError(f"meta keys {clash} are reserved in the JSON 'jaxproj' block")
    label: str | list[str] = joints if isinstance(joints, str) else list(names)
    doc = _naoqi_document(motion, names, label, lead)
    return atomic_write(path, lambda tmp: _write_text(tmp, json.dumps(doc, allow_nan=False)))


def _write_text(tmp: Path, text: str) -> None:
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)
        if not text.endswith("\n"):
            fh.write("\n")


def _write_npz(tmp: Path, motion: Motion) -> None:
    arrays: dict[str, np.ndarray] = {
        "angles": motion.angles,
        "times": motion.times,
        "valid": motion.valid,
        "joint_names": np.array(robot.JOINT_NAMES),
        "meta": np.array(json.dumps(dict(motion.meta), allow_nan=False)),
    }
    if motion.positions is not None:
        arrays["positions"] = motion.positions
    with open(tmp, "wb") as fh:  # a file object: np.savez would append ".npz" to a name
        np.savez(fh, **arrays)


def exact_strings(values: np.ndarray) -> list[str]:
    """Shortest decimal strings of float32 ``values`` that ``float()`` reads back bit-exactly.

    Args:
      values: any-shape float32 array (finite).

    Returns:
      ``values.size`` strings, C order: the shortest float32 representation (``"1.4"``) where
      parsing it as a Python float and rounding to float32 gives the same bits, else the exact
      float64 ``repr`` of the value (always exact).
    """
    flat = np.ascontiguousarray(values, dtype=np.float32).ravel()
    out = [str(v) for v in flat]
    back = np.array([float(s) for s in out], dtype=np.float64).astype(np.float32)
    for i in np.flatnonzero(back.view(np.uint32) != flat.view(np.uint32)):
        out[i] = repr(float(flat[i]))
    return out


def _write_csv(tmp: Path, motion: Motion) -> None:
    cells = exact_strings(motion.angles)
    n = robot.N_JOINTS
    lines = [",".join(("time", *robot.JOINT_NAMES))]
    for t, time in enumerate(motion.times.tolist()):
        lines.append(",".join((repr(time), *cells[t * n : (t + 1) * n])))
    _write_text(tmp, "\n".join(lines) + "\n")


def _naoqi_document(
    motion: Motion, names: tuple[str, ...], label: str | list[str], lead_in: float
) -> dict[str, Any]:
    """The NAOqi ``angleInterpolation`` arguments plus the ``jaxproj`` block."""
    times = motion.times - motion.times[0] + lead_in
    if not (np.diff(times) > 0).all() or not times[0] > 0:
        raise ConfigError(
            "times are too close together to stay strictly increasing once shifted to start at "
            f"lead_in={lead_in} s"
        )
    time_list = times.tolist()
    return {
        "names": list(names),
        "angleLists": [motion.angles[:, robot.IDX[n]].astype(np.float64).tolist() for n in names],
        "timeLists": [list(time_list) for _ in names],
        "isAbsolute": True,
        "jaxproj": {
            **motion.meta,
            "t0": float(motion.times[0]),
            "lead_in_s": lead_in,
            "joints": label,
            "invalid_frames": np.flatnonzero(~motion.valid).tolist(),
        },
    }


# --- reading ---------------------------------------------------------------------------------


def load_motion(path: str | os.PathLike[str]) -> Motion:
    """Read a motion written by ``save_motion`` (or by ``jaxproj retarget``, ``.npz``).

    Args:
      path: ``.npz``, ``.csv`` or ``.json`` (the format follows the extension).

    Returns:
      The ``Motion``. CSV: every frame valid, no positions, no meta. JSON: joints the file does
      not name take ``robot.STANDING_POSTURE``; times restored with ``t0`` / ``lead_in_s`` of the
      ``"jaxproj"`` block when present (else NAOqi's times as they are); frames valid except the
      block's ``invalid_frames``.

    Raises:
      ConfigError: an unsupported extension.
      InputError: the file is missing or malformed (missing keys, wrong shapes, unknown or
        repeated joint names, non-numeric or non-finite values, ragged lists, times not strictly
        increasing); the message names the file and the problem.
    """
    path = Path(path)
    ext = _check_format(path)
    if not path.is_file():
        raise InputError(path, "no such file" if not path.exists() else "not a file")
    reader = {".npz": _read_npz, ".csv": _read_csv, ".json": _read_json}[ext]
    try:
        return reader(path)
    except ConfigError as e:  # a Motion check the readers did not pre-empt: still the file's fault
        raise InputError(path, str(e)) from None


def _full_angles(path: Path, names: Sequence[str], columns: np.ndarray) -> np.ndarray:
    """``(T, 26)`` float32: ``columns`` ``(T, len(names))`` placed by name, others standing."""
    unknown = [str(n) for n in names if n not in robot.IDX]
    if unknown:
        raise InputError(path, f"unknown joint names {unknown}")
    if len(set(names)) != len(names):
        dup = sorted({str(n) for n in names if list(names).count(n) > 1})
        raise InputError(path, f"joint names repeated: {dup}")
    out = np.tile(robot.STANDING_POSTURE, (columns.shape[0], 1))
    out[:, [robot.IDX[n] for n in names]] = columns
    return out


def _check_times(path: Path, times: np.ndarray, what: str = "times") -> None:
    if not np.isfinite(times).all():
        raise InputError(path, f"{what} must be finite")
    steps = np.diff(times)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise InputError(
            path,
            f"{what} must increase strictly: frame {i} at {float(times[i])!r} follows "
            f"{float(times[i - 1])!r}",
        )


def _check_finite_angles(path: Path, angles: np.ndarray) -> None:
    ok = np.isfinite(angles)
    if not ok.all():
        raise InputError(path, "angles must be finite", frame=int(np.flatnonzero(~ok.all(1))[0]))


def _read_npz(path: Path) -> Motion:
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(path, f"not a readable .npz archive: {e}") from None
    for key in ("angles", "joint_names"):
        if key not in data:
            raise InputError(path, f"missing key {key!r} (keys: {sorted(data)})")
    names = data["joint_names"]
    if names.dtype.kind != "U" or names.ndim != 1:
        raise InputError(
            path, f"joint_names must be a 1-d str array, got {names.dtype} {names.shape}"
        )
    raw = data["angles"]
    if raw.dtype.kind not in "fiu" or raw.ndim != 2 or raw.shape[1] != names.shape[0]:
        raise InputError(
            path,
            f"angles must be a real (T, {names.shape[0]}) array (one column per joint name), "
            f"got {raw.dtype} {raw.shape}",
        )
    n = raw.shape[0]
    if n < 1:
        raise InputError(path, "no frames")
    columns = raw.astype(np.float32)
    _check_finite_angles(path, columns)
    angles = _full_angles(path, [str(s) for s in names], columns)
    if "times" in data:
        times = data["times"]
        if times.dtype.kind not in "fiu" or times.shape != (n,):
            raise InputError(
                path, f"times must be a real ({n},) array, got {times.dtype} {times.shape}"
            )
        times = times.astype(np.float64)
        _check_times(path, times)
    else:
        times = np.arange(n, dtype=np.float64) / DEFAULT_FPS
    valid = data.get("valid", np.ones(n, dtype=bool))
    if valid.dtype != np.bool_ or valid.shape != (n,):
        raise InputError(
            path, f"valid must be a bool ({n},) array, got {valid.dtype} {valid.shape}"
        )
    positions = data.get("positions")
    if positions is not None and (
        positions.dtype.kind not in "fiu" or positions.shape != (n, N_HUMAN_JOINTS, 3)
    ):
        raise InputError(
            path,
            f"positions must be a real ({n}, {N_HUMAN_JOINTS}, 3) array, got {positions.dtype} "
            f"{positions.shape}",
        )
    meta: dict[str, Any] = {}
    if "meta" in data:
        text = data["meta"]
        if text.dtype.kind != "U" or text.ndim != 0:
            raise InputError(
                path, f"meta must be a 0-d str array (JSON), got {text.dtype} {text.shape}"
            )
        try:
            meta = json.loads(str(text))
        except json.JSONDecodeError as e:
            raise InputError(path, f"meta is not valid JSON: {e}") from None
        if not isinstance(meta, dict):
            raise InputError(path, "meta must hold a JSON object")
    else:  # `jaxproj retarget` output
        for key in ("method", "smoothed"):
            if key in data and data[key].ndim == 0:
                meta[key] = data[key].item()
    try:
        meta = _check_meta(meta)
    except ConfigError as e:
        raise InputError(path, str(e)) from None
    return Motion(angles=angles, times=times, valid=valid, positions=positions, meta=meta)


def _read_csv(path: Path) -> Motion:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(path, "not a UTF-8 text file") from None
    except OSError as e:
        raise InputError(path, f"cannot read: {e.strerror or e}") from None
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise InputError(path, "empty file (expected a header 'time,<joint names>')")
    header = [c.strip() for c in lines[0].split(",")]
    if header[0] != "time" or len(header) < 2:
        raise InputError(
            path, f"line 1: the header must be 'time,<joint names>', got {lines[0][:60]!r}"
        )
    names = header[1:]
    if len(lines) < 2:
        raise InputError(path, "no frames (only a header)")
    width = len(header)
    values = np.empty((len(lines) - 1, width), dtype=np.float64)
    for i, line in enumerate(lines[1:]):
        cells = line.split(",")
        if len(cells) != width:
            raise InputError(path, f"line {i + 2}: expected {width} columns, got {len(cells)}")
        try:
            values[i] = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_float(c))
            raise InputError(path, f"line {i + 2}: not a number: {bad.strip()[:40]!r}") from None
    times = values[:, 0]
    _check_times(path, times)
    columns = values[:, 1:].astype(np.float32)
    _check_finite_angles(path, columns)
    angles = _full_angles(path, names, columns)
    return Motion(angles=angles, times=times, valid=np.ones(len(times), dtype=bool))


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


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


def _read_json(path: Path) -> Motion:
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
    _check_times(path, times, "timeLists")
    angles = _full_angles(path, names, columns)
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
    meta = {k: v for k, v in block.items() if k not in _RESERVED_META}
    try:
        meta = _check_meta(meta)
    except ConfigError as e:
        raise InputError(path, f"jaxproj block: {e}") from None
    return Motion(angles=angles, times=times, valid=valid, meta=meta)
