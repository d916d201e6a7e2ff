"""NTU RGB+D ``.skeleton`` text (Kinect v2, 25 joints), format ``"ntu"``.

The layout (the dataset's own readers, ``shahroudy/NTURGB-D``: ``Matlab/read_skeleton_file.m``
and ``Python/txt2npy.py``), one record per line, whitespace-separated:

- line 1: the number of frames;
- per frame: a line with the number of bodies (0 when nobody was tracked), then per body:

  - one line of 10 values: ``bodyID clipedEdges handLeftConfidence handLeftState
    handRightConfidence handRightState isRestricted leanX leanY trackingState``;
  - a line with the number of joints (25);
  - 25 lines of 12 values, one per joint in Kinect v2 ``JointType`` order (the ``kinect_v2``
    skeleton): ``x y z depthX depthY colorX colorY orientationW orientationX orientationY
    orientationZ trackingState``; ``x y z`` in camera space, metres (x to the sensor's left,
    y up, z out of the sensor: the Kinect v1 convention).

Body: ``read_skeleton(..., body=)`` (``jaxproj.io.formats.bodies``): ``"first"`` (default) or a
0-based index into each frame's bodies; a frame without it is invalid.

Valid frames: a joint's ``trackingState`` is 0 (not tracked), 1 (inferred) or 2 (tracked). A frame
is invalid when any joint that feeds the Kinect v1 layout (``Skeleton.kinect_v1_sources``: the
first 20 joints and ``SpineShoulder``; not ``Neck``, the hand tips or thumbs) is not tracked (0):
inferred joints are kept, as Kinect v1 datasets keep theirs. Non-finite and all-zero positions make
the frame invalid too (``make_recording``).

Time: the files carry no timing; frames are assumed ``KINECT_FPS`` (30) frames/s apart, the
Kinect v2's rate (``fps=`` overrides).

Detection: the suffix ``.skeleton``, or a start of one integer on the first line, integer body
counts and then a line of 10 numbers (a body line).

Errors (``InputError``, one line naming the file, the 1-based line and, within the frames, the
0-based frame): a count that is not one non-negative integer, a body line without 10 values, a
joint count other than 25, a joint line without 12 values, a non-numeric value, a tracking state
other than 0, 1, 2 (NaN included), a file that ends inside a frame (truncated) or goes on after
the last frame, a frame count of 0, no frame with the chosen body (no body at all).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human import skeletons
from jaxproj.io.formats.base import Format
from jaxproj.io.formats.bodies import BodyChoice, body_index, feeding_joints, no_body_error
from jaxproj.io.recording import KINECT_FPS, Recording, timed_recording
from jaxproj.io.text import SNIFF_BYTES, Head, decode, is_number, to_table

SKELETON = "kinect_v2"
"""The registered skeleton of the files (``jaxproj.human.layouts.KINECT_V2``)."""

N_JOINTS = 25
"""Joints per body (Kinect v2 ``JointType_Count``)."""

BODY_FIELDS = (
    "bodyID clipedEdges handLeftConfidence handLeftState handRightConfidence handRightState "
    "isRestricted leanX leanY trackingState"
).split()
"""The 10 values of a body line."""

JOINT_FIELDS = (
    "x y z depthX depthY colorX colorY orientationW orientationX orientationY orientationZ "
    "trackingState"
).split()
"""The 12 values of a joint line."""

TRACKED = 2
"""``trackingState`` of a tracked joint (1: inferred, 0: not tracked)."""

MIN_TRACKING = 1
"""The lowest ``trackingState`` a joint feeding the Kinect v1 layout may have in a valid frame
(inferred)."""


@dataclass(frozen=True)
class NtuBodies:
    """Every body of an NTU ``.skeleton`` file.

    Attributes:
      n_frames: the file's frames.
      frame: ``(B,)`` int64 frame of each body (0-based).
      slot: ``(B,)`` int64 index of each body within its frame (0-based).
      info: ``(B, 10)`` float64 body lines (``BODY_FIELDS``).
      joints: ``(B, 25, 12)`` float64 joint lines (``JOINT_FIELDS``).
      joint_lines: ``(B, 25)`` int64 1-based line of each joint line.
    """

    n_frames: int
    frame: np.ndarray
    slot: np.ndarray
    info: np.ndarray
    joints: np.ndarray
    joint_lines: np.ndarray


def _count(path: str | os.PathLike[str], row: tuple[int, list[str]], what: str) -> int:
    """The one non-negative integer of a count line (``InputError`` otherwise)."""
    line, tokens = row
    if len(tokens) == 1 and tokens[0].isdigit():
        return int(tokens[0])
    shown = " ".join(tokens)
    shown = shown if len(shown) <= 40 else shown[:37] + "..."
    raise InputError(
        path, f"line {line}: expected {what} (one non-negative integer), found {shown!r}"
    )


def parse_ntu(path: str | os.PathLike[str], data: bytes) -> NtuBodies:
    """NTU ``.skeleton`` bytes -> every body of every frame (``NtuBodies``), checked.

    Raises:
      InputError: a malformed file (module docstring), naming the line and frame.
    """
    text = decode(path, data).replace("\r\n", "\n").replace("\r", "\n")
    rows = [(i, line.split()) for i, line in enumerate(text.split("\n"), start=1) if line.strip()]
    n_frames = _count(path, rows[0], "the frame count")
    if n_frames == 0:
        raise InputError(path, "line 1: the frame count is 0: no frames")
    last = rows[-1][0]
    frame, slot, info_at, joints_at = [], [], [], []
    i = 1

    def need(n: int, f: int, what: str) -> None:
        if i + n > len(rows):
            raise InputError(
                path,
                f"the file ends at line {last} inside this frame, before {what} (the first line "
                f"announces {n_frames} frames; truncated file?)",
                frame=f,
            )

    for f in range(n_frames):
        need(1, f, "its body count")
        n_bodies = _count(path, rows[i], f"frame {f}'s body count")
        i += 1
        for b in range(n_bodies):
            need(2, f, f"body {b} of its {n_bodies}")
            line, tokens = rows[i]
            if len(tokens) != len(BODY_FIELDS):
                raise InputError(
                    path,
                    f"line {line}: found {len(tokens)} values, expected {len(BODY_FIELDS)} (body "
                    f"{b} of the {n_bodies} the frame's body count announces: "
                    f"{' '.join(BODY_FIELDS)})",
                    frame=f,
                )
            n_joints = _count(path, rows[i + 1], "the joint count")
            if n_joints != N_JOINTS:
                raise InputError(
                    path,
                    f"line {rows[i + 1][0]}: joint count {n_joints}, expected {N_JOINTS} (Kinect "
                    "v2)",
                    frame=f,
                )
            need(2 + N_JOINTS, f, f"the {N_JOINTS} joint lines of body {b}")
            for line, tokens in rows[i + 2 : i + 2 + N_JOINTS]:
                if len(tokens) != len(JOINT_FIELDS):
                    raise InputError(
                        path,
                        f"line {line}: found {len(tokens)} values, expected {len(JOINT_FIELDS)} "
                        f"(joint line: {' '.join(JOINT_FIELDS)})",
                        frame=f,
                    )
            frame.append(f)
            slot.append(b)
            info_at.append(i)
            joints_at.append(i + 2)
            i += 2 + N_JOINTS
    if i < len(rows):
        raise InputError(
            path,
            f"line {rows[i][0]}: more lines after the {n_frames} frames the first line announces",
        )
    info_rows = [rows[k] for k in info_at]
    joint_rows = [rows[k + j] for k in joints_at for j in range(N_JOINTS)]
    info = to_table(
        path,
        [t for _, tokens in info_rows for t in tokens],
        np.array([line for line, _ in info_rows], dtype=np.int64),
        len(BODY_FIELDS),
    )
    joint_lines = np.array([line for line, _ in joint_rows], dtype=np.int64)
    joints = to_table(
        path, [t for _, tokens in joint_rows for t in tokens], joint_lines, len(JOINT_FIELDS)
    )
    state = joints[:, -1]
    bad = np.flatnonzero(~np.isin(state, (0, 1, 2)))
    if bad.size:
        k = int(bad[0])
        raise InputError(
            path,
            f"line {joint_lines[k]}: trackingState {state[k]:g} is not 0 (not tracked), "
            "1 (inferred) or 2 (tracked)",
            frame=frame[k // N_JOINTS],
        )
    return NtuBodies(
        n_frames=n_frames,
        frame=np.array(frame, dtype=np.int64),
        slot=np.array(slot, dtype=np.int64),
        info=info.reshape(-1, len(BODY_FIELDS)),
        joints=joints.reshape(-1, N_JOINTS, len(JOINT_FIELDS)),
        joint_lines=joint_lines.reshape(-1, N_JOINTS),
    )


def body_positions(
    path: str | os.PathLike[str], bodies: NtuBodies, body: BodyChoice = "first"
) -> tuple[np.ndarray, np.ndarray]:
    """One body of every frame: (``(T, 25, 3)`` float64 metres, Kinect v2 order; ``(T,)`` bool,
    ``False`` where the frame lacks the body or a joint feeding Kinect v1 is not tracked).

    Raises:
      InputError: no frame has the body (``bodies.no_body_error``).
      ConfigError: a bad ``body``.
    """
    k = body_index(body)
    pick = np.flatnonzero(bodies.slot == k)
    if pick.size == 0:
        most = int(bodies.slot.max()) + 1 if bodies.slot.size else 0
        raise no_body_error(path, k, bodies.n_frames, most)
    positions = np.zeros((bodies.n_frames, N_JOINTS, 3))
    valid = np.zeros(bodies.n_frames, dtype=bool)
    rows = bodies.joints[pick]
    positions[bodies.frame[pick]] = rows[:, :, :3]
    state = rows[:, feeding_joints(SKELETON), -1]
    valid[bodies.frame[pick]] = (state >= MIN_TRACKING).all(axis=1)
    return positions, valid


def _lines(head: Head, n: int) -> list[list[str]]:
    """The first ``n`` non-blank complete lines of the file's start, split."""
    data = head.data[:SNIFF_BYTES]
    if not head.complete or len(head.data) > SNIFF_BYTES:
        cut = max(data.rfind(b"\n"), data.rfind(b"\r"))
        data = data[: cut + 1] if cut >= 0 else b""
    found = []
    for line in data.decode("utf-8-sig", errors="replace").splitlines():
        if line.strip():
            found.append(line.split())
            if len(found) == n:
                break
    return found


def sniff(head: Head) -> tuple[bool, str]:
    """A first line of one integer (the frame count), integer body counts, then a body line of
    10 numbers (body counts of 0 may come first: frames without a body)."""
    if head.first_line is None or len(head.first_line.split()) != 1:
        why = "first line is not a frame count (one integer)" if head.suffix == ".skeleton" else ""
        return False, why
    lines = _lines(head, 1000)
    counts = 0
    for tokens in lines:
        if len(tokens) == 1 and tokens[0].isdigit():
            counts += 1
            continue
        if len(tokens) == len(BODY_FIELDS) and counts >= 2:
            if sum(not is_number(t) for t in tokens) <= 1:
                return True, ""
        break
    why = "no NTU RGB+D body line (10 numbers) after the frame and body counts"
    return False, why if head.suffix == ".skeleton" else ""


def read(
    path: str | os.PathLike[str],
    data: bytes,
    fps: float | None,
    *,
    body: BodyChoice = "first",
    **options: Any,
) -> Recording:
    """The file as a ``Recording``: the chosen body's Kinect v2 joints laid out as Kinect v1
    (``(T, 20, 3)`` metres, ``skeleton="kinect_v2"``), frames ``1 / KINECT_FPS`` s apart."""
    body_index(body)  # a bad choice is a ConfigError before the file is parsed
    positions, valid = body_positions(path, parse_ntu(path, data), body)
    kinect = skeletons.to_kinect_v1(positions, SKELETON)
    source = f"assumed {KINECT_FPS:g} fps"
    return timed_recording(
        path, "ntu", kinect, valid, None, source, fps, KINECT_FPS, skeleton=SKELETON
    )


FORMAT = Format(
    name="ntu",
    description="NTU RGB+D .skeleton text (Kinect v2, 25 joints; body= picks the body)",
    suffixes=(".skeleton",),
    sniff=sniff,
    read=read,
    first_line=("a frame count (NTU RGB+D .skeleton)", ""),
)
