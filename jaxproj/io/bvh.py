"""BVH motion capture (Biovision hierarchy: CMU, LAFAN1, Xsens exports) -> Kinect v1 skeletons.

``read_bvh(path, bvh_map="auto", scale="auto", fps=None)`` returns the same
``readers.Recording`` as every other reader (``(T, 20, 3)`` float32 metres, Kinect SDK joint
order), so everything downstream (descriptor, IK, projection, CLI) works unchanged;
``readers.read_skeleton(path, format="bvh")`` and ``--format bvh`` call it. The steps, each public:

1. ``parse_bvh`` -> ``BvhClip``: the ``HIERARCHY`` (joint names, parents, ``OFFSET``s, the
   ``CHANNELS`` of each joint in their file order: any of the six Euler orders, position channels
   on any joint) and the ``MOTION`` block (``Frames:``, ``Frame Time:``, one row of channel values
   per frame). ``End Site``s are kept as extra joints with no channels, named ``<parent>_End``
   (e.g. ``Head_End``, the top of the head), so a joint map may use them.
2. ``forward_kinematics`` -> ``(T, J, 3)`` joint positions in the file's own axes and units,
   vectorised over frames (one batched product per channel and per joint; the only Python loop
   is over the joints). Conventions (the BVH de-facto standard): rotations in degrees; a joint's
   local rotation is the product of its rotation channels' axis rotations in the order the
   channels are listed (``Zrotation Xrotation Yrotation`` -> ``Rz @ Rx @ Ry``, i.e. intrinsic
   Z-X-Y); position channels replace the corresponding ``OFFSET`` component (the root's
   translation; LAFAN1-style files carry every joint's offset as position channels);
   ``p_joint = p_parent + R_parent @ offset``, ``R_joint = R_parent @ R_local``.
3. A joint map (``JOINT_MAPS``, ``resolve_joint_map``) picks, for each of the 20 Kinect joints,
   the BVH joint whose position it takes; ``kinect_positions`` applies it, the scale and the axis
   change.

Joint maps (``bvh_map=``, CLI ``--bvh-map``):

- ``"cmu"``: the CMU database's "3dsMax-friendly" BVH release (cgspeed): ``Hips``, ``Chest``,
  ``Neck``, ``Head``, ``LeftShoulder``/``LeftElbow``/``LeftWrist``/``LFingers``,
  ``LeftHip``/``LeftKnee``/``LeftAnkle``/``LeftToe`` (and the right side); checked on the two
  bundled test clips.
- ``"cmu-mb"``: the "MotionBuilder-friendly" release: ``Hips``, ``Spine``, ``Neck1``, ``Head``,
  ``LeftArm``/``LeftForeArm``/``LeftHand``/``LeftHandIndex1``,
  ``LeftUpLeg``/``LeftLeg``/``LeftFoot``/``LeftToeBase``. Its joint names and offsets were
  checked against published hierarchies of that release, not against motion data of it (no such
  file is bundled).
- ``"auto"`` (default): the preset whose every joint the hierarchy has, when exactly one does;
  otherwise an ``InputError`` listing, per preset, the Kinect joints it could not map.
- a ``dict`` (Kinect joint name -> BVH joint name) or the path of a JSON or TOML file holding
  that table (flat: ``{"HipCenter": "Hips", "ShoulderLeft": "LeftArm", ...}``).

Which Kinect joints a map must give, and how the others are derived (``REQUIRED_JOINTS``,
``DERIVED_JOINTS``):

- required: ``Head``, both ``Shoulder``, ``Elbow``, ``Wrist``, ``Hip``, ``Knee`` and ``Ankle``
  joints (the descriptor's body frame and bones need them);
- ``HipCenter``: the BVH root joint when the map leaves it out;
- ``ShoulderCenter``: the midpoint of ``ShoulderLeft`` and ``ShoulderRight``;
- ``Spine``: the midpoint of ``HipCenter`` and ``ShoulderCenter``;
- ``HandLeft`` / ``HandRight``: ``Wrist + HAND_EXTENSION * (Wrist - Elbow)`` (along the
  forearm);
- ``FootLeft`` / ``FootRight``: the first child (joint or End Site) of the ankle's BVH joint.

A map naming a BVH joint the hierarchy lacks, or leaving out a required Kinect joint, raises an
``InputError`` that lists every such Kinect joint. Kinect "Left" is the performer's left: the map
pairs names, it never mirrors (``--mirror`` does that, downstream).

Units (``scale=``, CLI ``--bvh-scale``): metres = file units x scale. ``"auto"`` (default):
``CMU_SCALE`` for the CMU presets (CMU's documented unit, (1 / 0.45) x 2.54 cm = 0.05644 m: the
converted skeletons keep the ASF lengths). With it the bundled subject 131 has its hip joints
0.96 m and its ankles ~0.1 m above the floor, thighs 0.41 m, shins 0.39 m, upper arms 0.24 m, a
plausible adult's legs; the converted torso is short (pelvis to neck base 0.32 m, top of the
head End Site 1.44 m above the floor), a property of that skeleton, not of the scale. For
other skeletons the unit among
``UNITS`` (m, cm, mm, in) that makes the rest pose's head-to-ankle height (the lengths of the
``OFFSET`` chains from the root to ``Head`` and to ``AnkleLeft``) nearest to ``REFERENCE_HEIGHT_M``
(1.5 m, in ratio). Or a unit name of ``UNITS`` (``"cmu"``, ``"m"``, ``"cm"``, ``"mm"``, ``"in"``)
or a number. The descriptor does not depend on the scale; a scale off by 1000 would make every
bone shorter than ``skeleton.MIN_BONE_LENGTH`` (1 mm) and every frame invalid.

Axes: BVH files are y-up and right-handed, the performer facing +z with their left at +x (CMU;
checked: its toes point to +z and ``LeftHip`` is at +x). The positions are turned 180 degrees
about y, ``(x, y, z) -> (-x, y, -z)`` (``BVH_TO_KINECT``), into Kinect camera-space conventions:
y up, the performer facing the camera (-z) with their left at smaller x, as in the Kinect
datasets. The origin stays the file's (floor at y = 0 for CMU). The descriptor is built in a body
frame made from the skeleton itself, so any rotation gives the same angles; the change only
makes raw positions (NPZ outputs, videos) look like Kinect data. A z-up file gives the same
descriptors too.

Time: frames are ``Frame Time`` seconds apart (``times = arange(T) * frame_time``). ``fps=F``
(CLI ``--fps`` for BVH) resamples the clip to ``F`` frames per second: joint positions are
interpolated linearly between the two nearest frames on the grid ``k / F`` over the clip's
duration (a resampled frame is invalid if either frame it interpolates is); the default keeps
the clip's own rate. (For the Kinect text formats, which carry no timing, ``fps`` instead states
their rate; a BVH states its own.)

Errors: every problem with the file raises ``InputError``, one line naming the file, the 1-based
line and the problem: no ``HIERARCHY`` or ``MOTION``, bad ``OFFSET`` / ``CHANNELS`` lines,
unbalanced braces, duplicate joint names, a bad ``Frames:`` or ``Frame Time:`` line, a row with
another number of values than the hierarchy's channels (a truncated row), non-numeric values,
fewer or more rows than ``Frames:`` says. Non-finite values are not errors: the frame is kept
and marked invalid, as in every reader.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import JOINT_NAMES, N_JOINTS

CMU_SCALE = (1.0 / 0.45) * 2.54 / 100.0
"""Metres per CMU skeleton unit (the ASF files' ``length 0.45``: 1 unit = 1 / 0.45 inch)."""

UNITS: dict[str, float] = {"cmu": CMU_SCALE, "m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
"""Unit names accepted by ``scale=`` (metres per file unit)."""

REFERENCE_HEIGHT_M = 1.5
"""Head-to-ankle height (m) that ``scale="auto"`` aims at when it guesses the unit of a
skeleton without a preset (an adult's ~1.7 m stature less the head top and the feet)."""

HAND_EXTENSION = 0.3
"""A derived Kinect hand lies this fraction of the forearm beyond the wrist (Kinect v1 data:
hand 0.07 m, forearm 0.25-0.29 m)."""

BVH_TO_KINECT = np.diag([-1.0, 1.0, -1.0])
"""BVH axes -> Kinect camera-space axes: a 180 degree turn about y (a rotation, det +1)."""

REQUIRED_JOINTS: tuple[str, ...] = (
    "Head", "ShoulderLeft", "ElbowLeft", "WristLeft", "ShoulderRight", "ElbowRight",
    "WristRight", "HipLeft", "KneeLeft", "AnkleLeft", "HipRight", "KneeRight", "AnkleRight",
)  # fmt: skip
"""Kinect joints a joint map must name (nothing in a skeleton stands in for them)."""

DERIVED_JOINTS: dict[str, str] = {
    "HipCenter": "the BVH root joint",
    "ShoulderCenter": "midpoint of ShoulderLeft and ShoulderRight",
    "Spine": "midpoint of HipCenter and ShoulderCenter",
    "HandLeft": f"WristLeft + {HAND_EXTENSION} x (WristLeft - ElbowLeft)",
    "HandRight": f"WristRight + {HAND_EXTENSION} x (WristRight - ElbowRight)",
    "FootLeft": "first child (joint or End Site) of AnkleLeft's BVH joint",
    "FootRight": "first child (joint or End Site) of AnkleRight's BVH joint",
}
"""Kinect joints a joint map may leave out, and how they are made when it does."""

JOINT_MAPS: dict[str, dict[str, str]] = {
    "cmu": {
        "HipCenter": "Hips", "Spine": "Chest", "ShoulderCenter": "Neck", "Head": "Head",
        "ShoulderLeft": "LeftShoulder", "ElbowLeft": "LeftElbow", "WristLeft": "LeftWrist",
        "HandLeft": "LFingers",
        "ShoulderRight": "RightShoulder", "ElbowRight": "RightElbow",
        "WristRight": "RightWrist", "HandRight": "RFingers",
        "HipLeft": "LeftHip", "KneeLeft": "LeftKnee", "AnkleLeft": "LeftAnkle",
        "FootLeft": "LeftToe",
        "HipRight": "RightHip", "KneeRight": "RightKnee", "AnkleRight": "RightAnkle",
        "FootRight": "RightToe",
    },
    "cmu-mb": {
        "HipCenter": "Hips", "Spine": "Spine", "ShoulderCenter": "Neck1", "Head": "Head",
        "ShoulderLeft": "LeftArm", "ElbowLeft": "LeftForeArm", "WristLeft": "LeftHand",
        "HandLeft": "LeftHandIndex1",
        "ShoulderRight": "RightArm", "ElbowRight": "RightForeArm", "WristRight": "RightHand",
        "HandRight": "RightHandIndex1",
        "HipLeft": "LeftUpLeg", "KneeLeft": "LeftLeg", "AnkleLeft": "LeftFoot",
        "FootLeft": "LeftToeBase",
        "HipRight": "RightUpLeg", "KneeRight": "RightLeg", "AnkleRight": "RightFoot",
        "FootRight": "RightToeBase",
    },
}  # fmt: skip
"""Built-in joint maps (Kinect joint -> BVH joint) of the two CMU BVH releases.

``cmu`` (3dsMax-friendly): ``LeftShoulder`` is the shoulder joint (``LeftCollar`` the clavicle),
``Neck`` the base of the neck at shoulder height (``lowerneck`` sits lower, at ``Chest2``),
``LFingers`` the hand (``lhand`` coincides with ``LeftWrist``). ``cmu-mb`` (MotionBuilder-friendly):
``LeftShoulder`` is the clavicle and ``LeftArm`` the shoulder joint, ``Neck1`` the upper neck
(``Neck`` coincides with ``Spine1``), ``LeftHandIndex1`` the hand (``LeftFingerBase`` coincides
with ``LeftHand``)."""

_PRESET_SCALE = {"cmu": CMU_SCALE, "cmu-mb": CMU_SCALE}
_ROTATION_AXES = {"Xrotation": 0, "Yrotation": 1, "Zrotation": 2}
_POSITION_AXES = {"Xposition": 0, "Yposition": 1, "Zposition": 2}
_KEYWORDS = frozenset({"JOINT", "End", "OFFSET", "CHANNELS", "ROOT", "{", "}"})
_TOKEN_RE = re.compile(r"[{}]|[^\s{}]+")
_FRAMES_RE = re.compile(r"^frames\s*:\s*(\S+)\s*$", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"^frame\s+time\s*:\s*(\S+)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class BvhClip:
    """A parsed BVH file.

    Attributes:
      names: ``(J,)`` joint names in file order (a parent before its children); End Sites are
        named ``<parent>_End``.
      parents: ``(J,)`` int64 index of each joint's parent, ``-1`` for the root.
      offsets: ``(J, 3)`` float64 ``OFFSET`` of each joint from its parent, file units.
      channels: per joint, its channel names in file order (``()`` for End Sites).
      end_site: ``(J,)`` bool, true for End Sites.
      motion: ``(T, C)`` float64 channel values (degrees for rotations, file units for
        positions), columns in hierarchy order.
      frame_time: seconds per frame (``Frame Time:``).
      source: the file.
      lines: ``(T,)`` int64 1-based line of each frame's row.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_site: np.ndarray
    motion: np.ndarray
    frame_time: float
    source: str
    lines: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def fps(self) -> float:
        """``1 / frame_time``."""
        return 1.0 / self.frame_time

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (``ValueError`` if there is none)."""
        return self.names.index(name)


# --- parsing -------------------------------------------------------------------------------------


def parse_bvh(path: str | os.PathLike[str], data: bytes | None = None) -> BvhClip:
    """Parse a BVH file (``HIERARCHY`` and ``MOTION``) into a ``BvhClip``.

    Args:
      path: the file (named in errors).
      data: its bytes, if already read.

    Raises:
      InputError: one line naming the file, the line and the problem (module docstring).
    """
    from jaxproj.io import readers

    if data is None:
        data = readers._read_bytes(path)
    text = readers._decode(path, data).replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    motion_at = next((i for i, ln in enumerate(lines) if ln.split()[:1] == ["MOTION"]), None)
    head = lines if motion_at is None else lines[:motion_at]
    skeleton = _parse_hierarchy(path, head)
    if motion_at is None:
        raise InputError(path, f"no MOTION section (the file ends at line {len(lines)})")
    return _parse_motion(path, lines, motion_at, skeleton)


def _parse_hierarchy(path: str | os.PathLike[str], lines: list[str]) -> dict:
    tokens: list[tuple[str, int]] = [
        (tok, i) for i, ln in enumerate(lines, start=1) for tok in _TOKEN_RE.findall(ln)
    ]
    if not tokens or tokens[0][0] != "HIERARCHY":
        where = f"line {tokens[0][1]}: found {tokens[0][0]!r}" if tokens else "no text"
        raise InputError(path, f"not a BVH file: {where}, expected 'HIERARCHY'")
    names: list[str] = []
    parents: list[int] = []
    offsets: list[tuple[float, float, float] | None] = []
    channels: list[tuple[str, ...]] = []
    end_site: list[bool] = []
    stack: list[int] = []
    pos = 1

    def take() -> tuple[str, int]:
        nonlocal pos
        if pos >= len(tokens):
            last = tokens[-1][1]
            raise InputError(path, f"line {last}: the HIERARCHY ends early (unclosed '{{'?)")
        tok = tokens[pos]
        pos += 1
        return tok

    def expect(word: str, after: str) -> None:
        tok, line = take()
        if tok != word:
            raise InputError(path, f"line {line}: expected {word!r} after {after}, found {tok!r}")

    def number(after: str) -> float:
        tok, line = take()
        try:
            value = float(tok)
        except ValueError:
            raise InputError(path, f"line {line}: non-numeric {after} value {tok!r}") from None
        if not math.isfinite(value):
            raise InputError(path, f"line {line}: {after} value {tok!r} is not finite")
        return value

    def open_joint(name: str, line: int, is_end: bool) -> None:
        if not is_end and name in names:
            raise InputError(path, f"line {line}: joint name {name!r} appears twice")
        if is_end:
            base, k = f"{name}_End", 2
            name = base
            while name in names:
                name, k = f"{base}{k}", k + 1
        names.append(name)
        parents.append(stack[-1] if stack else -1)
        offsets.append(None)
        channels.append(())
        end_site.append(is_end)
        stack.append(len(names) - 1)

    tok, line = take()
    if tok != "ROOT":
        raise InputError(
            path, f"line {line}: expected 'ROOT <name>' after HIERARCHY, found {tok!r}"
        )
    open_joint(take()[0], line, False)
    expect("{", f"ROOT {names[0]}")
    root_line = line
    while stack:
        tok, line = take()
        j = stack[-1]
        if tok == "OFFSET":
            offsets[j] = (number("OFFSET"), number("OFFSET"), number("OFFSET"))
        elif tok == "CHANNELS":
            if end_site[j]:
                raise InputError(path, f"line {line}: an End Site has no CHANNELS")
            count = take()[0]
            if not count.isdigit():
                raise InputError(
                    path, f"line {line}: CHANNELS needs a channel count, found {count!r}"
                )
            found = []
            for _ in range(int(count)):
                name, at = take()
                if name in _KEYWORDS:
                    raise InputError(
                        path,
                        f"line {line}: CHANNELS {count} of joint {names[j]} lists "
                        f"{len(found)} channel(s)",
                    )
                if name not in _ROTATION_AXES and name not in _POSITION_AXES:
                    raise InputError(
                        path,
                        f"line {at}: unknown channel {name!r} (CHANNELS {count} of joint "
                        f"{names[j]}; expected [XYZ]rotation or [XYZ]position)",
                    )
                found.append(name)
            if len(set(found)) != len(found):
                raise InputError(path, f"line {line}: a channel is listed twice: {found}")
            channels[j] = tuple(found)
        elif tok in ("JOINT", "End"):
            if end_site[j]:
                raise InputError(path, f"line {line}: an End Site cannot have children")
            if tok == "JOINT":
                open_joint(take()[0], line, False)
            else:
                expect("Site", "End")
                open_joint(names[j], line, True)
            expect("{", f"{tok} {names[-1]}")
        elif tok == "}":
            if offsets[j] is None:
                raise InputError(path, f"line {line}: joint {names[j]} has no OFFSET")
            stack.pop()
        elif tok == "ROOT":
            raise InputError(path, f"line {line}: a second ROOT (one skeleton per file supported)")
        else:
            raise InputError(
                path,
                f"line {line}: unexpected {tok!r} in joint {names[j]} (expected OFFSET, "
                "CHANNELS, JOINT, End Site or '}')",
            )
    if pos < len(tokens):
        tok, line = tokens[pos]
        what = "a second ROOT (one skeleton per file supported)" if tok == "ROOT" else repr(tok)
        raise InputError(path, f"line {line}: {what} after the skeleton closed (ROOT at line "
                               f"{root_line}); expected MOTION")  # fmt: skip
    return {
        "names": tuple(names),
        "parents": np.array(parents, np.int64),
        "offsets": np.array(offsets, np.float64),
        "channels": tuple(channels),
        "end_site": np.array(end_site, bool),
    }


def _parse_motion(
    path: str | os.PathLike[str], lines: list[str], motion_at: int, skeleton: dict
) -> BvhClip:
    from jaxproj.io import readers

    n_channels = sum(len(c) for c in skeleton["channels"])
    if n_channels == 0:
        raise InputError(path, "the HIERARCHY has no CHANNELS: nothing moves")
    rest = [(i, ln) for i, ln in enumerate(lines[motion_at + 1 :], start=motion_at + 2)
            if ln.strip()]  # fmt: skip
    after_motion = f"line {motion_at + 1} (MOTION)"
    if not rest:
        raise InputError(path, f"no 'Frames:' line after {after_motion}")
    frames_line, text = rest[0]
    m = _FRAMES_RE.match(text.strip())
    if not m:
        raise InputError(path, f"line {frames_line}: expected 'Frames: <count>', found "
                               f"{text.strip()[:40]!r}")  # fmt: skip
    if not m.group(1).isdigit():
        raise InputError(path, f"line {frames_line}: the frame count {m.group(1)!r} is not a "
                               "whole number")  # fmt: skip
    n_frames = int(m.group(1))
    if n_frames == 0:
        raise InputError(path, f"line {frames_line}: 'Frames: 0', no frames")
    if len(rest) < 2:
        raise InputError(path, f"no 'Frame Time:' line after line {frames_line}")
    time_line, text = rest[1]
    m = _FRAME_TIME_RE.match(text.strip())
    if not m:
        raise InputError(path, f"line {time_line}: expected 'Frame Time: <seconds>', found "
                               f"{text.strip()[:40]!r}")  # fmt: skip
    try:
        frame_time = float(m.group(1))
    except ValueError:
        frame_time = math.nan
    lo, hi = readers.FPS_RANGE
    if not (math.isfinite(frame_time) and 1.0 / hi <= frame_time <= 1.0 / lo):
        raise InputError(
            path,
            f"line {time_line}: Frame Time {m.group(1)!r} is not a time step in "
            f"[{1.0 / hi:g}, {1.0 / lo:g}] s",
        )
    rows = rest[2:]
    line_numbers = np.array([i for i, _ in rows], np.int64)
    split = [ln.split() for _, ln in rows]
    counts = np.fromiter(map(len, split), np.int64, count=len(split))
    bad = np.flatnonzero(counts != n_channels)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            path,
            f"line {line_numbers[i]}: found {counts[i]} values, expected {n_channels} (the "
            "channels of the HIERARCHY)",
        )
    if len(rows) != n_frames:
        last = int(line_numbers[-1]) if len(rows) else time_line
        what = "ends after" if len(rows) < n_frames else "has"
        raise InputError(
            path,
            f"line {last}: the file {what} {len(rows)} frame rows, 'Frames: {n_frames}' "
            f"(line {frames_line}) says {n_frames}"
            + (" (truncated?)" if what == "ends after" else ""),
        )
    table = readers._to_table(path, [t for f in split for t in f], line_numbers, n_channels)
    return BvhClip(
        skeleton["names"],
        skeleton["parents"],
        skeleton["offsets"],
        skeleton["channels"],
        skeleton["end_site"],
        table,
        frame_time,
        str(path),
        line_numbers,
    )


# --- forward kinematics --------------------------------------------------------------------------


def _axis_rotations(angles: np.ndarray, axis: int) -> np.ndarray:
    """``(T,)`` radians about ``axis`` (0 x, 1 y, 2 z) -> ``(T, 3, 3)`` rotation matrices."""
    c, s = np.cos(angles), np.sin(angles)
    r = np.zeros(angles.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r[:, axis, axis] = 1.0
    r[:, i, i] = c
    r[:, j, j] = c
    r[:, i, j] = -s
    r[:, j, i] = s
    return r


def forward_kinematics(clip: BvhClip, scale: float = 1.0) -> np.ndarray:
    """Positions of every joint (End Sites included) in every frame.

    Args:
      clip: from ``parse_bvh``.
      scale: multiplies offsets and position channels (e.g. ``CMU_SCALE`` for metres).

    Returns:
      ``(T, J, 3)`` float64 positions in the file's axes (``clip.names`` order); frames with
      non-finite channel values give non-finite positions.
    """
    t = clip.n_frames
    n = len(clip.names)
    pos = np.zeros((t, n, 3))
    rot = np.zeros((t, n, 3, 3))
    col = 0
    with np.errstate(invalid="ignore", over="ignore"):
        for j in range(n):
            local_t = np.broadcast_to(clip.offsets[j] * scale, (t, 3)).copy()
            local_r = None
            for name in clip.channels[j]:
                values = clip.motion[:, col]
                col += 1
                if name in _POSITION_AXES:
                    local_t[:, _POSITION_AXES[name]] = values * scale
                else:
                    r = _axis_rotations(np.radians(values), _ROTATION_AXES[name])
                    local_r = r if local_r is None else local_r @ r
            p = int(clip.parents[j])
            if p < 0:
                pos[:, j] = local_t
                rot[:, j] = np.eye(3) if local_r is None else local_r
            else:
                pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], local_t)
                rot[:, j] = rot[:, p] if local_r is None else rot[:, p] @ local_r
    return pos


# --- joint maps ----------------------------------------------------------------------------------


def load_joint_map(path: str | os.PathLike[str]) -> dict[str, str]:
    """A joint map file: JSON or TOML (by extension; ``.toml``, else JSON), one flat table of
    Kinect joint name -> BVH joint name.

    Raises:
      InputError: unreadable file, bad syntax, not a flat table of names.
    """
    from jaxproj.io import readers

    data = readers._read_bytes(path)
    text = readers._decode(path, data)
    try:
        if Path(path).suffix.lower() == ".toml":
            table = tomllib.loads(text)
        else:
            table = json.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as err:
        raise InputError(path, f"not a joint map: {readers._one_line(err)}") from None
    if not isinstance(table, dict):
        raise InputError(path, "a joint map is a table of Kinect joint name -> BVH joint name")
    return _check_map(table, lambda problem: InputError(path, problem))


def _check_map(table: Mapping, error) -> dict[str, str]:
    bad_values = [k for k, v in table.items() if not isinstance(v, str)]
    if bad_values:
        raise error(f"joint map values must be BVH joint names (strings): {bad_values}")
    unknown = [k for k in table if k not in JOINT_NAMES]
    if unknown:
        raise error(f"unknown Kinect joint name(s) {unknown} in the joint map; the 20 Kinect "
                    f"joints are {', '.join(JOINT_NAMES)}")  # fmt: skip
    return {str(k): str(v) for k, v in table.items()}


def _unmapped(table: Mapping[str, str], names: tuple[str, ...]) -> list[str]:
    """Kinect joints the table cannot give from a hierarchy with these joint names."""
    out = [f"{k} ({v} not in the hierarchy)" for k, v in table.items() if v not in names]
    out += [f"{k} (not in the map)" for k in REQUIRED_JOINTS if k not in table]
    return out


def detect_joint_map(clip: BvhClip) -> str:
    """The preset of ``JOINT_MAPS`` whose every joint the hierarchy has.

    Raises:
      InputError: no preset fits (lists, per preset, the Kinect joints it could not map) or more
        than one does.
    """
    fits = [k for k, table in JOINT_MAPS.items() if not _unmapped(table, clip.names)]
    if len(fits) == 1:
        return fits[0]
    if fits:
        raise InputError(clip.source, f"the hierarchy fits several joint maps ({', '.join(fits)}):"
                                      " give one (--bvh-map, bvh_map=)")  # fmt: skip
    why = "; ".join(
        f"{k!r} could not map {', '.join(_unmapped(t, clip.names))}" for k, t in JOINT_MAPS.items()
    )
    raise InputError(
        clip.source,
        f"no built-in joint map fits this BVH skeleton ({len(clip.names)} joints, root "
        f"{clip.names[0]}): {why}. Give a map (--bvh-map FILE.json|FILE.toml, bvh_map=dict) "
        "of Kinect joint -> BVH joint",
    )


def resolve_joint_map(
    clip: BvhClip, bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto"
) -> tuple[str, dict[str, str]]:
    """``(name, table)`` of the joint map for ``clip``: a preset name, ``"auto"``, a file path
    (JSON / TOML) or a dict; checked against the hierarchy.

    Raises:
      ConfigError: a dict with unknown Kinect names or non-string values.
      InputError: a map file that cannot be read; a map that does not fit the hierarchy (lists
        every Kinect joint it could not map).
    """
    if isinstance(bvh_map, Mapping):
        name, table = "dict", _check_map(bvh_map, ConfigError)
    elif str(bvh_map) == "auto":
        name = detect_joint_map(clip)
        table = JOINT_MAPS[name]
    elif str(bvh_map) in JOINT_MAPS:
        name, table = str(bvh_map), JOINT_MAPS[str(bvh_map)]
    else:
        p = Path(bvh_map)
        if not p.exists():
            raise ConfigError(
                f"bvh map {str(bvh_map)!r}: not a built-in map ({', '.join(JOINT_MAPS)}, auto) "
                "nor an existing JSON / TOML file"
            )
        name, table = str(p), load_joint_map(p)
    missing = _unmapped(table, clip.names)
    if missing:
        raise InputError(
            clip.source,
            f"joint map {name!r} could not map {len(missing)} Kinect joint(s): "
            f"{', '.join(missing)}; the hierarchy's joints: {', '.join(clip.names)}",
        )
    return name, dict(table)


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


def kinect_positions(
    clip: BvhClip, table: Mapping[str, str], scale: float, points: np.ndarray | None = None
) -> np.ndarray:
    """The 20 Kinect joints of every frame from a resolved joint map (missing joints derived).

    Args:
      clip: the parsed file.
      table: Kinect joint -> BVH joint (``resolve_joint_map``).
      scale: metres per file unit.
      points: ``forward_kinematics(clip, scale)`` if already computed.

    Returns:
      ``(T, 20, 3)`` float64 metres in Kinect SDK joint order and Kinect axes
      (``BVH_TO_KINECT``).
    """
    p = forward_kinematics(clip, scale) if points is None else points
    out = np.zeros((p.shape[0], N_JOINTS, 3))
    k = {n: i for i, n in enumerate(JOINT_NAMES)}

    def get(name: str) -> np.ndarray:
        return out[:, k[name]]

    for name, joint in table.items():
        out[:, k[name]] = p[:, clip.index(joint)]
    with np.errstate(invalid="ignore", over="ignore"):
        if "HipCenter" not in table:
            out[:, k["HipCenter"]] = p[:, 0]
        if "ShoulderCenter" not in table:
            out[:, k["ShoulderCenter"]] = 0.5 * (get("ShoulderLeft") + get("ShoulderRight"))
        if "Spine" not in table:
            out[:, k["Spine"]] = 0.5 * (get("HipCenter") + get("ShoulderCenter"))
        for side in ("Left", "Right"):
            wrist, elbow = get(f"Wrist{side}"), get(f"Elbow{side}")
            if f"Hand{side}" not in table:
                out[:, k[f"Hand{side}"]] = wrist + HAND_EXTENSION * (wrist - elbow)
            if f"Foot{side}" not in table:
                ankle = clip.index(table[f"Ankle{side}"])
                children = np.flatnonzero(clip.parents == ankle)
                if not children.size:
                    raise InputError(
                        clip.source,
                        f"cannot derive Foot{side}: the ankle's BVH joint {clip.names[ankle]} "
                        f"has no child; map Foot{side} in the joint map",
                    )
                out[:, k[f"Foot{side}"]] = p[:, int(children[0])]
    return out @ BVH_TO_KINECT.T


# --- reading -------------------------------------------------------------------------------------


def read_bvh(
    path: str | os.PathLike[str],
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
    scale: float | str = "auto",
    fps: float | None = None,
    *,
    data: bytes | None = None,
):
    """Read a BVH file into a ``readers.Recording`` (``(T, 20, 3)`` float32 metres, Kinect order).

    Args:
      path: the ``.bvh`` file.
      bvh_map: ``"auto"`` (detect a preset), ``"cmu"``, ``"cmu-mb"``, a JSON / TOML map file or
        a dict of Kinect joint -> BVH joint (module docstring).
      scale: ``"auto"``, a unit name of ``UNITS`` or metres per file unit.
      fps: ``None`` keeps the clip's frames (``Frame Time``); a rate resamples the clip to it.
      data: the file's bytes, if already read.

    Returns:
      ``Recording`` with ``format="bvh"``, ``times`` from ``Frame Time`` (or the resampled grid)
      and ``time_source`` saying which map, scale and rate were used.

    Raises:
      InputError: a malformed file or a map that does not fit it (one line, file and line).
      ConfigError: a bad ``scale``, ``fps`` or map dict.
    """
    from jaxproj.io import readers

    if fps is not None:
        readers.check_fps(fps)
    clip = parse_bvh(path, data)
    map_name, table = resolve_joint_map(clip, bvh_map)
    metres, scale_note = _scale(clip, scale, map_name, table)
    positions = kinect_positions(clip, table, metres)
    times = np.arange(clip.n_frames, dtype=np.float64) * clip.frame_time
    if times[-1] > readers.MAX_DURATION_S:
        raise InputError(
            path,
            f"the clip spans {times[-1]:g} s (more than {readers.MAX_DURATION_S:g} s): corrupt "
            "Frame Time or Frames",
        )
    rec = readers._recording(positions, None, str(path), "bvh")
    note = (f"BVH Frame Time {clip.frame_time:g} s ({clip.fps:.6g} fps); map {map_name}; "
            f"scale {scale_note}")  # fmt: skip
    rec = dataclasses.replace(rec, times=times, time_source=note, nominal_fps=clip.fps)
    if fps is not None:
        rec = readers.resample(rec, fps)
    return rec
