"""MSR Action3D real-world skeleton text (``aXX_sYY_eZZ_skeleton3D.txt``), format ``"msr"``.

4 whitespace-separated columns ``x y z confidence`` per row, 20 rows per frame, joints in the MSR
order (converted to the SDK order with ``MSR_TO_SDK``); the confidence column is not kept by the
reader (the bundler of ``jaxproj.io.bundling`` keeps it, through ``read_msr_rows``). The files
hold no timing: frames are assumed ``MSR_FPS`` (15) frames/s apart. Recognised by a first line of
4 numbers.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human.skeleton import N_JOINTS
from jaxproj.io.formats.base import Format
from jaxproj.io.recording import MSR_FPS, Recording, timed_recording
from jaxproj.io.text import Head, decode, is_number_row, read_bytes, whitespace_table

MSR_TO_SDK: tuple[int, ...] = (6, 3, 2, 19, 0, 7, 9, 11, 1, 8, 10, 12, 4, 13, 15, 17, 5, 14, 16, 18)
"""0-based MSR Action3D row index of each SDK joint: ``sdk = msr[..., MSR_TO_SDK, :]``."""

MSR_COLUMNS = 4
"""Columns of an MSR Action3D row: ``x y z confidence``."""


def read_msr_rows(path: str | os.PathLike[str], data: bytes | None = None) -> np.ndarray:
    """MSR Action3D text -> ``(T, 20, 4)`` float64 ``x y z confidence`` in the *MSR* joint order.

    Args:
      path: the file.
      data: its bytes, if already read.

    Raises:
      InputError: a malformed file (rows of another column count, non-numeric tokens, a row
        count that is not a multiple of 20).
    """
    if data is None:
        data = read_bytes(path)
    table, _ = whitespace_table(
        path, decode(path, data), MSR_COLUMNS, "MSR Action3D: x y z confidence"
    )
    if table.shape[0] % N_JOINTS:
        raise InputError(
            path,
            f"found {table.shape[0]} rows, not a multiple of {N_JOINTS} "
            f"(MSR Action3D has {N_JOINTS} joint rows per frame)",
        )
    return table.reshape(-1, N_JOINTS, MSR_COLUMNS)


def sniff(head: Head) -> tuple[bool, str]:
    """A first line of 4 whitespace-separated numbers (one of them may be damaged)."""
    return is_number_row(head.first_line, MSR_COLUMNS), ""


def read(path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any) -> Recording:
    """The file as a ``Recording`` (``(T, 20, 3)`` SDK order; frames ``1 / MSR_FPS`` s apart)."""
    positions = read_msr_rows(path, data)[:, list(MSR_TO_SDK), :3]
    return timed_recording(
        path, "msr", positions, None, None, f"assumed {MSR_FPS:g} fps", fps, MSR_FPS
    )


FORMAT = Format(
    name="msr",
    description="MSR Action3D text: x y z confidence, 20 rows per frame",
    suffixes=(),
    sniff=sniff,
    read=read,
    first_line=(f"{MSR_COLUMNS} (MSR Action3D)", "numbers"),
)
