"""Kinect v1 skeleton: joint order, bone tree and the body-frame bone-direction descriptor.

Joint order everywhere in jaxproj is the Kinect SDK v1 order (``JOINT_NAMES``). A pose is a
``(20, 3)`` array of positions in metres in any right-handed camera frame; the descriptor does not
depend on that frame (it is expressed in a body frame built from the skeleton itself).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.buckets import call_bucketed
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError

JOINT_NAMES: tuple[str, ...] = (
    "HipCenter", "Spine", "ShoulderCenter", "Head",
    "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft",
    "ShoulderRight", "ElbowRight", "WristRight", "HandRight",
    "HipLeft", "KneeLeft", "AnkleLeft", "FootLeft",
    "HipRight", "KneeRight", "AnkleRight", "FootRight",
)  # fmt: skip
"""The 20 Kinect v1 joints in SDK order (the order of every ``(..., 20, 3)`` array)."""

N_JOINTS = len(JOINT_NAMES)
J = {name: i for i, name in enumerate(JOINT_NAMES)}
"""Joint name -> index in ``JOINT_NAMES``."""

BONES: tuple[tuple[str, str], ...] = (
    ("HipCenter", "Spine"), ("Spine", "ShoulderCenter"), ("ShoulderCenter", "Head"),
    ("ShoulderCenter", "ShoulderLeft"), ("ShoulderLeft", "ElbowLeft"),
    ("ElbowLeft", "WristLeft"), ("WristLeft", "HandLeft"),
    ("ShoulderCenter", "ShoulderRight"), ("ShoulderRight", "ElbowRight"),
    ("ElbowRight", "WristRight"), ("WristRight", "HandRight"),
    ("HipCenter", "HipLeft"), ("HipLeft", "KneeLeft"), ("KneeLeft", "AnkleLeft"),
    ("AnkleLeft", "FootLeft"),
    ("HipCenter", "HipRight"), ("HipRight", "KneeRight"), ("KneeRight", "AnkleRight"),
    ("AnkleRight", "FootRight"),
)  # fmt: skip
"""The 19 bones (parent, child) of the Kinect v1 tree; bone ``i`` is named ``BONE_NAMES[i]``."""

BONE_NAMES: tuple[str, ...] = (
    "spine_lower", "spine_upper", "neck",
    "clavicle_left", "upper_arm_left", "forearm_left", "hand_left",
    "clavicle_right", "upper_arm_right", "forearm_right", "hand_right",
    "pelvis_left", "thigh_left", "shin_left", "foot_left",
    "pelvis_right", "thigh_right", "shin_right", "foot_right",
)  # fmt: skip

UPPER_BODY: tuple[str, ...] = (
    "neck", "upper_arm_left", "forearm_left", "upper_arm_right", "forearm_right",
)  # fmt: skip
"""Default bone subset: what the NAO head and arms (up to the elbow) can follow. 15 numbers."""

FULL_BODY: tuple[str, ...] = BONE_NAMES
"""All 19 bones: 57 numbers."""

BONE_SUBSETS: dict[str, tuple[str, ...]] = {"upper": UPPER_BODY, "full": FULL_BODY}

_MIRROR_NAME = {n: n.replace("_left", "_TMP").replace("_right", "_left").replace("_TMP", "_right")
                for n in BONE_NAMES}  # fmt: skip

MIN_BONE_LENGTH = 1e-3
"""Metres. A bone (or body-frame axis) shorter than this makes the frame invalid."""


def resolve_bones(bones: str | tuple[str, ...]) -> tuple[str, ...]:
    """Turn a subset name (``"upper"``, ``"full"``) or a tuple of bone names into bone names."""
    if isinstance(bones, str):
        if bones not in BONE_SUBSETS:
            raise ConfigError(f"unknown bone subset {bones!r}; use one of {sorted(BONE_SUBSETS)}")
        return BONE_SUBSETS[bones]
    bones = tuple(bones)
    unknown = [b for b in bones if b not in BONE_NAMES]
    if unknown or not bones:
        raise ConfigError(f"unknown bone names {unknown}; valid names are {BONE_NAMES}")
    return bones


def body_frame(positions: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Body frame of a skeleton, built from the skeleton itself (not the camera axes).

    ``up`` points from HipCenter to ShoulderCenter; ``left`` from ShoulderRight to ShoulderLeft,
    made orthogonal to ``up``; ``forward = left x up``. In a right-handed camera frame (Kinect)
    ``forward`` points out of the person's chest. The axes match the NAO torso frame (x forward,
    y left, z up), so a bone direction in this frame can be compared with the robot's directly.

    Args:
      positions: ``(..., 20, 3)`` joint positions (Kinect SDK order), any units.

    Returns:
      ``(rotation, ok)``: ``(..., 3, 3)`` matrix whose rows are forward, left, up (so
      ``rotation @ v`` expresses a camera-frame vector in the body frame), and ``(...,)`` bool,
      false where the frame is degenerate or non-finite (the rotation is then the identity).
    """
    p = jnp.asarray(positions)
    up_raw = p[..., J["ShoulderCenter"], :] - p[..., J["HipCenter"], :]
    left_raw = p[..., J["ShoulderLeft"], :] - p[..., J["ShoulderRight"], :]
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
) -> tuple[jax.Array, jax.Array]:
    """The paper's pose descriptor: bone unit vectors expressed in the body frame.

    Invariant to translation, to any rotation of the whole skeleton (the frame is built from the
    skeleton) and to uniform scaling (unit vectors).

    Args:
      positions: ``(..., 20, 3)`` joint positions in Kinect SDK order.
      bones: subset name (``"upper"`` default: neck, upper arms, forearms; ``"full"``: all 19)
        or a tuple of names from ``BONE_NAMES``.
      mirror: if true, the human's left limbs drive the robot's right ones (mirror imitation):
        each left bone is swapped with its right twin and the lateral (y) component negated.
        Default false: direct imitation (human left arm -> robot left arm).

    Returns:
      ``(d, valid)``: ``(..., 3 * n_bones)`` float32 descriptor, bone after bone, each a unit
      ``(x forward, y left, z up)`` vector; and ``(...,)`` bool. A frame is invalid where its body
      frame is degenerate, a value is non-finite, or a chosen bone is shorter than
      ``MIN_BONE_LENGTH``; its descriptor is all zeros there (never NaN).

    Compiled once per shape; host arrays (NumPy) are padded along their frames to a bucket
    (``jaxproj._internal.buckets``), so recordings of most lengths share one compile. Inside
    a caller's trace it is plain JAX code.

    Raises:
      ConfigError: host ``positions`` not shaped ``(..., 20, 3)``.
    """
    names = resolve_bones(bones)
    if mirror:
        names = tuple(_MIRROR_NAME[n] for n in names)
    index = tuple(BONE_NAMES.index(n) for n in names)
    if isinstance(positions, jax.core.Tracer):  # inside a caller's trace: the plain core
        return _descriptor(positions, index, mirror)
    if isinstance(positions, jax.Array):  # on a device already: one compile per shape
        return _descriptor_jit(positions, index=index, mirror=mirror)
    # host data (a recording, a dataset): rows padded to a bucket, one compile per bucket
    p = np.asarray(positions, np.float32)
    if p.ndim < 2 or p.shape[-2:] != (N_JOINTS, 3):
        raise ConfigError(f"positions must be (..., {N_JOINTS}, 3), got {p.shape}")
    return call_bucketed(lambda x: _descriptor_jit(x, index=index, mirror=mirror), p, 2)


def _descriptor(
    positions: jax.Array, index: tuple[int, ...], mirror: bool
) -> tuple[jax.Array, jax.Array]:
    """``descriptor``'s traceable core for the bones ``BONE_NAMES[i]`` of ``index`` (already
    swapped when ``mirror``)."""
    parents = np.array([J[BONES[i][0]] for i in index])
    children = np.array([J[BONES[i][1]] for i in index])
    p = jnp.asarray(positions, dtype=jnp.float32)
    finite = jnp.all(jnp.isfinite(p), axis=(-2, -1))
    p = jnp.where(finite[..., None, None], p, 0.0)
    rot, ok_frame = body_frame(p)
    vec = p[..., children, :] - p[..., parents, :]  # (..., B, 3)
    unit, ok_bone = _safe_unit(vec)
    local = jnp.einsum("...ij,...bj->...bi", rot, unit)
    if mirror:
        local = local.at[..., 1].multiply(-1.0)
    valid = ok_frame & finite & jnp.all(ok_bone, axis=-1)
    local = jnp.where(valid[..., None, None], local, 0.0)
    return local.reshape(*local.shape[:-2], 3 * len(index)), valid


_descriptor_jit = jit(_descriptor, static_argnames=("index", "mirror"))


NECK_TILT_REFERENCE = math.radians(-27.1)
"""rad: the median forward tilt ``atan2(n_x, n_z)`` of the neck bone (ShoulderCenter -> Head, body
frame) over the 22,365 valid frames of the bundled MSR Action3D recordings: the capture set-up
the default projector's landmarks come from. ``level_neck`` brings each recording's own neutral
tilt here (the NAO's IK reads this tilt as HeadPitch 0, ``ik.HEAD_PITCH_NEUTRAL``)."""


def neck_tilt(d: jax.Array, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """``(...,)`` forward tilt ``atan2(n_x, n_z)`` (rad) of the neck bone of ``(..., 3 * n_bones)``
    descriptors (``bones`` must hold ``"neck"``)."""
    i = 3 * resolve_bones(bones).index("neck")
    return jnp.arctan2(d[..., i], d[..., i + 2])


def recording_neck_tilt(
    d: ArrayLike, valid: ArrayLike, bones: str | tuple[str, ...] = "upper"
) -> jax.Array:
    """The neutral neck tilt of one recording: the median ``neck_tilt`` of its valid frames.

    Traceable (a sort, no host sync). Args: ``d`` ``(T, 3 * n_bones)`` descriptors, ``valid``
    ``(T,)`` bool. Returns ``()`` float32 rad; ``NECK_TILT_REFERENCE`` if no frame is valid.
    """
    valid = jnp.asarray(valid, bool)
    tilt = jnp.where(valid, neck_tilt(jnp.asarray(d, jnp.float32), bones), jnp.inf)
    ordered = jnp.sort(tilt)
    k = jnp.sum(valid.astype(jnp.int32))
    mid = 0.5 * (ordered[jnp.maximum(k - 1, 0) // 2] + ordered[k // 2])
    return jnp.where(k > 0, mid, NECK_TILT_REFERENCE).astype(jnp.float32)


def level_neck(
    d: ArrayLike,
    neutral: ArrayLike,
    bones: str | tuple[str, ...] = "upper",
    reference: float = NECK_TILT_REFERENCE,
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
    """
    names = resolve_bones(bones)
    d = jnp.asarray(d, jnp.float32)
    if "neck" not in names:
        return d
    i = 3 * names.index("neck")
    delta = jnp.asarray(reference, jnp.float32) - jnp.asarray(neutral, jnp.float32)
    c, s = jnp.cos(delta), jnp.sin(delta)
    x, z = d[..., i], d[..., i + 2]
    d = d.at[..., i].set(c * x + s * z)
    return d.at[..., i + 2].set(c * z - s * x)
