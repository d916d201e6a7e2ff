"""The bundled MSR Action3D skeletons (567 sequences, 20 actions x 10 subjects x 2-3 takes), and
a UTKinect-Action3D subset (10 recordings; section at the end).

(Over 500 lines on purpose: each archive's format is documented, written and read in one place.)

``msr_action3d()`` returns every sequence as a ``MotionSequence`` with ``(T, 20, 3)`` float32
positions in metres, Kinect SDK joint order (``jaxproj.human.skeleton.JOINT_NAMES``), camera frame with y
up, z away from the sensor and the subject's right side at larger x. Frames where the skeleton was
lost (all zeros in the source) are kept and marked ``False`` in ``valid``; no sequence is dropped.
Source, citation and licence caveat: ``jaxproj/data/MSR_ACTION3D.md``.

The data live in one compressed archive, ``jaxproj/data/msr_action3d.npz``, built from the original
text files by ``bundle_msr_action3d`` (``python -m jaxproj.io.datasets SRC_DIR OUT.npz``). Archive
layout (format 1; S sequences, N frames in total; every array is plain numeric or unicode, so
``np.load(..., allow_pickle=False)`` reads it):

- ``positions_um_planes`` ``(4, N*20*3)`` uint8: the positions as little-endian int32 micrometres
  (``round(x * 1e6)``; lossless because the source has exactly 6 decimals), array ``(N, 20, 3)``
  in SDK order, flattened, split into its 4 byte planes (plane k = byte k of every int32; the
  "shuffle" filter of HDF5/Blosc), which deflate compresses ~30 % better than plain int32.
  Decode: ``np.ascontiguousarray(planes.T).view("<i4").reshape(N, 20, 3) / 1e6``.
- ``confidence_values`` ``(K,)`` float64 (sorted distinct values) and ``confidence_index``
  ``(N, 20)`` uint16: confidence = ``confidence_values[confidence_index]`` (lossless; SDK order).
- ``offsets`` ``(S + 1,)`` int64: sequence i is frames ``offsets[i]:offsets[i + 1]``.
- ``names`` ``(S,)`` unicode (``"a01_s01_e01"``, sorted), ``action`` / ``subject`` / ``take``
  ``(S,)`` uint8 (1-based numbers), ``cvpr12`` ``(S,)`` bool (listed in
  ``files_used_in_cvpr12_paper.txt``).
- ``joint_names`` ``(20,)`` unicode, ``format_version`` int64 scalar.

The archive is written with fixed zip timestamps, so the same sources give byte-identical files.

UTKinect-Action3D (a second, independent Kinect v1 dataset; 10 of its 20 recordings)
-------------------------------------------------------------------------------------
``utkinect_action3d()`` returns the labelled action segments (or, with ``segments=False``, the
ten whole recordings) of ``jaxproj/data/utkinect_action3d.npz`` as ``MotionSequence``s with the
same ``(T, 20, 3)`` float32 metres, SDK joint order and camera frame, plus ``frame_numbers`` and
``times`` (``frame_numbers / UTK_FPS`` seconds). Source, citation and licence caveat:
``jaxproj/data/UTKINECT_ACTION3D.md``. Built from ``joints_sXX_eYY.txt`` and ``actionLabel.txt``
by ``bundle_utkinect_action3d`` (``python -m jaxproj.io.datasets --dataset utkinect SRC_DIR
OUT.npz``). Archive layout (format 1; R recordings, N frames in total; no pickles):

- ``dataset`` unicode scalar ``"utkinect_action3d"``, ``format_version`` int64 scalar,
  ``joint_names`` ``(20,)`` and ``action_names`` ``(10,)`` unicode (``UTK_ACTION_NAMES``).
- ``positions_um_planes`` ``(4, N*20*3)`` uint8: int32 micrometres in byte planes, exactly as in
  the MSR archive (lossless: the source has exactly 6 decimals).
- ``frame_numbers`` ``(N,)`` int32: the source's frame number of each kept frame (strictly
  increasing within a recording; a repeated frame number keeps its first line, the rule of
  ``readers.read_skeleton(format="utkinect")``).
- ``offsets`` ``(R + 1,)`` int64: recording i is frames ``offsets[i]:offsets[i + 1]``.
- ``names`` ``(R,)`` unicode (``"s03_e01"``, sorted), ``subject`` / ``take`` ``(R,)`` uint8.
- ``segments`` ``(R, 10, 2)`` int32: ``[start, end]`` frame numbers (inclusive) of action
  ``a`` (1-based) of recording i at ``segments[i, a - 1]``; ``-1, -1`` where ``actionLabel.txt``
  says ``NaN NaN`` (absent).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import io
import os
import re
import sys
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import JOINT_NAMES, N_JOINTS
from jaxproj.io.readers import MSR_FPS, MSR_TO_SDK, _read_msr_rows, _read_utkinect_rows
from jaxproj.io.readers import UTK_FPS as _UTK_FPS

DATA_PATH = Path(__file__).parents[1] / "data" / "msr_action3d.npz"
"""The bundled archive."""

FORMAT_VERSION = 1

ACTION_NAMES: tuple[str, ...] = (
    "high arm wave", "horizontal arm wave", "hammer", "hand catch", "forward punch",
    "high throw", "draw x", "draw tick", "draw circle", "hand clap",
    "two hand wave", "side-boxing", "bend", "forward kick", "side kick",
    "jogging", "tennis swing", "tennis serve", "golf swing", "pickup & throw",
)  # fmt: skip
"""Names of actions a01..a20: ``ACTION_NAMES[action - 1]``."""

ARM_ACTIONS: tuple[int, ...] = (*range(1, 13), 17, 18, 19)
"""1-based numbers of the upper-body-rich actions (a01-a12, a17-a19)."""

N_SUBJECTS = 10
N_ACTIONS = len(ACTION_NAMES)

_FILE_RE = re.compile(r"^a(\d{2})_s(\d{2})_e(\d{2})_skeleton3D\.txt$")
_CVPR12_LIST = "files_used_in_cvpr12_paper.txt"
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)

UTK_DATA_PATH = Path(__file__).parents[1] / "data" / "utkinect_action3d.npz"
"""The bundled UTKinect-Action3D archive."""

UTK_FORMAT_VERSION = 1
_UTK_DATASET = "utkinect_action3d"

UTK_ACTION_NAMES: tuple[str, ...] = (
    "walk", "sitDown", "standUp", "pickUp", "carry",
    "throw", "push", "pull", "waveHands", "clapHands",
)  # fmt: skip
"""Names of the UTKinect actions, in the order performed: ``UTK_ACTION_NAMES[action - 1]``."""

UTK_UPPER_BODY_ACTIONS: tuple[int, ...] = (6, 7, 8, 9, 10)
"""1-based numbers of the upper-body-rich UTKinect actions: throw, push, pull, waveHands,
clapHands."""

UTK_FPS = _UTK_FPS
"""Nominal capture rate of UTKinect-Action3D (frames/s, from the dataset's description;
``readers.UTK_FPS``).

Only tracked frames were saved, so frame numbers jump; ``times = frame_numbers / UTK_FPS`` are
seconds since the capture's frame 0 and are approximate (the rate is nominal, not measured). The
frame numbers are all even and step by 2 at least, and walking speeds come out at 0.3-0.4 m/s, so
the counter may advance 2 per captured frame and these times be up to 2x too long (see the Notes
of ``jaxproj/data/UTKINECT_ACTION3D.md``)."""

UTK_N_SUBJECTS = 10
"""UTKinect-Action3D has subjects 1..10; the bundled subset holds 3, 4, 6, 7 and 9."""

_UTK_FILE_RE = re.compile(r"^joints_s(\d{2})_e(\d{2})\.txt$")
_UTK_LABELS = "actionLabel.txt"
_UTK_BLOCK_RE = re.compile(r"^s(\d{2})_e(\d{2})$")


@dataclass(frozen=True)
class MotionSequence:
    """One recorded sequence: MSR Action3D, a UTKinect-Action3D segment / recording, or a file.

    Attributes:
      name: ``"aXX_sYY_eZZ"`` (MSR), ``"sXX_eYY_<action>"`` / ``"sXX_eYY"`` (UTKinect segment /
        whole recording) or the file stem (folder).
      action: 1-based action number (MSR: ``ACTION_NAMES[action - 1]``; UTKinect:
        ``UTK_ACTION_NAMES[action - 1]``); 0 when unknown (whole UTKinect recording, folder file).
      subject: 1-based subject number (1..10).
      take: 1-based execution number (MSR 1..3, UTKinect 1..2).
      positions: ``(T, 20, 3)`` float32 metres, Kinect SDK joint order; invalid frames are 0.
      confidence: ``(T, 20)`` float32 per-joint tracking confidence in [0, 1] (SDK order; all 1
        where the source has none).
      valid: ``(T,)`` bool, frame is not all zeros and all finite.
      frame_numbers: ``(T,)`` int64 source frame numbers, strictly increasing (UTKinect, whose
        frame numbers jump over untracked frames); ``None`` where frames are consecutive (MSR).
      times: ``(T,)`` float64 seconds: ``frame_numbers / UTK_FPS`` (UTKinect, approximate), the
        reader's time axis (folder files, see ``jaxproj.io.readers``); ``None`` for MSR Action3D
        (``sequence_times`` then assumes ``readers.MSR_FPS``).
    """

    name: str
    action: int
    subject: int
    take: int
    positions: np.ndarray
    confidence: np.ndarray
    valid: np.ndarray
    frame_numbers: np.ndarray | None = None
    times: np.ndarray | None = None


def sequence_times(seq: MotionSequence) -> np.ndarray:
    """``(T,)`` float64 seconds of each frame of ``seq``, from its first frame.

    ``seq.times`` when the sequence has them (UTKinect; folder files: the reader's time axis),
    otherwise frames ``1 / readers.MSR_FPS`` apart (MSR Action3D has no timing; 15 frames/s is
    an assumption, see ``jaxproj.io.readers``).
    """
    if seq.times is not None:
        t = np.asarray(seq.times, np.float64)
        return t - t[0]
    return np.arange(len(seq.valid), dtype=np.float64) / MSR_FPS


# --- bundling -------------------------------------------------------------------------------------


def bundle_msr_action3d(src_dir: str | os.PathLike[str], out_path: str | os.PathLike[str]) -> None:
    """Convert the raw MSR Action3D text files of ``src_dir`` into one compressed npz.

    Reads every ``aXX_sYY_eZZ_skeleton3D.txt`` (sorted by name) and, if present,
    ``files_used_in_cvpr12_paper.txt``; writes ``out_path`` in the layout of the module docstring.

    Raises:
      InputError: no sequence files, a malformed file (see ``jaxproj.io.readers``), or coordinates
        that int32 micrometres cannot hold exactly (more than 6 decimals, non-finite, > 2 km).
    """
    src = Path(src_dir)
    if not src.is_dir():
        raise InputError(src, "not a directory")
    files = sorted(p for p in src.iterdir() if _FILE_RE.match(p.name))
    if not files:
        raise InputError(src, "no aXX_sYY_eZZ_skeleton3D.txt files")
    names, numbers, positions, confidence = [], [], [], []
    for path in files:
        raw = _read_msr_rows(path)[:, list(MSR_TO_SDK), :]  # (T, 20, 4) float64, SDK order
        names.append(path.name[: -len("_skeleton3D.txt")])
        numbers.append([int(g) for g in _FILE_RE.match(path.name).groups()])
        positions.append(_micrometres(path, raw[..., :3]))
        confidence.append(raw[..., 3])
    cvpr12_path = src / _CVPR12_LIST
    used = set(cvpr12_path.read_text().split()) if cvpr12_path.is_file() else set()
    pos = np.concatenate(positions)
    conf_values, conf_index = np.unique(np.concatenate(confidence), return_inverse=True)
    index_dtype = np.uint16 if conf_values.size <= 2**16 else np.uint32
    lengths = [len(p) for p in positions]
    arrays = {
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
        "joint_names": np.array(JOINT_NAMES),
        "names": np.array(names),
        "action": np.array([n[0] for n in numbers], dtype=np.uint8),
        "subject": np.array([n[1] for n in numbers], dtype=np.uint8),
        "take": np.array([n[2] for n in numbers], dtype=np.uint8),
        "cvpr12": np.array([n in used for n in names], dtype=bool),
        "offsets": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "positions_um_planes": _byte_planes(pos),
        "confidence_values": conf_values.astype(np.float64),
        "confidence_index": conf_index.reshape(pos.shape[:2]).astype(index_dtype),
    }
    _write_npz(Path(out_path), arrays)


def _micrometres(path: Path, xyz: np.ndarray) -> np.ndarray:
    """``(..., 3)`` float64 metres with <= 6 decimals -> the same shape as ``<i4`` micrometres.

    Raises:
      InputError: a value that int32 micrometres cannot hold exactly (more than 6 decimals,
        non-finite, > 2 km).
    """
    with np.errstate(invalid="ignore", over="ignore"):
        um = np.round(xyz * 1e6)
    exact = np.isfinite(um).all() and np.abs(um).max() < 2**31
    if not exact or np.abs(um / 1e6 - xyz).max() > 1e-9:
        raise InputError(
            path,
            "coordinates not representable as int32 micrometres (non-finite, > 2 km, "
            "or more than 6 decimals)",
        )
    return um.astype("<i4")


def _byte_planes(um: np.ndarray) -> np.ndarray:
    """``<i4`` array (any shape, n values) -> ``(4, n)`` uint8 byte planes (plane k = byte k)."""
    flat = np.ascontiguousarray(um, dtype="<i4").reshape(-1)
    return np.ascontiguousarray(flat.view(np.uint8).reshape(-1, 4).T)


def _from_planes(planes: np.ndarray, n_frames: int) -> np.ndarray:
    """Inverse of ``_byte_planes`` for positions: ``(4, n_frames*60)`` uint8 -> float32 metres
    ``(n_frames, 20, 3)``."""
    um = np.ascontiguousarray(planes.T).view("<i4").reshape(n_frames, N_JOINTS, 3)
    return (um / 1e6).astype(np.float32)


def _valid(positions: np.ndarray) -> np.ndarray:
    """``(T, 20, 3)`` -> ``(T,)`` bool: not all zeros and all finite."""
    return (positions != 0).any(axis=(1, 2)) & np.isfinite(positions).all(axis=(1, 2))


def bundle_utkinect_action3d(
    src_dir: str | os.PathLike[str], out_path: str | os.PathLike[str]
) -> None:
    """Convert the raw UTKinect-Action3D text files of ``src_dir`` into one compressed npz.

    Reads every ``joints_sXX_eYY.txt`` (sorted by name) with the reader of
    ``readers.read_skeleton(format="utkinect")`` (a repeated frame number keeps its first line)
    and the segment table ``actionLabel.txt`` (blocks of a ``sXX_eYY`` line and one
    ``action: start end`` line per action of ``UTK_ACTION_NAMES``; ``NaN NaN`` = absent; blocks of
    recordings not in ``src_dir`` are ignored); writes ``out_path`` in the layout of the module
    docstring (fixed zip timestamps: byte-identical for the same input).

    Raises:
      InputError: no recording files, no ``actionLabel.txt`` or no block in it for a recording,
        a malformed file (see ``jaxproj.io.readers``) or label line, frame numbers that do not
        increase after the repeats are dropped or are negative / beyond int32, or coordinates that
        int32 micrometres cannot hold exactly.
    """
    src = Path(src_dir)
    if not src.is_dir():
        raise InputError(src, "not a directory")
    files = sorted(p for p in src.iterdir() if _UTK_FILE_RE.match(p.name))
    if not files:
        raise InputError(src, "no joints_sXX_eYY.txt files")
    labels = _read_utk_labels(src / _UTK_LABELS)
    names, numbers, frames, positions, segments = [], [], [], [], []
    for path in files:
        frame, xyz = _read_utkinect_rows(path, order=False)
        if frame[0] < 0 or frame[-1] >= 2**31 or (np.diff(frame) <= 0).any():
            raise InputError(
                path,
                "frame numbers must be >= 0, < 2**31 and increase (after dropping repeats)",
            )
        name = path.name[len("joints_") : -len(".txt")]
        if name not in labels:
            raise InputError(src / _UTK_LABELS, f"no segment block for {name}")
        names.append(name)
        numbers.append([int(g) for g in _UTK_FILE_RE.match(path.name).groups()])
        frames.append(frame.astype("<i4"))
        positions.append(_micrometres(path, xyz))
        segments.append(labels[name])
    lengths = [len(f) for f in frames]
    arrays = {
        "dataset": np.array(_UTK_DATASET),
        "format_version": np.array(UTK_FORMAT_VERSION, dtype=np.int64),
        "joint_names": np.array(JOINT_NAMES),
        "action_names": np.array(UTK_ACTION_NAMES),
        "names": np.array(names),
        "subject": np.array([n[0] for n in numbers], dtype=np.uint8),
        "take": np.array([n[1] for n in numbers], dtype=np.uint8),
        "offsets": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "frame_numbers": np.concatenate(frames),
        "positions_um_planes": _byte_planes(np.concatenate(positions)),
        "segments": np.stack(segments).astype(np.int32),
    }
    _write_npz(Path(out_path), arrays)


def _read_utk_labels(path: Path) -> dict[str, np.ndarray]:
    """``actionLabel.txt`` -> ``{"sXX_eYY": (10, 2) int64 [start, end]}`` (-1, -1: absent).

    Raises:
      InputError: missing file, a line that is neither ``sXX_eYY`` nor ``action: start end``, an
        unknown or repeated action, an action missing from a block, ``start > end``, non-integer
        bounds, or only one of the two bounds ``NaN``.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(path, "segment labels not found") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(path, f"cannot read segment labels ({type(err).__name__})") from None
    blocks: dict[str, np.ndarray] = {}
    seen: dict[str, set[str]] = {}
    current: str | None = None
    for i, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        if _UTK_BLOCK_RE.match(line):
            if line in blocks:
                raise InputError(path, f"line {i}: block {line} repeated")
            current = line
            blocks[current] = np.full((len(UTK_ACTION_NAMES), 2), -1, dtype=np.int64)
            seen[current] = set()
            continue
        action, colon, bounds = line.partition(":")
        fields = bounds.split()
        action = action.strip()
        if current is None or not colon or len(fields) != 2:
            raise InputError(
                path, f"line {i}: expected 'sXX_eYY' or 'action: start end', got {line!r}"
            )
        if action not in UTK_ACTION_NAMES or action in seen[current]:
            what = "repeated" if action in seen[current] else "unknown"
            raise InputError(path, f"line {i}: {what} action {action!r} in block {current}")
        seen[current].add(action)
        if fields == ["NaN", "NaN"]:
            continue
        if not all(re.fullmatch(r"\d{1,9}", f) for f in fields) or int(fields[0]) > int(fields[1]):
            raise InputError(
                path,
                f"line {i}: bounds must be integers 0 <= start <= end < 1e9 (or 'NaN NaN'), "
                f"got {bounds.strip()!r}",
            )
        blocks[current][UTK_ACTION_NAMES.index(action)] = [int(f) for f in fields]
    for name, actions in seen.items():
        missing = [a for a in UTK_ACTION_NAMES if a not in actions]
        if missing:
            raise InputError(path, f"block {name} lacks actions {missing}")
    return blocks


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Like ``np.savez_compressed`` but deterministic (fixed timestamps, level 9), atomic."""
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w") as zf:
        for key, array in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(array), allow_pickle=False)
            info = zipfile.ZipInfo(key + ".npy", date_time=_ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue(), compresslevel=9)
    os.replace(tmp, path)


# --- loading --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Bundle:
    sequences: tuple[MotionSequence, ...]
    cvpr12: tuple[bool, ...]


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _read_archive(path: str | os.PathLike[str], rebuild: str) -> dict[str, np.ndarray]:
    """Every member of an npz archive; ``rebuild`` is the hint given when it is missing."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError(path, f"dataset archive not found; rebuild it with {rebuild}") from None
    except Exception as err:  # corrupt zip / npy member
        raise InputError(path, f"corrupt dataset archive ({type(err).__name__}: {err})") from None


def _load(path: str | os.PathLike[str]) -> _Bundle:
    """Decode an archive written by ``bundle_msr_action3d`` (arrays are read-only views)."""
    d = _read_archive(
        path,
        "`python -m jaxproj.io.datasets SRC_DIR OUT.npz` (see jaxproj/data/MSR_ACTION3D.md)",
    )
    if int(d.get("format_version", -1)) != FORMAT_VERSION or "dataset" in d:
        raise InputError(path, f"unsupported dataset archive format (expected {FORMAT_VERSION})")
    offsets = d["offsets"]
    positions = _readonly(_from_planes(d["positions_um_planes"], int(offsets[-1])))
    confidence = _readonly(d["confidence_values"][d["confidence_index"]].astype(np.float32))
    valid = _readonly(_valid(positions))
    sequences = tuple(
        MotionSequence(
            name=str(name),
            action=int(a),
            subject=int(s),
            take=int(t),
            positions=positions[lo:hi],
            confidence=confidence[lo:hi],
            valid=valid[lo:hi],
        )
        for name, a, s, t, lo, hi in zip(
            d["names"],
            d["action"],
            d["subject"],
            d["take"],
            offsets[:-1],
            offsets[1:],
            strict=True,
        )
    )
    return _Bundle(sequences=sequences, cvpr12=tuple(bool(c) for c in d["cvpr12"]))


@functools.lru_cache(maxsize=1)
def _bundled() -> _Bundle:
    return _load(DATA_PATH)


@dataclass(frozen=True)
class _UtkBundle:
    recordings: tuple[MotionSequence, ...]
    segments: tuple[MotionSequence, ...]


def _load_utkinect(path: str | os.PathLike[str]) -> _UtkBundle:
    """Decode an archive written by ``bundle_utkinect_action3d`` (arrays are read-only views).

    Segments (``segments[i, a - 1] = [start, end]``) become the frames of recording i whose frame
    number lies in ``[start, end]``; absent segments, and segments that hold no frame, are
    skipped. Order: recordings by name, within each the segments by action number.
    """
    d = _read_archive(
        path,
        "`python -m jaxproj.io.datasets --dataset utkinect SRC_DIR OUT.npz` "
        "(see jaxproj/data/UTKINECT_ACTION3D.md)",
    )
    if str(d.get("dataset", "")) != _UTK_DATASET:
        raise InputError(path, "not a UTKinect-Action3D archive (no dataset='utkinect_action3d')")
    if int(d.get("format_version", -1)) != UTK_FORMAT_VERSION:
        raise InputError(
            path, f"unsupported dataset archive format (expected {UTK_FORMAT_VERSION})"
        )
    offsets = d["offsets"]
    positions = _readonly(_from_planes(d["positions_um_planes"], int(offsets[-1])))
    confidence = _readonly(np.ones(positions.shape[:2], np.float32))
    valid = _readonly(_valid(positions))
    frame_numbers = _readonly(d["frame_numbers"].astype(np.int64))
    times = _readonly(frame_numbers / UTK_FPS)
    recordings, segments = [], []
    for i, (name, subject, take) in enumerate(
        zip(d["names"], d["subject"], d["take"], strict=True)
    ):
        lo, hi = int(offsets[i]), int(offsets[i + 1])
        recordings.append(
            MotionSequence(
                name=str(name),
                action=0,
                subject=int(subject),
                take=int(take),
                positions=positions[lo:hi],
                confidence=confidence[lo:hi],
                valid=valid[lo:hi],
                frame_numbers=frame_numbers[lo:hi],
                times=times[lo:hi],
            )
        )
        for a, (start, end) in enumerate(d["segments"][i], start=1):
            if start < 0:  # NaN NaN in actionLabel.txt
                continue
            # frame numbers increase, so [start, end] is one slice of the recording
            a_lo = lo + int(np.searchsorted(frame_numbers[lo:hi], start, side="left"))
            a_hi = lo + int(np.searchsorted(frame_numbers[lo:hi], end, side="right"))
            if a_hi <= a_lo:
                continue
            segments.append(
                MotionSequence(
                    name=f"{name}_{UTK_ACTION_NAMES[a - 1]}",
                    action=a,
                    subject=int(subject),
                    take=int(take),
                    positions=positions[a_lo:a_hi],
                    confidence=confidence[a_lo:a_hi],
                    valid=valid[a_lo:a_hi],
                    frame_numbers=frame_numbers[a_lo:a_hi],
                    times=times[a_lo:a_hi],
                )
            )
    return _UtkBundle(recordings=tuple(recordings), segments=tuple(segments))


@functools.lru_cache(maxsize=1)
def _bundled_utkinect() -> _UtkBundle:
    return _load_utkinect(UTK_DATA_PATH)


def _select(values: Iterable[int] | None, what: str, n: int) -> frozenset[int] | None:
    if values is None:
        return None
    chosen = frozenset(int(v) for v in values)
    bad = sorted(v for v in chosen if not 1 <= v <= n)
    if bad:
        raise ConfigError(f"{what}: {bad} out of range; use 1-based numbers 1..{n}")
    return chosen


def msr_action3d(
    subjects: Iterable[int] | None = None,
    actions: Iterable[int] | None = None,
    *,
    cvpr12_only: bool = False,
) -> list[MotionSequence]:
    """The bundled MSR Action3D sequences, in sorted name order (``a01_s01_e01`` first).

    Args:
      subjects: 1-based subject numbers to keep (1..10); ``None`` keeps all.
      actions: 1-based action numbers to keep (1..20, e.g. ``ARM_ACTIONS``); ``None`` keeps all.
      cvpr12_only: keep only the 557 sequences of the CVPR 2012 protocol list.

    Returns:
      ``MotionSequence`` list (567 by default). Every sequence is kept, even an entirely invalid
      one (``a13_s09_e02``); lost frames are masked in ``valid``, never dropped. The arrays are
      read-only views of one cached decode of the archive.

    Raises:
      ConfigError: a subject or action number out of range.
    """
    keep_s = _select(subjects, "subjects", N_SUBJECTS)
    keep_a = _select(actions, "actions", N_ACTIONS)
    bundle = _bundled()
    return [
        seq
        for seq, in_cvpr12 in zip(bundle.sequences, bundle.cvpr12, strict=True)
        if (keep_s is None or seq.subject in keep_s)
        and (keep_a is None or seq.action in keep_a)
        and (in_cvpr12 or not cvpr12_only)
    ]


def utkinect_action3d(
    subjects: Iterable[int] | None = None,
    actions: Iterable[int] | None = None,
    *,
    segments: bool = True,
) -> list[MotionSequence]:
    """The bundled UTKinect-Action3D data (10 recordings: subjects 3, 4, 6, 7, 9, takes 1-2).

    Args:
      subjects: 1-based subject numbers to keep (1..10; only 3, 4, 6, 7 and 9 are bundled, the
        others match nothing); ``None`` keeps all.
      actions: 1-based action numbers to keep (1..10, ``UTK_ACTION_NAMES``, e.g.
        ``UTK_UPPER_BODY_ACTIONS``); ``None`` keeps all. Only with ``segments=True``.
      segments: ``True``: one sequence per labelled action segment (the frames whose frame number
        lies in the segment's ``[start, end]`` of ``actionLabel.txt``), named ``"s03_e01_throw"``,
        ``action`` its 1-based number; ordered by recording name, then action number. Segments
        may overlap (the labels do); an absent (``NaN NaN``) segment, or one with no recorded
        frame, is left out. ``False``: the whole recordings (``"s03_e01"``, action 0).

    Returns:
      ``MotionSequence`` list with ``frame_numbers`` ``(T,)`` int64 and ``times`` ``(T,)`` float64
      seconds (``frame_numbers / UTK_FPS``, approximate), read-only views of one cached decode.
      ``confidence`` is all 1 (the source has none); ``valid`` marks finite, not all-zero frames.

    Raises:
      ConfigError: a subject or action number out of range, ``subjects`` naming no bundled
        subject, or ``actions`` with ``segments=False``.
    """
    keep_s = _select(subjects, "subjects", UTK_N_SUBJECTS)
    keep_a = _select(actions, "actions", len(UTK_ACTION_NAMES))
    bundle = _bundled_utkinect()
    present = sorted({r.subject for r in bundle.recordings})
    if keep_s is not None and not keep_s & set(present):
        raise ConfigError(
            f"subjects: none of {sorted(keep_s)} is in the bundled UTKinect-Action3D subset "
            f"(subjects {present})"
        )
    if not segments:
        if keep_a is not None:
            raise ConfigError("actions: whole recordings (segments=False) have no action")
        return [r for r in bundle.recordings if keep_s is None or r.subject in keep_s]
    return [
        seg
        for seg in bundle.segments
        if (keep_s is None or seg.subject in keep_s) and (keep_a is None or seg.action in keep_a)
    ]


def dataset_summary(name: str = "msr") -> dict[str, int]:
    """Counts of a bundled dataset.

    Args:
      name: ``"msr"`` (MSR Action3D) or ``"utkinect"`` (UTKinect-Action3D).

    Returns:
      ``"msr"``: ``{"sequences": 567, "frames": 23478, "valid_frames": ..., "subjects": 10,
      "actions": 20, "cvpr12_sequences": 557}``. ``"utkinect"``: ``{"recordings": 10,
      "frames": ..., "valid_frames": ..., "subjects": 5, "segments": ..., "segment_frames": ...,
      "upper_body_segments": ..., "upper_body_frames": ...}`` (frames after dropping repeated
      frame numbers; segment frames count a frame once per segment holding it).

    Raises:
      ConfigError: an unknown ``name``.
    """
    if name == "utkinect":
        utk = _bundled_utkinect()
        upper = [s for s in utk.segments if s.action in UTK_UPPER_BODY_ACTIONS]
        return {
            "recordings": len(utk.recordings),
            "frames": sum(len(r.valid) for r in utk.recordings),
            "valid_frames": sum(int(r.valid.sum()) for r in utk.recordings),
            "subjects": len({r.subject for r in utk.recordings}),
            "segments": len(utk.segments),
            "segment_frames": sum(len(s.valid) for s in utk.segments),
            "upper_body_segments": len(upper),
            "upper_body_frames": sum(len(s.valid) for s in upper),
        }
    if name != "msr":
        raise ConfigError(f"dataset_summary: unknown dataset {name!r}; use 'msr' or 'utkinect'")
    bundle = _bundled()
    seqs = bundle.sequences
    return {
        "sequences": len(seqs),
        "frames": sum(len(s.valid) for s in seqs),
        "valid_frames": sum(int(s.valid.sum()) for s in seqs),
        "subjects": len({s.subject for s in seqs}),
        "actions": len({s.action for s in seqs}),
        "cvpr12_sequences": sum(bundle.cvpr12),
    }


# --- splits, folders and training descriptors -----------------------------------------------------

TRAIN_SUBJECTS: tuple[int, ...] = (1, 3, 5, 7, 9)
"""The paper's cross-subject protocol: landmarks and kernels come from these subjects ..."""
TEST_SUBJECTS: tuple[int, ...] = (2, 4, 6, 8, 10)
"""... and every accuracy figure is measured on these, which the landmarks never saw."""

_SUBJECT_RE = re.compile(r"s(\d{2})")
_CMU_RE = re.compile(r"^(\d+)_(\d+)(?:_[^.]*)?\.bvh$", re.IGNORECASE)
_ACTION_RE = re.compile(r"a(\d{2})_")


def load_sequences(
    data: str | os.PathLike[str] = "bundled",
    subjects: Iterable[int] | None = None,
    *,
    progress: Callable[[Iterable[Path]], Iterable[Path]] | None = None,
    strict: bool = True,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
) -> list[MotionSequence]:
    """The bundled MSR Action3D or UTKinect-Action3D sequences, or every recording in a folder.

    Args:
      data: ``"bundled"`` or ``"msr"`` (MSR Action3D, ``msr_action3d``), ``"utkinect"`` (every
        labelled UTKinect-Action3D action segment, ``utkinect_action3d``; callers filter by
        ``action``), or a folder of recordings (``load_folder``: files that are not recordings
        are skipped; what was skipped, left out or unreadable is in ``load_folder``'s result).
      subjects: keep only these subjects (``None``: all). Folder files with no subject in their
        name are kept.
      progress: optional wrapper of the file iterable (e.g. a progress bar).
      strict: folders only: ``True`` raises at an unreadable recording, ``False`` leaves it out.
      bvh_map: folders only: the joint map of the BVH files in it (``jaxproj.io.bvh``; default
        ``"auto"``: a built-in map detected per file).

    Raises:
      InputError: ``data`` is none of the names above nor a folder, the folder holds no
        recording, or (``strict``) a recording in it cannot be read.
      ConfigError: a subject number out of range (bundled data), or for ``"utkinect"`` none of
        ``subjects`` bundled (only 3, 4, 6, 7, 9 are).
    """
    wanted = None if subjects is None else set(subjects)
    if str(data) in ("bundled", "msr"):
        return msr_action3d(subjects=wanted)
    if str(data) == "utkinect":
        return utkinect_action3d(subjects=wanted)
    return load_folder(data, subjects, progress=progress, strict=strict, bvh_map=bvh_map).sequences


@dataclass(frozen=True)
class FolderContents:
    """What ``load_folder`` found in a folder, file by file (names relative to the folder).

    Attributes:
      sequences: the recordings read, in file-name order.
      skipped: ``(name, why)`` of files that are not recordings (``readers.recording_format``).
      left_out: ``(name, subject)`` of recordings of subjects not asked for (not read).
      unreadable: ``(name, error)`` of recordings that could not be read (``strict=False``).
      subjects: the subjects asked for (``None``: all).
      missing_subjects: subjects asked for that no file name holds.
    """

    sequences: list[MotionSequence]
    skipped: list[tuple[str, str]]
    left_out: list[tuple[str, int]]
    unreadable: list[tuple[str, str]]
    subjects: list[int] | None = None
    missing_subjects: list[int] = dataclasses.field(default_factory=list)

    def notes(self, limit: int = 10) -> list[str]:
        """One line per thing a user should know (at most ``limit`` names per kind)."""

        def some(items: list[str]) -> str:
            more = len(items) - limit
            return ", ".join(items[:limit]) + (f" and {more} more" if more > 0 else "")

        lines = [f"skipped {name}: {why}" for name, why in self.skipped[:limit]]
        if len(self.skipped) > limit:
            lines.append(f"skipped {len(self.skipped) - limit} more files that are not recordings")
        if self.left_out:
            names = [f"{name} (subject {s})" for name, s in self.left_out]
            lines.append(
                f"left out {len(self.left_out)} recording(s) of subjects other than "
                f"{self.subjects}: {some(names)}"
            )
        if self.missing_subjects:
            lines.append(f"no recording of subject(s) {self.missing_subjects} in the folder")
        lines += [f"unreadable recording, not used: {err}" for _, err in self.unreadable]
        return lines

    def to_json(self) -> dict:
        """The same, JSON-ready (for reports)."""
        return {
            "recordings": len(self.sequences),
            "skipped": [{"file": n, "reason": w} for n, w in self.skipped],
            "left_out": [{"file": n, "subject": s} for n, s in self.left_out],
            "unreadable": [{"file": n, "error": e} for n, e in self.unreadable],
            "missing_subjects": list(self.missing_subjects),
        }


def load_folder(
    folder: str | os.PathLike[str],
    subjects: Iterable[int] | None = None,
    *,
    progress: Callable[[Iterable[Path]], Iterable[Path]] | None = None,
    strict: bool = True,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
) -> FolderContents:
    """Every recording in a folder (not its subfolders), and an account of the rest.

    Each file is first recognised (``readers.recording_format``): files that are not recordings
    (documentation such as ``SOURCE.md``, UTKinect's ``actionLabel.txt``, hidden files, images,
    an npz without ``positions``) are skipped and listed in ``skipped``. A file name with
    ``sNN`` gives the subject (0 when absent) and ``aNN_`` the action (0 when absent); a BVH file
    named the CMU way, ``SUBJECT_TRIAL.bvh`` (``131_03.bvh``, ``131_03_every6.bvh``), gives
    its subject and take from those numbers. With
    ``subjects``, recordings of other subjects are listed in ``left_out`` without being read;
    files with no subject in their name are kept. The rest are read with
    ``readers.read_skeleton``.

    Args:
      folder: the folder.
      subjects: subjects to keep (``None``: every recording).
      progress: optional wrapper of the file iterable (e.g. a progress bar).
      strict: ``True``: an unreadable recording raises its ``InputError``; ``False``: it is
        listed in ``unreadable`` and the others are read.
      bvh_map: the joint map of BVH files (``readers.read_skeleton``'s ``bvh_map``).

    Returns:
      ``FolderContents``.

    Raises:
      InputError: not a folder; no recording read (the message counts what was skipped, left
        out and unreadable); with ``strict``, the first unreadable recording.
    """
    from jaxproj.io.readers import read_skeleton, recording_format

    path = Path(folder)
    if not path.is_dir():
        raise InputError(
            path, "--data must be 'bundled', 'msr', 'utkinect' or a folder of recordings"
        )
    wanted = None if subjects is None else sorted({int(s) for s in subjects})
    files = sorted(path.iterdir(), key=lambda f: f.name)
    seqs: list[MotionSequence] = []
    skipped: list[tuple[str, str]] = []
    left_out: list[tuple[str, int]] = []
    unreadable: list[tuple[str, str]] = []
    seen_subjects: set[int] = set()
    for f in files if progress is None else progress(files):
        fmt, why = recording_format(f)
        if fmt is None:
            skipped.append((f.name, "a folder (not searched)" if f.is_dir() else why))
            continue
        subj = _SUBJECT_RE.search(f.name)
        act = _ACTION_RE.search(f.name)
        cmu = _CMU_RE.match(f.name) if fmt == "bvh" and not subj else None
        subj = subj or cmu
        subject = int(subj.group(1)) if subj else 0
        take = int(cmu.group(2)) if cmu else 0
        if subj:
            seen_subjects.add(subject)
        if wanted is not None and subj and subject not in wanted:
            left_out.append((f.name, subject))
            continue
        try:
            rec = read_skeleton(f, format=fmt, bvh_map=bvh_map)
        except InputError as err:
            if strict:
                raise
            unreadable.append((f.name, str(err)))
            continue
        conf = np.ones(rec.valid.shape + (N_JOINTS,), np.float32)
        action = int(act.group(1)) if act else 0
        seqs.append(
            MotionSequence(
                f.stem, action, subject, take, rec.positions, conf, rec.valid, times=rec.times
            )
        )
    missing = [s for s in wanted if s not in seen_subjects] if wanted is not None else []
    contents = FolderContents(seqs, skipped, left_out, unreadable, wanted, missing)
    if not seqs:
        counts = (
            f"{len(skipped)} file(s) not recordings, {len(left_out)} recording(s) of other "
            f"subjects than {wanted}, {len(unreadable)} unreadable"
            if wanted is not None
            else f"{len(skipped)} file(s) not recordings, {len(unreadable)} unreadable"
        )
        first = f"; first unreadable: {unreadable[0][1]}" if unreadable else ""
        raise InputError(path, f"no recording to use ({counts}){first}")
    return contents


def valid_descriptors(
    sequences_or_points: Any,
    *,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
) -> np.ndarray:
    """Descriptors of the valid frames of some recordings (e.g. a training set).

    Args:
      sequences_or_points: an iterable of sequences (objects with ``positions (T, 20, 3)`` and
        ``valid (T,)``, e.g. ``msr_action3d()``), or a ``(T, 20, 3)`` position array, or an
        ``(N, 3 * n_bones)`` array of descriptors (taken as they are, checked finite).
      bones, mirror: descriptor options (``skeleton.descriptor``); ignored for descriptors.

    Returns:
      ``(N, 3 * n_bones)`` float32 descriptors of the frames that are valid both in the sequence
      (``valid``) and for the descriptor (frame and bones not degenerate).

    Raises:
      ConfigError: no valid frame, or an array of the wrong shape or with non-finite values.
    """
    from jaxproj.human.skeleton import descriptor

    if isinstance(sequences_or_points, (np.ndarray, jax.Array)):
        a = np.asarray(sequences_or_points, dtype=np.float32)
        if a.ndim == 2:
            if len(a) == 0 or a.shape[1] == 0 or not np.isfinite(a).all():
                raise ConfigError(f"descriptors must be finite (N >= 1, m >= 1), got {a.shape}")
            return a
        if a.ndim == 3 and a.shape[1:] == (N_JOINTS, 3):
            positions, valid = a, np.ones(a.shape[0], bool)
        else:
            raise ConfigError(
                f"expected (N, 3 * n_bones) descriptors or (T, 20, 3) positions, got {a.shape}"
            )
    else:
        seqs = list(sequences_or_points)
        if not seqs:
            raise ConfigError("no sequences given")
        positions = np.concatenate([np.asarray(s.positions, np.float32) for s in seqs])
        valid = np.concatenate([np.asarray(s.valid, bool) for s in seqs])
    d, ok = descriptor(positions, bones=bones, mirror=mirror)
    keep = valid & np.asarray(ok)
    if not keep.any():
        raise ConfigError("no valid frame")
    return np.asarray(d)[keep].astype(np.float32)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m jaxproj.io.datasets [--dataset msr|utkinect] SRC_DIR OUT.npz``: bundle raw files."""
    parser = argparse.ArgumentParser(
        prog="python -m jaxproj.io.datasets",
        description="Bundle raw MSR Action3D or UTKinect-Action3D skeleton text files into one "
        "compressed npz.",
    )
    parser.add_argument(
        "--dataset",
        choices=("msr", "utkinect"),
        default="msr",
        help="msr: aXX_sYY_eZZ_skeleton3D.txt files; utkinect: joints_sXX_eYY.txt files and "
        "actionLabel.txt (default: msr)",
    )
    parser.add_argument("src_dir", help="folder with the raw text files")
    parser.add_argument("out_path", help="npz file to write")
    args = parser.parse_args(argv)
    try:
        if args.dataset == "utkinect":
            bundle_utkinect_action3d(args.src_dir, args.out_path)
            utk = _load_utkinect(args.out_path)
            counts = (
                f"{len(utk.recordings)} recordings, "
                f"{sum(len(r.valid) for r in utk.recordings)} frames, "
                f"{len(utk.segments)} segments"
            )
        else:
            bundle_msr_action3d(args.src_dir, args.out_path)
            bundle = _load(args.out_path)
            frames = sum(len(s.valid) for s in bundle.sequences)
            counts = f"{len(bundle.sequences)} sequences, {frames} frames"
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    size = Path(args.out_path).stat().st_size
    print(f"wrote {args.out_path}: {counts}, {size} bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
