"""Every recording in a folder (``load_folder``) or a list of files (``load_files``), and an
account of the files that were not used.

Each file is recognised by the format registry's detection (``jaxproj.io.formats``,
``recording_format``) and read with ``jaxproj.io.readers.read_skeleton``.
"""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jaxproj.errors import InputError
from jaxproj.human.skeleton import N_JOINTS
from jaxproj.io.formats import recording_format
from jaxproj.io.readers import read_skeleton
from jaxproj.io.sequences import MotionSequence

_SUBJECT_RE = re.compile(r"s(\d{2})")
_CMU_RE = re.compile(r"^(\d+)_(\d+)(?:_[^.]*)?\.bvh$", re.IGNORECASE)
_ACTION_RE = re.compile(r"a(\d{2})_")


@dataclass(frozen=True)
class FolderContents:
    """What ``load_folder`` found in a folder, file by file (names relative to the folder).

    Attributes:
      sequences: the recordings read, in file-name order.
      skipped: ``(name, why)`` of files that are not recordings (``formats.recording_format``).
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

    Each file is first recognised (``formats.recording_format``): files that are not recordings
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
    path = Path(folder)
    if not path.is_dir():
        raise InputError(
            path,
            "--data must be 'bundled', 'msr', 'utkinect', a folder of recordings, a recording "
            "or @LIST (a text file naming recordings)",
        )
    files = sorted(path.iterdir(), key=lambda f: f.name)
    return load_files(
        files, subjects, where=path, progress=progress, strict=strict, bvh_map=bvh_map
    )


def load_files(
    files: Sequence[str | os.PathLike[str]],
    subjects: Iterable[int] | None = None,
    *,
    where: str | os.PathLike[str] | None = None,
    progress: Callable[[Iterable[Path]], Iterable[Path]] | None = None,
    strict: bool = True,
    bvh_map: str | os.PathLike[str] | Mapping[str, str] = "auto",
) -> FolderContents:
    """``load_folder`` over the given files, in the given order (a recording file named on the
    command line, or the files of an ``@LIST``): each is recognised, named, left out by
    ``subjects`` or read by the same rules; ``where`` names them in the error when none is
    read (default: the first file)."""
    paths = [Path(f) for f in files]
    path = Path(where) if where is not None else (paths[0] if paths else Path("."))
    wanted = None if subjects is None else sorted({int(s) for s in subjects})
    seqs: list[MotionSequence] = []
    skipped: list[tuple[str, str]] = []
    left_out: list[tuple[str, int]] = []
    unreadable: list[tuple[str, str]] = []
    seen_subjects: set[int] = set()
    for f in paths if progress is None else progress(paths):
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
