"""Read a recorded skeleton file -> ``Recording`` with ``(T, 20, 3)`` positions in SDK joint order.

``read_skeleton(path, format="auto", fps=None, *, bvh_map=, scale=, up=, body=, skeleton=,
units=)`` (``jaxproj.read``)
dispatches through the format registry (``jaxproj.io.formats.FORMATS``; one module per format):

- ``"msr"``: MSR Action3D real-world text (``aXX_sYY_eZZ_skeleton3D.txt``): 4 whitespace-separated
  columns ``x y z confidence`` per row, 20 rows per frame, joints in the MSR order (converted to the
  SDK order with ``MSR_TO_SDK``); the confidence column is not kept (``formats.msr``).
- ``"utkinect"``: UTKinect-Action3D ``joints_sXX_eYY.txt``: one line per frame, the frame number
  then 60 values (20 joints x ``x y z``, SDK order); a repeated frame number keeps its first line;
  frames are ordered by frame number (``formats.utkinect``).
- ``"npz"``: a NumPy archive with key ``positions`` (or ``joints``) ``(T, J, 3)`` (metres) of any
  registered skeleton, named by an optional ``skeleton`` key or by ``J`` (20 Kinect v1, 22
  SMPL-X body, 24 SMPL, 25 Kinect v2, 32 Azure Kinect, 33 MediaPipe Pose, the ``smplx``
  package's longer arrays), laid out as Kinect v1; ``read_skeleton(..., up="z")`` turns z-up
  data (AMASS) into y up. An optional ``valid`` ``(T,)`` bool mask (and MediaPipe
  ``visibility``) is honoured, and optional timing: ``times`` ``(T,)`` seconds (strictly
  increasing) or ``fps`` (a scalar) (``formats.table``).
- ``"npy"``: a NumPy ``.npy`` ``(T, J, 3)`` joint array alone (HumanML3D's ``new_joints``),
  read as an NPZ holding it as ``joints`` (``formats.table``).
- ``"csv"``: comma-separated, 60 numeric columns per row (``x, y, z`` per joint, SDK order); one
  header line of non-numeric column names is allowed and skipped (``formats.table``).
- ``"bvh"``: BVH motion capture (CMU, LAFAN1, Xsens exports...): the hierarchy's forward
  kinematics, mapped to the 20 Kinect joints by a joint map, in metres (``formats.bvh``;
  ``read_skeleton(..., bvh_map=, scale=)``).
- ``"ntu"``: NTU RGB+D ``.skeleton`` text (Kinect v2, 25 joints, camera space metres): the
  frame count, then per frame the body count and per body a body line, the joint count and 25
  joint lines; one body (``read_skeleton(..., body=)``) laid out as Kinect v1, a frame invalid
  where it lacks the body or a joint Kinect v1 reads is not tracked; detected by ``.skeleton``
  or its first lines (``formats.ntu``).
- ``"azure_kinect"``: Azure Kinect Body Tracking JSON (the SDK samples' ``offline_processor``:
  ``frames`` of ``bodies`` with 32 ``joint_positions`` in millimetres): one body (``body=``) in
  metres and Kinect axes, laid out as Kinect v1, a frame invalid where it lacks the body or a
  joint Kinect v1 reads has confidence 0 (``confidence_levels``, when present); detected by
  content only (``formats.azure_kinect``).
- ``"mediapipe"``: MediaPipe Pose world landmarks as JSON (frames of 33 ``{x, y, z,
  visibility}`` objects; TensorFlow.js ``keypoints3D``, the JavaScript solution's
  ``poseWorldLandmarks``, Pose Landmarker results) or CSV (one row per frame under a
  ``nose_x,...`` / ``x0,y0,...`` / ``x1,y1,...`` header, or one row per landmark), turned
  from MediaPipe's y-down axes into Kinect's, completed and laid out as Kinect v1; a checked
  landmark's visibility below 0.5 makes its frame invalid (``formats.mediapipe``).
- ``"auto"`` (default): detected (``jaxproj.io.formats.detect``): by the file name's suffix
  (``.npz`` / ``.csv`` / ``.bvh``) and the content (a zip signature; a first non-blank line of 4
  (MSR Action3D) or 61 (UTKinect) numbers, of 60 comma-separated fields, or ``HIERARCHY``; a
  MediaPipe JSON landmark object with ``x``, ``y``, ``z`` or a ``nose_x,...`` header). A file
  that is none of these is an ``InputError`` that says so and lists the formats.

Time axis (``Recording.times``, ``time_source``) and its bounds: ``jaxproj.io.recording``
(UTKinect: frame numbers at ``UTK_FPS``; MSR: assumed ``MSR_FPS`` = 15 fps; CSV and NPZ without
timing: assumed 30 fps; BVH: its ``Frame Time``; MediaPipe: a JSON's ``fps``, a CSV's ``frame``
column at 30 fps, else assumed 30 fps; ``fps=`` overrides, or resamples a BVH).
NTU RGB+D files carry no timing (assumed 30 fps, the Kinect v2's rate); Azure Kinect times
come from ``timestamp_usec``.

Units and skeleton (``jaxproj.io.plausible``): the table formats (NPZ, NPY, CSV) state neither
their units nor, named by the joint count alone, their skeleton; the bones' lengths decide the
units (metres, centimetres or millimetres, converted with a note; else an error asking for
``units=``), and a skeleton guessed from the joint count must have a person's proportions.
``Recording.notes`` say what was assumed (a frame rate, units, a guessed skeleton).

Every problem with the file raises ``jaxproj.errors.InputError`` with a one-line message naming
the file, the problem and, where local, the 1-based line (text) or 0-based frame (npz).
Non-finite values and all-zero frames (skeleton lost) are *not* errors: the frame is kept, marked
``False`` in ``Recording.valid`` and its positions are set to 0. Windows line endings, a UTF-8
byte-order mark, blank lines and trailing whitespace are accepted.

``recording_format(path)`` says whether a file in a folder is a recording at all (used by
``jaxproj.io.folders.load_folder`` to skip documentation, label files and the like); it is the
same detection, which there does not trust the suffix alone.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path

from jaxproj.errors import ConfigError, InputError
from jaxproj.io import plausible
from jaxproj.io.formats import describe_formats, detect, format_names, get_format
from jaxproj.io.formats import recording_format as recording_format
from jaxproj.io.formats.bodies import BodyChoice, body_index
from jaxproj.io.formats.msr import MSR_TO_SDK as MSR_TO_SDK
from jaxproj.io.formats.table import check_up
from jaxproj.io.recording import FPS_RANGE as FPS_RANGE
from jaxproj.io.recording import KINECT_FPS as KINECT_FPS
from jaxproj.io.recording import MAX_DURATION_S as MAX_DURATION_S
from jaxproj.io.recording import MAX_RESAMPLED_FRAMES as MAX_RESAMPLED_FRAMES
from jaxproj.io.recording import MIN_STEP_S as MIN_STEP_S
from jaxproj.io.recording import MSR_FPS as MSR_FPS
from jaxproj.io.recording import UTK_FPS as UTK_FPS
from jaxproj.io.recording import Recording, check_fps
from jaxproj.io.recording import resample as resample
from jaxproj.io.text import Head, decode, read_bytes

HIPS = ("required", "shoulders")
"""``read_skeleton(hips=)``: what a MediaPipe frame whose hips are hidden becomes."""


def read_skeleton(
    path: str | os.PathLike[str],
    format: str = "auto",
    fps: float | None = None,
    *,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
    scale: float | str = "auto",
    up: str = "y",
    body: BodyChoice = "first",
    rest_frame: str = "drop",
    skeleton: str | None = None,
    units: str = "auto",
    hips: str = "required",
) -> Recording:
    """Read a skeleton file into a ``Recording`` (``(T, 20, 3)`` float32 positions, SDK order).

    Args:
      path: the file.
      format: ``"auto"`` (detect; see the module docstring) or a registered format's name
        (``jaxproj.io.formats.format_names()``: ``"msr"``, ``"utkinect"``, ``"npz"``, ``"csv"``,
        ``"bvh"``).
      fps: frames per second; when given, ``times = arange(T) / fps`` replaces whatever timing
        the file has or the format assumes. A BVH states its own rate (``Frame Time``): there
        ``fps`` resamples the clip to ``fps`` frames per second (``resample``).
      bvh_map: BVH only: the joint map, ``"auto"`` (detect a preset), ``"cmu"``, ``"cmu-mb"``,
        ``"lafan1"``, ``"mixamo"``,
        a JSON / TOML file or a dict of Kinect joint -> BVH joint (``jaxproj.io.formats.bvh``).
      scale: BVH only: metres per file unit, a unit name (``jaxproj.io.formats.bvh.UNITS``) or
        ``"auto"``.
      rest_frame: BVH only: ``"drop"`` (default) leaves out a first frame that is a converter's
        synthetic rest pose (every joint rotation 0: ``bvh.rest_pose_first``), ``"keep"``
        reads it.
      up: NPZ only: the axis that points up in the file, ``"y"`` (SMPL's own frame, the Kinect
        camera's; kept as it is) or ``"z"`` (AMASS, most mocap: turned -90 degrees about x,
        ``(x, y, z) -> (x, z, -y)``). The descriptor is the same either way (it is read in the
        body's own frame); positions and videos differ. MediaPipe landmarks have their own axes
        (``"z"`` is refused for an NPZ of them; the JSON / CSV reader ignores ``up``).
      body: NTU RGB+D and Azure Kinect only (files of several bodies per frame): ``"first"`` or
        a 0-based index into each frame's bodies; a frame without it is invalid
        (``jaxproj.io.formats.bodies``).
      skeleton: NPZ / NPY: the registered skeleton the joints are (``jaxproj.human.skeletons``
        names); it wins over the file's ``skeleton`` key and the joint count. Another format
        records one skeleton: naming another is a ``ConfigError``.
      units: NPZ / NPY / CSV: the positions' unit, ``"auto"`` (read from the bones' lengths,
        ``jaxproj.io.plausible``), ``"m"``, ``"cm"`` or ``"mm"``.
      hips: MediaPipe (JSON, CSV, NPZ): ``"required"`` (a frame whose hips have a low visibility is
        invalid) or ``"shoulders"`` (its hips are made from the shoulders and the capture's up,
        ``jaxproj.human.upper_body``, and it stays valid: for a robot that reads no leg bone;
        ``jaxproj retarget`` chooses so for such a robot). Other formats ignore it.

    Returns:
      ``Recording`` with ``positions`` ``(T, 20, 3)`` float32 metres and ``valid`` ``(T,)``
      bool; ``notes`` say what was assumed or changed (a rate the file does not give, units
      converted, a skeleton guessed from the joint count).

    Raises:
      InputError: missing / empty / malformed file, unknown format, or a file of no known format;
        the message names the file and the problem.
      ConfigError: ``fps`` out of range, a bad BVH ``scale`` or map dict, a bad ``body``, ``up``
        neither ``"y"`` nor ``"z"`` (or ``"z"`` for an NPZ of MediaPipe landmarks), an unknown
        ``skeleton`` (or one the format does not record), a bad ``units`` (or one for a format
        that states its own).
    """
    names = format_names()
    if format != "auto" and format not in names:
        expected = ", ".join(("auto", *names))
        raise InputError(path, f"unknown format {format!r}; expected one of {expected}")
    if fps is not None:
        check_fps(fps)
    body_index(body)
    check_up(up)
    plausible.check_units(units)
    if hips not in HIPS:
        raise ConfigError(f"hips must be one of {', '.join(HIPS)}, got {hips!r}")
    data = read_bytes(path)
    if format == "auto":
        format = _detect_file(path, data)
    rec = get_format(format).read(
        path, data, fps, bvh_map=bvh_map, scale=scale, body=body, up=up, rest_frame=rest_frame,
        skeleton=skeleton, hips=hips,
    )  # fmt: skip
    if skeleton is not None and rec.skeleton != skeleton:
        raise ConfigError(
            f"skeleton={skeleton!r}: a {rec.format} file records {rec.skeleton} joints "
            "(skeleton= names the joints of an npz / npy array)"
        )
    rec = plausible.check(rec, units)
    if rec.time_source.startswith("assumed"):
        rate = rec.time_source.removeprefix("assumed ")
        note = f"the file gives no frame times: {rate} assumed (--fps says the rate)"
        rec = dataclasses.replace(rec, notes=(*rec.notes, note))
    return rec


def _detect_file(path: str | os.PathLike[str], data: bytes) -> str:
    """The format of a file named on its own (``InputError`` when it is none)."""
    head = Head(Path(path), data, complete=True)
    name, why = detect(head, trust_suffix=True)
    if name is not None:
        return name
    decode(path, data)  # binary or blank: the text readers' own message (byte, offset)
    raise InputError(
        path,
        f"cannot detect the format: {why}; it is no recording of any known format "
        f"({describe_formats()})",
    )
