"""Readers for recorded Kinect v1 skeleton files -> ``(T, 20, 3)`` positions in SDK joint order.

Supported formats (``read_skeleton(path, format=...)``):

- ``"msr"``: MSR Action3D real-world text (``aXX_sYY_eZZ_skeleton3D.txt``): 4 whitespace-separated
  columns ``x y z confidence`` per row, 20 rows per frame, joints in the MSR order (converted to the
  SDK order with ``MSR_TO_SDK``); the confidence column is not kept.
- ``"utkinect"``: UTKinect-Action3D ``joints_sXX_eYY.txt``: one line per frame, the frame number
  then 60 values (20 joints x ``x y z``, SDK order). A line whose frame number repeats an earlier
  line's is dropped (the first one is kept); frames are ordered by frame number (the file's own
  order in every recording of the dataset).
- ``"npz"``: a NumPy archive with key ``positions`` ``(T, 20, 3)`` (metres, SDK order), an
  optional ``valid`` ``(T,)`` bool mask, which is honoured, and optional timing: ``times``
  ``(T,)`` seconds (strictly increasing) or ``fps`` (a scalar).
- ``"csv"``: comma-separated, 60 numeric columns per row (``x, y, z`` per joint, SDK order); one
  header line of non-numeric column names is allowed and skipped.
- ``"bvh"``: BVH motion capture (CMU, LAFAN1, Xsens exports...): the hierarchy's forward
  kinematics, mapped to the 20 Kinect joints by a joint map, in metres; see ``jaxproj.io.bvh``
  (``read_skeleton(..., bvh_map=, scale=)``).
- ``"auto"`` (default): ``.npz`` / ``.csv`` / ``.bvh`` by extension (or a zip signature, commas
  in the first line, a first line ``HIERARCHY``), otherwise by the column count of the first
  non-blank line (4 -> msr, 61 -> utkinect).

Time axis: every ``Recording`` carries ``times`` ``(T,)`` float64 seconds from the recording's
first frame and ``time_source``, which says where they came from:

- UTKinect: the frame numbers at the dataset's nominal 30 frames/s (``UTK_FPS``), so frames the
  tracker dropped leave gaps (``"frame numbers at 30 fps"``);
- MSR Action3D: the files hold no timing; frames are assumed ``MSR_FPS`` = 15 frames/s apart (the
  rate the dataset's skeleton sequences are usually quoted at; an assumption, ``"assumed 15
  fps"``);
- NPZ: the file's ``times`` or ``fps`` when present (``"file"``), otherwise like CSV;
- CSV: no timing in the format; frames are assumed ``KINECT_FPS`` = 30 frames/s apart (the
  Kinect v1 sensor's rate, ``"assumed 30 fps"``);
- BVH: the file's ``Frame Time`` (``"BVH Frame Time ..."``);
- ``read_skeleton(..., fps=F)`` (the CLI's ``--fps``) overrides all of these with ``t / F``,
  except for BVH, which states its own rate: there ``fps=F`` resamples the clip to ``F`` frames
  per second (``resample``: linear interpolation of the joint positions).

Bounds on the time axis (beyond them a file is corrupt, and the float32 time steps of smoothing
and of the feasibility filter would overflow): frame rates (``fps=``, an NPZ's ``fps``) within
``FPS_RANGE`` (1e-3 to 1e6 frames/s), an NPZ's ``times`` steps of at least ``MIN_STEP_S``
(1 us), a time axis of at most ``MAX_DURATION_S`` (1e9 s), UTKinect frame numbers integers of
magnitude at most 2**53.

Every problem with the file raises ``jaxproj.errors.InputError`` with a one-line message naming
the file, the problem and, where local, the 1-based line (text) or 0-based frame (npz).
Non-finite values and all-zero frames (skeleton lost) are *not* errors: the frame is kept, marked
``False`` in ``Recording.valid`` and its positions are set to 0. Windows line endings, a UTF-8
byte-order mark, blank lines and trailing whitespace are accepted.

``recording_format(path)`` says whether a file in a folder is a recording at all (used by
``datasets.load_folder`` to skip documentation, label files and the like).

Text is parsed in bulk (one ``str.split`` per line to count columns, one vectorised float
conversion for the whole file); a 1000-frame MSR file reads in about 10-20 ms.
"""

from __future__ import annotations

import dataclasses
import io
import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import N_JOINTS

Format = Literal["auto", "msr", "utkinect", "npz", "csv", "bvh"]
FORMATS: tuple[str, ...] = ("auto", "msr", "utkinect", "npz", "csv", "bvh")
"""Accepted values of ``read_skeleton(..., format=)``."""

MSR_TO_SDK: tuple[int, ...] = (6, 3, 2, 19, 0, 7, 9, 11, 1, 8, 10, 12, 4, 13, 15, 17, 5, 14, 16, 18)
"""0-based MSR Action3D row index of each SDK joint: ``sdk = msr[..., MSR_TO_SDK, :]``."""

MSR_FPS = 15.0
"""Frame rate assumed for MSR Action3D skeleton files (frames/s): the files carry no timing."""
KINECT_FPS = 30.0
"""Frame rate assumed for CSV (and NPZ without timing): the Kinect v1 sensor's rate, frames/s."""
UTK_FPS = 30.0
"""Nominal capture rate of UTKinect-Action3D (frames/s): ``times = frame_numbers / UTK_FPS``."""
FPS_RANGE = (1e-3, 1e6)
"""Frame rates (frames/s) accepted from ``fps=`` (``--fps``) and an NPZ's ``fps``."""
MIN_STEP_S = 1e-6
"""Smallest step (s) between the ``times`` of consecutive frames that an NPZ may give."""
MAX_DURATION_S = 1e9
"""Longest time axis (s, ~32 years) a recording may have: beyond it the frame numbers or times
are corrupt (and would overflow the float32 time steps of smoothing and the feasibility
filter)."""
MAX_RESAMPLED_FRAMES = 1_000_000
"""Most frames ``resample`` makes (``ConfigError`` beyond: a rate far too high for the clip)."""

_MSR_COLUMNS = 4
_UTK_COLUMNS = 1 + 3 * N_JOINTS
_CSV_COLUMNS = 3 * N_JOINTS
_MAX_FRAME_NUMBER = 2.0**53  # integers a float64 holds exactly (and int64 too)


@dataclass(frozen=True)
class Recording:
    """One skeleton recording.

    Attributes:
      positions: ``(T, 20, 3)`` float32 joint positions in metres, Kinect SDK joint order; rows of
        invalid frames are 0.
      valid: ``(T,)`` bool, ``False`` where the frame was all zeros, had a non-finite value, or was
        marked invalid in the file (npz ``valid``).
      source: the path the recording was read from.
      format: the format it was read as (``"msr"``, ``"utkinect"``, ``"npz"``, ``"csv"`` or
        ``"bvh"``).
      times: ``(T,)`` float64 seconds since the first frame, strictly increasing (see the module
        docstring for where they come from).
      time_source: how ``times`` were obtained, in words (e.g. ``"assumed 15 fps"``).
      nominal_fps: the rate a one-frame recording reports as ``fps`` (``None``: the format's
        assumed rate; a BVH's ``1 / Frame Time``).
    """

    positions: np.ndarray
    valid: np.ndarray
    source: str
    format: str
    times: np.ndarray
    time_source: str
    nominal_fps: float | None = None

    @property
    def fps(self) -> float:
        """Median frame rate, frames/s (``1 / median(diff(times))``; the nominal rate of a
        one-frame recording)."""
        if len(self.times) < 2:
            return float(self._nominal_fps)
        return float(1.0 / np.median(np.diff(self.times)))

    @property
    def _nominal_fps(self) -> float:
        if self.nominal_fps is not None:
            return self.nominal_fps
        return {"msr": MSR_FPS, "utkinect": UTK_FPS}.get(self.format, KINECT_FPS)


def read_skeleton(
    path: str | os.PathLike[str],
    format: Format = "auto",
    fps: float | None = None,
    *,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
    scale: float | str = "auto",
) -> Recording:
    """Read a skeleton file into a ``Recording`` (``(T, 20, 3)`` float32 positions, SDK order).

    Args:
      path: the file.
      format: ``"auto"`` (detect; see the module docstring), ``"msr"``, ``"utkinect"``, ``"npz"``,
        ``"csv"`` or ``"bvh"``.
      fps: frames per second; when given, ``times = arange(T) / fps`` replaces whatever timing
        the file has or the format assumes. A BVH states its own rate (``Frame Time``): there
        ``fps`` resamples the clip to ``fps`` frames per second (``resample``).
      bvh_map: BVH only: the joint map, ``"auto"`` (detect a preset), ``"cmu"``, ``"cmu-mb"``,
        a JSON / TOML file or a dict of Kinect joint -> BVH joint (``jaxproj.io.bvh``).
      scale: BVH only: metres per file unit, a unit name (``jaxproj.io.bvh.UNITS``) or ``"auto"``.

    Returns:
      ``Recording`` with ``positions`` ``(T, 20, 3)`` float32 and ``valid`` ``(T,)`` bool.

    Raises:
      InputError: missing / empty / malformed file or unknown format; the message names the file
        and the problem.
      ConfigError: ``fps`` out of range, a bad BVH ``scale`` or map dict.
    """
    if format not in FORMATS:
        raise InputError(path, f"unknown format {format!r}; expected one of {', '.join(FORMATS)}")
    if fps is not None:
        check_fps(fps)
    data = _read_bytes(path)
    if format == "auto":
        format = _detect(path, data)
    times: np.ndarray | None = None
    if format == "bvh":
        from jaxproj.io.bvh import read_bvh

        return read_bvh(path, bvh_map, scale, fps, data=data)
    if format == "npz":
        positions, valid, times, source = _parse_npz(path, data)
    elif format == "msr":
        positions, valid = _read_msr_rows(path, data)[:, list(MSR_TO_SDK), :3], None
        source = f"assumed {MSR_FPS:g} fps"
    elif format == "utkinect":
        frames, positions = _read_utkinect_rows(path, data)
        valid, times = None, (frames - frames[0]) / UTK_FPS
        source = f"frame numbers at {UTK_FPS:g} fps"
    else:
        positions, valid = _parse_csv(path, data), None
        source = f"assumed {KINECT_FPS:g} fps"
    if fps is not None:
        times, source = None, f"given {fps:g} fps"
    if times is None:
        rate = fps or (MSR_FPS if format == "msr" else KINECT_FPS)
        times = np.arange(len(positions), dtype=np.float64) / rate
    times = np.asarray(times, np.float64)
    if times[-1] - times[0] > MAX_DURATION_S:
        raise InputError(
            path,
            f"the time axis spans {times[-1] - times[0]:g} s (more than {MAX_DURATION_S:g} s): "
            "corrupt frame numbers or times",
        )
    rec = _recording(positions, valid, str(path), format)
    return dataclasses.replace(rec, times=times, time_source=source)


def check_fps(fps: float) -> None:
    """``ConfigError`` unless ``fps`` is a frame rate within ``FPS_RANGE``."""
    if not (np.isfinite(fps) and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        raise ConfigError(
            f"fps must be a frame rate in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}] frames per "
            f"second, got {fps}"
        )


def resample(rec: Recording, fps: float) -> Recording:
    """The recording on a uniform grid of ``fps`` frames per second (linear interpolation).

    The grid is ``k / fps`` for every ``k`` with ``k / fps`` within the recording's time span
    (at least one frame). Each new frame interpolates joint positions linearly between the two
    recorded frames around it; it is invalid (zeros) if either of them is. Positions of a
    rotating bone shorten slightly between frames (by ``1 - cos(a / 2)`` for a turn ``a`` in one
    frame step; a 10 degree step: 0.4 %); the descriptor uses directions only.

    Args:
      rec: any ``Recording``.
      fps: the new rate, frames/s, within ``FPS_RANGE``.

    Returns:
      A ``Recording`` with ``times = arange(N) / fps`` and ``time_source`` extended by
      ``", resampled to <fps> fps (linear)"``.
    """
    check_fps(fps)
    t = np.asarray(rec.times, np.float64)
    span = float(t[-1] - t[0])
    n = int(np.floor(span * fps * (1.0 + 1e-12) + 1e-9)) + 1
    if n > MAX_RESAMPLED_FRAMES:
        raise ConfigError(
            f"resampling {span:g} s to {fps:g} fps would make {n} frames (more than "
            f"{MAX_RESAMPLED_FRAMES}): choose a lower rate"
        )
    grid = np.arange(n, dtype=np.float64) / fps
    hi = np.clip(np.searchsorted(t - t[0], grid, side="left"), 0, len(t) - 1)
    lo = np.maximum(hi - 1, 0)
    step = t[hi] - t[lo]
    w = np.where(step > 0, (grid - (t[lo] - t[0])) / np.where(step > 0, step, 1.0), 1.0)
    w = np.clip(w, 0.0, 1.0)
    pos = rec.positions.astype(np.float64)
    out = (1.0 - w)[:, None, None] * pos[lo] + w[:, None, None] * pos[hi]
    exact_lo, exact_hi = w <= 0.0, w >= 1.0
    valid = (rec.valid[lo] | exact_hi) & (rec.valid[hi] | exact_lo)
    out = out.astype(np.float32)
    out[~valid] = 0.0
    source = f"{rec.time_source}, resampled to {fps:g} fps (linear)"
    return dataclasses.replace(
        rec, positions=out, valid=valid, times=grid, time_source=source, nominal_fps=float(fps)
    )


_SNIFF_BYTES = 1 << 16


def recording_format(path: str | os.PathLike[str]) -> tuple[str | None, str]:
    """Is this file (in a folder of recordings) a skeleton recording? ``(format, "")`` if it
    looks like one, ``(None, why not)`` otherwise; never raises.

    Only the start of the file is looked at: ``.npz``: a zip archive with a ``positions``
    member (an npz without one, e.g. a model, is not a recording; one that is not a readable
    zip is, and ``read_skeleton`` reports it); otherwise text named ``.bvh`` or whose first
    non-blank line is ``HIERARCHY`` (BVH), is 60 comma-separated fields (CSV, header or
    numbers), or 4 (MSR Action3D) or 61 (UTKinect) whitespace-separated numbers. Hidden files,
    empty files, binaries and documentation or label files (``SOURCE.md``, UTKinect's
    ``actionLabel.txt``) are not recordings. A file that passes may still be malformed further
    on: ``read_skeleton`` decides.
    """
    p = Path(path)
    if p.name.startswith("."):
        return None, "hidden file"
    if not p.is_file():
        return None, "not a regular file"
    try:
        with open(p, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as err:
        return None, f"cannot be read ({_one_line(err)})"
    if not head:
        return None, "empty file"
    if p.suffix.lower() == ".npz" or head[:4] == b"PK\x03\x04":
        try:
            with zipfile.ZipFile(p) as zf:
                names = zf.namelist()
        except (OSError, zipfile.BadZipFile, ValueError):
            return "npz", ""  # looks like an npz: read_skeleton says what is wrong with it
        if "positions.npy" not in names:
            return None, "an npz archive without 'positions' (not a recording)"
        return "npz", ""
    lines = head.split(b"\n")
    complete = lines if len(head) < _SNIFF_BYTES else lines[:-1]
    first = next((line for line in complete if line.strip()), None)
    if first is None:
        return None, "no text line to recognise (blank or binary)"
    try:
        text = first.decode("utf-8-sig" if first is lines[0] else "utf-8").strip()
    except UnicodeDecodeError:
        return None, "not a text file"
    if p.suffix.lower() == ".bvh" or text.split()[:1] == ["HIERARCHY"]:
        return "bvh", ""
    fields = text.split(",") if "," in text else text.split()
    if "," in text:
        if len(fields) == _CSV_COLUMNS:
            return "csv", ""
        return None, f"first line has {len(fields)} comma-separated fields, not {_CSV_COLUMNS}"
    if len(fields) in (_MSR_COLUMNS, _UTK_COLUMNS) and all(_is_number(f) for f in fields):
        return ("msr" if len(fields) == _MSR_COLUMNS else "utkinect"), ""
    return None, (
        f"first line is not {_MSR_COLUMNS} (MSR Action3D) or {_UTK_COLUMNS} (UTKinect) numbers "
        "nor HIERARCHY (BVH)"
    )


# --- helpers ------------------------------------------------------------------------------------


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def _read_bytes(path: str | os.PathLike[str]) -> bytes:
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, "is a directory, not a file") from None
    except OSError as err:
        raise InputError(path, f"cannot read file ({_one_line(err)})") from None
    if not data:
        raise InputError(path, "file is empty (0 bytes)")
    return data


def _decode(path: str | os.PathLike[str], data: bytes) -> str:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(
            path, f"not a text file (byte 0x{data[err.start]:02x} at offset {err.start})"
        ) from None
    if not text.strip():
        raise InputError(path, "file is empty (only whitespace)")
    return text


def _detect(path: str | os.PathLike[str], data: bytes) -> str:
    suffix = Path(path).suffix.lower()
    if suffix == ".npz" or data[:4] == b"PK\x03\x04":
        return "npz"
    if suffix == ".csv":
        return "csv"
    if suffix == ".bvh":
        return "bvh"
    text = _decode(path, data)
    first = next(line for line in text.splitlines() if line.strip())
    if first.split()[:1] == ["HIERARCHY"]:
        return "bvh"
    if "," in first:
        return "csv"
    n = len(first.split())
    if n == _MSR_COLUMNS:
        return "msr"
    if n == _UTK_COLUMNS:
        return "utkinect"
    raise InputError(
        path,
        f"cannot detect the format: first line has {n} columns, expected {_MSR_COLUMNS} "
        f"(MSR Action3D) or {_UTK_COLUMNS} (UTKinect); give the format "
        "(--format on the command line, format= in Python)",
    )


def _first_bad_token(tokens: list[str]) -> int:
    """Index of the first token numpy cannot convert to float (searched in chunks)."""
    step = 1024
    for lo in range(0, len(tokens), step):
        try:
            np.array(tokens[lo : lo + step], dtype=np.float64)
        except ValueError:
            for i in range(lo, min(lo + step, len(tokens))):
                try:
                    np.array(tokens[i], dtype=np.float64)
                except ValueError:
                    return i
    raise AssertionError("unreachable: no bad token found")  # pragma: no cover


def _to_table(
    path: str | os.PathLike[str], tokens: list[str], line_numbers: np.ndarray, n_columns: int
) -> np.ndarray:
    """``(n_rows, n_columns)`` float64 from row-major tokens of rows with n_columns each."""
    try:
        flat = np.array(tokens, dtype=np.float64)
    except ValueError:
        i = _first_bad_token(tokens)
        line, column = line_numbers[i // n_columns], i % n_columns + 1
        raise InputError(
            path, f"line {line}, column {column}: non-numeric token {tokens[i]!r}"
        ) from None
    return flat.reshape(-1, n_columns)


def _check_counts(
    path: str | os.PathLike[str],
    counts: np.ndarray,
    line_numbers: np.ndarray,
    n_columns: int,
    what: str,
) -> None:
    if counts.size == 0:
        raise InputError(path, "file has no data rows")
    bad = np.flatnonzero(counts != n_columns)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            path,
            f"line {line_numbers[i]}: found {counts[i]} columns, expected {n_columns} ({what})",
        )


_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True  # ASCII whitespace of str.split()


def _whitespace_table(
    path: str | os.PathLike[str], text: str, n_columns: int, what: str
) -> tuple[np.ndarray, np.ndarray]:
    """Whitespace-separated text -> (``(n_rows, n_columns)`` float64, ``(n_rows,)`` 1-based lines).

    Blank lines are skipped. For ASCII text the columns per line are counted with vectorised byte
    operations (no Python loop per line); other text falls back to a per-line split.
    """
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    if text.isascii():
        tokens = text.split()
        b = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
        ws = _WHITESPACE[b]
        starts = ~ws
        starts[1:] &= ws[:-1]
        line_of_byte = np.cumsum(b == 10)
        token_line = line_of_byte[starts]
        assert token_line.size == len(tokens)
        counts = np.bincount(token_line, minlength=int(line_of_byte[-1]) + 1)
        lines = np.flatnonzero(counts)
        counts, lines = counts[lines], lines + 1
    else:  # str.split() also splits at non-ASCII whitespace: split line by line
        per_line = [line.split() for line in text.split("\n")]
        lines = np.array([i for i, f in enumerate(per_line, start=1) if f], dtype=np.int64)
        counts = np.array([len(f) for f in per_line if f], dtype=np.int64)
        tokens = [t for f in per_line for t in f]
    _check_counts(path, counts, lines, n_columns, what)
    return _to_table(path, tokens, lines, n_columns), lines


def _read_msr_rows(path: str | os.PathLike[str], data: bytes | None = None) -> np.ndarray:
    """MSR Action3D text -> ``(T, 20, 4)`` float64 ``x y z confidence`` in the *MSR* joint order."""
    if data is None:
        data = _read_bytes(path)
    table, _ = _whitespace_table(
        path, _decode(path, data), _MSR_COLUMNS, "MSR Action3D: x y z confidence"
    )
    if table.shape[0] % N_JOINTS:
        raise InputError(
            path,
            f"found {table.shape[0]} rows, not a multiple of {N_JOINTS} "
            f"(MSR Action3D has {N_JOINTS} joint rows per frame)",
        )
    return table.reshape(-1, N_JOINTS, _MSR_COLUMNS)


def _read_utkinect_rows(
    path: str | os.PathLike[str], data: bytes | None = None, *, order: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """UTKinect text -> (``(T,)`` int64 frame numbers, ``(T, 20, 3)`` float64 positions, SDK order).

    A line whose frame number repeats an earlier line's is dropped (the first one is kept); the
    frames come out ordered by frame number (``order=False``: in file order, for the bundler,
    which refuses a file out of order).
    """
    if data is None:
        data = _read_bytes(path)
    table, lines = _whitespace_table(
        path, _decode(path, data), _UTK_COLUMNS, "UTKinect: frame number + 20 x y z"
    )
    frame = table[:, 0]
    bad = np.flatnonzero(~np.isfinite(frame) | (frame != np.round(frame)))
    if bad.size:
        i = int(bad[0])
        raise InputError(path, f"line {lines[i]}: frame number {frame[i]:g} is not an integer")
    bad = np.flatnonzero(np.abs(frame) > _MAX_FRAME_NUMBER)
    if bad.size:
        i = int(bad[0])
        raise InputError(
            path, f"line {lines[i]}: frame number {frame[i]:g} is out of range (|n| <= 2**53)"
        )
    _, keep = np.unique(frame, return_index=True)  # first line of each number, by frame number
    if not order:
        keep = np.sort(keep)
    return frame[keep].astype(np.int64), table[keep, 1:].reshape(-1, N_JOINTS, 3)


def _is_number(token: str) -> bool:
    try:
        np.array(token, dtype=np.float64)
    except ValueError:
        return False
    return True


def _parse_csv(path: str | os.PathLike[str], data: bytes) -> np.ndarray:
    rows, numbers = [], []
    first = True
    for i, line in enumerate(_decode(path, data).splitlines(), start=1):
        if not line.strip():
            continue
        fields = line.split(",")
        if first:
            first = False
            if not any(_is_number(f) for f in fields):
                continue  # the one allowed header line of column names
        rows.append(fields)
        numbers.append(i)
    if not rows:
        raise InputError(path, "file has a header line but no data rows")
    counts = np.fromiter(map(len, rows), dtype=np.int64, count=len(rows))
    lines = np.array(numbers, dtype=np.int64)
    _check_counts(path, counts, lines, _CSV_COLUMNS, "CSV: x,y,z for 20 joints")
    table = _to_table(path, [t for fields in rows for t in fields], lines, _CSV_COLUMNS)
    return table.reshape(-1, N_JOINTS, 3)


def _parse_npz(
    path: str | os.PathLike[str], data: bytes
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, str]:
    """NPZ -> (positions, valid or None, times or None, time source)."""
    if data[:4] != b"PK\x03\x04":
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
                ("positions", positions), ("valid", valid), ("times", times), ("fps", rate)
            ):
                if value is not None and not isinstance(value, np.ndarray):
                    raise InputError(
                        path, f"corrupt or unreadable npz archive (member {key!r} is not .npy)"
                    )
    except InputError:
        raise
    except Exception as err:  # zipfile / zlib / numpy format errors of a corrupt archive
        raise InputError(path, f"corrupt or unreadable npz archive ({_one_line(err)})") from None
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
        times = _check_times(path, times, shape[0])
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


def _check_times(path: str | os.PathLike[str], times: np.ndarray, n: int) -> np.ndarray:
    """Validate a file's ``times``: ``(n,)`` finite, strictly increasing; returned from 0."""
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


def _recording(
    positions: np.ndarray, valid: np.ndarray | None, source: str, format: str
) -> Recording:
    """Cast to float32, mark all-zero / non-finite (/ file-invalid) frames and zero them."""
    with np.errstate(over="ignore", invalid="ignore"):
        pos = np.asarray(positions).astype(np.float32)
    ok = np.isfinite(pos).all(axis=(1, 2)) & (pos != 0).any(axis=(1, 2))
    if valid is not None:
        ok &= valid
    pos[~ok] = 0.0
    times = np.arange(len(pos), dtype=np.float64)
    return Recording(pos, ok, source, format, times, "frame index")
