"""BVH parsing: the ``HIERARCHY`` and ``MOTION`` blocks of a file -> ``BvhClip``.

Step 1 of ``jaxproj.io.formats.bvh`` (the package docstring has the conventions and the errors):
joint names, parents, ``OFFSET``s, the ``CHANNELS`` of each joint in their file order (any of
the six Euler orders, position channels on any joint), ``Frames:``, ``Frame Time:`` and one row of
channel values per frame. ``End Site``s are kept as extra joints with no channels, named
``<parent>_End``. Every problem raises a one-line ``InputError`` naming the file and the line.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from jaxproj.errors import InputError
from jaxproj.io.recording import FPS_RANGE
from jaxproj.io.text import decode, read_bytes, to_table

ROTATION_AXES = {"Xrotation": 0, "Yrotation": 1, "Zrotation": 2}
"""Rotation channel name -> axis (0 x, 1 y, 2 z)."""
POSITION_AXES = {"Xposition": 0, "Yposition": 1, "Zposition": 2}
"""Position channel name -> axis (0 x, 1 y, 2 z)."""
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


def parse_bvh(path: str | os.PathLike[str], data: bytes | None = None) -> BvhClip:
    """Parse a BVH file (``HIERARCHY`` and ``MOTION``) into a ``BvhClip``.

    Args:
      path: the file (named in errors).
      data: its bytes, if already read.

    Raises:
      InputError: one line naming the file, the line and the problem (module docstring).
    """
    if data is None:
        data = read_bytes(path)
    text = decode(path, data).replace("\r\n", "\n").replace("\r", "\n")
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
            found: list[str] = []
            for _ in range(int(count)):
                name, at = take()
                if name in _KEYWORDS:
                    raise InputError(
                        path,
                        f"line {line}: CHANNELS {count} of joint {names[j]} lists "
                        f"{len(found)} channel(s)",
                    )
                if name not in ROTATION_AXES and name not in POSITION_AXES:
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
    n_channels = sum(len(c) for c in skeleton["channels"])
    if n_channels == 0:
        raise InputError(path, "the HIERARCHY has no CHANNELS: nothing moves")
    rest = [(i, ln) for i, ln in enumerate(lines[motion_at + 1 :], start=motion_at + 2)
            if ln.strip()]  # fmt: skip
    after_motion = f"line {motion_at + 1} (MOTION)"
    if not rest:
        raise InputError(path, f"no 'Frames:' line after {after_motion}")
    frames_line, m = _header(path, rest[0], _FRAMES_RE, "Frames: <count>")
    if not m.group(1).isdigit():
        raise InputError(path, f"line {frames_line}: the frame count {m.group(1)!r} is not a "
                               "whole number")  # fmt: skip
    n_frames = int(m.group(1))
    if n_frames == 0:
        raise InputError(path, f"line {frames_line}: 'Frames: 0', no frames")
    if len(rest) < 2:
        raise InputError(path, f"no 'Frame Time:' line after line {frames_line}")
    time_line, m = _header(path, rest[1], _FRAME_TIME_RE, "Frame Time: <seconds>")
    try:
        frame_time = float(m.group(1))
    except ValueError:
        frame_time = math.nan
    lo, hi = FPS_RANGE
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
    table = to_table(path, [t for f in split for t in f], line_numbers, n_channels)
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


def _header(
    path: str | os.PathLike[str], line: tuple[int, str], pattern: re.Pattern[str], expected: str
) -> tuple[int, re.Match[str]]:
    """``(line number, match)`` of a ``MOTION`` header line (``Frames:``, ``Frame Time:``)."""
    number, text = line
    m = pattern.match(text.strip())
    if not m:
        raise InputError(path, f"line {number}: expected {expected!r}, found {text.strip()[:40]!r}")
    return number, m
