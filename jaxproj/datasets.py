"""The bundled MSR Action3D skeletons (567 sequences, 20 actions x 10 subjects x 2-3 takes).

``msr_action3d()`` returns every sequence as a ``MotionSequence`` with ``(T, 20, 3)`` float32
positions in metres, Kinect SDK joint order (``jaxproj.skeleton.JOINT_NAMES``), camera frame with y
up, z away from the sensor and the subject's right side at larger x. Frames where the skeleton was
lost (all zeros in the source) are kept and marked ``False`` in ``valid``; no sequence is dropped.
Source, citation and licence caveat: ``jaxproj/data/MSR_ACTION3D.md``.

The data live in one compressed archive, ``jaxproj/data/msr_action3d.npz``, built from the original
text files by ``bundle_msr_action3d`` (``python -m jaxproj.datasets SRC_DIR OUT.npz``). Archive
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
"""

from __future__ import annotations

import argparse
import functools
import io
import os
import re
import sys
import zipfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxproj.exceptions import ConfigError, InputError
from jaxproj.readers import MSR_TO_SDK, _read_msr_rows
from jaxproj.skeleton import JOINT_NAMES, N_JOINTS

DATA_PATH = Path(__file__).with_name("data") / "msr_action3d.npz"
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


@dataclass(frozen=True)
class MotionSequence:
    """One MSR Action3D sequence (read-only arrays).

    Attributes:
      name: ``"aXX_sYY_eZZ"``.
      action: 1-based action number (``ACTION_NAMES[action - 1]``).
      subject: 1-based subject number (1..10).
      take: 1-based execution number (1..3).
      positions: ``(T, 20, 3)`` float32 metres, Kinect SDK joint order; invalid frames are 0.
      confidence: ``(T, 20)`` float32 per-joint tracking confidence in [0, 1] (SDK order).
      valid: ``(T,)`` bool, frame is not all zeros and all finite.
    """

    name: str
    action: int
    subject: int
    take: int
    positions: np.ndarray
    confidence: np.ndarray
    valid: np.ndarray


# --- bundling -------------------------------------------------------------------------------------


def bundle_msr_action3d(src_dir: str | os.PathLike[str], out_path: str | os.PathLike[str]) -> None:
    """Convert the raw MSR Action3D text files of ``src_dir`` into one compressed npz.

    Reads every ``aXX_sYY_eZZ_skeleton3D.txt`` (sorted by name) and, if present,
    ``files_used_in_cvpr12_paper.txt``; writes ``out_path`` in the layout of the module docstring.

    Raises:
      InputError: no sequence files, a malformed file (see ``jaxproj.readers``), or coordinates
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
        with np.errstate(invalid="ignore", over="ignore"):
            um = np.round(raw[..., :3] * 1e6)
        exact = np.isfinite(um).all() and np.abs(um).max() < 2**31
        if not exact or np.abs(um / 1e6 - raw[..., :3]).max() > 1e-9:
            raise InputError(
                path,
                "coordinates not representable as int32 micrometres (non-finite, > 2 km, "
                "or more than 6 decimals)",
            )
        names.append(path.name[: -len("_skeleton3D.txt")])
        numbers.append([int(g) for g in _FILE_RE.match(path.name).groups()])
        positions.append(um.astype("<i4"))
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
        "positions_um_planes": np.ascontiguousarray(
            pos.reshape(-1).view(np.uint8).reshape(-1, 4).T
        ),
        "confidence_values": conf_values.astype(np.float64),
        "confidence_index": conf_index.reshape(pos.shape[:2]).astype(index_dtype),
    }
    _write_npz(Path(out_path), arrays)


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


def _load(path: str | os.PathLike[str]) -> _Bundle:
    """Decode an archive written by ``bundle_msr_action3d`` (arrays are read-only views)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError(
            path,
            "dataset archive not found; rebuild it with `python -m jaxproj.datasets "
            "SRC_DIR OUT.npz` (see jaxproj/data/MSR_ACTION3D.md)",
        ) from None
    except Exception as err:  # corrupt zip / npy member
        raise InputError(path, f"corrupt dataset archive ({type(err).__name__}: {err})") from None
    if int(d.get("format_version", -1)) != FORMAT_VERSION:
        raise InputError(path, f"unsupported dataset archive format (expected {FORMAT_VERSION})")
    offsets = d["offsets"]
    n = int(offsets[-1])
    um = np.ascontiguousarray(d["positions_um_planes"].T).view("<i4").reshape(n, N_JOINTS, 3)
    positions = _readonly((um / 1e6).astype(np.float32))
    confidence = _readonly(d["confidence_values"][d["confidence_index"]].astype(np.float32))
    valid = _readonly((positions != 0).any(axis=(1, 2)) & np.isfinite(positions).all(axis=(1, 2)))
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


def dataset_summary() -> dict[str, int]:
    """Counts of the bundled dataset.

    Returns:
      ``{"sequences": 567, "frames": 23478, "valid_frames": ..., "subjects": 10, "actions": 20,
      "cvpr12_sequences": 557}``.
    """
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
_ACTION_RE = re.compile(r"a(\d{2})_")


def load_sequences(
    data: str | os.PathLike[str] = "bundled",
    subjects: Iterable[int] | None = None,
    *,
    progress: Callable[[Iterable[Path]], Iterable[Path]] | None = None,
) -> list[MotionSequence]:
    """The bundled MSR Action3D sequences, or every recording in a folder.

    Args:
      data: ``"bundled"`` or a folder of recordings. Folder files are read with
        ``readers.read_skeleton`` (format by extension / content); a file name with ``sNN``
        gives the subject and ``aNN_`` the action (0 when absent).
      subjects: keep only these subjects (``None``: all). Folder files with no subject in their
        name are kept.
      progress: optional wrapper of the file iterable (e.g. a progress bar).

    Raises:
      InputError: ``data`` is neither ``"bundled"`` nor a folder, or it holds no recording.
    """
    from jaxproj.readers import read_skeleton

    wanted = None if subjects is None else set(subjects)
    if str(data) == "bundled":
        return msr_action3d(subjects=wanted)
    folder = Path(data)
    if not folder.is_dir():
        raise InputError(folder, "--data must be 'bundled' or a folder of recordings")
    files = sorted(p for p in folder.iterdir() if p.is_file())
    seqs = []
    for f in files if progress is None else progress(files):
        subj = _SUBJECT_RE.search(f.name)
        act = _ACTION_RE.search(f.name)
        subject = int(subj.group(1)) if subj else 0
        if wanted is not None and subj and subject not in wanted:
            continue
        rec = read_skeleton(f)
        conf = np.ones(rec.valid.shape + (N_JOINTS,), np.float32)
        action = int(act.group(1)) if act else 0
        seqs.append(MotionSequence(f.stem, action, subject, 0, rec.positions, conf, rec.valid))
    if not seqs:
        raise InputError(folder, f"no recordings found (for subjects {subjects})")
    return seqs


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
    from jaxproj.skeleton import descriptor

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
    """``python -m jaxproj.datasets SRC_DIR OUT.npz``: bundle raw MSR Action3D text files."""
    parser = argparse.ArgumentParser(
        prog="python -m jaxproj.datasets",
        description="Bundle the raw MSR Action3D skeleton text files into one compressed npz.",
    )
    parser.add_argument("src_dir", help="folder with aXX_sYY_eZZ_skeleton3D.txt files")
    parser.add_argument("out_path", help="npz file to write")
    args = parser.parse_args(argv)
    try:
        bundle_msr_action3d(args.src_dir, args.out_path)
        bundle = _load(args.out_path)
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    frames = sum(len(s.valid) for s in bundle.sequences)
    size = Path(args.out_path).stat().st_size
    print(
        f"wrote {args.out_path}: {len(bundle.sequences)} sequences, {frames} frames, {size} bytes"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
