"""Bundling: the raw MSR Action3D / UTKinect-Action3D text files -> one compressed archive each.

``bundle_msr_action3d`` and ``bundle_utkinect_action3d`` write the archives that
``jaxproj.io.bundled`` loads (layouts: that module's docstring), with fixed zip timestamps, so
the same sources give byte-identical files. The converter command line (``main``) runs as
``python -m jaxproj.io.datasets [--dataset msr|utkinect] SRC_DIR OUT.npz`` (or
``python -m jaxproj.io.bundling``). The text files are read with the formats' public row readers
(``formats.msr.read_msr_rows``, which keeps the confidence column, and
``formats.utkinect.read_utkinect_rows``).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from jaxproj._internal.atomic import write_npz
from jaxproj.errors import InputError
from jaxproj.human.skeleton import JOINT_NAMES
from jaxproj.io.bundled import (
    FORMAT_VERSION,
    UTK_ACTION_NAMES,
    UTK_DATASET,
    UTK_FORMAT_VERSION,
    load_msr_archive,
    load_utkinect_archive,
)
from jaxproj.io.formats.msr import MSR_TO_SDK, read_msr_rows
from jaxproj.io.formats.utkinect import read_utkinect_rows

_FILE_RE = re.compile(r"^a(\d{2})_s(\d{2})_e(\d{2})_skeleton3D\.txt$")
_CVPR12_LIST = "files_used_in_cvpr12_paper.txt"
_UTK_FILE_RE = re.compile(r"^joints_s(\d{2})_e(\d{2})\.txt$")
_UTK_LABELS = "actionLabel.txt"
_UTK_BLOCK_RE = re.compile(r"^s(\d{2})_e(\d{2})$")


def _file_numbers(pattern: re.Pattern[str], path: Path) -> tuple[str, ...]:
    """The numbers in a recording's file name (the listing kept only names that match)."""
    m = pattern.match(path.name)
    if m is None:
        raise InputError(path, f"file name does not match {pattern.pattern}")
    return m.groups()


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
        raw = read_msr_rows(path)[:, list(MSR_TO_SDK), :]  # (T, 20, 4) float64, SDK order
        names.append(path.name[: -len("_skeleton3D.txt")])
        numbers.append([int(g) for g in _file_numbers(_FILE_RE, path)])
        positions.append(micrometres(path, raw[..., :3]))
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
        "positions_um_planes": byte_planes(pos),
        "confidence_values": conf_values.astype(np.float64),
        "confidence_index": conf_index.reshape(pos.shape[:2]).astype(index_dtype),
    }
    write_npz(out_path, arrays, compress=True)


def micrometres(path: Path, xyz: np.ndarray) -> np.ndarray:
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


def byte_planes(um: np.ndarray) -> np.ndarray:
    """``<i4`` array (any shape, n values) -> ``(4, n)`` uint8 byte planes (plane k = byte k)."""
    flat = np.ascontiguousarray(um, dtype="<i4").reshape(-1)
    return np.ascontiguousarray(flat.view(np.uint8).reshape(-1, 4).T)


def bundle_utkinect_action3d(
    src_dir: str | os.PathLike[str], out_path: str | os.PathLike[str]
) -> None:
    """Convert the raw UTKinect-Action3D text files of ``src_dir`` into one compressed npz.

    Reads every ``joints_sXX_eYY.txt`` (sorted by name) with the reader of
    ``read_skeleton(format="utkinect")`` (a repeated frame number keeps its first line)
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
        frame, xyz = read_utkinect_rows(path, order=False)
        if frame[0] < 0 or frame[-1] >= 2**31 or (np.diff(frame) <= 0).any():
            raise InputError(
                path,
                "frame numbers must be >= 0, < 2**31 and increase (after dropping repeats)",
            )
        name = path.name[len("joints_") : -len(".txt")]
        if name not in labels:
            raise InputError(src / _UTK_LABELS, f"no segment block for {name}")
        names.append(name)
        numbers.append([int(g) for g in _file_numbers(_UTK_FILE_RE, path)])
        frames.append(frame.astype("<i4"))
        positions.append(micrometres(path, xyz))
        segments.append(labels[name])
    lengths = [len(f) for f in frames]
    arrays = {
        "dataset": np.array(UTK_DATASET),
        "format_version": np.array(UTK_FORMAT_VERSION, dtype=np.int64),
        "joint_names": np.array(JOINT_NAMES),
        "action_names": np.array(UTK_ACTION_NAMES),
        "names": np.array(names),
        "subject": np.array([n[0] for n in numbers], dtype=np.uint8),
        "take": np.array([n[1] for n in numbers], dtype=np.uint8),
        "offsets": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "frame_numbers": np.concatenate(frames),
        "positions_um_planes": byte_planes(np.concatenate(positions)),
        "segments": np.stack(segments).astype(np.int32),
    }
    write_npz(out_path, arrays, compress=True)


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


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m jaxproj.io.datasets [--dataset msr|utkinect] SRC_DIR OUT.npz``: bundle raw
    files (exit status 0, or 1 after a one-line error)."""
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
            utk = load_utkinect_archive(args.out_path)
            counts = (
                f"{len(utk.recordings)} recordings, "
                f"{sum(len(r.valid) for r in utk.recordings)} frames, "
                f"{len(utk.segments)} segments"
            )
        else:
            bundle_msr_action3d(args.src_dir, args.out_path)
            bundle = load_msr_archive(args.out_path)
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
