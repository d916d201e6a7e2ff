"""The bundled datasets, loaded: MSR Action3D skeletons (567 sequences, 20 actions x 10 subjects x
2-3 takes) and a UTKinect-Action3D subset (10 recordings; section at the end).

``msr_action3d()`` returns every sequence as a ``MotionSequence`` with ``(T, 20, 3)`` float32
positions in metres, Kinect SDK joint order (``jaxproj.human.skeleton.JOINT_NAMES``), camera frame
with y up, z away from the sensor and the subject's right side at larger x. Frames where the
skeleton was lost (all zeros in the source) are kept and marked ``False`` in ``valid``; no
sequence is dropped.
Source, citation and licence caveat: ``jaxproj/data/MSR_ACTION3D.md``.

The data live in one compressed archive, ``jaxproj/data/msr_action3d.npz``, built from the original
text files by ``jaxproj.io.bundling.bundle_msr_action3d`` (``python -m jaxproj.io.datasets SRC_DIR
OUT.npz``). Archive
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
  ``read_skeleton(format="utkinect")``).
- ``offsets`` ``(R + 1,)`` int64: recording i is frames ``offsets[i]:offsets[i + 1]``.
- ``names`` ``(R,)`` unicode (``"s03_e01"``, sorted), ``subject`` / ``take`` ``(R,)`` uint8.
- ``segments`` ``(R, 10, 2)`` int32: ``[start, end]`` frame numbers (inclusive) of action
  ``a`` (1-based) of recording i at ``segments[i, a - 1]``; ``-1, -1`` where ``actionLabel.txt``
  says ``NaN NaN`` (absent).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import N_JOINTS
from jaxproj.io.recording import UTK_FPS as _UTK_FPS
from jaxproj.io.sequences import MotionSequence

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

UTK_DATA_PATH = Path(__file__).parents[1] / "data" / "utkinect_action3d.npz"
"""The bundled UTKinect-Action3D archive."""

UTK_FORMAT_VERSION = 1
UTK_DATASET = "utkinect_action3d"
"""The ``dataset`` member of a UTKinect-Action3D archive."""

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
``jaxproj.io.recording.UTK_FPS``).

Only tracked frames were saved, so frame numbers jump; ``times = frame_numbers / UTK_FPS`` are
seconds since the capture's frame 0 and are approximate (the rate is nominal, not measured). The
frame numbers are all even and step by 2 at least, and walking speeds come out at 0.3-0.4 m/s, so
the counter may advance 2 per captured frame and these times be up to 2x too long (see the Notes
of ``jaxproj/data/UTKINECT_ACTION3D.md``)."""

UTK_N_SUBJECTS = 10
"""UTKinect-Action3D has subjects 1..10; the bundled subset holds 3, 4, 6, 7 and 9."""


TRAIN_SUBJECTS: tuple[int, ...] = (1, 3, 5, 7, 9)
"""The paper's cross-subject protocol: landmarks and kernels come from these subjects ..."""
TEST_SUBJECTS: tuple[int, ...] = (2, 4, 6, 8, 10)
"""... and every accuracy figure is measured on these, which the landmarks never saw."""

UTK_SUBJECTS: tuple[int, ...] = (3, 4, 6, 7, 9)
"""The UTKinect-Action3D people of the bundled subset (two recordings each)."""
UTK_TRAIN_SUBJECTS: tuple[int, ...] = (3, 4, 6)
"""The UTKinect-Action3D people whose whole recordings the default model trains on beside MSR
Action3D's ``TRAIN_SUBJECTS`` (``BuildConfig.utkinect_people``; ``datasets.training_sequences``).
Chosen by measurement: a model holding some frames of UTKinect's capture set-up errs less on the
UTKinect people it never saw and on the held-out MSR people (``docs/results.md``) ..."""
UTK_TEST_SUBJECTS: tuple[int, ...] = (7, 9)
"""... and the UTKinect-Action3D people the default model is scored on, which it never saw
(``datasets.utkinect_held_out``)."""


# --- loading --------------------------------------------------------------------------------------


def from_planes(planes: np.ndarray, n_frames: int) -> np.ndarray:
    """Inverse of ``bundling.byte_planes`` for positions: ``(4, n_frames*60)`` uint8 -> float32
    metres ``(n_frames, 20, 3)``."""
    um = np.ascontiguousarray(planes.T).view("<i4").reshape(n_frames, N_JOINTS, 3)
    return (um / 1e6).astype(np.float32)


def valid_frames(positions: np.ndarray) -> np.ndarray:
    """``(T, 20, 3)`` -> ``(T,)`` bool: not all zeros and all finite."""
    return (positions != 0).any(axis=(1, 2)) & np.isfinite(positions).all(axis=(1, 2))


@dataclass(frozen=True)
class MsrArchive:
    """A decoded MSR Action3D archive: its sequences and, per sequence, whether the CVPR 2012
    protocol list holds it."""

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


def load_msr_archive(path: str | os.PathLike[str]) -> MsrArchive:
    """Decode an archive written by ``bundle_msr_action3d`` (arrays are read-only views)."""
    d = _read_archive(
        path,
        "`python -m jaxproj.io.datasets SRC_DIR OUT.npz` (see jaxproj/data/MSR_ACTION3D.md)",
    )
    if int(d.get("format_version", -1)) != FORMAT_VERSION or "dataset" in d:
        raise InputError(path, f"unsupported dataset archive format (expected {FORMAT_VERSION})")
    offsets = d["offsets"]
    positions = _readonly(from_planes(d["positions_um_planes"], int(offsets[-1])))
    confidence = _readonly(d["confidence_values"][d["confidence_index"]].astype(np.float32))
    valid = _readonly(valid_frames(positions))
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
    return MsrArchive(sequences=sequences, cvpr12=tuple(bool(c) for c in d["cvpr12"]))


@functools.lru_cache(maxsize=1)
def _bundled() -> MsrArchive:
    return load_msr_archive(DATA_PATH)


@dataclass(frozen=True)
class UtkinectArchive:
    """A decoded UTKinect-Action3D archive: whole recordings and labelled action segments."""

    recordings: tuple[MotionSequence, ...]
    segments: tuple[MotionSequence, ...]


def load_utkinect_archive(path: str | os.PathLike[str]) -> UtkinectArchive:
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
    if str(d.get("dataset", "")) != UTK_DATASET:
        raise InputError(path, "not a UTKinect-Action3D archive (no dataset='utkinect_action3d')")
    if int(d.get("format_version", -1)) != UTK_FORMAT_VERSION:
        raise InputError(
            path, f"unsupported dataset archive format (expected {UTK_FORMAT_VERSION})"
        )
    offsets = d["offsets"]
    positions = _readonly(from_planes(d["positions_um_planes"], int(offsets[-1])))
    confidence = _readonly(np.ones(positions.shape[:2], np.float32))
    valid = _readonly(valid_frames(positions))
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
    return UtkinectArchive(recordings=tuple(recordings), segments=tuple(segments))


@functools.lru_cache(maxsize=1)
def _bundled_utkinect() -> UtkinectArchive:
    return load_utkinect_archive(UTK_DATA_PATH)


def _select(values: Iterable[int] | None, what: str, n: int) -> frozenset[int] | None:
    if values is None:
        return None
    chosen = frozenset(int(v) for v in values)
    bad = sorted(v for v in chosen if not 1 <= v <= n)
    if bad:
        raise ConfigError(f"{what}: {bad} out of range; use 1-based numbers 1..{n}")
    return chosen


def _kept(
    seq: MotionSequence, subjects: frozenset[int] | None, actions: frozenset[int] | None
) -> bool:
    """Is ``seq`` of one of ``subjects`` and ``actions`` (``None``: any)?"""
    return (subjects is None or seq.subject in subjects) and (
        actions is None or seq.action in actions
    )


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
        if _kept(seq, keep_s, keep_a) and (in_cvpr12 or not cvpr12_only)
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
        return [r for r in bundle.recordings if _kept(r, keep_s, None)]
    return [seg for seg in bundle.segments if _kept(seg, keep_s, keep_a)]


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
