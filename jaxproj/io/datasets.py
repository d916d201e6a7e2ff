"""The bundled datasets and folders of recordings, in one place: the names users import.

- Loading the bundled data (``jaxproj.io.bundled``): ``msr_action3d`` (MSR Action3D, 567
  sequences), ``utkinect_action3d`` (a UTKinect-Action3D subset), ``dataset_summary``, the
  archive paths and the action / subject constants; the archive layouts are documented there.
- Folders of recordings (``jaxproj.io.folders``): ``load_folder``, ``load_files``,
  ``FolderContents``.
- ``load_sequences``: either of them by one name (``--data``).
- ``training_sequences``: the default model's training recordings (MSR Action3D subjects
  1,3,5,7,9 and the UTKinect-Action3D people 3, 4, 6); ``utkinect_held_out``: the UTKinect
  segments of the people a model did not train on (7, 9 for the default model).
- ``MotionSequence`` and ``sequence_times`` (``jaxproj.io.sequences``).
- ``valid_descriptors`` (``jaxproj.human.descriptors``): training descriptors of sequences.
- Bundling the raw text files (``jaxproj.io.bundling``): ``bundle_msr_action3d``,
  ``bundle_utkinect_action3d`` and the converter command line, which runs as
  ``python -m jaxproj.io.datasets [--dataset msr|utkinect] SRC_DIR OUT.npz``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

from jaxproj.errors import ConfigError
from jaxproj.human.descriptors import valid_descriptors
from jaxproj.io.bundled import (
    ACTION_NAMES,
    ARM_ACTIONS,
    DATA_PATH,
    FORMAT_VERSION,
    N_ACTIONS,
    N_SUBJECTS,
    TEST_SUBJECTS,
    TRAIN_SUBJECTS,
    UTK_ACTION_NAMES,
    UTK_DATA_PATH,
    UTK_FORMAT_VERSION,
    UTK_FPS,
    UTK_N_SUBJECTS,
    UTK_SUBJECTS,
    UTK_TEST_SUBJECTS,
    UTK_TRAIN_SUBJECTS,
    UTK_UPPER_BODY_ACTIONS,
    dataset_summary,
    load_msr_archive,
    load_utkinect_archive,
    msr_action3d,
    utkinect_action3d,
)
from jaxproj.io.bundling import bundle_msr_action3d, bundle_utkinect_action3d, main
from jaxproj.io.folders import FolderContents, load_files, load_folder
from jaxproj.io.sequences import MotionSequence, sequence_times

__all__ = [
    "ACTION_NAMES",
    "ARM_ACTIONS",
    "DATA_PATH",
    "FORMAT_VERSION",
    "N_ACTIONS",
    "N_SUBJECTS",
    "TEST_SUBJECTS",
    "TRAIN_SUBJECTS",
    "UTK_ACTION_NAMES",
    "UTK_DATA_PATH",
    "UTK_FORMAT_VERSION",
    "UTK_FPS",
    "UTK_N_SUBJECTS",
    "UTK_SUBJECTS",
    "UTK_TEST_SUBJECTS",
    "UTK_TRAIN_SUBJECTS",
    "UTK_UPPER_BODY_ACTIONS",
    "FolderContents",
    "MotionSequence",
    "bundle_msr_action3d",
    "bundle_utkinect_action3d",
    "dataset_summary",
    "load_files",
    "load_folder",
    "load_msr_archive",
    "load_sequences",
    "load_utkinect_archive",
    "main",
    "msr_action3d",
    "sequence_times",
    "training_sequences",
    "utkinect_action3d",
    "utkinect_held_out",
    "valid_descriptors",
]


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
      bvh_map: folders only: the joint map of the BVH files in it (``jaxproj.io.formats.bvh``;
        default ``"auto"``: a built-in map detected per file).

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


def training_sequences(
    utkinect_people: Iterable[int] = UTK_TRAIN_SUBJECTS,
    subjects: Iterable[int] = TRAIN_SUBJECTS,
) -> list[MotionSequence]:
    """The default model's training recordings: every recording of the MSR Action3D
    ``subjects`` (default ``TRAIN_SUBJECTS``, 1,3,5,7,9) and the whole recordings
    (``utkinect_action3d(segments=False)``) of the bundled UTKinect-Action3D people
    ``utkinect_people`` (default ``UTK_TRAIN_SUBJECTS``, 3, 4, 6: 6 recordings; ``()``: MSR
    Action3D alone, the default training data of 0.2.0).

    ``jaxproj build`` trains on these (``BuildConfig.utkinect_people`` names the UTKinect
    people); score such a model on UTKinect only with ``utkinect_held_out(utkinect_people)``.

    Raises:
      ConfigError: a subject number out of range, or a UTKinect person not bundled (only 3, 4,
        6, 7, 9 are).
    """
    people = tuple(utkinect_people)
    bad = sorted(set(people) - set(UTK_SUBJECTS))
    if bad:
        raise ConfigError(
            f"utkinect_people: {bad} not in the bundled UTKinect-Action3D subset {UTK_SUBJECTS}"
        )
    seqs = msr_action3d(subjects=subjects)
    if people:
        seqs = seqs + utkinect_action3d(subjects=people, segments=False)
    return seqs


def utkinect_held_out(
    utkinect_people: Iterable[int] = UTK_TRAIN_SUBJECTS,
    actions: Iterable[int] | None = UTK_UPPER_BODY_ACTIONS,
) -> list[MotionSequence]:
    """The UTKinect-Action3D action segments (default: the upper-body ones,
    ``UTK_UPPER_BODY_ACTIONS``) of the bundled people NOT in ``utkinect_people``: the people a
    model trained on ``training_sequences(utkinect_people)`` never saw (default: 7 and 9,
    ``UTK_TEST_SUBJECTS``; ``()``: all five). Pass a model's ``config.utkinect_people``.

    Raises:
      ConfigError: every bundled person is in ``utkinect_people`` (none is left to score), or
        one is not bundled.
    """
    trained = set(utkinect_people)
    bad = sorted(trained - set(UTK_SUBJECTS))
    if bad:
        raise ConfigError(
            f"utkinect_people: {bad} not in the bundled UTKinect-Action3D subset {UTK_SUBJECTS}"
        )
    rest = [s for s in UTK_SUBJECTS if s not in trained]
    if not rest:
        raise ConfigError(
            "the model trained on every bundled UTKinect-Action3D person: none is left to score"
        )
    return utkinect_action3d(subjects=rest, actions=actions)


if __name__ == "__main__":
    raise SystemExit(main())
