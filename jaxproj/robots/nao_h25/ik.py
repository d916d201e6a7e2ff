"""Analytic inverse kinematics: body-frame bone directions -> NAO H25 joint angles.

This is the ground truth of the whole method: every landmark's robot pose is ``ik(h_i)`` and every
error metric compares against it.

What it drives (``robot.DRIVEN_JOINTS``), from the descriptor bones of ``skeleton.UPPER_BODY``:

* Arms, closed form (reference notes section 9). With ``u`` the upper-arm and ``f`` the forearm
  direction in the body frame (x forward, y left, z up), the NAO arm produces
  ``seg = Ry(p) Rz(r + s*delta) ex`` for the shoulder->elbow *segment* (``delta = atan2(15, 105)``,
  the ElbowOffsetY, ``s = +1`` left, ``-1`` right) and ``f = Ry(p) Rz(r) Rx(y) Rz(e) ex``. The IK
  makes the physical shoulder->elbow segment parallel to the human upper arm and the forearm
  parallel to the human forearm:

  1. ``ShoulderPitch = atan2(-u_z, u_x)``;
  2. ``ShoulderRoll = atan2(u_y, hypot(u_x, u_z)) - s*delta``;
  3. ``f' = Rz(-r) Ry(-p) f`` (forearm in the upper-arm frame, with the *clamped* p, r);
  4. ``ElbowRoll = -s * atan2(hypot(f'_y, f'_z), f'_x)``;
  5. ``LElbowYaw = atan2(-f'_z, -f'_y)``, ``RElbowYaw = atan2(f'_z, f'_y)``.

* Head. A Kinect v1 skeleton has a single head point, so only the direction of the neck bone
  (ShoulderCenter -> Head) is observed. ``HeadPitch`` is its forward tilt
  ``atan2(n_x, n_z) - HEAD_PITCH_NEUTRAL`` (positive = looking down, as on the NAO), where the
  neutral offset is the median neck tilt of the bundled MSR Action3D recordings (the Kinect head
  joint sits behind the hip->shoulder axis of an upright person). That tilt depends on the
  capture set-up (UTKinect's median is 41 deg further forward), so ``retarget`` levels each
  recording before the IK (and the projection) read it: by default the recording's own median
  neck tilt over its valid frames is turned to ``HEAD_PITCH_NEUTRAL``
  (``skeleton.level_neck``, ``pipeline.level``); ``retarget(neck_neutral=rad)`` gives the
  neutral tilt instead, ``neck_neutral=None`` turns the levelling off. This IK itself stays a
  pure function of one descriptor. HeadPitch is then clipped to NAOqi's head anti-collision
  envelope at the HeadYaw (``robot.HEAD_ENVELOPE``). Head *yaw* is not observable;
  ``HeadYaw`` follows the sideways lean of the neck ``atan2(n_y, n_z)`` (leaning left turns the
  head left) — a documented proxy, not a measurement of head rotation.

Singular configurations, resolved by deterministic per-frame rules (no history, so the IK is a
pure function of one descriptor and the same input always gives the same output):

* straight elbow (ElbowYaw undefined or ill-conditioned): ElbowYaw is blended towards
  ``ELBOW_YAW_NEUTRAL`` (0) with a smoothstep weight of the *human* elbow flexion (the angle
  between upper arm and forearm) that is 0 at <= 2 deg and 1 at >= 30 deg. Two reasons: (a) the
  yaw of a nearly straight elbow is set by the small sideways part of the forearm, i.e. by
  Kinect noise (3.7 mm per joint coordinate, measured; ~5 deg of forearm direction is ~30 deg of
  yaw at 10 deg of flexion); (b) because of the 8.13 deg ElbowOffsetY, a straight human arm puts
  the NAO forearm on the ``atan2`` branch cut of ElbowYaw (+-180 deg, outside the +-119.5 deg
  range), where the clipped yaw flips sign with round-off. Weighting by the human flexion makes
  straight arms map to yaw 0 continuously. Inside the band the robot forearm deviates from the
  human's by at most ~16 deg (2 x 8.13 deg for a straight arm);
* upper arm along the shoulder axis (``hypot(u_x, u_z) -> 0``, ShoulderPitch undefined):
  ShoulderPitch is blended towards 0 (arm horizontal) with a smoothstep weight that is 0 below
  ``sin(1 deg)`` and 1 above ``sin(4 deg)`` (every reachable arm has ``hypot >= sin(5.9 deg)``:
  ShoulderRoll is at most 76 deg, plus the 8.13 deg segment offset);
* a zero-length (or non-finite) input vector is replaced by the standing direction (arms hanging,
  neck up). Inputs need not be unit length (mean-shift modes are averages): each bone vector is
  normalised first.

Every angle is clamped to its joint limits, and HeadPitch to the head anti-collision envelope
at the clamped HeadYaw (``robot.HEAD_ENVELOPE``, NAOqi's table); joints outside
``DRIVEN_JOINTS`` are held at ``robot.STANDING_POSTURE``. The result never contains NaN.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.buckets import call_bucketed
from jaxproj._internal.jit import full_precision, jit
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import NECK_TILT_REFERENCE, UPPER_BODY, resolve_bones
from jaxproj.robots import robot_file
from jaxproj.robots.base import Chain, Robot
from jaxproj.robots.base import chain_columns as base_chain_columns
from jaxproj.robots.base import driven_to_full as _driven_to_full
from jaxproj.robots.generic_ik import BonePair, Correspondence
from jaxproj.robots.nao_h25 import robot

ELBOW_OFFSET_ANGLE = math.atan2(robot.ELBOW_OFFSET_Y, robot.UPPER_ARM_LENGTH)
"""rad (8.13 deg): angle between the ElbowYaw axis and the shoulder->elbow segment."""

HEAD_PITCH_NEUTRAL = NECK_TILT_REFERENCE
"""rad (-27.1 deg): the neck tilt read as HeadPitch 0: ``skeleton.NECK_TILT_REFERENCE``, the
median forward tilt ``atan2(n_x, n_z)`` of the neck bone over the 22,365 valid frames of the
bundled MSR Action3D recordings (5th..95th percentile -51..-3.5 deg). ``retarget`` first levels
each recording's neck so that its own median tilt sits here (``skeleton.level_neck``)."""

ELBOW_YAW_NEUTRAL = 0.0
"""rad: ElbowYaw taken when the elbow is straight (where yaw does not move the forearm)."""

_ELBOW_BLEND = (math.radians(2.0), math.radians(30.0))
_PITCH_BLEND = (math.sin(math.radians(1.0)), math.sin(math.radians(4.0)))
_REQUIRED = ("neck", "upper_arm_left", "forearm_left", "upper_arm_right", "forearm_right")

_LO = {n: float(robot.LOWER[robot.IDX[n]]) for n in robot.DRIVEN_JOINTS}
_HI = {n: float(robot.UPPER[robot.IDX[n]]) for n in robot.DRIVEN_JOINTS}


def _chain_ik(x: np.ndarray, *, name: str) -> np.ndarray:
    """``Chain.ik`` of the chain called ``name``: ``solve_chain`` from its own columns."""
    return solve_chain(x, _CHAIN_BY_NAME[name])


CHAINS: tuple[Chain, ...] = tuple(
    replace(c, ik=partial(_chain_ik, name=c.name)) for c in robot_file.describe(robot.FILE).chains
)
"""How the IK factorises (the robot file's ``[[chains]]``, with this IK's chain functions): the
head angles depend only on the neck bone, each arm's four angles only on that arm's upper arm and
forearm (``_solve_driven`` computes them from exactly these bones; ``tests/robots/test_ik.py``
perturbs one chain's bones and checks the others' outputs are bit-identical). Together the chains
cover ``robot.DRIVEN_JOINTS`` once each. Their bandwidths (the file's) were tuned
leave-one-training-subject-out over MSR subjects 1,3,5,7,9 (``benchmarks/TUNING.md``)."""

WHOLE_BODY = Chain("whole", UPPER_BODY, robot.DRIVEN_JOINTS, partial(_chain_ik, name="whole"))
"""The paper's formulation as one chain: all five upper-body bones -> all ten driven joints."""

CHAIN_SETS: dict[str, tuple[Chain, ...]] = {"upper": CHAINS, "whole": (WHOLE_BODY,)}
"""Named chain sets of ``BuildConfig.chains``: per-chain projection (default) or whole-body."""

_CHAIN_BY_NAME = {c.name: c for c in (*CHAINS, WHOLE_BODY)}

_REST_DIRECTION = {"neck": (0.0, 0.0, 1.0)}
"""Fill for the bones a chain does not read (any valid direction gives the same chain angles);
arm bones hang: (0, 0, -1)."""


def chain_set(name: str) -> tuple[Chain, ...]:
    """The chains of ``CHAIN_SETS[name]``; ``ConfigError`` for an unknown name."""
    if name not in CHAIN_SETS:
        raise ConfigError(f"unknown chain set {name!r}; use one of {sorted(CHAIN_SETS)}")
    return CHAIN_SETS[name]


def chain_columns(chain: Chain, bones: str | tuple[str, ...] = "upper") -> tuple[int, ...]:
    """The columns of a ``bones`` descriptor holding ``chain``'s bones (``base.chain_columns``)."""
    return base_chain_columns(chain, bones)


def chain_joints(chain: Chain) -> tuple[int, ...]:
    """Positions of ``chain.joints`` in ``robot.DRIVEN_JOINTS``."""
    return tuple(robot.DRIVEN_JOINTS.index(j) for j in chain.joints)


def solve_chain(x: np.ndarray, chain: Chain, bones: str | tuple[str, ...] = "upper") -> np.ndarray:
    """IK of one chain from its own bones: ``(N, 3 * len(chain.bones))`` -> ``(N, len(joints))``.

    The chain's bones are placed in a ``bones`` descriptor whose other bones rest (neck up, arms
    hanging); by the IK's factorisation (``CHAINS``) the result does not depend on that fill.
    """
    x = np.asarray(x, np.float32)
    names = resolve_bones(bones)
    fill = np.concatenate([_REST_DIRECTION.get(b, (0.0, 0.0, -1.0)) for b in names])
    d = np.broadcast_to(fill.astype(np.float32), (len(x), len(fill))).copy()
    d[:, list(chain_columns(chain, bones))] = x
    return np.asarray(solve_driven(d, bones))[:, list(chain_joints(chain))]


def _smoothstep(x: jax.Array, lo: float, hi: float) -> jax.Array:
    t = jnp.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _unit_or(v: jax.Array, fallback: tuple[float, float, float]) -> jax.Array:
    """Normalise ``(..., 3)``; where the norm is tiny or non-finite use ``fallback``."""
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    ok = (n > 1e-6) & jnp.isfinite(n)
    fb = jnp.broadcast_to(jnp.asarray(fallback, dtype=v.dtype), v.shape)
    return jnp.where(ok, v / jnp.where(ok, n, 1.0), fb)


def _arm(u: jax.Array, f: jax.Array, side: str) -> tuple[jax.Array, ...]:
    """Closed-form arm IK for one side; ``u``, ``f``: ``(..., 3)``. Returns p, r, yaw, roll."""
    s = 1.0 if side == "L" else -1.0
    u = _unit_or(u, (0.0, 0.0, -1.0))
    f = _unit_or(f, (0.0, 0.0, -1.0))
    ux, uy, uz = u[..., 0], u[..., 1], u[..., 2]
    c = jnp.sqrt(ux * ux + uz * uz)
    w_p = _smoothstep(c, *_PITCH_BLEND)
    pitch = w_p * jnp.arctan2(-uz, ux)
    roll = jnp.arctan2(uy, c) - s * ELBOW_OFFSET_ANGLE
    pitch = jnp.clip(pitch, _LO[f"{side}ShoulderPitch"], _HI[f"{side}ShoulderPitch"])
    roll = jnp.clip(roll, _LO[f"{side}ShoulderRoll"], _HI[f"{side}ShoulderRoll"])
    cp, sp = jnp.cos(pitch), jnp.sin(pitch)
    cr, sr = jnp.cos(roll), jnp.sin(roll)
    ax = cp * f[..., 0] - sp * f[..., 2]
    ay = f[..., 1]
    az = sp * f[..., 0] + cp * f[..., 2]
    fx = cr * ax + sr * ay
    fy = -sr * ax + cr * ay
    fz = az
    lateral = jnp.sqrt(fy * fy + fz * fz)
    flex = jnp.arctan2(lateral, fx)  # >= 0
    yaw_raw = jnp.arctan2(-s * fz, -s * fy)
    yaw_raw = jnp.clip(yaw_raw, _LO[f"{side}ElbowYaw"], _HI[f"{side}ElbowYaw"])
    # the human elbow's own flexion (angle between upper arm and forearm) decides the blend
    cross = jnp.cross(u, f)
    human_flex = jnp.arctan2(jnp.sqrt(jnp.sum(cross * cross, axis=-1)), jnp.sum(u * f, axis=-1))
    w_e = _smoothstep(human_flex, *_ELBOW_BLEND)
    yaw = w_e * yaw_raw + (1.0 - w_e) * ELBOW_YAW_NEUTRAL
    elbow_roll = jnp.clip(-s * flex, _LO[f"{side}ElbowRoll"], _HI[f"{side}ElbowRoll"])
    return pitch, roll, yaw, elbow_roll


@full_precision
def driven_angles(d: jax.Array, bone_index: tuple[int, ...]) -> jax.Array:
    """The traceable core of ``solve_driven`` (call it inside a jitted function).

    Args:
      d: ``(..., 3 * n_bones)`` descriptors.
      bone_index: ``bone_index(bones)``: positions of the neck, upper arms and forearms.

    Returns:
      ``(..., 10)`` driven angles (see ``solve_driven``).
    """
    d = jnp.asarray(d, dtype=jnp.float32)
    vec = d.reshape(*d.shape[:-1], d.shape[-1] // 3, 3)
    neck, lu, lf, ru, rf = (vec[..., i, :] for i in bone_index)
    n = _unit_or(neck, (0.0, 0.0, 1.0))
    head_pitch = jnp.arctan2(n[..., 0], n[..., 2]) - HEAD_PITCH_NEUTRAL
    head_yaw = jnp.arctan2(n[..., 1], n[..., 2])
    head_yaw = jnp.clip(head_yaw, _LO["HeadYaw"], _HI["HeadYaw"])
    head_pitch = jnp.clip(head_pitch, _LO["HeadPitch"], _HI["HeadPitch"])
    env_lo, env_hi = robot.HEAD_ENVELOPE.bounds(head_yaw)  # NAOqi's anti-collision envelope
    head_pitch = jnp.clip(head_pitch, env_lo, env_hi)
    left = _arm(lu, lf, "L")
    right = _arm(ru, rf, "R")
    out = jnp.stack([head_yaw, head_pitch, *left, *right], axis=-1)
    # Non-finite input cannot reach here as NaN (``_unit_or``), but keep the contract explicit.
    standing = jnp.broadcast_to(jnp.asarray(_standing_driven(), out.dtype), out.shape)
    return jnp.where(jnp.isfinite(out), out, standing)


def _standing_driven() -> np.ndarray:
    return robot.STANDING_POSTURE[robot.DRIVEN_INDEX]


def bone_index(bones: str | tuple[str, ...]) -> tuple[int, ...]:
    """Where the IK's bones (neck, upper arms, forearms) sit in a ``bones`` descriptor.

    Raises:
      ConfigError: an unknown subset, or one without the bones the IK needs.
    """
    names = resolve_bones(bones)
    missing = [b for b in _REQUIRED if b not in names]
    if missing:
        raise ConfigError(f"the IK needs the bones {_REQUIRED}; the descriptor lacks {missing}")
    return tuple(names.index(b) for b in _REQUIRED)


_solve_driven_jit = jit(driven_angles, static_argnames=("bone_index",))


def solve_driven(d: ArrayLike, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """IK of the driven joints only.

    Args:
      d: ``(..., 3 * n_bones)`` descriptor(s) (``skeleton.descriptor`` layout for ``bones``);
        vectors need not be unit length.
      bones: the bone subset the descriptor was built with; it must contain the neck, both upper
        arms and both forearms.

    Returns:
      ``(..., 10)`` float32 radians in ``robot.DRIVEN_JOINTS`` order, within limits, finite.

    Compiled once per shape; host arrays (NumPy) are padded along their rows to a bucket
    (``jaxproj._internal.buckets``), so most lengths share one compile.
    """
    index = bone_index(bones)
    if isinstance(d, jax.Array):  # on a device already: one compile per shape
        return _solve_driven_jit(d, bone_index=index)
    # host data: rows padded to a bucket (zero rows: the standing answer), one compile per bucket
    x = np.asarray(d, np.float32)
    if x.ndim == 0:
        raise ConfigError(f"descriptors must be (..., 3 * n_bones), got a scalar {x!r}")
    return call_bucketed(lambda rows: _solve_driven_jit(rows, bone_index=index), x, 1)


def driven_to_full(q_driven: jax.Array) -> jax.Array:
    """``(..., 10)`` driven angles -> ``(..., 26)`` configuration; the rest at the standing pose."""
    return _driven_to_full(robot.STANDING_POSTURE, robot.DRIVEN_INDEX, q_driven)


def solve(d: jax.Array, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """IK of the whole robot: ``(..., 3 * n_bones)`` descriptors -> ``(..., 26)`` angles (rad).

    Driven joints as ``solve_driven``; all other joints at ``robot.STANDING_POSTURE``
    (RHipYawPitch = LHipYawPitch holds there).
    """
    return driven_to_full(solve_driven(d, bones))


def traced_ik(d: jax.Array, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """``driven_angles`` for a ``bones`` descriptor: the IK inside a trace (no nested jit)."""
    return driven_angles(d, bone_index(bones))


IK_CONSTANTS: dict[str, float] = {
    "head_pitch_neutral": HEAD_PITCH_NEUTRAL,
    "elbow_yaw_neutral": ELBOW_YAW_NEUTRAL,
}
"""The IK's constants a model file records (meta ``"ik"``)."""


def attach(data: Robot) -> Robot:
    """The robot file's ``[ik] kind = "python"`` hook: the NAO ``data`` (the robot file's robot)
    with this closed form as its IK (``Robot.ik``, ``traced_ik``, each chain's IK, the whole-body
    chain, ``ik_constants``).

    Raises:
      ConfigError: ``data`` is not the robot this closed form was written for (its joints,
        driven joints or chains differ from the file this module reads).
    """
    if (data.joint_names, data.driven_joints, data.chains) != (
        robot.JOINT_NAMES, robot.DRIVEN_JOINTS, CHAINS
    ):  # fmt: skip
        raise ConfigError(f"the NAO closed-form IK drives {robot.DRIVEN_JOINTS} through the "
                          f"chains of {robot.FILE}; robot {data.name!r} differs")  # fmt: skip
    return replace(
        data,
        chains=CHAINS,
        ik=solve_driven,
        traced_ik=traced_ik,
        whole_chain=WHOLE_BODY,
        ik_constants=IK_CONSTANTS,
    )


ARM_CORRESPONDENCE = Correspondence(
    "torso",
    tuple(
        BonePair(f"{bone}_{side}", a, b)
        for side, (shoulder, elbow, wrist) in robot.ARM_SITES.items()
        for bone, a, b in (("upper_arm", shoulder, elbow), ("forearm", elbow, wrist))
    ),
    source="the closed form's own choice: the shoulder -> elbow segment and the forearm",
)
"""The NAO's arms as data for the generic IK (``jaxproj.robots.generic_ik``; tests and
benchmarks compare the two IKs): each upper arm follows the shoulder -> elbow segment, each
forearm the elbow -> wrist, in the torso frame, as the closed form matches them (its head rule
is not a direction and stays the closed form's)."""
