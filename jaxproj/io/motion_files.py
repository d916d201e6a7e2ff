"""Robot-motion files: a robot joint trajectory (``Motion``) saved as NPZ, CSV or the robot's own
document (``Robot.exports``; the default robot's is a JSON document, written by a module of its
package under ``jaxproj.robots``).

``save_motion(path, motion)`` picks the format from the extension; ``load_motion(path)`` reads any
of them back. The robot: ``motion.robot`` when writing; when reading, ``load_motion(path,
robot=...)`` (a ``Robot`` or a registered name) or, by default (``None``), the registered robot
whose joints the file names (``jaxproj.robots.for_joints``: the NPZ's ``joint_names``, the CSV's
header; the default robot when it has them all), and for a robot's own document the robot that
exports that suffix (the default robot first):

- ``.npz`` (lossless, everything): ``angles`` ``(T, n_joints)`` float32 rad, ``times`` ``(T,)``
  float64 s, ``valid`` ``(T,)`` bool, ``joint_names`` ``(n_joints,)`` str (``robot.joint_names``),
  ``positions`` ``(T, 20, 3)`` float32 m and ``confidence`` ``(T,)`` float32 (each only when
  the motion has it) and ``meta`` (a 0-d str array holding a JSON object). ``load_motion``
  also reads the ``.npz`` of ``jaxproj retarget`` (no ``times``: frames are taken
  ``1 / DEFAULT_FPS`` s apart; its ``method`` / ``smoothed`` become ``meta``).
- ``.csv`` (for the robot's tools): header ``time,<the robot's joint names in its SDK order>``
  (``robot.joint_names``: one column per joint of the robot), one row per frame,
  times in s and angles in rad, written so that parsing each value with ``float`` gives the
  float32 angle bit-exactly and the float64 time exactly. Nothing else: no validity and no
  confidence column (they are the NPZ's; write both files, or ``save_motion`` the ``.csv`` from
  ``load_motion`` of the ``.npz``). Loading a CSV marks every frame valid (and it has no
  positions and no meta); a last ``confidence`` column, as jaxproj 0.2.0 wrote, is still
  read. ``jaxproj retarget`` writes its motions at a uniform rate (``--rate``), so its CSV
  rows are evenly spaced in time.
- **whole-body motions** (``Motion.root_pos`` / ``root_rot``: ``jaxproj.motion.whole_body``,
  ``jaxproj retarget --root world``): the NPZ adds ``root_pos`` ``(T, 3)`` float32 m,
  ``root_rot`` ``(T, 4)`` float32 quaternions ``(x, y, z, w)``, ``dof_pos`` (the angles again,
  under the name GMR's files use), ``fps`` (0-d float64) and ``contacts`` ``(T, 2)`` bool (left,
  right foot); the CSV is the LAFAN1 retargeting layout that motion-tracking trainers'
  ``csv_to_npz.py`` scripts read (``motion[:, 3:7][:, [3, 0, 1, 2]]``: scalar last; sources in
  the guide, "Whole-body motion"): no header, one row
  per frame of root x, y, z, quaternion x, y, z, w, then every joint in the robot's SDK order,
  frames evenly spaced (written only so) and no time column: ``load_motion(path, fps=...)``
  (default ``ROOT_CSV_FPS``, the LAFAN1 files' 30) gives frame ``k`` the time ``k / fps``, and
  the robot is the registered one with ``n_joints + 7`` columns unless ``robot=`` names it.
- the robot's exports (the default robot's: ``.json``, the arguments of its software's
  ``angleInterpolation``; ``joints`` and ``lead_in`` of ``save_motion`` are its options): see
  the export's module in the robot's package (``jaxproj.robots``).

The CSV and the robot's exports are files for the robot: ``save_motion`` writes their angles
``EXPORT_MARGIN`` (2e-4 rad, 0.011 deg) inside each joint's range, ``[lower + margin, upper -
margin]`` (``export_angles``; and, for a robot with coupled ranges such as the default robot's
head envelope, inside those), so that a validator that checks a robot's URDF limits strictly never
rejects a frame clamped at a limit. Why 2e-4: ``Robot.lower`` / ``upper`` are the documentation's
4-decimal values; the default robot's URDF (qibullet 1.4.6's, the one its maker generated)
differs from them by up to 5.2e-5 rad on the head and arms (HeadPitch's -0.671952 against
-0.6720) and 1.7e-4 rad on the legs, except RKneePitch, whose URDF range copies the left knee's
(0.011 rad narrower; the legs of a retargeted motion stay at the standing posture, far from
their limits). ``margin=None`` writes the angles as they are. Clipping to a fixed range never
lengthens a step between two frames, so it moves no joint faster; a follower brought back into
its coupled range after its leader was clipped moves by at most the range's slope times that
clip (the default robot's head: <= 5e-5 rad, where HeadYaw meets its limit). The NPZ stays lossless.

Every write is atomic (a temporary file in the same folder, then ``os.replace``): a failed write
never leaves a half-written file. No folder is created: writing into a folder that does not
exist is a ``ConfigError`` naming it (the CLI's rule for its outputs). Bad files raise
``InputError`` naming the file and the problem.

Size: over 500 lines: one writer and one reader per format (NPZ, CSV, a robot's export) with the
checks and the export margin they share; split by format when a fourth format comes.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from jaxproj._internal.atomic import atomic_write, check_output, write_npz
from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import N_JOINTS as N_HUMAN_JOINTS
from jaxproj.robots import Robot, clip_coupled
from jaxproj.robots import for_joints as robot_for_joints
from jaxproj.robots import get as get_robot
from jaxproj.robots import names as robot_names
from jaxproj.robots.export import MetaValue, check_meta, check_times

__all__ = ["DEFAULT_FPS", "EXPORT_MARGIN", "FORMATS", "MetaValue", "Motion", "exact_strings",
           "export_angles", "formats", "load_motion", "save_motion"]  # fmt: skip

FORMATS: tuple[str, ...] = (".npz", ".csv")
"""File extensions ``save_motion`` / ``load_motion`` accept for every robot; a robot's exports
add theirs (``formats``: ``.npz``, ``.csv``, ``.json`` for the default robot)."""

EXPORT_MARGIN = 2e-4
"""rad: how far inside each joint's ``[lower, upper]`` the CSV and the robot's exports hold
every angle (module doc: covers the default robot's URDF limits, <= 1.7e-4 off ours)."""

DEFAULT_FPS = 15.0
"""Frame rate assumed where a file has no times (``jaxproj retarget`` output; MSR Action3D rate)
and for a one-frame motion without ``meta["fps"]``."""


# --- the motion ------------------------------------------------------------------------------


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Motion:
    """A robot joint trajectory, with the human motion it came from (optional).

    The arrays are copied into read-only arrays of the stated dtypes when constructed
    (``eq=False``: motions compare by identity; compare the arrays themselves).

    Attributes:
      angles: ``(T, n_joints)`` float32 rad, ``robot.joint_names`` order, all finite; ``T >= 1``.
      times: ``(T,)`` float64 s, finite and strictly increasing (may start at any ``t0``).
      valid: ``(T,)`` bool; ``False`` where the input frame was invalid and its angles were filled.
      positions: ``(T, 20, 3)`` float32 human joints, Kinect SDK order, m (for rendering; may hold
        non-finite values at invalid frames), or ``None``.
      meta: JSON scalars describing the motion, e.g. ``method``, ``smoothed``, ``feasible``,
        ``source``, ``fps``.
      robot: the robot the angles are for (a ``Robot`` or a registered name; ``None``, the
        default: the default robot, ``jaxproj.robots.get()``); a ``Robot`` once constructed.
      confidence: ``(T,)`` float32 in ``[0, 1]``, each frame's confidence
        (``jaxproj.projection.confidence``; ``RetargetResult.confidence``), or ``None``.
      root_pos: ``(T, 3)`` float32 m, the root body's origin in the world (z up, the floor at
        0; ``jaxproj.motion.whole_body``), or ``None``: a fixed base (joint angles only).
      root_rot: ``(T, 4)`` float32 unit quaternions ``(x, y, z, w)``, the root body's
        orientation; given with ``root_pos`` and only with it.
      contacts: ``(T, 2)`` bool, the person's left and right foot on the floor, or ``None``.

    Raises:
      ConfigError: a wrong shape or dtype, a non-finite angle, times not finite and strictly
        increasing, a confidence outside ``[0, 1]``, or a meta value that is not a finite JSON
        scalar.
    """

    angles: np.ndarray
    times: np.ndarray
    valid: np.ndarray
    positions: np.ndarray | None = None
    meta: Mapping[str, MetaValue] = field(default_factory=dict)
    robot: Robot = field(default_factory=get_robot)
    confidence: np.ndarray | None = None
    root_pos: np.ndarray | None = None
    root_rot: np.ndarray | None = None
    contacts: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.robot is None or isinstance(self.robot, str):
            object.__setattr__(self, "robot", get_robot(self.robot))
        if not isinstance(self.robot, Robot):
            kind = type(self.robot).__name__
            raise ConfigError(f"robot must be a jaxproj.robots.Robot, got {kind}")
        n_joints = self.robot.n_joints
        angles = np.asarray(self.angles)
        if angles.dtype.kind not in "fiu" or angles.ndim != 2 or angles.shape[1] != n_joints:
            raise ConfigError(
                f"angles must be a real (T, {n_joints}) array, got {angles.dtype} {angles.shape}"
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
        conf = self.confidence
        if conf is not None:
            conf = np.asarray(conf)
            if conf.dtype.kind not in "fiu" or conf.shape != (n,):
                raise ConfigError(
                    f"confidence must be a real ({n},) array or None, got {conf.dtype} {conf.shape}"
                )
            conf = np.array(conf, dtype=np.float32)
            if not (np.isfinite(conf) & (conf >= 0) & (conf <= 1)).all():
                bad = int(np.flatnonzero(~(np.isfinite(conf) & (conf >= 0) & (conf <= 1)))[0])
                raise ConfigError(f"confidence must lie in [0, 1]; frame {bad} does not")
            conf = _frozen(conf)
        object.__setattr__(self, "confidence", conf)
        self._check_root(n)
        object.__setattr__(self, "angles", _frozen(angles))
        object.__setattr__(self, "times", _frozen(times))
        object.__setattr__(self, "valid", _frozen(np.array(valid)))
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "meta", check_meta(self.meta))

    def _check_root(self, n: int) -> None:
        pos, rot, contacts = self.root_pos, self.root_rot, self.contacts
        if (pos is None) != (rot is None):
            raise ConfigError("root_pos and root_rot come together (a floating base) or not at all")
        if pos is not None:
            pos, rot = np.asarray(pos), np.asarray(rot)
            for name, a, w in (("root_pos", pos, 3), ("root_rot", rot, 4)):
                if a.dtype.kind not in "fiu" or a.shape != (n, w):
                    raise ConfigError(f"{name} must be a real ({n}, {w}) array, got {a.dtype} "
                                      f"{a.shape}")  # fmt: skip
                if not np.isfinite(a).all():
                    bad = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
                    raise ConfigError(f"{name} must be finite; frame {bad} is not")
            pos, rot = np.array(pos, np.float32), np.array(rot, np.float32)
            norm = np.linalg.norm(rot.astype(np.float64), axis=1)
            if (np.abs(norm - 1) > 1e-3).any():
                bad = int(np.flatnonzero(np.abs(norm - 1) > 1e-3)[0])
                raise ConfigError(f"root_rot must hold unit quaternions (x, y, z, w); frame {bad} "
                                  f"has norm {norm[bad]:.4f}")  # fmt: skip
            object.__setattr__(self, "root_pos", _frozen(pos))
            object.__setattr__(self, "root_rot", _frozen(rot))
        if contacts is not None:
            contacts = np.asarray(contacts)
            if contacts.dtype != np.bool_ or contacts.shape != (n, 2):
                raise ConfigError(f"contacts must be a bool ({n}, 2) array, got {contacts.dtype} "
                                  f"{contacts.shape}")  # fmt: skip
            object.__setattr__(self, "contacts", _frozen(np.array(contacts)))

    @property
    def whole_body(self) -> bool:
        """Whether the motion has a root trajectory (``root_pos`` / ``root_rot``)."""
        return self.root_pos is not None

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


def formats(robot: Robot | str | None = None) -> tuple[str, ...]:
    """File extensions of ``robot``'s motions (``None``: the default robot's): ``FORMATS`` and
    its exports' (the default robot's: ``.json``)."""
    return (*FORMATS, *get_robot(robot).exports)


def _check_format(path: Path, robot: Robot | None) -> str:
    """The extension of ``path``, checked against ``robot``'s formats (``None``: any registered
    robot's)."""
    ext = path.suffix.lower()
    known = formats(robot) if robot is not None else _all_formats()
    if ext not in known:
        raise ConfigError(
            f"{path}: unsupported motion file extension {path.suffix!r}; use one of "
            f"{', '.join(known)}"
        )
    return ext


def _all_formats() -> tuple[str, ...]:
    exports = (s for name in robot_names() for s in get_robot(name).exports)
    return tuple(dict.fromkeys((*formats(), *exports)))


def _robot_of_export(ext: str) -> Robot:
    """The robot whose own document has the suffix ``ext`` (the default robot first)."""
    default = get_robot()
    if ext in default.exports:
        return default
    return next(r for r in map(get_robot, robot_names()) if ext in r.exports)


def _robot_of_names(path: Path, robot: Robot | None, names: Sequence[str]) -> Robot:
    """``robot``, or the registered robot whose joints ``names`` are (``InputError`` if none)."""
    if robot is not None:
        return robot
    try:
        return robot_for_joints(names)
    except ConfigError as e:
        raise InputError(path, str(e)) from None


# --- writing ---------------------------------------------------------------------------------


def save_motion(
    path: str | os.PathLike[str],
    motion: Motion,
    *,
    joints: str | Sequence[str] = "upper",
    lead_in: float | None = None,
    margin: float | None = EXPORT_MARGIN,
    overwrite: bool = True,
) -> Path:
    """Write ``motion`` to ``path``; the format follows the extension (module docstring).

    Args:
      path: ``.npz``, ``.csv`` or one of ``motion.robot.exports`` (the default robot's: ``.json``);
        its folder must exist (no folder is created, as for ``jaxproj retarget --out``).
      motion: the motion.
      joints: options of the robot's export (checked whatever the format). The default robot's
        JSON: which joints to write, ``"upper"`` (default, the export's upper-body joints),
        ``"body"`` (all) or a sequence of names (written in that order). NPZ and CSV always hold
        every joint.
      lead_in: the default robot's JSON: seconds before the first pose (> 0; ``None``: the
        export's default, 1 s); its times are ``times - times[0] + lead_in``.
      margin: CSV and the robot's exports: rad inside each joint's range the angles are
        written at (``export_angles``; default ``EXPORT_MARGIN``); ``None``: as they are. The
        NPZ always holds the motion's own angles.
      overwrite: replace an existing ``path`` (default, as numpy's savers); ``False``: refuse
        it (``jaxproj retarget`` passes ``--force``, off by default).

    Returns:
      ``path`` as a ``Path``.

    Raises:
      ConfigError: an unsupported extension, bad ``joints`` / ``lead_in`` / ``margin``, a meta
        key the JSON block reserves (``t0``, ``lead_in_s``, ``joints``, ``invalid_frames``), a
        folder of ``path`` that does not exist (nothing is created), an existing ``path`` with
        ``overwrite=False`` ("exists; pass overwrite=True ...").
      InputError: the file cannot be written (nothing is left behind).
    """
    path = Path(path)
    robot = motion.robot if isinstance(motion, Motion) else get_robot()
    ext = _check_format(path, robot)
    if not isinstance(motion, Motion):
        kind = type(motion).__name__
        raise ConfigError(f"motion must be a jaxproj.io.motion_files.Motion, got {kind}")
    options = {s: e.check(robot, joints, lead_in) for s, e in robot.exports.items()}
    _check_margin(robot, margin)
    check_output(path, overwrite=overwrite)
    if ext == ".npz":
        return write_npz(path, _npz_arrays(motion), overwrite=overwrite)
    angles = motion.angles if margin is None else export_angles(robot, motion.angles, margin)
    if ext == ".csv" and motion.whole_body:
        _check_regular(path, motion.times)
        return atomic_write(path, lambda tmp: _write_root_csv(tmp, motion, angles),
                            overwrite=overwrite)  # fmt: skip
    if ext == ".csv":
        return atomic_write(path, lambda tmp: _write_csv(tmp, motion, angles), overwrite=overwrite)
    text = robot.exports[ext].write(
        robot, angles, motion.times, motion.valid, motion.meta, options[ext],
        confidence=motion.confidence,
    )  # fmt: skip
    return atomic_write(path, lambda tmp: _write_text(tmp, text), overwrite=overwrite)


def _check_margin(robot: Robot, margin: float | None) -> None:
    if margin is None:
        return
    ok = isinstance(margin, (int, float)) and not isinstance(margin, bool) and margin >= 0
    if not ok or not (robot.lower + 2 * float(margin) <= robot.upper).all():
        raise ConfigError(
            f"margin must be None or a number of rad >= 0 that leaves every joint a range, got "
            f"{margin!r}"
        )


def export_angles(robot: Robot, angles: np.ndarray, margin: float = EXPORT_MARGIN) -> np.ndarray:
    """The angles a robot file holds: ``(T, n_joints)`` clipped to ``[lower + margin, upper -
    margin]`` (float32 bounds rounded inwards, so that each written value is at least ``margin``
    inside in exact arithmetic too), then each follower of ``robot.coupled_limits`` into its
    range at its leader's angle, and clipped to the margin once more: where a coupled range
    overlaps the follower's margin band (the default robot's head envelope does at every
    HeadYaw) the result lies in both.

    Returns:
      ``(T, n_joints)`` float32 (a new array).
    """
    m = float(margin)
    lo64 = robot.lower.astype(np.float64) + m
    hi64 = robot.upper.astype(np.float64) - m
    lo, hi = lo64.astype(np.float32), hi64.astype(np.float32)
    lo = np.where(lo < lo64, np.nextafter(lo, np.float32(np.inf)), lo)
    hi = np.where(hi > hi64, np.nextafter(hi, np.float32(-np.inf)), hi)
    q = np.clip(np.asarray(angles, np.float32), lo, hi)
    if robot.coupled_limits:
        q = np.clip(np.asarray(clip_coupled(robot, q)), lo, hi)
    return q.astype(np.float32)


def _write_text(tmp: Path, text: str) -> None:
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(text)
        if not text.endswith("\n"):
            fh.write("\n")


def _npz_arrays(motion: Motion) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {
        "angles": motion.angles,
        "times": motion.times,
        "valid": motion.valid,
        "joint_names": np.array(motion.robot.joint_names),
        "meta": np.array(json.dumps(dict(motion.meta), allow_nan=False)),
    }
    if motion.positions is not None:
        arrays["positions"] = motion.positions
    if motion.confidence is not None:
        arrays["confidence"] = motion.confidence
    if motion.root_pos is not None and motion.root_rot is not None:
        arrays |= {"root_pos": motion.root_pos, "root_rot": motion.root_rot,
                   "dof_pos": motion.angles, "fps": np.array(motion.fps)}  # fmt: skip
    if motion.contacts is not None:
        arrays["contacts"] = motion.contacts
    return arrays


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


def _write_csv(tmp: Path, motion: Motion, angles: np.ndarray) -> None:
    cells = exact_strings(angles)
    n = motion.robot.n_joints
    lines = [",".join(("time", *motion.robot.joint_names))]
    for t, time in enumerate(motion.times.tolist()):
        lines.append(",".join((repr(time), *cells[t * n : (t + 1) * n])))
    _write_text(tmp, "\n".join(lines) + "\n")


ROOT_CSV_FPS = 30.0
"""Frame rate a whole-body CSV is read at when ``load_motion`` is given none: the LAFAN1
retargeting files' (30 fps)."""


def _check_regular(path: Path, times: np.ndarray) -> None:
    """A whole-body CSV has no time column: its frames must be evenly spaced."""
    steps = np.diff(times)
    if len(steps) and not np.allclose(steps, np.median(steps), rtol=1e-4, atol=0.0):
        raise ConfigError(
            f"{path}: a whole-body CSV holds no times, so its frames must be evenly spaced "
            "(jaxproj retarget: leave --rate at auto or give a rate)"
        )


def _write_root_csv(tmp: Path, motion: Motion, angles: np.ndarray) -> None:
    """The LAFAN1 retargeting layout: no header, one row per frame: root x, y, z (m), root
    quaternion x, y, z, w, then the joints in the robot's SDK order (rad)."""
    assert motion.root_pos is not None and motion.root_rot is not None
    table = np.concatenate([motion.root_pos, motion.root_rot, angles], axis=1).astype(np.float32)
    cells = exact_strings(table)
    w = table.shape[1]
    lines = [",".join(cells[t * w : (t + 1) * w]) for t in range(len(table))]
    _write_text(tmp, "\n".join(lines) + "\n")


# --- reading ---------------------------------------------------------------------------------


def load_motion(
    path: str | os.PathLike[str], robot: Robot | str | None = None, fps: float | None = None
) -> Motion:
    """Read a motion written by ``save_motion`` (or by ``jaxproj retarget``, ``.npz``).

    Args:
      path: ``.npz``, ``.csv`` or one of ``robot.exports`` (the default robot's: ``.json``); the
        format follows the extension.
      robot: the robot the motion is for: a ``Robot`` or a registered name; ``None`` (the
        default): the registered robot whose joints the file names (``jaxproj.robots.for_joints``:
        the default robot when it has them all), for a robot's own document the robot that
        exports its suffix. A whole-body CSV (no header) names no joints: the registered
        robot with ``n_joints + 7`` columns, when exactly one has.
      fps: a whole-body CSV's frame rate (it holds no times; ``None``: ``ROOT_CSV_FPS``, the
        LAFAN1 files' 30); its frames are then ``k / fps`` s. Refused for other files.

    Returns:
      The ``Motion``. Joints the file does not name take ``robot.standing``. CSV: every frame
      valid, no positions, no meta. An export: see its module.

    Raises:
      ConfigError: an unsupported extension.
      InputError: the file is missing or malformed (missing keys, wrong shapes, unknown or
        repeated joint names, joint names of no registered robot, non-numeric or non-finite
        values, ragged lists, times not strictly increasing); the message names the file and the
        problem.
    """
    path = Path(path)
    given = None if robot is None else get_robot(robot)
    ext = _check_format(path, given)
    if fps is not None and (ext != ".csv" or not (isinstance(fps, (int, float)) and fps > 0)):
        raise ConfigError(f"fps= is a whole-body CSV's frame rate (a number > 0), got {fps!r} "
                          f"for {path.name}")  # fmt: skip
    if not path.is_file():
        raise InputError(path, "no such file" if not path.exists() else "not a file")
    try:
        if ext == ".npz":
            return _read_npz(path, given)
        if ext == ".csv":
            return _read_csv(path, given, fps)
        robot = given if given is not None else _robot_of_export(ext)
        angles, times, valid, meta, conf = robot.exports[ext].read(robot, path)
        return Motion(angles=angles, times=times, valid=valid, meta=meta, robot=robot,
                      confidence=conf)  # fmt: skip
    except ConfigError as e:  # a Motion check the readers did not pre-empt: still the file's fault
        raise InputError(path, str(e)) from None


def _check_finite_angles(path: Path, angles: np.ndarray) -> None:
    ok = np.isfinite(angles)
    if not ok.all():
        raise InputError(path, "angles must be finite", frame=int(np.flatnonzero(~ok.all(1))[0]))


def _read_npz(path: Path, robot: Robot | None) -> Motion:
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
    robot = _robot_of_names(path, robot, [str(s) for s in names])
    angles = robot.from_columns([str(s) for s in names], columns)
    if "times" in data:
        times = data["times"]
        if times.dtype.kind not in "fiu" or times.shape != (n,):
            raise InputError(
                path, f"times must be a real ({n},) array, got {times.dtype} {times.shape}"
            )
        times = times.astype(np.float64)
        check_times(times)
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
    conf = data.get("confidence")
    if conf is not None and (conf.dtype.kind not in "fiu" or conf.shape != (n,)):
        raise InputError(
            path, f"confidence must be a real ({n},) array, got {conf.dtype} {conf.shape}"
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
        meta = check_meta(meta)
    except ConfigError as e:
        raise InputError(path, str(e)) from None
    root = {k: data[k] for k in ("root_pos", "root_rot", "contacts") if k in data}
    return Motion(
        angles=angles, times=times, valid=valid, positions=positions, meta=meta, robot=robot,
        confidence=conf, **root,
    )  # fmt: skip


def _read_csv(path: Path, robot: Robot | None, fps: float | None = None) -> Motion:
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
    if all(_is_float(c) for c in header):
        return _read_root_csv(path, lines, robot, ROOT_CSV_FPS if fps is None else float(fps))
    if fps is not None:
        raise ConfigError(f"{path}: fps= is for a whole-body CSV (no header); this one has "
                          "times")  # fmt: skip
    if header[0] != "time" or len(header) < 2:
        raise InputError(
            path, f"line 1: the header must be 'time,<joint names>', got {lines[0][:60]!r}"
        )
    names = header[1:]
    has_conf = names[-1] == "confidence"  # as jaxproj 0.2.0 wrote it
    if has_conf:
        names = names[:-1]
    robot = _robot_of_names(path, robot, names)
    if len(lines) < 2:
        raise InputError(path, "no frames (only a header)")
    values = _number_rows(path, lines[1:], len(header), first_line=2)
    times = values[:, 0]
    check_times(times)
    columns = values[:, 1 : 1 + len(names)].astype(np.float32)
    _check_finite_angles(path, columns)
    angles = robot.from_columns(names, columns)
    conf = values[:, -1].astype(np.float32) if has_conf else None
    return Motion(angles=angles, times=times, valid=np.ones(len(times), dtype=bool), robot=robot,
                  confidence=conf)  # fmt: skip


def _read_root_csv(path: Path, lines: list[str], robot: Robot | None, fps: float) -> Motion:
    """A whole-body CSV (``_write_root_csv``'s layout)."""
    width = len(lines[0].split(","))
    if robot is None:
        fits = [r for r in map(get_robot, robot_names()) if r.n_joints + 7 == width]
        if len(fits) != 1:
            have = ", ".join(f"{r.name} {r.n_joints + 7}" for r in map(get_robot, robot_names()))
            raise InputError(path, f"a whole-body CSV of {width} columns (root 7 + joints) fits "
                             f"{len(fits)} registered robots ({have}): pass robot=")  # fmt: skip
        robot = fits[0]
    if width != robot.n_joints + 7:
        raise InputError(path, f"line 1: {width} columns; the {robot.name}'s whole-body CSV has "
                         f"{robot.n_joints + 7} (root x y z, quaternion x y z w, "
                         f"{robot.n_joints} joints)")  # fmt: skip
    table = _number_rows(path, lines, width, first_line=1).astype(np.float32)
    if not np.isfinite(table).all():
        raise InputError(path, "values must be finite", frame=int(np.flatnonzero(
            ~np.isfinite(table).all(axis=1))[0]))  # fmt: skip
    n = len(table)
    try:
        return Motion(angles=table[:, 7:], times=np.arange(n, dtype=np.float64) / fps,
                      valid=np.ones(n, dtype=bool), robot=robot, root_pos=table[:, :3],
                      root_rot=table[:, 3:7], meta={"fps": fps})  # fmt: skip
    except ConfigError as e:
        raise InputError(path, str(e)) from None


def _number_rows(path: Path, lines: list[str], width: int, first_line: int) -> np.ndarray:
    """``(len(lines), width)`` float64 of comma-separated ``lines`` (the file's line
    ``first_line`` first), or ``InputError`` naming the line: a row of another width, a cell
    that is not a number."""
    values = np.empty((len(lines), width), dtype=np.float64)
    for i, line in enumerate(lines):
        cells = line.split(",")
        if len(cells) != width:
            raise InputError(
                path, f"line {i + first_line}: expected {width} columns, got {len(cells)}"
            )
        try:
            values[i] = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_float(c))
            raise InputError(
                path, f"line {i + first_line}: not a number: {bad.strip()[:40]!r}"
            ) from None
    return values


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
