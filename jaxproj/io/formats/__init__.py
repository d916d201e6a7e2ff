"""The skeleton file formats, registered in one table (``FORMATS``), and format detection.

One module per format, each defining its ``Format`` record (``jaxproj.io.formats.base``):

- ``msr``: MSR Action3D text (``x y z confidence``, 20 rows per frame, MSR joint order);
- ``utkinect``: UTKinect-Action3D text (frame number + 60 values per line);
- ``table``: ``npz`` and ``csv``, plain tables of positions (our own formats): CSV of
  ``(T, 20, 3)`` Kinect v1 positions, NPZ of ``(T, J, 3)`` joints of any registered skeleton
  (``skeleton=``, the ``skeleton`` key or ``J`` says which; ``up=`` for z-up data);
- ``npy``: such a joint array alone (HumanML3D's ``new_joints``), read as an NPZ of it;
- ``bvh``: BVH motion capture (a package: parser, forward kinematics, joint maps, reader);
- ``ntu``: NTU RGB+D ``.skeleton`` text (Kinect v2, 25 joints, several bodies per frame);
- ``azure_kinect``: Azure Kinect Body Tracking JSON (the SDK samples' ``offline_processor``: 32
  joints in millimetres, several bodies per frame); the two share ``bodies`` (``body=``);
- ``mediapipe``: MediaPipe Pose world landmarks as JSON or CSV (33 landmarks, visibility).

Text helpers all of them share are in ``jaxproj.io.text``; the ``Recording`` they return and its
time-axis rules in ``jaxproj.io.recording``. Adding a format is one module and one line in
``FORMATS``; ``format_names()`` feeds the CLI's ``--format`` choices.

Detection (``detect``), for a file named on its own (``read_skeleton(format="auto")``) and for
each file of a folder (``recording_format``) alike: the first format whose ``sniff`` recognises
the file, trying those whose suffix the file name has first (``.npz`` / ``.csv`` / ``.bvh``),
then the others by content (a zip signature with a ``positions`` or ``joints`` member; NumPy's
``\x93NUMPY`` signature; a first
non-blank line of 4 (MSR Action3D) or 61 (UTKinect) whitespace-separated numbers, of 60
comma-separated fields (or a header line of names, then such a line), or ``HIERARCHY``; a JSON
whose first flat object has ``x``, ``y``, ``z`` keys or that has a ``keypoints3D`` /
``poseWorldLandmarks`` / ``worldLandmarks`` / ``pose_world_landmarks`` key, or a CSV header
naming MediaPipe landmark columns (``nose_x,...``, ``x0,y0,z0,...``, or ``frame,landmark,x,y,z``):
MediaPipe). When none recognises it, a file named on its own is still read as the
format its suffix names (that reader says what is wrong); otherwise it is no recording, and the
reason says why.

The two multi-body formats: NTU RGB+D by its suffix ``.skeleton`` or by a first line of one
integer (the frame count), then integer body counts and a body line of 10 numbers; Azure Kinect
JSON by content only (``.json`` names other formats too): an object whose start holds
``"frames"`` and ``"joint_positions"``, ``"num_bodies"``, ``"bone_list"`` or ``k4abt``.
"""

from __future__ import annotations

import os
from pathlib import Path

from jaxproj.io.formats import azure_kinect, mediapipe, msr, npy, ntu, table, utkinect
from jaxproj.io.formats.base import Format
from jaxproj.io.formats.bvh.reader import FORMAT as BVH
from jaxproj.io.text import SNIFF_BYTES, Head, one_line

FORMATS: tuple[Format, ...] = (
    msr.FORMAT,
    utkinect.FORMAT,
    table.NPZ,
    table.CSV,
    BVH,
    ntu.FORMAT,
    azure_kinect.FORMAT,
    mediapipe.FORMAT,
    npy.FORMAT,
)
"""Every input format, in the order listed to users (``format_names``)."""


def format_names() -> tuple[str, ...]:
    """Names of the registered formats (``read_skeleton(format=)``, ``--format``), without
    ``"auto"``."""
    return tuple(f.name for f in FORMATS)


def get_format(name: str) -> Format:
    """The registered format called ``name`` (``KeyError`` if none is)."""
    for fmt in FORMATS:
        if fmt.name == name:
            return fmt
    raise KeyError(name)


def describe_formats() -> str:
    """``"msr: MSR Action3D text ...; utkinect: ...; ..."``: the formats, for messages."""
    return "; ".join(f"{f.name}: {f.description}" for f in FORMATS)


def detect(head: Head, *, trust_suffix: bool) -> tuple[str | None, str]:
    """The format of a file from its start: ``(name, "")``, or ``(None, why not)``.

    Args:
      head: the file's start (or all of it) and name.
      trust_suffix: ``True`` for a file named on its own: when no format recognises it, the
        format its suffix names is still returned (its reader then says what is wrong).
        ``False`` for a file in a folder, which is then no recording.

    Returns:
      The format's name, or ``None`` and the reason, in words: what the format the file nearly
      is says is wrong, else why the file is not text, else what its first line is not.
    """
    named = [f for f in FORMATS if head.suffix in f.suffixes]
    reasons = []
    for fmt in [*named, *(f for f in FORMATS if f not in named)]:
        recognised, why = fmt.sniff(head)
        if recognised:
            return fmt.name, ""
        if why:
            reasons.append(why)
    if named and trust_suffix:
        return named[0].name, ""
    if reasons:
        return None, reasons[0]
    if head.problem:
        return None, head.problem
    n = len((head.first_line or "").split())
    return None, f"first line ({n} columns) is not " + _first_lines()


def _first_lines() -> str:
    """``"4 (MSR Action3D) or 61 (UTKinect) numbers nor ... nor HIERARCHY (BVH)"``."""
    groups: dict[str, list[str]] = {}  # unit (or the phrase itself, for none) -> phrases
    for fmt in FORMATS:
        if fmt.first_line is not None:
            phrase, unit = fmt.first_line
            groups.setdefault(unit or phrase, []).append(phrase)
    return " nor ".join(
        " or ".join(phrases) + ("" if unit == phrases[0] else f" {unit}")
        for unit, phrases in groups.items()
    )


def recording_format(path: str | os.PathLike[str]) -> tuple[str | None, str]:
    """Is this file (in a folder of recordings) a skeleton recording? ``(format, "")`` if it
    looks like one, ``(None, why not)`` otherwise; never raises.

    Only the start of the file (``SNIFF_BYTES``) is looked at (``detect``, the suffix not
    trusted). Hidden files, folders, empty files, binaries, an npz without ``positions`` (e.g. a
    model) and documentation or label files (``SOURCE.md``, UTKinect's ``actionLabel.txt``) are
    not recordings. A file that passes may still be malformed further on: ``read_skeleton``
    decides.
    """
    p = Path(path)
    if p.name.startswith("."):
        return None, "hidden file"
    if not p.is_file():
        return None, "not a regular file"
    try:
        with open(p, "rb") as fh:
            data = fh.read(SNIFF_BYTES)
    except OSError as err:
        return None, f"cannot be read ({one_line(err)})"
    if not data:
        return None, "empty file"
    return detect(Head(p, data, complete=len(data) < SNIFF_BYTES), trust_suffix=False)
