"""UTKinect-Action3D ``joints_sXX_eYY.txt``, format ``"utkinect"``.

One line per frame: the frame number then 60 values (20 joints x ``x y z``, SDK order). A line
whose frame number repeats an earlier line's is dropped (the first one is kept); frames are ordered
by frame number (the file's own order in every recording of the dataset). Times are the frame
numbers at the dataset's nominal ``UTK_FPS`` (30) frames/s, so frames the tracker dropped leave
gaps. Recognised by a first line of 61 numbers.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human.skeleton import N_JOINTS
from jaxproj.io.formats.base import Format
from jaxproj.io.recording import UTK_FPS, Recording, timed_recording
from jaxproj.io.text import Head, decode, is_number_row, read_bytes, whitespace_table

UTK_COLUMNS = 1 + 3 * N_JOINTS
"""Columns of a UTKinect line: the frame number and 20 x ``x y z``."""

MAX_FRAME_NUMBER = 2.0**53
"""Largest frame number magnitude (integers a float64 holds exactly, and int64 too)."""


def read_utkinect_rows(
    path: str | os.PathLike[str], data: bytes | None = None, *, order: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """UTKinect text -> (``(T,)`` int64 frame numbers, ``(T, 20, 3)`` float64 positions, SDK order).

    A line whose frame number repeats an earlier line's is dropped (the first one is kept); the
    frames come out ordered by frame number (``order=False``: in file order, for the bundler,
    which refuses a file out of order).

    Raises:
      InputError: a malformed file, a frame number that is not an integer or beyond 2**53.
    """
    if data is None:
        data = read_bytes(path)
    table, lines = whitespace_table(
        path, decode(path, data), UTK_COLUMNS, "UTKinect: frame number + 20 x y z"
    )
    frame = table[:, 0]
    bad = np.flatnonzero(~np.isfinite(frame) | (frame != np.round(frame)))
    if bad.size:
        i = int(bad[0])
        raise InputError(path, f"line {lines[i]}: frame number {frame[i]:g} is not an integer")
    bad = np.flatnonzero(np.abs(frame) > MAX_FRAME_NUMBER)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            path, f"line {lines[i]}: frame number {frame[i]:g} is out of range (|n| <= 2**53)"
        )
    _, keep = np.unique(frame, return_index=True)  # first line of each number, by frame number
    if not order:
        keep = np.sort(keep)
    return frame[keep].astype(np.int64), table[keep, 1:].reshape(-1, N_JOINTS, 3)


def sniff(head: Head) -> tuple[bool, str]:
    """A first line of 61 whitespace-separated numbers (one of them may be damaged)."""
    return is_number_row(head.first_line, UTK_COLUMNS), ""


def read(path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any) -> Recording:
    """The file as a ``Recording`` (``(T, 20, 3)``; times from the frame numbers)."""
    frames, positions = read_utkinect_rows(path, data)
    times = (frames - frames[0]) / UTK_FPS
    source = f"frame numbers at {UTK_FPS:g} fps"
    return timed_recording(path, "utkinect", positions, None, times, source, fps, UTK_FPS)


FORMAT = Format(
    name="utkinect",
    description="UTKinect-Action3D text: frame number + 20 x y z per line",
    suffixes=(),
    sniff=sniff,
    read=read,
    first_line=(f"{UTK_COLUMNS} (UTKinect)", "numbers"),
)
