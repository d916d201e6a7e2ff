"""The two plain table formats: ``"csv"`` (``(T, 20, 3)`` positions) and ``"npz"`` (any skeleton).

They share a module because they are the formats *we* define (not a dataset's): the same table
of SDK-order positions in metres, as text or as a NumPy archive, with no dataset-specific layout.

- ``"npz"`` (``.npz``, or a zip signature): a NumPy archive with key ``positions`` (or
  ``joints``) ``(T, J, 3)`` in metres, the joints of any registered skeleton in its order: an
  optional ``skeleton`` key (a string, a registered skeleton's name) names it, else ``J`` does
  (``JOINT_COUNTS``: 20 Kinect v1, 22 SMPL-X body, 24 SMPL, 25 Kinect v2, 32 Azure Kinect, 33
  MediaPipe Pose, and the longer joint arrays of the ``smplx`` package, whose first 22 or 24
  joints are read); an unknown ``J`` is an error that asks for a ``skeleton`` key. Positions
  are laid out as Kinect v1 (``skeletons.to_kinect_v1``; ``Recording.skeleton`` says which
  skeleton). Axes: ``read_skeleton(up="y")`` (default: y up, as SMPL and the Kinect camera) or
  ``up="z"`` (AMASS and most mocap: z up), which turns the joints -90 degrees about x,
  ``(x, y, z) -> (x, z, -y)``, into y up (a rotation: the frame stays right-handed; the
  descriptor, read in the body's own frame, is the same either way). MediaPipe Pose arrays are
  world landmarks in MediaPipe's own axes (``formats.mediapipe``: turned as that reader turns
  them; ``up="z"`` is refused), with an optional ``visibility`` ``(T, 33)``. An optional
  ``valid`` ``(T,)`` bool mask is honoured, and optional timing: ``times`` ``(T,)`` seconds
  (strictly increasing) or ``fps`` (a scalar); without timing frames are assumed ``KINECT_FPS``
  (30) frames/s apart. A zip without ``positions`` or ``joints`` (e.g. a model) is not a
  recording.
- ``"csv"`` (``.csv``, or a first line of 60 comma-separated fields, or a header line of names
  followed by one): comma-separated, 60 numeric columns per row (``x, y, z`` per joint, SDK
  order); one header line of non-numeric column names is allowed and skipped. No timing: frames
  are assumed ``KINECT_FPS`` frames/s apart.
"""

from __future__ import annotations

import dataclasses
import io
import os
import zipfile
from typing import Any, NamedTuple

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import N_JOINTS
from jaxproj.io.formats import mediapipe
from jaxproj.io.formats.base import Format
from jaxproj.io.recording import (
    FPS_RANGE,
    KINECT_FPS,
    MIN_STEP_S,
    Recording,
    timed_recording,
)
from jaxproj.io.text import Head, check_counts, decode, is_number, one_line, to_table

CSV_COLUMNS = 3 * N_JOINTS
"""Columns of a CSV row: ``x, y, z`` of the 20 joints."""

_ZIP_SIGNATURE = b"PK\x03\x04"


# --- CSV -----------------------------------------------------------------------------------------


def parse_csv(path: str | os.PathLike[str], data: bytes) -> np.ndarray:
    """CSV bytes -> ``(T, 20, 3)`` float64 positions, SDK order.

    Raises:
      InputError: no data rows, a row of another column count, a non-numeric token.
    """
    rows, numbers = [], []
    first = True
    for i, line in enumerate(decode(path, data).splitlines(), start=1):
        if not line.strip():
            continue
        fields = line.split(",")
        if first:
            first = False
            if not any(is_number(f) for f in fields):
                continue  # the one allowed header line of column names
        rows.append(fields)
        numbers.append(i)
    if not rows:
        raise InputError(path, "file has a header line but no data rows")
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    lines = np.array(numbers, dtype=np.int64)
    check_counts(path, counts, lines, CSV_COLUMNS, "CSV: x,y,z for 20 joints")
    table = to_table(path, [t for fields in rows for t in fields], lines, CSV_COLUMNS)
    return table.reshape(-1, N_JOINTS, 3)


def sniff_csv(head: Head) -> tuple[bool, str]:
    """A first line of 60 comma-separated fields, or a header line of names and then one."""
    line = head.first_line
    if line is None or "," not in line:
        return False, ""
    fields = line.split(",")
    if len(fields) == CSV_COLUMNS:
        return True, ""
    second = head.second_line
    if (
        second is not None
        and len(second.split(",")) == CSV_COLUMNS
        and not any(is_number(f) for f in fields)
    ):
        return True, ""
    return False, f"first line has {len(fields)} comma-separated fields, not {CSV_COLUMNS}"


def read_csv(
    path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any
) -> Recording:
    """The file as a ``Recording`` (``(T, 20, 3)``; frames ``1 / KINECT_FPS`` s apart)."""
    positions = parse_csv(path, data)
    source = f"assumed {KINECT_FPS:g} fps"
    return timed_recording(path, "csv", positions, None, None, source, fps, KINECT_FPS)


CSV = Format(
    name="csv",
    description="comma-separated x,y,z of 20 joints per row, one header line allowed",
    suffixes=(".csv",),
    sniff=sniff_csv,
    read=read_csv,
    first_line=(f"{CSV_COLUMNS} comma-separated fields (CSV)", ""),
)


# --- NPZ -----------------------------------------------------------------------------------------

NPZ_KEYS = ("positions", "joints")
"""The keys an NPZ's ``(T, J, 3)`` joint array may have, in the order they are looked for."""

UP_AXES = ("y", "z")
"""``read_skeleton(up=)``: the axis that points up in an NPZ's joint array."""


def check_up(up: str) -> None:
    """``ConfigError`` unless ``up`` is one of ``UP_AXES``."""
    if up not in UP_AXES:
        raise ConfigError(f"up must be 'y' or 'z' (the axis that points up), got {up!r}")


JOINT_COUNTS: dict[int, tuple[str, int]] = {
    20: ("kinect_v1", 20),
    22: ("smplx", 22),  # SMPL-X's (and SMPL-H's, SMPL's) first 22 body joints; HumanML3D's 22
    24: ("smpl", 24),
    25: ("kinect_v2", 25),
    32: ("azure_kinect", 32),
    33: ("mediapipe_pose", 33),
    45: ("smpl", 24),  # smplx package, SMPL: 24 joints + 21 vertex joints (face, feet, tips)
    52: ("smplx", 22),  # SMPL-H (AMASS's body model): 22 body + 2 x 15 finger joints
    55: ("smplx", 22),  # SMPL-X's joints: 22 body, jaw, 2 eyes, 2 x 15 finger joints
    73: ("smplx", 22),  # smplx package, SMPL-H: 52 + 21 vertex joints
    127: ("smplx", 22),  # smplx package, SMPL-X: 55 + 21 vertex joints + 51 face landmarks
    144: ("smplx", 22),  # the same with use_face_contour=True: + 17 face contour landmarks
}
"""``J`` of an NPZ without a ``skeleton`` key -> (the registered skeleton, how many of the
array's first joints are its joints). The longer SMPL / SMPL-H / SMPL-X arrays are what the
``smplx`` package returns (``JOINT_NAMES``, ``VertexJointSelector``): their first joints are the
body model's own, in its order."""


def _known_counts() -> str:
    """``"20 kinect_v1, ..., 33 mediapipe_pose, 45 smpl (first 24), 52/55/... smplx (first
    22)"``, for messages."""
    longer: dict[tuple[str, int], list[str]] = {}
    for n, (name, k) in sorted(JOINT_COUNTS.items()):
        longer.setdefault((name, k) if n != k else (str(n), -1), []).append(str(n))
    return ", ".join(
        f"{ns[0]} {JOINT_COUNTS[int(ns[0])][0]}" if k < 0 else f"{'/'.join(ns)} {name} (first {k})"
        for (name, k), ns in longer.items()
    )


def _skeleton_key(path: str | os.PathLike[str], value: np.ndarray) -> str:
    """The registered skeleton an NPZ's ``skeleton`` key names (one string)."""
    if value.dtype.kind not in "US" or value.size != 1:
        raise InputError(
            path, f"skeleton must be one string (a registered skeleton's name), got {value!r}"
        )
    name = value.reshape(()).item()
    name = name.decode(errors="replace") if isinstance(name, bytes) else str(name)
    if name not in skeletons.names():
        raise InputError(
            path,
            f"skeleton {name!r} is not a registered skeleton (registered: "
            f"{', '.join(skeletons.names())})",
        )
    return name


def npz_layout(
    path: str | os.PathLike[str], key: str, shape: tuple[int, ...], name: str | None
) -> tuple[skeletons.Skeleton, int]:
    """The skeleton of an NPZ's ``(T, J, 3)`` joint array and how many of its first joints are
    that skeleton's recorded joints (``Skeleton.sensor_joints``).

    Args:
      path: the file (named in errors).
      key: the array's key (``"positions"`` or ``"joints"``), for messages.
      shape: the array's shape ``(T, J, 3)``.
      name: the file's ``skeleton`` key (a registered name), or ``None``: ``JOINT_COUNTS[J]``.

    Raises:
      InputError: ``J`` names no known layout (without ``skeleton``), or is not the named
        skeleton's joint count (nor one of ``JOINT_COUNTS`` for it).
    """
    n = shape[1]
    if name is None:
        if n not in JOINT_COUNTS:
            raise InputError(
                path,
                f"{key} has {n} joints, the count of no known layout ({_known_counts()}); add "
                f"a 'skeleton' key naming its registered skeleton (shape {shape})",
            )
        name, k = JOINT_COUNTS[n]
        return skeletons.get(name), k
    s = skeletons.get(name)
    k = len(s.sensor_joints)
    if n != k and JOINT_COUNTS.get(n) != (name, k):
        longer = [str(c) for c, (s_name, _) in sorted(JOINT_COUNTS.items()) if s_name == name]
        counts = " or ".join(dict.fromkeys([str(k), *longer]))
        raise InputError(
            path, f"{key} has {n} joints, but skeleton {name!r} records {counts} (shape {shape})"
        )
    return s, k


def z_up_to_y_up(positions: np.ndarray) -> np.ndarray:
    """``(..., 3)`` z-up positions -> y up: -90 degrees about x, ``(x, y, z) -> (x, z, -y)``
    (float64; a rotation, so the frame stays right-handed: z-up data facing +y faces -z)."""
    p = np.asarray(positions, dtype=np.float64)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def _check_visibility(path: str | os.PathLike[str], vis: np.ndarray, n: int) -> np.ndarray:
    """An NPZ's ``visibility``: ``(T, 33)`` numbers (MediaPipe Pose only)."""
    want = (n, mediapipe.N_LANDMARKS)
    if vis.shape != want or vis.dtype.kind not in "iuf":
        raise InputError(
            path, f"visibility has shape {vis.shape} and dtype {vis.dtype}, expected {want} numbers"
        )
    return vis.astype(np.float64)


class NpzArrays(NamedTuple):
    """What ``read_npz_arrays`` reads from an NPZ (the fields of a ``Recording`` it decides)."""

    positions: np.ndarray  # (T, 20, 3) in the Kinect v1 layout
    valid: np.ndarray | None  # (T,) bool, or None: every frame
    times: np.ndarray | None  # (T,) s, or None: the format's rate
    time_source: str
    skeleton: str  # the registered skeleton the file recorded
    skeleton_from: str  # "option", "file" or "count" (``Recording.skeleton_from``)
    notes: tuple[str, ...]  # ``Recording.notes``: a guessed skeleton, hips made
    invalid_reason: str | None  # ``Recording.invalid_reason`` (MediaPipe visibility)


def read_npz_arrays(
    path: str | os.PathLike[str],
    data: bytes,
    up: str = "y",
    skeleton: str | None = None,
    hips: str = "required",
) -> NpzArrays:
    """NPZ bytes -> ``NpzArrays``.

    Args:
      path: the file (named in errors).
      data: its bytes.
      up: ``"y"`` (the file is y-up: kept as it is) or ``"z"`` (turned by ``z_up_to_y_up``).
      skeleton: a registered skeleton's name (``read_skeleton(skeleton=)``): it wins over the
        file's ``skeleton`` key and the joint count; ``None``: the key, else the count.
      hips: MediaPipe landmarks with ``visibility`` only: ``"shoulders"`` makes hidden hips
        from the shoulders as the JSON / CSV reader does (``mediapipe.hips_from_shoulders``).

    Raises:
      InputError: not a zip, a corrupt archive, no ``positions`` / ``joints``, wrong shapes or
        dtypes, a ``J`` of no known layout, a bad ``skeleton``, ``valid``, ``visibility``,
        ``times`` or ``fps``.
      ConfigError: ``up`` is not ``"y"`` or ``"z"``, or ``"z"`` for MediaPipe Pose landmarks.
    """
    check_up(up)
    if data[:4] != _ZIP_SIGNATURE:
        raise InputError(path, "not an npz archive (not a zip file)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            keys = list(archive.files)
            key = next((k for k in NPZ_KEYS if k in keys), None)
            if key is None:
                found = ", ".join(keys) if keys else "none"
                hint = ""
                if {"poses", "trans"} <= set(keys):  # an AMASS file: body model parameters
                    hint = (
                        "; body model parameters (AMASS poses, trans) are not read: save the "
                        "model's joint positions (e.g. from the smplx package) as 'joints'"
                    )
                raise InputError(
                    path, f"missing key 'positions' or 'joints' (keys found: {found}){hint}"
                )
            members = {
                name: archive[name] if name in keys else None
                for name in (key, "valid", "times", "skeleton", "visibility")
            }
            members["fps"] = archive["fps"] if "fps" in keys and "times" not in keys else None
            for name, value in members.items():
                if value is not None and not isinstance(value, np.ndarray):
                    raise InputError(
                        path, f"corrupt or unreadable npz archive (member {name!r} is not .npy)"
                    )
    except InputError:
        raise
    except Exception as err:  # zipfile / zlib / numpy format errors of a corrupt archive
        raise InputError(path, f"corrupt or unreadable npz archive ({one_line(err)})") from None
    positions, valid, times, rate = (members[k] for k in (key, "valid", "times", "fps"))
    assert positions is not None
    if not (
        np.issubdtype(positions.dtype, np.floating) or np.issubdtype(positions.dtype, np.integer)
    ):
        raise InputError(path, f"{key} has dtype {positions.dtype}, expected floats")
    shape = positions.shape
    if positions.ndim != 3 or shape[2] != 3:
        raise InputError(path, f"{key} has shape {shape}, expected (T, J, 3)")
    named = members["skeleton"]
    chosen = _choose(skeleton, None if named is None else _skeleton_key(path, named))
    layout, k = npz_layout(path, key, shape, chosen[0])
    if shape[0] == 0:
        raise InputError(path, f"{key} has no frames (shape {shape})")
    if valid is not None:
        if valid.shape != (shape[0],):
            raise InputError(path, f"valid has shape {valid.shape}, expected ({shape[0]},)")
        if valid.dtype != np.bool_:
            if not np.issubdtype(valid.dtype, np.integer) or not np.isin(valid, (0, 1)).all():
                raise InputError(path, f"valid has dtype {valid.dtype}, expected bool")
            valid = valid.astype(bool)
    raw = positions[:, :k]
    positions = _to_kinect_v1(path, raw, layout, up)
    seen: np.ndarray | None = None
    notes = _guessed_note(layout.name, shape[1], chosen[1])
    reason = None
    if layout.name == mediapipe.SKELETON and members["visibility"] is not None:
        # as the JSON / CSV reader reads it: the checked landmarks decide, and say why
        vis = _check_visibility(path, members["visibility"], shape[0])
        checked = mediapipe._visibility(path, vis, None)
        if checked is not None and hips == "shoulders":
            positions, seen, checked, made = mediapipe.hips_from_shoulders(positions, checked)
            notes += made
        elif checked is not None:
            seen = np.asarray(~mediapipe._low_visibility(checked).any(axis=1), bool)
        reason = mediapipe.invalid_reason(raw.astype(np.float64), checked)
    if seen is not None:
        valid = seen if valid is None else valid & seen
    source = f"assumed {KINECT_FPS:g} fps"
    if times is not None:
        times = check_times(path, times, shape[0])
        source = "file"
    elif rate is not None:
        lo, hi = FPS_RANGE
        if (
            rate.shape != ()
            or rate.dtype.kind not in "iuf"
            or not (np.isfinite(rate) and lo <= rate <= hi)
        ):
            raise InputError(path, f"fps must be one frame rate in [{lo:g}, {hi:g}], got {rate!r}")
        times = np.arange(shape[0], dtype=np.float64) / float(rate)
        source = f"file ({float(rate):g} fps)"
    return NpzArrays(positions, valid, times, source, layout.name, chosen[1], notes, reason)


def _choose(option: str | None, named: str | None) -> tuple[str | None, str]:
    """(the skeleton's name or ``None`` for the joint count, ``Recording.skeleton_from``)."""
    if option is not None:
        if option not in skeletons.names():
            raise ConfigError(
                f"skeleton {option!r} is not a registered skeleton (registered: "
                f"{', '.join(skeletons.names())})"
            )
        return option, "option"
    if named is not None:
        return named, "file"
    return None, "count"


def _guessed_note(skeleton: str, n_joints: int, how: str) -> tuple[str, ...]:
    """The note of a skeleton guessed from the joint count (none otherwise)."""
    if how != "count":
        return ()
    return (
        f"skeleton {skeleton} guessed from the joint count ({n_joints}); --skeleton NAME "
        "says which",
    )


def _to_kinect_v1(
    path: str | os.PathLike[str],
    joints: np.ndarray,
    skeleton: skeletons.Skeleton,
    up: str,
) -> np.ndarray:
    """``(T, k, 3)`` recorded joints -> ``(T, 20, 3)`` Kinect v1 layout (MediaPipe's
    ``visibility`` is read by ``read_npz_arrays``). Kinect v1 data with ``up="y"`` is returned as
    it is."""
    if skeleton.name == mediapipe.SKELETON:
        if up != "y":
            raise ConfigError(
                "up='z' does not apply to MediaPipe Pose world landmarks: their axes are "
                "MediaPipe's (y down), turned to y up by the reader"
            )
        return mediapipe.to_kinect_v1(joints)
    if up == "z":
        joints = z_up_to_y_up(joints)
    if skeleton.name == skeletons.DEFAULT:
        return joints
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            full = skeleton.complete(joints) if skeleton.derived else joints
            return skeletons.to_kinect_v1(full, skeleton)
    except ConfigError as err:  # a registered skeleton that cannot be laid out as Kinect v1
        raise InputError(path, str(err)) from None


def parse_npz(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, str]:
    """NPZ bytes -> (``(T, 20, 3)`` positions in the Kinect v1 layout, ``(T,)`` valid or None,
    ``(T,)`` times or None, time source): ``read_npz_arrays`` with y up, without the skeleton.

    Raises:
      InputError: as ``read_npz_arrays``.
    """
    return read_npz_arrays(path, data)[:4]


def check_times(path: str | os.PathLike[str], times: np.ndarray, n: int) -> np.ndarray:
    """Validate a file's ``times``: ``(n,)`` finite, strictly increasing; returned from 0.

    Raises:
      InputError: wrong shape or dtype, non-finite, not increasing by ``MIN_STEP_S`` or more.
    """
    if times.shape != (n,):
        raise InputError(path, f"times has shape {times.shape}, expected ({n},)")
    if times.dtype.kind not in "iuf":
        raise InputError(path, f"times has dtype {times.dtype}, expected numbers (seconds)")
    t = times.astype(np.float64)
    if not np.isfinite(t).all():
        raise InputError(path, f"times[{int(np.argmax(~np.isfinite(t)))}] is not finite")
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0)) + 1
        raise InputError(path, f"times must increase strictly: times[{i}] = {t[i]:g} after "
                               f"{t[i - 1]:g}")  # fmt: skip
    if (steps < MIN_STEP_S).any():
        i = int(np.argmax(steps < MIN_STEP_S)) + 1
        raise InputError(path, f"times must increase by at least {MIN_STEP_S:g} s per frame: "
                               f"times[{i}] = {t[i]:g} after {t[i - 1]:g}")  # fmt: skip
    return t - t[0]


def sniff_npz(head: Head) -> tuple[bool, str]:
    """A zip archive with a ``positions`` or ``joints`` member (or a file named ``.npz``: its
    reader says what is wrong with it, as for a zip that cannot be opened)."""
    if head.data[:4] != _ZIP_SIGNATURE:
        return head.suffix == ".npz", ""
    try:
        source = io.BytesIO(head.data) if head.complete else head.path
        with zipfile.ZipFile(source) as zf:
            names = zf.namelist()
    except (OSError, zipfile.BadZipFile, ValueError):
        return True, ""  # looks like an npz: its reader says what is wrong with it
    if not any(f"{key}.npy" in names for key in NPZ_KEYS):
        return False, "an npz archive without 'positions' or 'joints' (not a recording)"
    return True, ""


def read_npz(
    path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any
) -> Recording:
    """The archive as a ``Recording`` (``(T, 20, 3)`` in the Kinect v1 layout; its ``valid``,
    MediaPipe ``visibility`` and timing honoured; ``options["up"]``: ``read_npz_arrays``)."""
    a = read_npz_arrays(
        path, data, options.get("up", "y"), options.get("skeleton"), options.get("hips", "required")
    )
    rec = timed_recording(path, "npz", a.positions, a.valid, a.times, a.time_source, fps,
                          KINECT_FPS, a.skeleton)  # fmt: skip
    return dataclasses.replace(
        rec, skeleton_from=a.skeleton_from, notes=a.notes, invalid_reason=a.invalid_reason
    )


NPZ = Format(
    name="npz",
    description="NumPy archive of positions (or joints) T x J x 3 of a registered skeleton, "
    "optional skeleton, valid, times or fps",
    suffixes=(".npz",),
    sniff=sniff_npz,
    read=read_npz,
)
