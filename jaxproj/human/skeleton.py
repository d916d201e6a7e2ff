"""The body-frame bone-direction descriptor of a skeleton, and Kinect v1's joint order.

A pose is a ``(n_joints, 3)`` array of positions in metres in any right-handed camera frame, in
the joint order of a skeleton format (``jaxproj.human.skeletons``: the spec, the canonical bones,
the registry). Every function here takes ``skeleton=`` (a registered name or a ``Skeleton``;
default ``"kinect_v1"``) and computes from that skeleton's joints into the same canonical bone
layout; the descriptor does not depend on the camera frame (it is expressed in a body frame built
from the skeleton itself).

``JOINT_NAMES``, ``J``, ``N_JOINTS``, ``BONES`` are the Kinect v1 instance's values (the joint
order of every reader and bundled dataset); ``BONE_NAMES``, ``UPPER_BODY``, ``FULL_BODY`` and
``resolve_bones`` the canonical vocabulary's.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.buckets import call_bucketed
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.human import skeletons
from jaxproj.human.skeletons import (
    BONE_NAMES,
    BONE_SUBSETS,
    FULL_BODY,
    KINECT_V1,
    MIRROR_BONE,
    UPPER_BODY,
    Skeleton,
    SkeletonLike,
    resolve_bones,
)

__all__ = [
    "BONES", "BONE_NAMES", "BONE_SUBSETS", "FULL_BODY", "JOINT_NAMES", "J", "MIN_BONE_LENGTH",
    "NECK_TILT_REFERENCE", "N_JOINTS", "SkeletonLike", "UPPER_BODY", "body_frame", "descriptor",
    "level_body", "level_neck", "neck_tilt", "recording_neck_tilt", "resolve_bones", "world_up",
]  # fmt: skip

JOINT_NAMES: tuple[str, ...] = KINECT_V1.joints
"""The 20 Kinect v1 joints in SDK order (the order of every ``(..., 20, 3)`` array)."""

N_JOINTS = KINECT_V1.n_joints
J = dict(KINECT_V1.index)
"""Joint name -> index in ``JOINT_NAMES``."""

BONES: tuple[tuple[str, str], ...] = tuple(KINECT_V1.bones[n] for n in BONE_NAMES)
"""The 19 bones (parent, child) of the Kinect v1 tree; bone ``i`` is named ``BONE_NAMES[i]``."""

MIN_BONE_LENGTH = 1e-3
"""Metres. A bone (or body-frame axis) shorter than this makes the frame invalid."""


def body_frame(
    positions: jax.Array, *, skeleton: SkeletonLike = skeletons.DEFAULT
) -> tuple[jax.Array, jax.Array]:
    """Body frame of a skeleton, built from the skeleton itself (not the camera axes).

    ``up`` points along the skeleton's ``frame.up`` joints (Kinect v1: HipCenter ->
    ShoulderCenter); ``left`` along ``frame.left`` (ShoulderRight -> ShoulderLeft), made orthogonal
    to ``up``; ``forward = left x up``. In a right-handed camera frame (Kinect) ``forward`` points
    out of the person's chest. The axes match the default robot's torso frame (x forward, y left, z
    up), so a bone direction in this frame can be compared with the robot's directly.

    Args:
      positions: ``(..., n_joints, 3)`` joint positions in the skeleton's order, any units.
      skeleton: a registered skeleton's name or a ``Skeleton`` (default Kinect v1).

    Returns:
      ``(rotation, ok)``: ``(..., 3, 3)`` matrix whose rows are forward, left, up (so
      ``rotation @ v`` expresses a camera-frame vector in the body frame), and ``(...,)`` bool,
      false where the frame is degenerate or non-finite (the rotation is then the identity).

    Raises:
      ConfigError: an unknown skeleton; ``positions`` not shaped ``(..., n_joints, 3)``.
    """
    s = skeletons.get(skeleton)
    p = jnp.asarray(positions)
    _check_shape(p.shape, s)
    (up_from, up_to), (left_from, left_to) = ((s.index[a], s.index[b]) for a, b in s.frame)
    up_raw = p[..., up_to, :] - p[..., up_from, :]
    left_raw = p[..., left_to, :] - p[..., left_from, :]
    up, ok_up = _safe_unit(up_raw)
    left_orth = left_raw - jnp.sum(left_raw * up, axis=-1, keepdims=True) * up
    left, ok_left = _safe_unit(left_orth)
    forward = jnp.cross(left, up)
    rot = jnp.stack([forward, left, up], axis=-2)
    ok = ok_up & ok_left & jnp.all(jnp.isfinite(p), axis=(-2, -1))
    rot = jnp.where(
        ok[..., None, None], rot, jnp.broadcast_to(jnp.eye(3, dtype=rot.dtype), rot.shape)
    )
    return rot, ok


def _check_shape(shape: tuple[int, ...], s: Skeleton) -> None:
    if len(shape) < 2 or tuple(shape[-2:]) != (s.n_joints, 3):
        raise ConfigError(
            f"positions must be (..., {s.n_joints}, 3) ({s.name} joints), got {tuple(shape)}"
        )


def _safe_unit(v: jax.Array, min_norm: float = MIN_BONE_LENGTH) -> tuple[jax.Array, jax.Array]:
    """``v / |v|`` where ``|v| >= min_norm`` and finite, else zeros; plus the ok mask."""
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    ok = (n >= min_norm) & jnp.isfinite(n)
    safe = jnp.where(ok, n, 1.0)
    return jnp.where(ok, v / safe, 0.0), ok[..., 0]


def descriptor(
    positions: ArrayLike,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    *,
    skeleton: SkeletonLike = skeletons.DEFAULT,
) -> tuple[jax.Array, jax.Array]:
    """The paper's pose descriptor: bone unit vectors expressed in the body frame.

    Invariant to translation, to any rotation of the whole skeleton (the frame is built from the
    skeleton) and to uniform scaling (unit vectors). Every skeleton's descriptor has the same
    layout: the chosen canonical bones in the order given, 3 numbers each.

    Args:
      positions: ``(..., n_joints, 3)`` joint positions in the skeleton's order (Kinect v1: SDK
        order, ``(..., 20, 3)``).
      bones: subset name (``"upper"`` default: neck, upper arms, forearms; ``"full"``: all 19)
        or a tuple of names from ``BONE_NAMES``.
      mirror: if true, the human's left limbs drive the robot's right ones (mirror imitation):
        each left bone is swapped with its right twin and the lateral (y) component negated.
        Default false: direct imitation (human left arm -> robot left arm).
      skeleton: a registered skeleton's name or a ``Skeleton`` (default ``"kinect_v1"``): whose
        joints the bones and the body frame are read from.

    Returns:
      ``(d, valid)``: ``(..., 3 * n_bones)`` float32 descriptor, bone after bone, each a unit
      ``(x forward, y left, z up)`` vector; and ``(...,)`` bool. A frame is invalid where its body
      frame is degenerate, a value is non-finite, or a chosen bone is shorter than
      ``MIN_BONE_LENGTH``; its descriptor is all zeros there (never NaN).

    Compiled once per shape (and skeleton); host arrays (NumPy) are padded along their frames to
    a bucket (``jaxproj._internal.buckets``), so recordings of most lengths share one compile.
    Inside a caller's trace it is plain JAX code.

    Raises:
      ConfigError: an unknown bone, subset or skeleton; a bone the skeleton does not define
        (named, with the skeleton); ``positions`` not shaped ``(..., n_joints, 3)``.
    """
    s = skeletons.get(skeleton)
    names = s.require(bones)
    if mirror:
        names = tuple(MIRROR_BONE[n] for n in names)
    index = tuple(BONE_NAMES.index(n) for n in names)
    if isinstance(positions, jax.core.Tracer):  # inside a caller's trace: the plain core
        _check_shape(positions.shape, s)
        return _descriptor(positions, index, mirror, s)
    if isinstance(positions, jax.Array):  # on a device already: one compile per shape
        _check_shape(positions.shape, s)
        return _descriptor_jit(positions, index=index, mirror=mirror, skeleton=s)
    # host data (a recording, a dataset): rows padded to a bucket, one compile per bucket
    p = np.asarray(positions, np.float32)
    _check_shape(p.shape, s)
    return call_bucketed(lambda x: _descriptor_jit(x, index=index, mirror=mirror, skeleton=s), p, 2)


def _descriptor(
    positions: jax.Array, index: tuple[int, ...], mirror: bool, skeleton: Skeleton = KINECT_V1
) -> tuple[jax.Array, jax.Array]:
    """``descriptor``'s traceable core for the bones ``BONE_NAMES[i]`` of ``index`` (already
    swapped when ``mirror``) of ``skeleton``."""
    pairs = skeleton.bone_joints(tuple(BONE_NAMES[i] for i in index))
    parents = np.array([a for a, _ in pairs])
    children = np.array([b for _, b in pairs])
    p = jnp.asarray(positions, dtype=jnp.float32)
    finite = jnp.all(jnp.isfinite(p), axis=(-2, -1))
    p = jnp.where(finite[..., None, None], p, 0.0)
    rot, ok_frame = body_frame(p, skeleton=skeleton)
    vec = p[..., children, :] - p[..., parents, :]  # (..., B, 3)
    unit, ok_bone = _safe_unit(vec)
    local = jnp.einsum("...ij,...bj->...bi", rot, unit)
    if mirror:
        local = local.at[..., 1].multiply(-1.0)
    valid = ok_frame & finite & jnp.all(ok_bone, axis=-1)
    local = jnp.where(valid[..., None, None], local, 0.0)
    return local.reshape(*local.shape[:-2], 3 * len(index)), valid


_descriptor_jit = jit(_descriptor, static_argnames=("index", "mirror", "skeleton"))


NECK_TILT_REFERENCE = math.radians(-27.1)
"""rad: the median forward tilt ``atan2(n_x, n_z)`` of the neck bone (ShoulderCenter -> Head, body
frame) over the 22,365 valid frames of the bundled MSR Action3D recordings: the capture set-up
the default projector's landmarks come from. ``level_neck`` brings each recording's own neutral
tilt here (the default robot's IK reads this tilt as HeadPitch 0, its ``HEAD_PITCH_NEUTRAL``)."""


def _neck_offset(bones: str | Iterable[str], skeleton: SkeletonLike) -> int:
    """Index of the neck bone's first number in a descriptor of ``bones``."""
    names = skeletons.get(skeleton).require(bones)
    if "neck" not in names:
        raise ConfigError(f"the descriptor's bones {names} hold no neck bone")
    return 3 * names.index("neck")


def neck_tilt(
    d: jax.Array,
    bones: str | tuple[str, ...] = "upper",
    *,
    skeleton: SkeletonLike = skeletons.DEFAULT,
) -> jax.Array:
    """``(...,)`` forward tilt ``atan2(n_x, n_z)`` (rad) of the neck bone of ``(..., 3 * n_bones)``
    descriptors of ``skeleton`` (``bones`` must hold ``"neck"``; ConfigError if not, or if the
    skeleton lacks one of ``bones``)."""
    i = _neck_offset(bones, skeleton)
    return jnp.arctan2(d[..., i], d[..., i + 2])


def recording_neck_tilt(
    d: ArrayLike,
    valid: ArrayLike,
    bones: str | tuple[str, ...] = "upper",
    *,
    skeleton: SkeletonLike = skeletons.DEFAULT,
) -> jax.Array:
    """The neutral neck tilt of one recording: the median ``neck_tilt`` of its valid frames.

    Traceable (a sort, no host sync). Args: ``d`` ``(T, 3 * n_bones)`` descriptors, ``valid``
    ``(T,)`` bool, ``bones`` / ``skeleton`` as for ``neck_tilt``. Returns ``()`` float32 rad;
    ``NECK_TILT_REFERENCE`` if no frame is valid.
    """
    tilt = neck_tilt(jnp.asarray(d, jnp.float32), bones, skeleton=skeleton)
    return _median(tilt, jnp.asarray(valid, bool), NECK_TILT_REFERENCE)


def level_neck(
    d: ArrayLike,
    neutral: ArrayLike,
    bones: str | tuple[str, ...] = "upper",
    reference: float = NECK_TILT_REFERENCE,
    *,
    skeleton: SkeletonLike = skeletons.DEFAULT,
) -> jax.Array:
    """Descriptors whose neck bone is turned about the body's left axis by ``reference -
    neutral``: a recording whose neutral tilt is ``neutral`` then has it at ``reference``.

    Why: the Kinect's Head joint sits at a tilt that depends on the capture set-up (the camera's
    height and pitch: MSR Action3D's median is -27.1 deg, UTKinect's +14 deg), not only on the
    person. Levelling each recording to the reference makes the neck read as it would in the
    set-up the landmarks came from; the rotation keeps the bone's length and its sideways part.
    Other bones are unchanged; without a neck bone in ``bones`` ``d`` is returned as is.

    Args:
      d: ``(..., 3 * n_bones)`` descriptors.
      neutral: the recording's neutral tilt, rad (scalar or broadcastable to ``d``'s batch).
      bones: the descriptor's bones.
      reference: the tilt the neutral is moved to, rad.
      skeleton: the skeleton the descriptors were computed from (ConfigError if it lacks one of
        ``bones``).
    """
    names = skeletons.get(skeleton).require(bones)
    d = jnp.asarray(d, jnp.float32)
    if "neck" not in names:
        return d
    i = 3 * names.index("neck")
    delta = jnp.asarray(reference, jnp.float32) - jnp.asarray(neutral, jnp.float32)
    c, s = jnp.cos(delta), jnp.sin(delta)
    x, z = d[..., i], d[..., i + 2]
    d = d.at[..., i].set(c * x + s * z)
    return d.at[..., i + 2].set(c * z - s * x)


LEG_TILT_REFERENCE = 0.0
"""rad: where ``level_body`` puts a recording's median shin tilt (``atan2(-s_x, -s_z)`` of the
knee -> ankle bones, the angle of the shin, turned upwards, from the body's up axis towards its
forward axis): straight down. The trackers disagree on where the trunk axis (HipCenter ->
ShoulderCenter) sits against the legs: the median shin of a standing MSR Action3D person leans
17 deg forward in that frame, of a UTKinect-Action3D person 18 deg back, of a CMU BVH clip 19
deg back (the playability benchmark of issue 57, ``benchmarks/README.md``). Levelling makes a
person's legs hang straight below their body frame on the median, so a robot whose torso follows the
body frame stands upright over its legs when the person does."""

BONE_TILT_REFERENCES: dict[str, float] = {
    "spine_lower": math.atan2(-0.468, 0.884),
    "foot_left": math.atan2(0.965, 0.260),
    "foot_right": math.atan2(0.968, 0.250),
}
"""rad: where ``level_body`` puts a recording's median tilt ``atan2(v_x, v_z)`` of each of these
bones: the median directions over the valid frames of the bundled MSR Action3D training
subjects (1, 3, 5, 7, 9; spine_lower -27.9 deg, the feet 74.9 and 75.5 deg), which the robots'
correspondence rows take as their standing posture (``BonePair.rest``). Where a capture system
puts these points depends on the tracker far more than on the person (the Kinect v1 foot point
sits 15 deg above the ankle's horizontal in MSR Action3D, 30-48 deg below it in
UTKinect-Action3D; a BVH toe 7-17 deg below), so each recording's own median is taken as its
standing direction."""


def _tilt(v: jax.Array) -> jax.Array:
    """``(...)`` angle ``atan2(v_x, v_z)`` of ``(..., 3)`` vectors: from the up axis to forward."""
    return jnp.arctan2(v[..., 0], v[..., 2])


def _median(x: jax.Array, valid: jax.Array, default: float) -> jax.Array:
    """The median of ``(T,)`` ``x`` over the ``valid`` entries (``default`` if none); a sort."""
    ordered = jnp.sort(jnp.where(valid, x, jnp.inf))
    k = jnp.sum(valid.astype(jnp.int32))
    mid = 0.5 * (ordered[jnp.maximum(k - 1, 0) // 2] + ordered[k // 2])
    return jnp.where(k > 0, mid, jnp.float32(default)).astype(jnp.float32)


def _turn(v: jax.Array, angle: jax.Array) -> jax.Array:
    """``(..., 3)`` vectors turned about the body's left (y) axis by ``angle`` (adds ``angle``
    to their ``_tilt``)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    x, z = v[..., 0], v[..., 2]
    return jnp.stack([c * x + s * z, v[..., 1], c * z - s * x], axis=-1)


def world_up(positions: ArrayLike, *, skeleton: SkeletonLike = skeletons.DEFAULT) -> jax.Array:
    """``(..., n_joints, 3)`` positions -> ``(..., 3)`` the capture's up axis (+y: Kinect v1
    camera space and every reader's output) in each frame's body frame (``body_frame``; the
    identity's where the frame is degenerate). A camera's own pitch is not removed."""
    rot, _ = body_frame(jnp.asarray(positions, jnp.float32), skeleton=skeleton)
    return rot[..., :, 1]


def level_body(
    d: ArrayLike,
    valid: ArrayLike,
    bones: str | tuple[str, ...] = "full",
    *,
    skeleton: SkeletonLike = skeletons.DEFAULT,
    up: ArrayLike | None = None,
    legs: bool = True,
) -> jax.Array:
    """One recording's descriptors levelled against its own medians, for robots that read the
    legs: (1) (with ``legs``, the default) every bone turned about the body's left axis so
    that the median shin (both sides, valid frames) points straight down
    (``LEG_TILT_REFERENCE``), then (2) each bone of
    ``BONE_TILT_REFERENCES`` turned about the same axis so that its median tilt is the
    reference. Both take out where a tracker puts its points, not what the person does: a
    person's legs hang below the trunk and their feet stand flat for most of a recording, and
    levelling keeps every frame's deviation from the recording's own median.

    With ``up`` (each frame's capture up axis in the body frame, ``world_up``) the feet are
    levelled against the floor instead of the body: each foot's median tilt measured from the
    capture's horizontal (its tilt less ``up``'s, before step 1) is what moves to the
    reference, so a foot flat on the floor corresponds to the robot's flat sole whatever the
    trunk's lean, and a robot that stands on its soles leans as the person does. Without it
    (``None``) the feet's median in the body frame moves to the reference: the robot stands
    upright over flat soles, leaning or not. Measured on a bundled robot's per-frame generic IK,
    the trunk's lean on flat soles minus the person's, deg: UTKinect s07 e01 / e02 / s09 e01
    -9.9 / -5.9 / -14.9 against the body, -7.5 / -4.7 / -10.7 against the floor; CMU 131_01
    -10.0 / -2.3 (every 3rd frame; the 2-core VM, 2026-11-28).

    Without both shins in ``bones`` (the upper-body descriptors) ``d`` is returned as it is. A
    recording with no valid frame is left as it is. Traceable (sorts, no host sync).

    Args:
      d: ``(T, 3 * n_bones)`` one recording's descriptors.
      valid: ``(T,)`` bool.
      bones, skeleton: the descriptor's bones and skeleton.
      up: ``(T, 3)`` the capture's up axis in each frame's body frame, or ``None``.
      legs: take step (1). Without it every bone keeps its direction in the person's own body
        frame (a whole-body motion places the robot's torso at that frame in the world, where
        the turn would tilt every limb by it: ``jaxproj.motion.whole_body``); step (2) still
        runs.

    Returns:
      ``(T, 3 * n_bones)`` float32.
    """
    names = skeletons.get(skeleton).require(bones)
    d = jnp.asarray(d, jnp.float32)
    if not {"shin_left", "shin_right"} <= set(names):
        return d
    valid = jnp.asarray(valid, bool)
    v = d.reshape(*d.shape[:-1], len(names), 3)
    shins = jnp.concatenate(
        [-v[:, names.index("shin_left")], -v[:, names.index("shin_right")]], axis=0
    )
    neutral = _median(_tilt(shins), jnp.concatenate([valid, valid]), LEG_TILT_REFERENCE)
    if legs:
        v = _turn(v, jnp.float32(LEG_TILT_REFERENCE) - neutral)
    floor = None if up is None else _tilt(jnp.asarray(up, jnp.float32))  # (T,), unturned
    for bone, reference in BONE_TILT_REFERENCES.items():
        if bone in names:
            i = names.index(bone)
            tilt = _tilt(v[:, i])
            if floor is not None and bone.startswith("foot"):  # wrapped far from the data
                tilt = _wrap(tilt - floor - reference) + reference
            own = _median(tilt, valid, reference)
            v = v.at[:, i].set(_turn(v[:, i], jnp.float32(reference) - own))
    return v.reshape(d.shape)


def _wrap(angle: jax.Array) -> jax.Array:
    """Angles wrapped to ``(-pi, pi]``."""
    return jnp.arctan2(jnp.sin(angle), jnp.cos(angle))
