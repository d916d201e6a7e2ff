"""Azure Kinect Body Tracking JSON (the SDK samples' ``offline_processor``), format
``"azure_kinect"``.

The layout (``microsoft/Azure-Kinect-Samples``, ``body-tracking-samples/offline_processor/
main.cpp``): one JSON object with

- ``joint_names``: the 32 joint names in ``k4abt_joint_id_t`` order (``PELVIS``, ...,
  ``EAR_RIGHT``), checked against the ``azure_kinect`` skeleton when present;
- ``bone_list``, ``k4abt_sdk_version``, ``source_file``: not read;
- ``frames``: a list of ``{"frame_id", "num_bodies", "timestamp_usec", "bodies"}``, each body
  ``{"body_id", "joint_positions": 32 x [x, y, z], "joint_orientations": 32 x [w, x, y, z]}``.
  Positions are millimetres in the depth camera's frame (x right, y down, z forward); the sample
  writes no confidence levels, tools derived from it (``kinect_mocap_studio``) add
  ``"confidence_levels"``: 32 integers per body, which are honoured when present.

Units and axes: millimetres -> metres, then turned 180 degrees about z, ``(x, y, z) -> (-x, -y,
z)`` (``AZURE_TO_KINECT``), into Kinect camera space (x to the sensor's left, y up, z forward). A
rotation: the descriptor's body frame makes it irrelevant (only the handedness counts, and both
frames are right-handed); it makes raw positions and videos look like Kinect data.

Body: ``read_skeleton(..., body=)`` (``jaxproj.io.formats.bodies``): ``"first"`` (default) or a
0-based index into each frame's ``bodies``; a frame without it is invalid.

Valid frames: a joint's confidence level is 0 (``K4ABT_JOINT_CONFIDENCE_NONE``: out of range),
1 (``LOW``: not observed, predicted), 2 (``MEDIUM``, the most the SDK gives) or 3 (``HIGH``,
reserved). A frame is invalid when any joint that feeds the Kinect v1 layout
(``Skeleton.kinect_v1_sources``: not the clavicles, hand tips, thumbs or the face) has level 0:
predicted joints (1) are kept, as Kinect v2's inferred ones are. Without confidence levels every
frame with the body is valid (the tracker gives a position for every joint). Non-finite (``null``)
and all-zero positions make the frame invalid too.

Time: ``timestamp_usec`` (the device timestamp, microseconds), from the first frame; they must
increase strictly. Every timestamp the same (some exports write 0 throughout) is no timing: an
error that asks for ``--fps``. A rate given by the caller (``fps=``, ``--fps``) replaces the
timestamps, which are then not read (zero or broken ones do not stop the file). A file
without any timestamp is assumed ``KINECT_FPS`` (30) frames/s, the Azure Kinect's default rate
(``Recording.notes`` says so).

Detection (by content only: ``.json`` names other formats too): a JSON object whose start holds
``"frames"`` and one of ``"joint_positions"``, ``"num_bodies"``, ``"bone_list"`` or ``k4abt``
(other JSON files, e.g. motion files, are not claimed).

Errors (``InputError``, one line naming the file and the 1-based line, or the 0-based frame of
``frames``): invalid JSON (truncated), no ``frames`` or none in it, a frame or body of another
shape, ``joint_positions`` not 32 x 3 numbers, ``joint_names`` not the 32 SDK names (e.g. a
26-joint file of SDK 0.9), a ``num_bodies`` other than ``len(bodies)``, confidence levels other than
0-3, a missing or non-increasing ``timestamp_usec``, no frame with the chosen body (no body at all).
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human import skeletons
from jaxproj.io.formats.base import Format
from jaxproj.io.formats.bodies import BodyChoice, body_index, feeding_joints, no_body_error
from jaxproj.io.recording import KINECT_FPS, Recording, timed_recording
from jaxproj.io.text import SNIFF_BYTES, Head, decode

SKELETON = "azure_kinect"
"""The registered skeleton of the files (``jaxproj.human.layouts.AZURE_KINECT``)."""

N_JOINTS = 32
"""Joints per body (``K4ABT_JOINT_COUNT``, Body Tracking SDK 1.0 and later)."""

MM = 1e-3
"""Metres per file unit (millimetres)."""

AZURE_TO_KINECT = np.diag([-1.0, -1.0, 1.0])
"""Depth camera axes (x right, y down, z forward) -> Kinect camera space (x left, y up, z
forward): a 180 degree turn about z."""

MIN_CONFIDENCE = 1
"""The lowest confidence level a joint feeding the Kinect v1 layout may have in a valid frame
(``K4ABT_JOINT_CONFIDENCE_LOW``: predicted)."""

NAME_ALIASES = {"SPINE_NAVAL": "SPINE_NAVEL"}
"""Joint names some tools write (the SDK documentation's spelling) -> the sample's."""

_MARKERS = (b'"joint_positions"', b'"num_bodies"', b'"bone_list"', b"k4abt")


def _load(path: str | os.PathLike[str], data: bytes) -> dict[str, Any]:
    """The file's top-level JSON object (``InputError`` naming the line of a syntax error)."""
    text = decode(path, data)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        ends = err.pos >= len(text.rstrip())
        hint = "; the file ends there (truncated?)" if ends else ""
        where = f"line {err.lineno}, column {err.colno}"
        raise InputError(path, f"{where}: invalid JSON ({err.msg}){hint}") from None
    except RecursionError:
        raise InputError(path, "invalid JSON (nested too deeply)") from None
    if not isinstance(doc, dict):
        raise InputError(
            path, f"expected a JSON object with 'frames', found a {type(doc).__name__}"
        )
    return doc


def _check_names(path: str | os.PathLike[str], names: Any) -> None:
    """``InputError`` unless ``joint_names`` are the ``azure_kinect`` skeleton's, in order."""
    expected = skeletons.get(SKELETON).joints
    if not isinstance(names, list) or len(names) != N_JOINTS:
        n = len(names) if isinstance(names, list) else "no list of"
        raise InputError(
            path,
            f"joint_names lists {n} joints, expected the {N_JOINTS} of k4abt_joint_id_t (Body "
            "Tracking SDK 1.0 or later)",
        )
    for j, (name, want) in enumerate(zip(names, expected, strict=True)):
        if NAME_ALIASES.get(name, name) != want:
            raise InputError(
                path, f"joint_names[{j}] is {name!r}, expected {want!r} (k4abt_joint_id_t order)"
            )


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _numbers(value: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    """``value`` as float64 of ``shape`` (``null`` -> NaN), or ``None`` if it is not that."""
    try:
        arr = np.array(value)
    except ValueError:  # ragged
        return None
    if arr.shape != shape:
        return None
    if arr.dtype.kind in "iuf":
        return arr.astype(np.float64)
    flat = arr.ravel()
    if arr.dtype != object or not all(v is None or _is_number(v) for v in flat):
        return None
    return np.array([np.nan if v is None else v for v in flat], np.float64).reshape(shape)


def _what(value: Any, levels: bool = False) -> str:
    """What is wrong with a per-joint list that ``_numbers`` refused (the first problem)."""
    if not isinstance(value, list):
        return f"found a {type(value).__name__}"
    if len(value) != N_JOINTS:
        return f"found {len(value)} entries"
    for j, e in enumerate(value):
        if levels:
            ok = _is_number(e) and e in (0, 1, 2, 3)
        else:
            ok = isinstance(e, list) and len(e) == 3 and all(v is None or _is_number(v) for v in e)
        if not ok:
            return f"entry {j} is {json.dumps(e)[:40]}"
    return "a value of another type"  # pragma: no cover (only refused lists come here)


def _frame_bodies(path: str | os.PathLike[str], f: int, frame: Any) -> list[Any]:
    """A frame's ``bodies``, checked against its ``num_bodies``."""
    if not isinstance(frame, dict):
        raise InputError(path, f"expected an object, found a {type(frame).__name__}", f)
    bodies = frame.get("bodies", [])
    if not isinstance(bodies, list):
        raise InputError(path, f"'bodies' is a {type(bodies).__name__}, not a list", f)
    n = frame.get("num_bodies", len(bodies))
    if n != len(bodies) or isinstance(n, bool):
        raise InputError(path, f"num_bodies is {n!r} but 'bodies' holds {len(bodies)}", f)
    return bodies


def _body(
    path: str | os.PathLike[str], f: int, b: int, body: Any
) -> tuple[np.ndarray, np.ndarray | None]:
    """One body: (``(32, 3)`` float64 mm, file axes; ``(32,)`` confidence levels or ``None``)."""
    if not isinstance(body, dict) or "joint_positions" not in body:
        raise InputError(path, f"body {b} is not an object with 'joint_positions'", f)
    value = body["joint_positions"]
    pos = _numbers(value, (N_JOINTS, 3))
    if pos is None:
        raise InputError(
            path,
            f"body {b}: joint_positions is not {N_JOINTS} x [x, y, z] numbers ({_what(value)})",
            f,
        )
    if "confidence_levels" not in body:
        return pos, None
    conf = _numbers(body["confidence_levels"], (N_JOINTS,))
    if conf is None or not np.isin(conf, (0, 1, 2, 3)).all():
        found = _what(body["confidence_levels"], levels=True)
        raise InputError(
            path,
            f"body {b}: confidence_levels is not {N_JOINTS} levels of 0, 1, 2 or 3 ({found})",
            f,
        )
    return pos, conf


def _times(path: str | os.PathLike[str], stamps: list[Any]) -> np.ndarray | None:
    """``timestamp_usec`` of every frame -> ``(T,)`` seconds from the first (``None``: the file
    has none)."""
    if all(s is None for s in stamps):
        return None
    for f, s in enumerate(stamps):
        if not (_is_number(s) and abs(s) < 1e18):  # NaN, inf and absurd values fail too
            if s is None:
                raise InputError(path, "no timestamp_usec (other frames have one)", f)
            raise InputError(path, f"timestamp_usec {json.dumps(s)[:40]} is not a number", f)
    t = np.array(stamps, dtype=np.float64)
    if len(t) > 1 and (t == t[0]).all():  # e.g. every timestamp_usec 0 (some exports)
        raise InputError(
            path,
            f"every frame's timestamp_usec is {stamps[0]}: the file gives no timing; give the "
            "rate with --fps (read_skeleton(fps=)), which replaces the timestamps",
        )
    steps = np.diff(t)
    if (steps <= 0).any():
        f = int(np.argmax(steps <= 0)) + 1
        raise InputError(
            path,
            f"timestamp_usec {stamps[f]} is not after the previous frame's {stamps[f - 1]} "
            "(timestamps must increase strictly)",
            f,
        )
    return (t - t[0]) * 1e-6


def parse_azure(
    path: str | os.PathLike[str], data: bytes, body: BodyChoice = "first", timed: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Azure Kinect JSON bytes -> one body of every frame.

    Args:
      path: the file (named in errors).
      data: its bytes.
      body: ``"first"`` or a 0-based index into each frame's bodies.
      timed: read ``timestamp_usec``; ``False`` (a rate given by the caller, ``fps=``): the
        timestamps are not read, so zero or broken ones do not stop the file.

    Returns:
      ``(T, 32, 3)`` float64 metres in Kinect camera axes (``AZURE_TO_KINECT``), k4abt order
      (zeros where the frame lacks the body); ``(T,)`` bool, ``False`` where the frame lacks the
      body or a joint feeding Kinect v1 has confidence 0; ``(T,)`` seconds from
      ``timestamp_usec`` or ``None``.

    Raises:
      InputError: a malformed file (module docstring).
      ConfigError: a bad ``body``.
    """
    k = body_index(body)
    doc = _load(path, data)
    if "joint_names" in doc:
        _check_names(path, doc["joint_names"])
    frames = doc.get("frames")
    if not isinstance(frames, list):
        found = "none" if frames is None else f"a {type(frames).__name__}"
        raise InputError(path, f"expected a list 'frames' of body-tracking frames, found {found}")
    if not frames:
        raise InputError(path, "'frames' is empty: no frames")
    n = len(frames)
    positions = np.zeros((n, N_JOINTS, 3))
    valid = np.zeros(n, dtype=bool)
    feeding = feeding_joints(SKELETON)
    most = 0
    for f, frame in enumerate(frames):
        bodies = _frame_bodies(path, f, frame)
        most = max(most, len(bodies))
        for b, entry in enumerate(bodies):
            pos, conf = _body(path, f, b, entry)
            if b == k:
                positions[f] = pos
                valid[f] = conf is None or bool((conf[feeding] >= MIN_CONFIDENCE).all())
    if most <= k:
        raise no_body_error(path, k, n, most)
    times = _times(path, [fr.get("timestamp_usec") for fr in frames]) if timed else None
    return (positions * MM) @ AZURE_TO_KINECT.T, valid, times


def sniff(head: Head) -> tuple[bool, str]:
    """A JSON object whose start holds ``"frames"`` and a body-tracking key (module docstring)."""
    data = head.data[:SNIFF_BYTES]
    if not data.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{"):
        return False, ""
    if b'"frames"' in data and any(m in data for m in _MARKERS):
        return True, ""
    return False, ""


def read(
    path: str | os.PathLike[str],
    data: bytes,
    fps: float | None,
    *,
    body: BodyChoice = "first",
    **options: Any,
) -> Recording:
    """The file as a ``Recording``: the chosen body's 32 joints laid out as Kinect v1
    (``(T, 20, 3)`` metres, ``skeleton="azure_kinect"``), times from ``timestamp_usec``."""
    positions, valid, times = parse_azure(path, data, body, timed=fps is None)
    kinect = skeletons.to_kinect_v1(positions, SKELETON)
    if times is None:
        source = f"assumed {KINECT_FPS:g} fps"
    else:
        source = "file (timestamp_usec)"
    return timed_recording(
        path, "azure_kinect", kinect, valid, times, source, fps, KINECT_FPS, skeleton=SKELETON
    )


FORMAT = Format(
    name="azure_kinect",
    description="Azure Kinect Body Tracking JSON (offline_processor: 32 joints, mm; body= picks "
    "the body)",
    suffixes=(),  # ".json" names other formats too: recognised by content only
    sniff=sniff,
    read=read,
    first_line=("a JSON object of body-tracking frames (Azure Kinect)", ""),
)
