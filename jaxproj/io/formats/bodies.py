"""Helpers of the formats whose frames hold several bodies (``ntu``, ``azure_kinect``).

A sensor that tracks people (Kinect v2, Azure Kinect) records, per frame, zero or more bodies.
``read_skeleton(..., body=)`` picks one of them in every frame: ``"first"`` (the default, the
frame's first body) or a 0-based index into the frame's bodies, in the order the file lists them
(the tracker's order). A frame without that body is an invalid frame, not an error; a file in
which no frame has it is an ``InputError`` (``no_body_error``).

A joint's tracking state (Kinect v2) or confidence level (Azure Kinect) makes the frame invalid
when it is below the format's threshold on any joint that feeds the Kinect v1 layout
(``feeding_joints``: the joints ``skeletons.to_kinect_v1`` reads); the others (hand tips, thumbs,
the face) do not matter.
"""

from __future__ import annotations

import os

import numpy as np

from jaxproj.errors import ConfigError, InputError
from jaxproj.human import skeletons

BodyChoice = int | str
"""``read_skeleton(body=)``: ``"first"`` or a 0-based index into each frame's bodies."""


def body_index(body: BodyChoice) -> int:
    """The 0-based index of ``body`` in each frame's bodies (``"first"``: 0).

    Raises:
      ConfigError: neither ``"first"`` nor a non-negative integer.
    """
    if body == "first":
        return 0
    if isinstance(body, bool) or not isinstance(body, int | np.integer) or body < 0:
        raise ConfigError(
            f"body must be 'first' or a 0-based index into each frame's bodies (0, 1, ...), "
            f"got {body!r}"
        )
    return int(body)


def feeding_joints(skeleton: skeletons.SkeletonLike) -> np.ndarray:
    """``(k,)`` int64: the joints of ``skeleton`` that ``to_kinect_v1`` reads (its
    ``kinect_v1_sources`` that are ``>= 0``), in Kinect v1 order."""
    src = np.asarray(skeletons.get(skeleton).kinect_v1_sources, dtype=np.int64)
    return src[src >= 0]


def no_body_error(path: str | os.PathLike[str], index: int, n_frames: int, most: int) -> InputError:
    """The ``InputError`` of a file in which no frame has body ``index``.

    Args:
      path: the file.
      index: the chosen body (0-based).
      n_frames: the file's frames.
      most: the largest number of bodies any frame holds.
    """
    if most == 0:
        return InputError(path, f"no body in any of the {n_frames} frames: nothing to read")
    return InputError(
        path,
        f"no frame has body {index} (0-based; at most {most} bodies per frame): choose "
        f"body=0{'' if most == 1 else f' to {most - 1}'}",
    )
