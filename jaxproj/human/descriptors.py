"""Descriptors of many recordings at once: the training data of a projector.

``valid_descriptors`` turns sequences (anything with ``positions (T, 20, 3)`` and ``valid (T,)``:
the bundled datasets' ``MotionSequence``s, ``Recording``s), a position array or a descriptor array
into the ``(N, 3 * n_bones)`` descriptors of their valid frames. It belongs to the human layer
(the descriptor of a skeleton, ``jaxproj.human.skeleton.descriptor``, applied to sequences), so
algorithm modules take training data from here, never from the bundled data
(``jaxproj.io.datasets`` re-exports it).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from jaxproj._internal.buckets import bucket, pad_rows
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import descriptor, level_body, world_up
from jaxproj.human.skeletons import SkeletonLike

_level_jit = jit(level_body, static_argnames=("bones", "skeleton"))


def valid_descriptors(
    sequences_or_points: Any,
    *,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    skeleton: SkeletonLike = skeletons.DEFAULT,
    level: bool = True,
) -> np.ndarray:
    """Descriptors of the valid frames of some recordings (e.g. a training set).

    Args:
      sequences_or_points: an iterable of sequences (objects with ``positions (T, 20, 3)`` and
        ``valid (T,)``, e.g. ``msr_action3d()``), or a ``(T, 20, 3)`` position array, or an
        ``(N, 3 * n_bones)`` array of descriptors (taken as they are, checked finite). Positions
        are ``(T, n_joints, 3)`` in ``skeleton``'s order (20: Kinect v1, the default).
      bones, mirror, skeleton: descriptor options (``skeleton.descriptor``); ignored for
        descriptors.
      level: each sequence levelled against its own medians and its feet against the floor
        (``skeleton.level_body`` with ``up``, as ``retarget`` levels a recording; a no-op for
        bones without both shins); ignored for arrays.

    Returns:
      ``(N, 3 * n_bones)`` float32 descriptors of the frames that are valid both in the sequence
      (``valid``) and for the descriptor (frame and bones not degenerate).

    Raises:
      ConfigError: no valid frame, or an array of the wrong shape or with non-finite values.
    """
    d, keep = frame_descriptors(
        sequences_or_points, bones=bones, mirror=mirror, skeleton=skeleton, level=level
    )
    return d[keep]


def frame_descriptors(
    sequences_or_points: Any,
    *,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    skeleton: SkeletonLike = skeletons.DEFAULT,
    level: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """``valid_descriptors`` frame by frame: ``(T, 3 * n_bones)`` float32 descriptors of every
    frame (sequences concatenated) and ``(T,)`` bool, the frames ``valid_descriptors`` keeps
    (what aligns a frame's descriptor with something else of that frame, e.g. a robot pose).
    Same arguments and errors."""
    n_joints = skeletons.get(skeleton).n_joints
    lengths: list[int] = []  # per sequence (none for an array: nothing to level)
    if isinstance(sequences_or_points, (np.ndarray, jax.Array)):
        a = np.asarray(sequences_or_points, dtype=np.float32)
        if a.ndim == 2:
            if len(a) == 0 or a.shape[1] == 0 or not np.isfinite(a).all():
                raise ConfigError(f"descriptors must be finite (N >= 1, m >= 1), got {a.shape}")
            return a, np.ones(len(a), bool)
        if a.ndim == 3 and a.shape[1:] == (n_joints, 3):
            positions, valid = a, np.ones(a.shape[0], bool)
        else:
            raise ConfigError(
                f"expected (N, 3 * n_bones) descriptors or (T, {n_joints}, 3) positions, "
                f"got {a.shape}"
            )
    else:
        seqs = list(sequences_or_points)
        if not seqs:
            raise ConfigError("no sequences given")
        positions = np.concatenate([np.asarray(s.positions, np.float32) for s in seqs])
        valid = np.concatenate([np.asarray(s.valid, bool) for s in seqs])
        lengths = [len(s.valid) for s in seqs]
    d_all, ok = descriptor(positions, bones=bones, mirror=mirror, skeleton=skeleton)
    keep = valid & np.asarray(ok)
    if not keep.any():
        raise ConfigError("no valid frame")
    d = np.asarray(d_all, np.float32)
    names = skeletons.get(skeleton).require(bones)
    if level and lengths and {"shin_left", "shin_right"} <= set(names):
        start = 0
        levelled = []
        up = np.asarray(world_up(positions, skeleton=skeleton), np.float32)
        for t in lengths:  # each recording on its own medians; padded to few shapes
            rows = bucket(t)
            part = slice(start, start + t)
            seg = _level_jit(
                pad_rows(d[part], rows), pad_rows(keep[part], rows, False), bones=names,
                skeleton=skeleton, up=pad_rows(up[part], rows),
            )  # fmt: skip
            levelled.append(np.asarray(seg)[:t])
            start += t
        d = np.concatenate(levelled)
    return d.astype(np.float32), keep
