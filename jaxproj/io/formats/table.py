"""The two plain table formats of ``(T, 20, 3)`` positions: ``"csv"`` and ``"npz"``.

They share a module because they are the formats *we* define (not a dataset's): the same table
of SDK-order positions in metres, as text or as a NumPy archive, with no dataset-specific layout.

- ``"npz"`` (``.npz``, or a zip signature): a NumPy archive with key ``positions`` ``(T, 20, 3)``
  (metres, SDK order), an optional ``valid`` ``(T,)`` bool mask, which is honoured, and optional
  timing: ``times`` ``(T,)`` seconds (strictly increasing) or ``fps`` (a scalar); without timing
  frames are assumed ``KINECT_FPS`` (30) frames/s apart. A zip without ``positions`` (e.g. a
  model) is not a recording.
- ``"csv"`` (``.csv``, or a first line of 60 comma-separated fields, or a header line of names
  followed by one): comma-separated, 60 numeric columns per row (``x, y, z`` per joint, SDK
  order); one header line of non-numeric column names is allowed and skipped. No timing: frames
  are assumed ``KINECT_FPS`` frames/s apart.
"""

from __future__ import annotations

import io
import os
import zipfile
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human.skeleton import N_JOINTS
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


def parse_npz(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, str]:
    """NPZ bytes -> (``(T, 20, 3)`` positions, ``(T,)`` valid or None, ``(T,)`` times or None,
    time source).

    Raises:
      InputError: not a zip, a corrupt archive, no ``positions``, wrong shapes or dtypes, bad
        ``valid`` / ``times`` / ``fps``.
    """
    if data[:4] != _ZIP_SIGNATURE:
        raise InputError(path, "not an npz archive (not a zip file)")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            keys = list(archive.files)
            if "positions" not in keys:
                found = ", ".join(keys) if keys else "none"
                raise InputError(path, f"missing key 'positions' (keys found: {found})")
            positions = archive["positions"]
            valid = archive["valid"] if "valid" in keys else None
            times = archive["times"] if "times" in keys else None
            rate = archive["fps"] if "fps" in keys and times is None else None
            for key, value in (
                ("positions", positions),
                ("valid", valid),
                ("times", times),
                ("fps", rate),
            ):
                if value is not None and not isinstance(value, np.ndarray):
                    raise InputError(
                        path, f"corrupt or unreadable npz archive (member {key!r} is not .npy)"
                    )
    except InputError:
        raise
    except Exception as err:  # zipfile / zlib / numpy format errors of a corrupt archive
        raise InputError(path, f"corrupt or unreadable npz archive ({one_line(err)})") from None
    if not (
        np.issubdtype(positions.dtype, np.floating) or np.issubdtype(positions.dtype, np.integer)
    ):
        raise InputError(path, f"positions has dtype {positions.dtype}, expected floats")
    shape = positions.shape
    if positions.ndim != 3 or shape[2] != 3:
        raise InputError(path, f"positions has shape {shape}, expected (T, {N_JOINTS}, 3)")
    if shape[1] != N_JOINTS:
        raise InputError(
            path, f"positions has {shape[1]} joints, expected {N_JOINTS} (shape {shape})"
        )
    if shape[0] == 0:
        raise InputError(path, "positions has no frames (shape (0, 20, 3))")
    if valid is not None:
        if valid.shape != (shape[0],):
            raise InputError(path, f"valid has shape {valid.shape}, expected ({shape[0]},)")
        if valid.dtype != np.bool_:
            if not np.issubdtype(valid.dtype, np.integer) or not np.isin(valid, (0, 1)).all():
                raise InputError(path, f"valid has dtype {valid.dtype}, expected bool")
            valid = valid.astype(bool)
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
    return positions, valid, times, source


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
    """A zip archive with a ``positions`` member (or a file named ``.npz``: its reader says
    what is wrong with it, as for a zip that cannot be opened)."""
    if head.data[:4] != _ZIP_SIGNATURE:
        return head.suffix == ".npz", ""
    try:
        source = io.BytesIO(head.data) if head.complete else head.path
        with zipfile.ZipFile(source) as zf:
            names = zf.namelist()
    except (OSError, zipfile.BadZipFile, ValueError):
        return True, ""  # looks like an npz: its reader says what is wrong with it
    if "positions.npy" not in names:
        return False, "an npz archive without 'positions' (not a recording)"
    return True, ""


def read_npz(
    path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any
) -> Recording:
    """The archive as a ``Recording`` (``(T, 20, 3)``; its ``valid`` and timing honoured)."""
    positions, valid, times, source = parse_npz(path, data)
    return timed_recording(path, "npz", positions, valid, times, source, fps, KINECT_FPS)


NPZ = Format(
    name="npz",
    description="NumPy archive of positions T x 20 x 3, optional valid, times or fps",
    suffixes=(".npz",),
    sniff=sniff_npz,
    read=read_npz,
)
