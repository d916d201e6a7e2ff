"""MediaPipe Pose world landmarks as JSON or CSV, format ``"mediapipe"`` (NPZ: ``formats.table``).

MediaPipe Pose (the legacy ``mp.solutions.pose`` and the Pose Landmarker task) gives, per image,
33 ``pose_world_landmarks``: ``x, y, z`` in metres with the origin at the centre of the hips, and
per landmark a ``visibility`` (and a ``presence``) score. The axes are the camera image's: x to
the image's right, y **down**, z away from the camera (negative between the hips and the camera),
a right-handed frame (the cross product of x right and y down points into the image, along +z).
Sources: the MediaPipe Pose guide (``pose_world_landmarks``: metres, origin between the hips);
google-ai-edge/mediapipe issue #4205 (z negative towards the camera, "this relates world
coordinates as well", a MediaPipe author); geaxgx/depthai_blazepose issue #51 (world y negative
above the hips); the ``Landmark`` proto and the Python ``Landmark`` container (``visibility``,
``presence``: optional floats).

The reader turns the landmarks 180 degrees about z, ``(x, y, z) -> (-x, -y, z)`` (a rotation, so
the frame stays right-handed), into Kinect camera conventions: y up, the performer's left at
smaller x when they face the camera, z away from the camera. The descriptor reads bone directions
in the body's own frame, so the turn changes no result; it makes positions and videos look like
Kinect data. Joints are then completed (``MEDIAPIPE_POSE.complete``: pelvis centre, spine top and
middle, head centre, hands) and laid out as Kinect v1 (``skeletons.to_kinect_v1``);
``Recording.skeleton`` is ``"mediapipe_pose"``.

Accepted files (what people save from MediaPipe; our own layouts, not a MediaPipe file format):

- **JSON**: a list of frames, each a list of the 33 landmarks in MediaPipe's order, each an object
  ``{"x": .., "y": .., "z": .., "visibility": .., "presence": ..}`` (``visibility`` and
  ``presence`` optional; other keys ignored). A frame may also be an object
  ``{"landmarks": [...]}`` (other keys ignored), and the whole file an object
  ``{"frames": [...], "fps": 30}`` (``fps`` optional). A frame with no detection is ``[]``,
  ``null`` or ``{"landmarks": []}``: it is kept, invalid (a file of such frames only is an
  error). ``null`` coordinates (and Python's ``NaN``) are missing values: the frame is invalid.
  Recognised by a first ``{...}`` object (with no nested object or list) that has keys ``x``,
  ``y`` and ``z``.
- **CSV**: one header line, then one row per frame. The header names every column
  ``<landmark>_<field>``: ``<landmark>`` one of the 33 names (``LANDMARKS``: ``nose``,
  ``left_eye_inner``, ..., ``right_foot_index``), ``<field>`` one of ``x``, ``y``, ``z``,
  ``visibility``, ``presence``, in any order; every landmark needs ``x``, ``y`` and ``z``
  (99 columns), ``visibility`` (``presence``) for all 33 landmarks or none (132 or 165 columns).
  One more column ``frame`` may give frame numbers (integers, increasing): times are then the
  frame numbers at 30 frames/s, so frames left out (no detection) leave gaps. Names are case
  insensitive, spaces around fields ignored. An empty field or ``nan`` is a missing value: a row
  of them is a frame with no detection (kept, invalid; rows of them only are an error); a row
  has as many fields as the header. Recognised by a header line with ``nose_x``, ``nose_y`` and
  ``nose_z`` among its fields.

Validity (``Recording.valid``): a frame is invalid when a coordinate is missing or non-finite,
or when any landmark of ``CHECKED_LANDMARKS`` has a ``visibility`` below
``VISIBILITY_THRESHOLD`` (0.5). The checked landmarks are those behind the body frame and the
upper-body bones the default robot follows (hips, shoulders, ears for the head centre, elbows,
wrists): a webcam often cuts off hands and legs, whose landmarks MediaPipe then still estimates, and
a frame of a good upper body stays valid; a full-body (``bones="full"``) model reads those
estimates. ``visibility`` must be a probability in [0, 1] (some MediaPipe builds give the
sigmoid's argument: apply the sigmoid first); a missing one is not checked, and a file whose
every visibility is exactly 0 is taken to carry none (unset protobuf fields read 0; several
MediaPipe builds leave them unset). ``presence`` is read and ignored: the legacy solution
always gives 0 (google-ai-edge/mediapipe issues #1790, #4411).

Time: the JSON object's ``fps``, the CSV's ``frame`` column at 30 frames/s, else frames are
assumed ``KINECT_FPS`` (30, a webcam's usual rate) apart; ``read_skeleton(fps=)`` overrides.
Every problem is an ``InputError`` naming the file and the 1-based line (CSV, JSON syntax) or the
0-based frame and the landmark (JSON values).
"""

from __future__ import annotations

import json
import math
import os
import re
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human import skeletons
from jaxproj.human.layouts import MEDIAPIPE_POSE
from jaxproj.io.formats.base import Format
from jaxproj.io.recording import FPS_RANGE, KINECT_FPS, Recording, timed_recording
from jaxproj.io.text import Head, check_counts, decode, is_number, to_table

LANDMARKS: tuple[str, ...] = MEDIAPIPE_POSE.sensor_joints
"""The 33 landmark names, in MediaPipe Pose's order (the index is the landmark's number)."""
N_LANDMARKS = len(LANDMARKS)

VISIBILITY_THRESHOLD = 0.5
"""A checked landmark with a ``visibility`` below this makes its frame invalid."""

FIELDS = ("x", "y", "z", "visibility", "presence")
"""The per-landmark fields of a CSV header (``<landmark>_<field>``) and a JSON landmark."""

SKELETON = MEDIAPIPE_POSE.name


def _checked_landmarks() -> tuple[str, ...]:
    """The landmarks behind the body frame and the upper-body bones, through derived joints."""
    s = MEDIAPIPE_POSE
    derived = dict(s.derived)
    joints = [j for pair in s.frame for j in pair]
    joints += [j for b in skeletons.UPPER_BODY for j in s.bones[b]]
    out: list[str] = []
    while joints:
        j = joints.pop(0)
        if j in derived:
            joints.extend(derived[j])
        elif j not in out:
            out.append(j)
    return tuple(sorted(out, key=LANDMARKS.index))


CHECKED_LANDMARKS: tuple[str, ...] = _checked_landmarks()
"""The landmarks whose ``visibility`` decides a frame's validity (MediaPipe order): hips,
shoulders, ears, elbows, wrists."""
_CHECKED = np.array([LANDMARKS.index(j) for j in CHECKED_LANDMARKS])


# --- landmarks -> Kinect v1 --------------------------------------------------------------------


def world_to_camera(landmarks: np.ndarray) -> np.ndarray:
    """MediaPipe world axes (x right, y down, z away from the camera) -> Kinect camera axes (y up,
    the performer's left at smaller x, z away from the camera): 180 degrees about z.

    Args:
      landmarks: ``(..., 3)`` positions.

    Returns:
      ``(..., 3)`` float64 ``(-x, -y, z)``.
    """
    out = np.array(landmarks, dtype=np.float64)
    out[..., :2] *= -1.0
    return out


def visibility_valid(
    path: str | os.PathLike[str], visibility: np.ndarray | None, line_numbers: np.ndarray | None
) -> np.ndarray | None:
    """``(T, 33)`` visibility -> ``(T,)`` bool: no checked landmark below the threshold.

    Missing (NaN) values are not checked; a table of zeros only is taken as no visibility.

    Args:
      path: the file (named in errors).
      visibility: ``(T, 33)`` scores, NaN where missing, or ``None``.
      line_numbers: ``(T,)`` 1-based line of each frame (CSV) for errors, or ``None``: errors
        name the 0-based frame.

    Returns:
      ``(T,)`` bool, or ``None`` when the file carries no visibility.

    Raises:
      InputError: a visibility outside [0, 1] (names the frame or line and the landmark).
    """
    if visibility is None:
        return None
    vis = np.asarray(visibility, np.float64)
    known = np.isfinite(vis)
    bad = np.argwhere((known & ((vis < 0.0) | (vis > 1.0))) | np.isinf(vis))
    if bad.size:
        t, j = (int(i) for i in bad[0])
        where = f"line {line_numbers[t]}: " if line_numbers is not None else ""
        raise InputError(
            path,
            f"{where}visibility of {LANDMARKS[j]!r} is {vis[t, j]:g}, not a probability in "
            "[0, 1] (a sigmoid's argument needs the sigmoid first)",
            None if line_numbers is not None else t,
        )
    if known.any() and not vis[known].any():
        return None  # every score exactly 0: unset fields, no visibility at all
    low = known[:, _CHECKED] & (vis[:, _CHECKED] < VISIBILITY_THRESHOLD)
    return np.asarray(~low.any(axis=1))


def to_kinect_v1(landmarks: np.ndarray) -> np.ndarray:
    """``(T, 33, 3)`` world landmarks as MediaPipe gives them -> ``(T, 20, 3)`` float32 Kinect v1
    positions in Kinect camera axes (``world_to_camera``, ``complete``, ``to_kinect_v1``)."""
    with np.errstate(over="ignore", invalid="ignore"):
        full = MEDIAPIPE_POSE.complete(world_to_camera(landmarks))
        return skeletons.to_kinect_v1(full, MEDIAPIPE_POSE)


# --- JSON --------------------------------------------------------------------------------------

_FLAT_OBJECT = re.compile(r"\{[^{}\[\]]*\}")


def _number(path: str | os.PathLike[str], value: Any, what: str, frame: int) -> float:
    """A JSON coordinate or score: a number, ``null`` (NaN) or NaN."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(path, f"{what} is {json.dumps(value)[:40]}, not a number", frame)
    return float(value)


def parse_json(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, float | None]:
    """JSON bytes -> (``(T, 33, 3)`` float64 world landmarks, MediaPipe axes, NaN where missing;
    ``(T, 33)`` visibility, NaN where missing, or ``None``; the file's ``fps`` or ``None``).

    Raises:
      InputError: invalid JSON (line, column), not the layout above, no frames, a frame of
        another landmark count, a landmark without ``x`` / ``y`` / ``z`` or with a value that is
        no number, a bad ``fps``.
    """
    try:
        doc = json.loads(decode(path, data))
    except json.JSONDecodeError as err:
        raise InputError(
            path, f"line {err.lineno}, column {err.colno}: not valid JSON ({err.msg})"
        ) from None
    fps = None
    if isinstance(doc, dict):
        if "frames" not in doc:
            raise InputError(
                path, f"a JSON object needs key 'frames' (keys found: {', '.join(doc) or 'none'})"
            )
        frames, rate = doc["frames"], doc.get("fps")
        if rate is not None:
            lo, hi = FPS_RANGE
            if isinstance(rate, bool) or not isinstance(rate, int | float) or not lo <= rate <= hi:
                raise InputError(
                    path, f"fps must be one frame rate in [{lo:g}, {hi:g}], got {rate!r}"
                )
            fps = float(rate)
    else:
        frames = doc
    if not isinstance(frames, list):
        raise InputError(path, f"frames must be a JSON list, got {type(frames).__name__}")
    if not frames:
        raise InputError(path, "no frames (an empty list)")
    xyz = np.full((len(frames), N_LANDMARKS, 3), np.nan)
    vis = np.full((len(frames), N_LANDMARKS), np.nan)
    for t, frame in enumerate(frames):
        if isinstance(frame, dict):
            if "landmarks" not in frame:
                raise InputError(path, "a frame object needs key 'landmarks'", t)
            frame = frame["landmarks"]
        if frame is None or frame == []:
            continue  # no detection: an invalid frame
        if not isinstance(frame, list):
            raise InputError(
                path, f"a frame must be a list of landmarks, got {type(frame).__name__}", t
            )
        if isinstance(frame[0], list):
            raise InputError(
                path, f"a list of lists (several poses?): give one pose, {N_LANDMARKS} landmarks", t
            )
        if len(frame) != N_LANDMARKS:
            raise InputError(
                path, f"found {len(frame)} landmarks, expected {N_LANDMARKS} (MediaPipe Pose)", t
            )
        for j, lm in enumerate(frame):
            name = f"landmark {j} ({LANDMARKS[j]})"
            if not isinstance(lm, dict):
                raise InputError(path, f"{name} must be an object with x, y, z", t)
            missing = [k for k in "xyz" if k not in lm]
            if missing:
                raise InputError(path, f"{name} has no {', '.join(missing)}", t)
            xyz[t, j] = [_number(path, lm[k], f"{name} {k}", t) for k in "xyz"]
            if "visibility" in lm:
                vis[t, j] = _number(path, lm["visibility"], f"{name} visibility", t)
    return xyz, (vis if np.isfinite(vis).any() else None), fps


def _sniff_json(head: Head) -> tuple[bool, str]:
    text = head.data[:65536].decode("utf-8-sig", errors="replace")
    match = _FLAT_OBJECT.search(text)
    if match is not None:
        try:
            obj = json.loads(match.group(0))
        except json.JSONDecodeError:
            obj = None
        if isinstance(obj, dict) and {"x", "y", "z"} <= obj.keys():
            return True, ""
    if head.suffix == ".json":
        return False, 'JSON without MediaPipe landmark objects ({"x", "y", "z", ...})'
    return False, ""


# --- CSV ---------------------------------------------------------------------------------------


def _header(path: str | os.PathLike[str], line: int, fields: list[str]) -> dict[str, int]:
    """Column name -> column index, checked against the header rule."""
    allowed = {f"{lm}_{f}" for lm in LANDMARKS for f in FIELDS} | {"frame"}
    names = [f.strip().lower() for f in fields]
    columns: dict[str, int] = {}
    for i, name in enumerate(names):
        if name not in allowed:
            raise InputError(
                path,
                f"line {line}, column {i + 1}: unknown column {fields[i].strip()!r} (expected "
                "<landmark>_x / _y / _z / _visibility / _presence, or frame)",
            )
        if name in columns:
            raise InputError(path, f"line {line}, column {i + 1}: column {name!r} repeats")
        columns[name] = i
    for field, required in (("x", True), ("y", True), ("z", True), ("visibility", False)):
        lacking = [lm for lm in LANDMARKS if f"{lm}_{field}" not in columns]
        if lacking and (required or len(lacking) < N_LANDMARKS):
            shown = ", ".join(f"{lm}_{field}" for lm in lacking[:3])
            more = f" and {len(lacking) - 3} more" if len(lacking) > 3 else ""
            raise InputError(path, f"line {line}: header has no column {shown}{more}")
    return columns


def parse_csv(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
    """CSV bytes -> (``(T, 33, 3)`` float64 world landmarks, MediaPipe axes; ``(T, 33)``
    visibility or ``None``; ``(T,)`` int64 frame numbers or ``None``; ``(T,)`` 1-based lines).

    Raises:
      InputError: no or a bad header (names the column), no data rows, a row of another column
        count, a non-numeric token, frame numbers that are not increasing integers.
    """
    rows: list[list[str]] = []
    numbers: list[int] = []
    columns: dict[str, int] | None = None
    for i, line in enumerate(decode(path, data).splitlines(), start=1):
        if not line.strip():
            continue
        fields = line.split(",")
        if columns is None:
            if any(is_number(f) for f in fields if f.strip()):
                raise InputError(path, f"line {i}: no header line (MediaPipe CSV starts with "
                                       "nose_x,nose_y,nose_z,...)")  # fmt: skip
            columns = _header(path, i, fields)
            continue
        rows.append(fields)
        numbers.append(i)
    assert columns is not None  # decode refuses a blank file
    if not rows:
        raise InputError(path, "file has a header line but no data rows")
    width = len(columns)
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    lines = np.array(numbers, dtype=np.int64)
    check_counts(path, counts, lines, width, f"MediaPipe CSV: the header's {width} columns")
    tokens = [t.strip() or "nan" for fields in rows for t in fields]
    table = to_table(path, tokens, lines, width)
    xyz = np.stack([table[:, [columns[f"{lm}_{c}"] for c in "xyz"]] for lm in LANDMARKS], axis=1)
    vis = None
    if "nose_visibility" in columns:
        vis = table[:, [columns[f"{lm}_visibility"] for lm in LANDMARKS]]
    frames = None
    if "frame" in columns:
        f = table[:, columns["frame"]]
        bad = np.flatnonzero(~np.isfinite(f) | (f != np.round(f)) | (np.abs(f) > 2.0**53))
        if bad.size:
            i = int(bad[0])
            raise InputError(path, f"line {lines[i]}: frame number {f[i]:g} is not an integer")
        back = np.flatnonzero(np.diff(f) <= 0)
        if back.size:
            i = int(back[0]) + 1
            raise InputError(
                path,
                f"line {lines[i]}: frame number {f[i]:g} does not increase ({f[i - 1]:g} before)",
            )
        frames = f.astype(np.int64)
    return xyz, vis, frames, lines


def _sniff_csv(head: Head) -> tuple[bool, str]:
    line = head.first_line
    if line is None or "," not in line:
        return False, ""
    names = {f.strip().lower() for f in line.split(",")}
    return {"nose_x", "nose_y", "nose_z"} <= names, ""


# --- the format --------------------------------------------------------------------------------


def _is_json(data: bytes) -> bool:
    start = data[:4096].decode("utf-8-sig", errors="replace").lstrip()
    return start[:1] in ("[", "{")


def sniff(head: Head) -> tuple[bool, str]:
    """A JSON file whose first flat object has ``x``, ``y``, ``z``, or a CSV header with
    ``nose_x``, ``nose_y``, ``nose_z``."""
    if _is_json(head.data):
        return _sniff_json(head)
    return _sniff_csv(head)


def read(path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any) -> Recording:
    """The file (JSON or CSV, told apart by a first ``[`` or ``{``) as a ``Recording``
    (``(T, 20, 3)`` Kinect v1 positions, skeleton ``"mediapipe_pose"``). ``options`` are ignored
    (``up`` does not apply: MediaPipe's axes are fixed)."""
    times, source = None, f"assumed {KINECT_FPS:g} fps"
    if _is_json(data):
        xyz, vis, rate = parse_json(path, data)
        valid = visibility_valid(path, vis, None)
        if rate is not None:
            times, source = np.arange(len(xyz)) / rate, f"file ({rate:g} fps)"
    else:
        xyz, vis, frames, lines = parse_csv(path, data)
        valid = visibility_valid(path, vis, lines)
        if frames is not None:
            times = (frames - frames[0]) / KINECT_FPS
            source = f"frame numbers at {KINECT_FPS:g} fps"
    if not np.isfinite(xyz).any():
        raise InputError(
            path, f"no pose detected in any of the {len(xyz)} frames (all empty): nothing to read"
        )
    positions = to_kinect_v1(xyz)
    return timed_recording(
        path, "mediapipe", positions, valid, times, source, fps, KINECT_FPS, SKELETON
    )


FORMAT = Format(
    name="mediapipe",
    description="MediaPipe Pose world landmarks: JSON frames of 33 {x, y, z, visibility} or CSV "
    "with a nose_x,nose_y,nose_z,... header",
    suffixes=(),  # ".json" and ".csv" name other formats too: recognised by content only
    sniff=sniff,
    read=read,
    first_line=("a nose_x,nose_y,nose_z,... header (MediaPipe CSV)", ""),
)
