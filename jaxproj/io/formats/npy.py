"""A NumPy ``.npy`` joint array alone, format ``"npy"``: HumanML3D's ``new_joints`` and the like.

HumanML3D (Guo et al., CVPR 2022) stores each motion as a ``(T, 22, 3)`` float array of the
SMPL body's first 22 joints, y up, metres, 20 frames/s (its ``new_joints/*.npy``); other tools
save ``(T, J, 3)`` arrays the same way. The array is read as an NPZ holding it as ``joints``
(``formats.table``): the skeleton named by ``read_skeleton(skeleton=)`` or guessed from ``J``
(said in ``Recording.notes``), ``up=`` for z-up data, units read from the bones
(``jaxproj.io.plausible``). An ``.npy`` has no timing: frames are assumed 30 frames/s apart, as
the note says; HumanML3D's are 20 (``--fps 20``). Recognised by NumPy's ``\\x93NUMPY`` signature
(or, named on its own, by the ``.npy`` suffix); a pickled object array is refused.
"""

from __future__ import annotations

import dataclasses
import io
import os
from typing import Any

import numpy as np

from jaxproj.errors import InputError
from jaxproj.io.formats.base import Format
from jaxproj.io.formats.table import read_npz
from jaxproj.io.recording import Recording
from jaxproj.io.text import Head, one_line

_NPY_SIGNATURE = b"\x93NUMPY"


def sniff_npy(head: Head) -> tuple[bool, str]:
    """A NumPy ``.npy`` array (its magic string; a file named ``.npy`` without it is read as
    one when named on its own, and its reader says what is wrong)."""
    return head.data[:6] == _NPY_SIGNATURE, ""


def read_npy(
    path: str | os.PathLike[str], data: bytes, fps: float | None, **options: Any
) -> Recording:
    """A ``.npy`` ``(T, J, 3)`` joint array (HumanML3D's ``new_joints``, a user's own) as a
    ``Recording``: what an NPZ with that array as ``joints`` gives (``options``: ``up``,
    ``skeleton``)."""
    if data[:6] != _NPY_SIGNATURE:
        raise InputError(path, "not a NumPy .npy array (no \\x93NUMPY signature)")
    try:
        array = np.load(io.BytesIO(data), allow_pickle=False)
    except Exception as err:  # a corrupt header, a pickled object array
        raise InputError(path, f"unreadable .npy array ({one_line(err)})") from None
    buf = io.BytesIO()
    np.savez(buf, joints=array)
    rec = read_npz(path, buf.getvalue(), fps, **options)
    return dataclasses.replace(rec, format="npy")


FORMAT = Format(
    name="npy",
    description="NumPy .npy array of joints T x J x 3 of a registered skeleton (as an npz's "
    "joints; HumanML3D's new_joints)",
    suffixes=(".npy",),
    sniff=sniff_npy,
    read=read_npy,
)
