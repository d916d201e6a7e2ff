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

Accepted files: what MediaPipe's own APIs give, saved as JSON or CSV (MediaPipe defines no file
format; these are the layouts people write), recognised by content (``sniff``). Only world
landmarks are read. Image landmarks (``poseLandmarks``, TensorFlow.js ``keypoints``, Python
``pose_landmarks``: x and y normalised to the image or in pixels) have no metric depth and carry
the image's aspect ratio: they are refused by their key (JSON) or by their values
(``check_world``: every x and y at least 0 and the hips' centre away from the origin; world
landmarks have their origin between the hips, so one hip has a negative x and the head a
negative y).

- **JSON** (``parse_json``): a list of frames, or an object ``{"frames": [...], "fps": 30}``
  (``fps`` optional), or one result object alone (one frame). A frame holds one pose or none
  (no detection: ``[]``, ``null``, or a result object with an empty list; kept, invalid; a file
  of such frames only is an error). A pose is

  - a list of the 33 landmarks in MediaPipe's order, each an object ``{"x", "y", "z",
    "visibility", "presence"}`` (``visibility`` and ``presence`` optional; other keys, such as
    TensorFlow.js's ``name``, ignored: the order says which landmark it is);
  - or an object holding such a list under one of these keys (the first found is read, other
    keys ignored):

    * ``keypoints3D``: TensorFlow.js ``@tensorflow-models/pose-detection`` with BlazePose, a pose
      ``{score, keypoints, keypoints3D}`` of ``detector.estimatePoses(...)``, each keypoint
      ``{x, y, z, score, name}``; ``score`` is read as the visibility. Sources:
      tensorflow/tfjs-models ``pose-detection/README.md`` ("keypoints3D ... absolute distance in
      meters ... the coordinate for the hip center is (0, 0, 0)") and
      ``pose-detection/src/blazepose_mediapipe/detector.ts`` (``keypoints3D`` are the MediaPipe
      solution's ``poseWorldLandmarks``, ``score: landmark.visibility``);
    * ``poseWorldLandmarks``: the MediaPipe JavaScript Pose solution (``@mediapipe/pose``, the
      ``results`` of ``pose.onResults``); the ``poseLandmarks`` beside it are image coordinates
      and are not read;
    * ``worldLandmarks``: the Tasks API's ``PoseLandmarkerResult`` in JavaScript
      (``@mediapipe/tasks-vision``, ``detect`` / ``detectForVideo``), a list of poses, each 33
      ``{x, y, z, visibility}`` (google-ai-edge/mediapipe
      ``mediapipe/tasks/web/vision/pose_landmarker/pose_landmarker_result.d.ts``,
      ``mediapipe/tasks/web/components/containers/landmark.d.ts``);
    * ``pose_world_landmarks``: the same result in Python
      (``mediapipe/tasks/python/vision/pose_landmarker.py``, e.g. saved with
      ``dataclasses.asdict``);
    * ``landmarks``: our own wrapper of 33 world landmarks (a list of poses there is a
      ``PoseLandmarkerResult``'s image landmarks: refused);

  - or a list of such poses (``estimatePoses``' return value; a result's per-pose list): its one
    pose. Several poses in one frame (several people) are an error.

  A frame object with none of these keys (JavaScript's ``JSON.stringify`` leaves undefined
  results out: ``{}``) is a frame without detection, where other frames have landmarks; when
  none has, the file is an error naming the keys looked for.

  ``null`` coordinates (and Python's ``NaN``) are missing values: the frame is invalid.
  Recognised by a first ``{...}`` object (with no nested object or list) that has keys ``x``,
  ``y`` and ``z``, or by a key ``"keypoints3D"``, ``"poseWorldLandmarks"``,
  ``"worldLandmarks"`` or ``"pose_world_landmarks"`` in the file's first 64 KiB. A JSON of 2D
  keypoints only (MoveNet, PoseNet) is not recognised, and the reason says so.
- **CSV** (``parse_csv``): one header line, then data rows of as many fields as the header.
  Names are case-insensitive, spaces and double quotes around them ignored; an empty field or
  ``nan`` is a missing value. Two styles, told apart by the header:

  - *one row per frame* ("wide"): every landmark's ``x``, ``y``, ``z`` (99 columns), and its
    ``visibility`` (``v``, ``vis``) for all 33 landmarks or none (``presence`` columns are
    ignored), in any order, named ``<landmark>_<field>`` (``nose_x``, ...,
    ``right_foot_index_visibility``) or by number: ``x0``, ``x_0``, ``0_x``, ``landmark_0_x``,
    ``lm_0_x`` and the like, numbered 0-32 or 1-33
    (the widely copied MediaPipe "body language decoder" notebooks write
    ``class,x1,y1,z1,v1,...,x33,y33,z33,v33``); the numbers present say which (other ranges,
    e.g. 21 hand or 501 holistic landmarks, are an error). One frame column (``frame``,
    ``frame_id``, ``frame_index``, ``frame_idx``, ``frame_number``, ``frame_num``,
    ``frame_no``) may give frame numbers (integers, increasing). Other columns (``class``,
    ``label``, ``filename``, ``timestamp``, pandas' unnamed index) are ignored, except one named
    after a landmark with an unknown field (``left_eye_w``: an error). A row of missing values is
    a frame with no detection (kept, invalid). Recognised by ``nose_x``, ``nose_y``, ``nose_z``
    among the header's fields, or by 33 or more fields named as landmark columns.
  - *one row per landmark* ("long"): columns ``x``, ``y``, ``z``, optional ``visibility``
    (``v``, ``vis``; ``presence`` ignored), a frame column (as above) and a landmark column
    (``landmark``, ``landmark_id``, ``landmark_index``, ``landmark_idx``, ``landmark_name``,
    ``id``, ``index``, ``idx``, ``name``) holding the landmark's number (0-32, or 1-33 when the
    numbers in the file are 1-33) or name (``NOSE``, ``left_shoulder``,
    ``PoseLandmark.LEFT_SHOULDER``); other columns ignored. Rows are grouped by frame, frames in
    increasing order, and every frame lists each of the 33 landmarks once, in any order; a frame
    with no detection has no rows (a gap in the frame numbers). What a ``csv.writer`` loop over
    ``enumerate(results.pose_world_landmarks.landmark)`` under a header
    ``frame,landmark,x,y,z,visibility`` writes, or a pandas ``DataFrame`` of
    ``frame,landmark_id,x,y,z,visibility`` rows. Recognised by ``x``, ``y``, ``z`` and a
    landmark column among the header's fields.

  A CSV without a header whose first line is 99, 100, 132, 133, 165 or 166 numbers (33
  landmarks of 3, 4 or 5 values, a frame number first or not) is recognised and refused: the
  order of the values (x, y, z, visibility per landmark, or all x first?) is written nowhere, and
  a guess would make a wrong motion without a word; the error gives the header line to add.

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
always gives 0 (google-ai-edge/mediapipe issues #1790, #4411). Why frames are invalid is told
in ``Recording.invalid_reason`` (``invalid_reason``): the checked landmarks whose visibility was
below the threshold, in how many frames and their range there ("visibility below 0.5 in 130 of
the file's 130 frames, of left_hip (130 frames, 0.26-0.34), right_hip (130 frames,
0.27-0.33)"), and the frames without a pose or with missing coordinates; ``jaxproj retarget``
quotes it when no frame, or few, are valid.

Time: the JSON object's ``fps``, the CSV's frame column at 30 frames/s, else frames are
assumed ``KINECT_FPS`` (30, a webcam's usual rate) apart; ``read_skeleton(fps=)`` overrides.
Every problem is an ``InputError`` naming the file and the 1-based line (CSV, JSON syntax) or the
0-based frame and the landmark (JSON values).

Size: one module for the format: the JSON and CSV layouts people save (each needs its own
parsing and its own one-line errors) share the axes, the layout and the visibility rules.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human import skeletons, upper_body
from jaxproj.human.layouts import MEDIAPIPE_POSE
from jaxproj.io.formats.base import Format
from jaxproj.io.recording import FPS_RANGE, KINECT_FPS, Recording, timed_recording
from jaxproj.io.text import Head, check_counts, decode, is_number

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
_HIPS = [LANDMARKS.index("left_hip"), LANDMARKS.index("right_hip")]


def landmark_index(name: str) -> int | None:
    """The number of a landmark named ``name`` (``"left_hip"``, ``"LEFT_HIP"``,
    ``"PoseLandmark.LEFT_HIP"``), or ``None``."""
    key = name.strip().strip('"').strip().lower()
    key = key.removeprefix("poselandmark.")
    return _INDEX.get(key)


_INDEX = {name: i for i, name in enumerate(LANDMARKS)}


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


def _low_visibility(visibility: np.ndarray) -> np.ndarray:
    """``(T, 33)`` scores -> ``(T, len(CHECKED_LANDMARKS))`` bool: known and below the threshold."""
    vis = visibility[:, _CHECKED]
    return np.isfinite(vis) & (vis < VISIBILITY_THRESHOLD)


def visibility_valid(
    path: str | os.PathLike[str], visibility: np.ndarray | None, line_numbers: np.ndarray | None
) -> np.ndarray | None:
    """``(T, 33)`` visibility -> ``(T,)`` bool: no checked landmark below the threshold.

    Missing (NaN) values are not checked; a table of zeros only is taken as no visibility.

    Args:
      path: the file (named in errors).
      visibility: ``(T, 33)`` scores, NaN where missing, or ``None``.
      line_numbers: 1-based line of each frame ``(T,)`` or of each landmark ``(T, 33)`` (CSV)
        for errors, or ``None``: errors name the 0-based frame.

    Returns:
      ``(T,)`` bool, or ``None`` when the file carries no visibility.

    Raises:
      InputError: a visibility outside [0, 1] (names the frame or line and the landmark).
    """
    vis = _visibility(path, visibility, line_numbers)
    if vis is None:
        return None
    return np.asarray(~_low_visibility(vis).any(axis=1))


def _visibility(
    path: str | os.PathLike[str], visibility: np.ndarray | None, line_numbers: np.ndarray | None
) -> np.ndarray | None:
    """The checked ``(T, 33)`` float64 visibility, or ``None`` (none, or zeros only)."""
    if visibility is None:
        return None
    vis = np.asarray(visibility, np.float64)
    known = np.isfinite(vis)
    bad = np.argwhere((known & ((vis < 0.0) | (vis > 1.0))) | np.isinf(vis))
    if bad.size:
        t, j = (int(i) for i in bad[0])
        where = ""
        if line_numbers is not None:
            lines = np.asarray(line_numbers)
            where = f"line {lines[t, j] if lines.ndim == 2 else lines[t]}: "
        raise InputError(
            path,
            f"{where}visibility of {LANDMARKS[j]!r} is {vis[t, j]:g}, not a probability in "
            "[0, 1] (a sigmoid's argument needs the sigmoid first)",
            None if line_numbers is not None else t,
        )
    if known.any() and not vis[known].any():
        return None  # every score exactly 0: unset fields, no visibility at all
    return vis


def invalid_reason(landmarks: np.ndarray, visibility: np.ndarray | None) -> str | None:
    """Why frames are invalid, in words (``Recording.invalid_reason``), or ``None`` (all valid).

    Args:
      landmarks: ``(T, 33, 3)`` world landmarks, NaN where missing.
      visibility: ``(T, 33)`` checked scores (``visibility_valid``'s), or ``None``.

    Returns:
      e.g. ``"visibility below 0.5 in 130 of the file's 130 frames, of left_hip (130 frames,
      0.26-0.34), right_hip (130 frames, 0.27-0.33)"``, then ``"; no pose detected in 4
      frames"`` and ``"; missing or non-finite coordinates in 2 frames"`` where there are such.
    """
    t = len(landmarks)
    parts = []
    if visibility is not None:
        vis = np.asarray(visibility, np.float64)[:, _CHECKED]
        low = _low_visibility(np.asarray(visibility, np.float64))
        n_low = int(low.any(axis=1).sum())
        if n_low:
            counts = low.sum(axis=0)
            order = sorted(np.flatnonzero(counts), key=lambda c: -counts[c])
            items = []
            for c in order[:4]:
                v = vis[low[:, c], c]
                lo, hi = float(v.min()), float(v.max())
                span = f"{lo:.2f}" if f"{lo:.2f}" == f"{hi:.2f}" else f"{lo:.2f}-{hi:.2f}"
                items.append(f"{CHECKED_LANDMARKS[c]} ({_frames(int(counts[c]))}, {span})")
            if len(order) > 4:
                items.append(f"{len(order) - 4} more")
            parts.append(
                f"visibility below {VISIBILITY_THRESHOLD:g} in {n_low} of the file's {t} frames, "
                f"of {', '.join(items)}"
            )
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(to_kinect_v1(landmarks)).all(axis=(1, 2))
    empty = ~np.isfinite(landmarks).any(axis=(1, 2))
    if empty.any():
        parts.append(f"no pose detected in {_frames(int(empty.sum()))}")
    if (~finite & ~empty).any():
        parts.append(
            f"missing or non-finite coordinates in {_frames(int((~finite & ~empty).sum()))}"
        )
    return "; ".join(parts) or None


def _frames(n: int) -> str:
    return f"{n} frame" if n == 1 else f"{n} frames"


def to_kinect_v1(landmarks: np.ndarray) -> np.ndarray:
    """``(T, 33, 3)`` world landmarks as MediaPipe gives them -> ``(T, 20, 3)`` float32 Kinect v1
    positions in Kinect camera axes (``world_to_camera``, ``complete``, ``to_kinect_v1``)."""
    with np.errstate(over="ignore", invalid="ignore"):
        full = MEDIAPIPE_POSE.complete(world_to_camera(landmarks))
        return skeletons.to_kinect_v1(full, MEDIAPIPE_POSE)


def check_world(path: str | os.PathLike[str], landmarks: np.ndarray) -> None:
    """``InputError`` when ``(T, 33, 3)`` landmarks look like image landmarks, not world ones.

    World landmarks have their origin between the hips: the hips' x have opposite signs and the
    head's y is negative (y down). Image landmarks (normalised to [0, 1], or pixels) have every
    x and y at least 0 and the hips' centre far from the origin. Both must hold to refuse.
    """
    xy = landmarks[..., :2]
    known = np.isfinite(xy)
    if not known.any() or (xy[known] < 0.0).any():
        return
    hips = landmarks[:, _HIPS, :2]
    hips = hips[np.isfinite(hips).all(axis=(1, 2))]
    if not len(hips):
        return
    centre = np.median(hips.mean(axis=1), axis=0)
    if np.hypot(*centre) <= 0.1:
        return
    kind = "normalised to the image" if xy[known].max() <= 1.0 else "in pixels"
    raise InputError(
        path,
        f"these look like image landmarks ({kind}: no x or y below 0, the hips' centre at "
        f"({centre[0]:.2f}, {centre[1]:.2f})), not world landmarks (metres, the origin between "
        "the hips): save pose_world_landmarks (Python), poseWorldLandmarks / worldLandmarks "
        "(JavaScript) or keypoints3D (TensorFlow.js)",
    )


# --- JSON --------------------------------------------------------------------------------------

_FLAT_OBJECT = re.compile(r"\{[^{}\[\]]*\}")

WORLD_KEYS: dict[str, str] = {
    "keypoints3D": "score",
    "poseWorldLandmarks": "visibility",
    "worldLandmarks": "visibility",
    "pose_world_landmarks": "visibility",
    "landmarks": "visibility",
}
"""Keys of a JSON pose object that hold its world landmarks, in the order they are looked for
(TensorFlow.js, the JavaScript Pose solution, the Tasks API in JavaScript and Python, ours),
and the key of a landmark's visibility there (``visibility`` is read first wherever present)."""
_IMAGE_KEYS = {
    "poseLandmarks": "poseWorldLandmarks",
    "keypoints": "keypoints3D",
    "pose_landmarks": "pose_world_landmarks",
}
"""Keys of image landmarks -> the key of the world landmarks the same API gives."""
_SNIFF_KEYS = re.compile(
    r'"(?:keypoints3D|poseWorldLandmarks|worldLandmarks|pose_world_landmarks)"\s*:'
)


def _number(path: str | os.PathLike[str], value: Any, what: str, frame: int) -> float:
    """A JSON coordinate or score: a number, ``null`` (NaN) or NaN."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(path, f"{what} is {json.dumps(value)[:40]}, not a number", frame)
    return float(value)


def _one_pose(path: str | os.PathLike[str], poses: list[Any], t: int) -> Any:
    """The one pose of a frame's list of poses."""
    if len(poses) > 1:
        raise InputError(
            path,
            f"several poses ({len(poses)}) in one frame (several people?): give one pose, "
            f"{N_LANDMARKS} landmarks, per frame",
            t,
        )
    return poses[0]


def _frame_pose(path: str | os.PathLike[str], frame: Any, t: int) -> tuple[Any, str]:
    """A JSON frame -> (its pose's landmarks: a list, or ``None`` / ``[]`` for no detection;
    the key of a landmark's visibility score, ``""`` for an object without landmark keys)."""
    if isinstance(frame, list) and frame and isinstance(frame[0], dict) and "x" not in frame[0]:
        frame = _one_pose(path, frame, t)  # a list of pose objects (estimatePoses)
    score = "visibility"
    if isinstance(frame, dict):
        key = next((k for k in WORLD_KEYS if k in frame), None)
        if key is None:
            image = next((k for k in _IMAGE_KEYS if k in frame), None)
            if image is not None:
                raise InputError(
                    path,
                    f"the frame has {image!r} (image coordinates) but no "
                    f"{_IMAGE_KEYS[image]!r} (world landmarks, metres): save those",
                    t,
                )
            return None, ""  # no landmarks: no detection, where other frames have some
        score, frame = WORLD_KEYS[key], frame[key]
        if key == "landmarks" and isinstance(frame, list) and frame and isinstance(frame[0], list):
            raise InputError(
                path,
                "'landmarks' holds a list per pose: a PoseLandmarkerResult's landmarks, image "
                "coordinates; save its worldLandmarks (metres)",
                t,
            )
    if isinstance(frame, list) and frame and isinstance(frame[0], list):
        frame = _one_pose(path, frame, t)  # a list of poses (PoseLandmarkerResult)
    return frame, score


def parse_json(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, float | None]:
    """JSON bytes -> (``(T, 33, 3)`` float64 world landmarks, MediaPipe axes, NaN where missing;
    ``(T, 33)`` visibility, NaN where missing, or ``None``; the file's ``fps`` or ``None``).

    Raises:
      InputError: invalid JSON (line, column), not a layout above, no frames, image landmarks
        only, several poses in a frame, a frame of another landmark count, a landmark without
        ``x`` / ``y`` / ``z`` or with a value that is no number, a bad ``fps``.
    """
    try:
        doc = json.loads(decode(path, data))
    except json.JSONDecodeError as err:
        raise InputError(
            path, f"line {err.lineno}, column {err.colno}: not valid JSON ({err.msg})"
        ) from None
    fps = None
    if isinstance(doc, dict) and "frames" not in doc and any(k in doc for k in WORLD_KEYS):
        doc = [doc]  # one result object: one frame
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
    keyless = None  # the first frame object without landmark keys
    for t, raw in enumerate(frames):
        frame, score = _frame_pose(path, raw, t)
        if not score and keyless is None:
            keyless = t
        if frame is None or frame == []:
            continue  # no detection: an invalid frame
        if not isinstance(frame, list):
            raise InputError(
                path, f"a frame must be a list of landmarks, got {type(frame).__name__}", t
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
            key = "visibility" if "visibility" in lm else score
            if key in lm:
                vis[t, j] = _number(path, lm[key], f"{name} {key}", t)
    if keyless is not None and not np.isfinite(xyz).any():  # no frame has landmark keys
        keys = ", ".join(map(repr, WORLD_KEYS))
        found = ", ".join(frames[keyless]) or "none"
        raise InputError(
            path, f"a frame object needs one of the keys {keys} (keys found: {found})", keyless
        )
    return xyz, (vis if np.isfinite(vis).any() else None), fps


def _sniff_json(head: Head) -> tuple[bool, str]:
    text = head.data[:65536].decode("utf-8-sig", errors="replace")
    if _SNIFF_KEYS.search(text):
        return True, ""
    match = _FLAT_OBJECT.search(text)
    obj = None
    if match is not None:
        try:
            obj = json.loads(match.group(0))
        except json.JSONDecodeError:
            obj = None
        if isinstance(obj, dict) and {"x", "y", "z"} <= obj.keys():
            return True, ""
    if isinstance(obj, dict) and {"x", "y"} <= obj.keys() and '"keypoints"' in text:
        return False, (
            "JSON of 2D keypoints without keypoints3D (MoveNet or PoseNet, or BlazePose's "
            "image keypoints): MediaPipe needs BlazePose's keypoints3D (metres)"
        )
    if head.suffix == ".json":
        return False, (
            'JSON without MediaPipe landmark objects ({"x", "y", "z", ...}) or a keypoints3D / '
            "poseWorldLandmarks / worldLandmarks key"
        )
    return False, ""


# --- CSV ---------------------------------------------------------------------------------------

FRAME_COLUMNS = (
    "frame", "frame_id", "frame_index", "frame_idx", "frame_number", "frame_num", "frame_no",
)  # fmt: skip
"""Names of a CSV's frame-number column."""
LANDMARK_COLUMNS = (
    "landmark", "landmark_id", "landmark_index", "landmark_idx", "landmark_name", "id", "index",
    "idx", "name",
)  # fmt: skip
"""Names of the landmark column of a CSV of one row per landmark."""
_FIELD = {"x": "x", "y": "y", "z": "z", "v": "visibility", "vis": "visibility",
          "visibility": "visibility", "presence": "presence"}  # fmt: skip
_F = "|".join(sorted(_FIELD, key=len, reverse=True))
_NUMBERED = (
    re.compile(rf"^(?:(?:landmark|lm|keypoint|kp|point|joint)_?)?(\d+)_({_F})$"),
    re.compile(rf"^({_F})_?(\d+)$"),
)
HEADERLESS_COLUMNS = (99, 100, 132, 133, 165, 166)
"""Counts of numbers on a first CSV line that say "MediaPipe Pose without a header" (refused)."""


def _name(field: str) -> str:
    return field.strip().strip('"').strip().lower()


def _column(name: str) -> tuple[str, int, str] | None:
    """A wide CSV's landmark column name -> ``("named" | "numbered", landmark, field)``."""
    base, _, field = name.rpartition("_")
    if base in _INDEX and field in _FIELD:
        return "named", _INDEX[base], _FIELD[field]
    for i, pattern in enumerate(_NUMBERED):
        m = pattern.match(name)
        if m:
            number, field = (m.group(1), m.group(2)) if i == 0 else (m.group(2), m.group(1))
            return "numbered", int(number), _FIELD[field]
    return None


def _numbers(
    path: str | os.PathLike[str], rows: list[list[str]], lines: np.ndarray, columns: list[int]
) -> np.ndarray:
    """``(len(rows), len(columns))`` float64 of the given columns (an empty field: NaN)."""
    tokens = [r[c].strip() or "nan" for r in rows for c in columns]
    try:
        flat = np.array(tokens, dtype=np.float64)
    except ValueError:
        i = next(i for i, tok in enumerate(tokens) if not is_number(tok))
        line, column = lines[i // len(columns)], columns[i % len(columns)] + 1
        raise InputError(
            path, f"line {line}, column {column}: non-numeric token {tokens[i]!r}"
        ) from None
    return flat.reshape(len(rows), len(columns))


def _frame_numbers(path: str | os.PathLike[str], f: np.ndarray, lines: np.ndarray) -> None:
    """``InputError`` unless every frame number is an integer."""
    bad = np.flatnonzero(~np.isfinite(f) | (f != np.round(f)) | (np.abs(f) > 2.0**53))
    if bad.size:
        i = int(bad[0])
        raise InputError(path, f"line {lines[i]}: frame number {f[i]:g} is not an integer")


def _headerless(path: str | os.PathLike[str], line: int, n: int) -> InputError:
    """The error for a first line of numbers: ask for a header, giving one where ``n`` fits."""
    if n not in HEADERLESS_COLUMNS:
        return InputError(
            path,
            f"line {line}: no header line (a MediaPipe CSV starts with one, e.g. "
            "nose_x,nose_y,nose_z,... or frame,landmark,x,y,z,visibility)",
        )
    frame, per = ("frame,", n - 1) if n % 33 else ("", n)
    fields = "xyzvp"[: per // 33]
    example = ",".join(f"{c}{i}" for i in (0, 1) for c in fields)
    last = ",".join(f"{c}32" for c in fields)
    return InputError(
        path,
        f"line {line}: no header line: {n} numbers fit MediaPipe Pose's 33 landmarks of "
        f"{per // 33} values{' after a frame number' if frame else ''}, but their order is "
        f"written nowhere; if they are {', '.join(fields)} per landmark (v visibility, p "
        f"presence), world landmarks, add the header line {frame}{example},...,{last}",
    )


def _wide_columns(
    path: str | os.PathLike[str], line: int, fields: list[str]
) -> tuple[dict[tuple[int, str], int], int | None]:
    """A wide header -> ({(landmark, field): column}, the frame column or ``None``)."""
    found: dict[tuple[int, str], int] = {}
    styles: set[str] = set()
    numbers: dict[tuple[int, str], int] = {}
    frame = None
    for i, raw in enumerate(fields):
        name = _name(raw)
        col = _column(name)
        if col is None:
            if name in FRAME_COLUMNS:
                if frame is not None:
                    raise InputError(path, f"line {line}, column {i + 1}: a second frame column")
                frame = i
            elif name.rpartition("_")[0] in _INDEX:
                raise InputError(
                    path,
                    f"line {line}, column {i + 1}: unknown column {raw.strip()!r} (expected "
                    "<landmark>_x / _y / _z / _visibility / _presence, or frame)",
                )
            continue  # another column (class, label, timestamp, an index): ignored
        style, number, field = col
        styles.add(style)
        target = found if style == "named" else numbers
        if (number, field) in target:
            raise InputError(path, f"line {line}, column {i + 1}: column {name!r} repeats")
        target[(number, field)] = i
    if len(styles) > 1:
        raise InputError(path, f"line {line}: header mixes landmark names and numbers")
    first = 0
    if numbers:
        present = sorted({n for n, _ in numbers})
        first = present[0]
        if present != list(range(first, first + N_LANDMARKS)) or first not in (0, 1):
            raise InputError(
                path,
                f"line {line}: the header numbers {len(present)} landmarks ({present[0]} to "
                f"{present[-1]}); MediaPipe Pose has {N_LANDMARKS}, numbered 0-32 or 1-33",
            )
        found = {(n - first, f): c for (n, f), c in numbers.items()}
    for field, required in (("x", True), ("y", True), ("z", True), ("visibility", False)):
        lacking = [j for j in range(N_LANDMARKS) if (j, field) not in found]
        if lacking and (required or len(lacking) < N_LANDMARKS):
            if numbers:
                shown = ", ".join(str(j + first) for j in lacking[:3])
                what = f"{field} column for landmark(s) {shown}"
            else:
                what = "column " + ", ".join(f"{LANDMARKS[j]}_{field}" for j in lacking[:3])
            more = f" and {len(lacking) - 3} more" if len(lacking) > 3 else ""
            why = "" if field != "z" else " (MediaPipe world landmarks have x, y and z)"
            raise InputError(path, f"line {line}: header has no {what}{more}{why}")
    return found, frame


def _long_ids(path: str | os.PathLike[str], tokens: list[str], lines: np.ndarray) -> np.ndarray:
    """A long CSV's landmark column -> ``(N,)`` landmark numbers 0-32."""
    numeric = [is_number(tok) for tok in tokens]
    values = [float(tok) if num else math.nan for tok, num in zip(tokens, numeric, strict=True)]
    known = [v for v in values if not math.isnan(v)]
    base = 1 if known and min(known) == 1 and max(known) == N_LANDMARKS else 0
    out = np.empty(len(tokens), np.int64)
    for i, (tok, v) in enumerate(zip(tokens, values, strict=True)):
        j = landmark_index(tok) if math.isnan(v) else v - base
        if j is None or j != int(j) or not 0 <= j < N_LANDMARKS:
            raise InputError(
                path,
                f"line {lines[i]}: landmark {tok.strip()!r} is neither a MediaPipe Pose landmark "
                "number (0-32, or 1-33 throughout) nor a name (nose, left_shoulder, ...)",
            )
        out[i] = int(j)
    return out


def _long_columns(path: str | os.PathLike[str], line: int, names: list[str]) -> list[int | None]:
    """A header of one row per landmark -> its columns: frame, landmark, x, y, z, visibility
    (``None``: none)."""
    where = {n: i for i, n in reversed(list(enumerate(names)))}
    if "z" not in where:
        raise InputError(path, f"line {line}: header has no z column (MediaPipe world landmarks "
                               "have x, y and z)")  # fmt: skip
    frame = next((where[n] for n in FRAME_COLUMNS if n in where), None)
    if frame is None:
        raise InputError(
            path,
            f"line {line}: one row per landmark needs a frame column ({', '.join(FRAME_COLUMNS)})",
        )
    mark = next(where[n] for n in LANDMARK_COLUMNS if n in where)
    vis = next((where[n] for n in ("visibility", "vis", "v") if n in where), None)
    return [frame, mark, where["x"], where["y"], where["z"], vis]


def _parse_long(
    path: str | os.PathLike[str],
    columns: list[int | None],
    rows: list[list[str]],
    lines: np.ndarray,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """A CSV of one row per landmark (see ``parse_csv``), its columns from ``_long_columns``."""
    frame, mark, x, y, z, vis_col = columns
    assert frame is not None and mark is not None and x is not None and y is not None
    assert z is not None
    values = _numbers(path, rows, lines, [frame, x, y, z])
    f = values[:, 0]
    _frame_numbers(path, f, lines)
    back = np.flatnonzero(np.diff(f) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise InputError(
            path,
            f"line {lines[i]}: frame number {f[i]:g} after {f[i - 1]:g}: rows must be grouped by "
            "frame, frames in increasing order",
        )
    ids = _long_ids(path, [r[mark] for r in rows], lines)
    new = np.r_[True, np.diff(f) > 0]
    group = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    count = np.zeros((len(starts), N_LANDMARKS), np.int64)
    np.add.at(count, (group, ids), 1)
    twice = np.argwhere(count > 1)
    if twice.size:
        g, j = (int(i) for i in twice[0])
        i = int(np.flatnonzero((group == g) & (ids == j))[1])
        raise InputError(
            path, f"line {lines[i]}: a second row for landmark {LANDMARKS[j]!r} in frame {f[i]:g}"
        )
    absent = np.argwhere(count == 0)
    if absent.size:
        g, j = (int(i) for i in absent[0])
        i = int(starts[g])
        raise InputError(
            path,
            f"line {lines[i]}: frame {f[i]:g} has no row for landmark {j} ({LANDMARKS[j]}): "
            f"every frame lists all {N_LANDMARKS} landmarks",
        )
    xyz = np.full((len(starts), N_LANDMARKS, 3), np.nan)
    xyz[group, ids] = values[:, 1:]
    grid = np.zeros((len(starts), N_LANDMARKS), np.int64)
    grid[group, ids] = lines
    vis = None
    if vis_col is not None:
        vis = np.full((len(starts), N_LANDMARKS), np.nan)
        vis[group, ids] = _numbers(path, rows, lines, [vis_col])[:, 0]
    return xyz, vis, f[starts].astype(np.int64), grid


def parse_csv(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
    """CSV bytes -> (``(T, 33, 3)`` float64 world landmarks, MediaPipe axes; ``(T, 33)``
    visibility or ``None``; ``(T,)`` int64 frame numbers or ``None``; 1-based lines: ``(T,)``
    of each row (one row per frame) or ``(T, 33)`` of each landmark (one row per landmark)).

    Raises:
      InputError: no header (with the header to add where the column count fits), a bad
        header (names the column), no data rows, a row of another column count, a non-numeric
        token, frame numbers that are not increasing integers, a frame without all 33 landmarks
        (one row per landmark).
    """
    rows: list[list[str]] = []
    numbers: list[int] = []
    header: list[str] | None = None
    line = 0
    for i, text in enumerate(decode(path, data).splitlines(), start=1):
        if not text.strip():
            continue
        fields = text.split(",")
        if header is None:
            if any(is_number(f) for f in fields if f.strip()):
                raise _headerless(path, i, len(fields))
            header, line = fields, i
            continue
        rows.append(fields)
        numbers.append(i)
    assert header is not None  # decode refuses a blank file
    names = [_name(f) for f in header]
    long = {"x", "y"} <= set(names) and bool(set(names) & set(LANDMARK_COLUMNS))
    if long:
        long_columns = _long_columns(path, line, names)
    else:
        columns, frame = _wide_columns(path, line, header)
    if not rows:
        raise InputError(path, "file has a header line but no data rows")
    width = len(header)
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    lines = np.array(numbers, dtype=np.int64)
    check_counts(path, counts, lines, width, f"MediaPipe CSV: the header's {width} columns")
    if long:
        return _parse_long(path, long_columns, rows, lines)
    order = [columns[(j, c)] for j in range(N_LANDMARKS) for c in "xyz"]
    xyz = _numbers(path, rows, lines, order).reshape(len(rows), N_LANDMARKS, 3)
    vis = None
    if (0, "visibility") in columns:
        vis_cols = [columns[(j, "visibility")] for j in range(N_LANDMARKS)]
        vis = _numbers(path, rows, lines, vis_cols)
    frames = None
    if frame is not None:
        f = _numbers(path, rows, lines, [frame])[:, 0]
        _frame_numbers(path, f, lines)
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
    fields = line.split(",")
    if all(is_number(f) for f in fields if f.strip()):  # no header: refused by the reader
        return len(fields) in HEADERLESS_COLUMNS, ""
    names = [_name(f) for f in fields]
    if {"x", "y", "z"} <= set(names) and set(names) & set(LANDMARK_COLUMNS):
        return True, ""  # one row per landmark
    if {"nose_x", "nose_y", "nose_z"} <= set(names):
        return True, ""
    return sum(_column(n) is not None for n in names) >= N_LANDMARKS, ""


# --- the format --------------------------------------------------------------------------------


def _is_json(data: bytes) -> bool:
    start = data[:4096].decode("utf-8-sig", errors="replace").lstrip()
    return start[:1] in ("[", "{")


def sniff(head: Head) -> tuple[bool, str]:
    """A JSON of MediaPipe landmark objects or results, or a CSV whose header names landmark
    columns (or whose first line is the numbers of 33 landmarks: refused by the reader)."""
    if _is_json(head.data):
        return _sniff_json(head)
    return _sniff_csv(head)


def read(path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any) -> Recording:
    """The file (JSON or CSV, told apart by a first ``[`` or ``{``) as a ``Recording``
    (``(T, 20, 3)`` Kinect v1 positions, skeleton ``"mediapipe_pose"``, ``invalid_reason``
    saying why frames are invalid). ``options["hips"]``: ``"required"`` (default: a checked
    landmark's low visibility invalidates its frame, the hips' too) or ``"shoulders"`` (frames
    whose hips alone are hidden get hips made from the shoulders, ``hips_from_shoulders``);
    other options are ignored (``up`` does not apply: MediaPipe's axes are fixed)."""
    times, source = None, f"assumed {KINECT_FPS:g} fps"
    if _is_json(data):
        xyz, vis, rate = parse_json(path, data)
        checked = _visibility(path, vis, None)
        if rate is not None:
            times, source = np.arange(len(xyz)) / rate, f"file ({rate:g} fps)"
    else:
        xyz, vis, frames, lines = parse_csv(path, data)
        checked = _visibility(path, vis, lines)
        if frames is not None:
            times = (frames - frames[0]) / KINECT_FPS
            source = f"frame numbers at {KINECT_FPS:g} fps"
    if not np.isfinite(xyz).any():
        raise InputError(
            path, f"no pose detected in any of the {len(xyz)} frames (all empty): nothing to read"
        )
    check_world(path, xyz)
    valid = None if checked is None else np.asarray(~_low_visibility(checked).any(axis=1))
    positions = to_kinect_v1(xyz)
    notes: tuple[str, ...] = ()
    if options.get("hips", "required") == "shoulders" and checked is not None:
        positions, valid, checked, notes = hips_from_shoulders(positions, checked)
    rec = timed_recording(
        path, "mediapipe", positions, valid, times, source, fps, KINECT_FPS, SKELETON
    )
    return dataclasses.replace(rec, invalid_reason=invalid_reason(xyz, checked), notes=notes)


def hips_from_shoulders(
    positions: np.ndarray, checked: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """``read(hips="shoulders")`` (and an NPZ's, ``formats.table``): frames whose only
    low-visibility checked landmarks are the hips get hips made from the shoulders
    (``jaxproj.human.upper_body``) and stay valid.

    Returns:
      (positions, ``(T,)`` valid, the visibility with the made hips' scores set to 1 (so that
      ``invalid_reason`` names only what still invalidates a frame), the notes)."""
    low = _low_visibility(checked)
    hip_cols = [list(CHECKED_LANDMARKS).index(n) for n in ("left_hip", "right_hip")]
    rest = np.ones(low.shape[1], bool)
    rest[hip_cols] = False
    valid = np.asarray(~low[:, rest].any(axis=1), bool)
    hidden = np.asarray(valid & low[:, hip_cols].any(axis=1), bool)
    positions, tilt = upper_body.hips_from_shoulders(positions, hidden, valid & ~hidden)
    checked = checked.copy()
    hips = np.array([LANDMARKS.index("left_hip"), LANDMARKS.index("right_hip")])
    checked[np.ix_(np.flatnonzero(hidden), hips)] = 1.0
    notes: tuple[str, ...] = ()
    if hidden.any():
        seen = int((valid & ~hidden).sum())
        notes = (
            f"hips hidden (visibility below {VISIBILITY_THRESHOLD:g}) in "
            f"{_frames(int(hidden.sum()))}: made from the shoulders and the capture's up, "
            f"the trunk tilted {np.degrees(tilt):.1f} deg as on the {_frames(seen)} that "
            "show them (a robot that reads no leg bone; docs: Input formats, MediaPipe)",
        )
    return positions, valid, checked, notes


FORMAT = Format(
    name="mediapipe",
    description="MediaPipe Pose world landmarks: JSON (frames of 33 {x, y, z, visibility}, "
    "keypoints3D, poseWorldLandmarks, worldLandmarks) or CSV (a row per frame: nose_x,... or "
    "x0,y0,z0,v0,...; a row per landmark: frame,landmark,x,y,z,visibility)",
    suffixes=(),  # ".json" and ".csv" name other formats too: recognised by content only
    sniff=sniff,
    read=read,
    first_line=("a MediaPipe CSV header (nose_x,nose_y,nose_z,... or frame,landmark,x,y,z)", ""),
)
