"""Does a recording hold a person, in metres? Units and a guessed skeleton checked from bones.

The plain table formats (``npz``, ``npy``, ``csv``: a user's own arrays) say neither their
units nor, for a joint array named by its joint count alone, their skeleton. A file in
centimetres read as metres, or a 32-landmark MediaPipe array read as Azure Kinect's 32 joints,
used to pass without a word. ``check`` reads the person's limbs and trunk from the Kinect v1
layout every reader returns (``BONES``: upper arms, forearms, thighs, shins and the trunk,
HipCenter -> ShoulderCenter), each bone's median length over the valid frames:

- **units** (``units="auto"``): the median of those lengths, ``s``, is an adult's 0.3-0.45 m
  and a child's a little less. ``s`` in ``RANGES``: ``[0.1, 1)`` reads as metres, ``[20, 100)``
  as centimetres and ``[200, 1000)`` as millimetres (converted to metres, with a note saying
  so); anything else is an ``InputError`` asking for ``units=`` (``--units``). Between the
  ranges lie an adult in inches (a median of 12-18) and in decimetres, which are refused, not
  guessed; so is a small child (bones under 0.2 m) in centimetres or millimetres, whose file
  needs ``units=``. ``units="m"`` / ``"cm"`` / ``"mm"`` says it and skips the guess.
- **a skeleton guessed from the joint count** (``Recording.skeleton_from == "count"``): a
  person's bones of that list lie within a factor ``PROPORTION`` (4) of each other (forearm
  about 0.25 m, trunk about 0.5 m); read with the wrong layout, joints of the face or hands take
  the places of shoulders and hips, and some bones come out a few centimetres long. Beyond the
  factor the file is refused with the lengths and a request to name the skeleton.

Bones of median length 0 (joints the file left at one place) are not compared. A recording
without a valid frame is returned as it is (``retarget`` says so). Other formats state their
units (Kinect's metres, Azure's millimetres, a BVH's ``scale``) and one skeleton: ``check``
returns them unchanged, and ``units`` other than ``"auto"`` is a ``ConfigError`` for them.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons
from jaxproj.io.recording import Recording

TABLE_FORMATS = ("npz", "npy", "csv")
"""Formats whose units ``check`` reads from the bones (the user's own arrays)."""

UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}
"""``units=`` names -> metres per file unit (``"auto"``: guessed, module doc)."""

RANGES: dict[str, tuple[float, float]] = {"m": (0.1, 1.0), "cm": (20.0, 100.0),
                                         "mm": (200.0, 1000.0)}  # fmt: skip
"""The median length of ``BONES`` (file units) that reads as a person in each unit."""

PROPORTION = 4.0
"""A person's ``BONES`` lie within this factor of each other (median lengths)."""

BONES: tuple[tuple[str, str, str], ...] = (
    ("upper arm left", "ShoulderLeft", "ElbowLeft"),
    ("forearm left", "ElbowLeft", "WristLeft"),
    ("upper arm right", "ShoulderRight", "ElbowRight"),
    ("forearm right", "ElbowRight", "WristRight"),
    ("thigh left", "HipLeft", "KneeLeft"),
    ("shin left", "KneeLeft", "AnkleLeft"),
    ("thigh right", "HipRight", "KneeRight"),
    ("shin right", "KneeRight", "AnkleRight"),
    ("trunk", "HipCenter", "ShoulderCenter"),
)
"""(name, Kinect v1 joint, Kinect v1 joint): the bones whose lengths ``check`` reads."""


def bone_lengths(positions: np.ndarray, valid: np.ndarray) -> dict[str, float]:
    """Median length of each of ``BONES`` over the valid frames (file units).

    Args:
      positions: ``(T, 20, 3)`` Kinect v1 layout.
      valid: ``(T,)`` bool; at least one ``True``.

    Returns:
      ``{bone name: median length}``.
    """
    idx = skeletons.KINECT_V1.index
    p = np.asarray(positions, np.float64)[np.asarray(valid, bool)]
    return {
        name: float(np.median(np.linalg.norm(p[:, idx[b]] - p[:, idx[a]], axis=-1)))
        for name, a, b in BONES
    }


def check_units(units: str) -> None:
    """``ConfigError`` unless ``units`` is ``"auto"`` or one of ``UNITS``."""
    if units != "auto" and units not in UNITS:
        raise ConfigError(f"units must be auto, {', '.join(UNITS)}, got {units!r}")


def check(rec: Recording, units: str = "auto") -> Recording:
    """The recording in metres, its guessed skeleton checked (module doc).

    Args:
      rec: a ``Recording`` as a format's reader returns it.
      units: ``"auto"`` or one of ``UNITS`` (the file's unit; table formats only).

    Returns:
      ``rec``, its positions converted to metres and a note added where they were not.

    Raises:
      InputError: (table formats) bones of no person's size in any unit with ``units="auto"``,
        or a skeleton guessed from the joint count whose bones are not a person's proportions.
      ConfigError: a bad ``units``, or one other than ``"auto"`` for a format that states its
        own.
    """
    check_units(units)
    if rec.format not in TABLE_FORMATS:
        if units != "auto":
            raise ConfigError(
                f"units={units!r} applies to the table formats ({', '.join(TABLE_FORMATS)}); "
                f"a {rec.format} file states its own units"
            )
        return rec
    if not rec.valid.any():
        return rec
    lengths = bone_lengths(rec.positions, rec.valid)
    seen = {k: v for k, v in lengths.items() if v > 0}
    if not seen:
        return rec
    scale = float(np.median(list(seen.values())))
    where = _guess(rec)
    if units == "auto":
        unit = next((u for u, (lo, hi) in RANGES.items() if lo <= scale < hi), None)
        if unit is None:
            ranges = ", ".join(f"{lo:g}-{hi:g} in {u}" for u, (lo, hi) in RANGES.items())
            raise InputError(
                rec.source,
                f"the bones' median length is {scale:.4g} file units: a person's reads "
                f"{ranges}, so the units are none of m, cm, mm{where}; give the units "
                f"(--units {'/'.join(UNITS)}, read_skeleton(units=))",
            )
    else:
        unit = units
    notes = rec.notes
    factor = UNITS[unit]
    if factor != 1.0:
        word = {"cm": "centimetres", "mm": "millimetres"}[unit]
        if units == "auto":
            notes = (
                *notes,
                f"positions read as {word} (median bone {scale:.3g}): converted to metres "
                "(--units says the unit)",
            )
        pos = (rec.positions.astype(np.float64) * factor).astype(np.float32)
        rec = dataclasses.replace(rec, positions=pos)
        seen = {k: v * factor for k, v in seen.items()}
    if rec.skeleton_from == "count":
        ratio = max(seen.values()) / min(seen.values())
        if ratio > PROPORTION:
            listed = ", ".join(f"{k} {v:.3g}" for k, v in seen.items())
            raise InputError(
                rec.source,
                f"read as {rec.skeleton} (guessed from the joint count), but its bones are no "
                f"person's: median lengths (m) {listed} differ by a factor {ratio:.3g} (a "
                f"person's lie within {PROPORTION:g}); name the skeleton: --skeleton NAME "
                f"(registered: {', '.join(skeletons.names())}) or a 'skeleton' key",
            )
    return dataclasses.replace(rec, notes=notes)


def _guess(rec: Recording) -> str:
    """``" (or the joints are not a smpl skeleton, guessed from the joint count)"``, or ``""``."""
    if rec.skeleton_from != "count":
        return ""
    return f" (or the joints are not a {rec.skeleton} skeleton, guessed from the joint count)"
