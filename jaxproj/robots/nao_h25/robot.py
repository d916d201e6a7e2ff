"""The NAO H25 humanoid: named joints, their order, limits, the standing posture, the MJCF model.

Robot configuration vectors in jaxproj are ``(..., 26)`` arrays of joint angles in radians in the
order of ``JOINT_NAMES`` (the ALMotion "Body" order of the H25). LHand / RHand are the hands'
open/close commands (unitless 0..1, kept as joints so the vector matches ALMotion).

The analytic IK (``jaxproj.robots.nao_h25.ik``) drives ``DRIVEN_JOINTS`` (head and both arms up
to the elbow); every other joint is held at ``STANDING_POSTURE``. Metrics average over
``DRIVEN_JOINTS`` only. ``jaxproj.robots.NAO_H25`` (``nao_h25/spec.py``) is the ``Robot`` built
from these constants.

All numbers come from ``shared/reference/nao_h25_kinematics.md`` (Aldebaran H25 V4/V5 docs and the
Aldebaran-generated V5 URDF, cross-checked); see the MJCF ``assets/nao_h25.xml`` for the inertials.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.robots import mjcf as _mjcf
from jaxproj.robots.base import RATED_FRACTION, CoupledLimit, mj_joint_ids, mj_site_ids
from jaxproj.robots.base import joint_qpos_index as _qpos_index

NAME = "NAO H25 V5"

JOINT_NAMES: tuple[str, ...] = (
    "HeadYaw", "HeadPitch",
    "LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll", "LWristYaw", "LHand",
    "LHipYawPitch", "LHipRoll", "LHipPitch", "LKneePitch", "LAnklePitch", "LAnkleRoll",
    "RHipYawPitch", "RHipRoll", "RHipPitch", "RKneePitch", "RAnklePitch", "RAnkleRoll",
    "RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll", "RWristYaw", "RHand",
)  # fmt: skip
"""The 26 named joints of the H25 in configuration order (ALMotion "Body" order)."""

N_JOINTS = len(JOINT_NAMES)
IDX = {name: i for i, name in enumerate(JOINT_NAMES)}
"""Joint name -> index in ``JOINT_NAMES``."""

# Official limits (rad), ALD-JOINTS "H25 - Joints V5 & V4"; right-leg values are the official,
# slightly asymmetric ones. LHand/RHand: unitless command 0..1.
_LIMITS: dict[str, tuple[float, float]] = {
    "HeadYaw": (-2.0857, 2.0857),
    "HeadPitch": (-0.6720, 0.5149),
    "LShoulderPitch": (-2.0857, 2.0857),
    "LShoulderRoll": (-0.3142, 1.3265),
    "LElbowYaw": (-2.0857, 2.0857),
    "LElbowRoll": (-1.5446, -0.0349),
    "LWristYaw": (-1.8238, 1.8238),
    "LHand": (0.0, 1.0),
    "LHipYawPitch": (-1.145303, 0.740810),
    "LHipRoll": (-0.379472, 0.790477),
    "LHipPitch": (-1.535889, 0.484090),
    "LKneePitch": (-0.092346, 2.112528),
    "LAnklePitch": (-1.189516, 0.922747),
    "LAnkleRoll": (-0.397880, 0.769001),
    "RHipYawPitch": (-1.145303, 0.740810),
    "RHipRoll": (-0.790477, 0.379472),
    "RHipPitch": (-1.535889, 0.484090),
    "RKneePitch": (-0.103083, 2.120198),
    "RAnklePitch": (-1.186448, 0.932056),
    "RAnkleRoll": (-0.768992, 0.397935),
    "RShoulderPitch": (-2.0857, 2.0857),
    "RShoulderRoll": (-1.3265, 0.3142),
    "RElbowYaw": (-2.0857, 2.0857),
    "RElbowRoll": (0.0349, 1.5446),
    "RWristYaw": (-1.8238, 1.8238),
    "RHand": (0.0, 1.0),
}

# No-load maximum joint speeds (rad/s) from the Aldebaran-generated URDF (motor speed / gear ratio).
_VMAX: dict[str, float] = {
    "HeadYaw": 8.26797, "HeadPitch": 7.19407,
    "LShoulderPitch": 8.26797, "LShoulderRoll": 7.19407, "LElbowYaw": 8.26797,
    "LElbowRoll": 7.19407, "LWristYaw": 24.6229, "LHand": 8.33,
    "LHipYawPitch": 4.16174, "LHipRoll": 4.16174, "LHipPitch": 6.40239, "LKneePitch": 6.40239,
    "LAnklePitch": 6.40239, "LAnkleRoll": 4.16174,
    "RHipYawPitch": 4.16174, "RHipRoll": 4.16174, "RHipPitch": 6.40239, "RKneePitch": 6.40239,
    "RAnklePitch": 6.40239, "RAnkleRoll": 4.16174,
    "RShoulderPitch": 8.26797, "RShoulderRoll": 7.19407, "RElbowYaw": 8.26797,
    "RElbowRoll": 7.19407, "RWristYaw": 24.6229, "RHand": 8.33,
}  # fmt: skip

LOWER = np.array([_LIMITS[n][0] for n in JOINT_NAMES], dtype=np.float32)
"""(26,) lower joint limits, rad (LHand/RHand: 0)."""
UPPER = np.array([_LIMITS[n][1] for n in JOINT_NAMES], dtype=np.float32)
"""(26,) upper joint limits, rad (LHand/RHand: 1)."""
VELOCITY_LIMITS = np.array([_VMAX[n] for n in JOINT_NAMES], dtype=np.float32)
"""(26,) no-load maximum joint speeds, rad/s."""

ACCELERATION_LIMITS = np.full(len(JOINT_NAMES), 80.0, np.float32)
"""(26,) rad/s^2, ours: Aldebaran publishes no acceleration limit. 80 on every joint is full speed
in about 0.1 s, chosen on the training subjects (``jaxproj.motion.feasible`` module doc: median
M_avg against the IK 3.42 deg at 40 rad/s^2, 2.67 at 80, 2.51 at 150)."""

# Rated ("nominal") joint speeds at the motors' nominal torque, rad/s: Aldebaran, "Description
# of the motors" (NAO documentation 2010, hardware/motor_type.html; mirror
# ii.tudelft.nl/naodoc/site_en/reddoc/hardware/motor_type.html): RE-Max 17 (11,900 rpm no-load,
# 8,810 rpm nominal) at 150.27:1 351.77 deg/s (ShoulderPitch, ElbowYaw, HeadYaw) and at 173.22:1
# 305.16 deg/s (ShoulderRoll, ElbowRoll, HeadPitch); RE-Max 24 (8,000 / 6,330 rpm) at 201.3:1
# 188.67 deg/s (HipYawPitch, HipRoll, AnkleRoll) and at 130.85:1 290.25 deg/s (HipPitch,
# KneePitch, AnklePitch). The motor / reduction of each joint is the one whose no-load speed is
# _VMAX's (shared/reference/nao_h25_kinematics.md section 3.2, "Notes on vmax"); the V4/V5
# joints use the same motors and ratios. WristYaw (A-max 12) and Hand: no rated speed published,
# base.RATED_FRACTION (0.75) x no-load.
_RATED_DEG_S: dict[str, float] = {
    "HeadYaw": 351.77, "HeadPitch": 305.16,
    "ShoulderPitch": 351.77, "ShoulderRoll": 305.16, "ElbowYaw": 351.77, "ElbowRoll": 305.16,
    "HipYawPitch": 188.67, "HipRoll": 188.67, "HipPitch": 290.25, "KneePitch": 290.25,
    "AnklePitch": 290.25, "AnkleRoll": 188.67,
}  # fmt: skip


def _rated(name: str) -> float:
    side = name[1:] if name[:1] in "LR" and name[1:] in _RATED_DEG_S else name
    if side in _RATED_DEG_S:
        return math.radians(_RATED_DEG_S[side])
    return RATED_FRACTION * _VMAX[name]


RATED_SPEEDS = np.array([_rated(n) for n in JOINT_NAMES], dtype=np.float32)
"""(26,) rated joint speeds, rad/s: Aldebaran's nominal speeds (6.1395 rad/s ShoulderPitch,
ElbowYaw, HeadYaw; 5.3260 ShoulderRoll, ElbowRoll, HeadPitch; 3.2929 / 5.0658 for the legs),
0.75 x no-load for WristYaw and Hand (none published). ``jaxproj.motion.feasible``'s default
cap."""

DRIVEN_JOINTS: tuple[str, ...] = (
    "HeadYaw", "HeadPitch",
    "LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll",
    "RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll",
)  # fmt: skip
"""The joints the analytic IK drives (and the projection engine predicts), in this order."""

DRIVEN_INDEX = np.array([IDX[n] for n in DRIVEN_JOINTS], dtype=np.int32)
"""(10,) indices of ``DRIVEN_JOINTS`` in ``JOINT_NAMES``."""

# The posture every non-driven joint is held at (and the whole robot takes when a sequence has no
# valid frame at all): NAO's "Stand" posture, knees slightly bent, arms hanging by the sides with
# the elbows a little flexed. Symmetric left/right per the H25 sign conventions.
_STANDING: dict[str, float] = {
    "HeadYaw": 0.0, "HeadPitch": 0.0,
    "LShoulderPitch": 1.4, "LShoulderRoll": 0.15, "LElbowYaw": -1.2, "LElbowRoll": -0.5,
    "LWristYaw": 0.0, "LHand": 0.25,
    "LHipYawPitch": 0.0, "LHipRoll": 0.0, "LHipPitch": -0.45, "LKneePitch": 0.70,
    "LAnklePitch": -0.35, "LAnkleRoll": 0.0,
    "RHipYawPitch": 0.0, "RHipRoll": 0.0, "RHipPitch": -0.45, "RKneePitch": 0.70,
    "RAnklePitch": -0.35, "RAnkleRoll": 0.0,
    "RShoulderPitch": 1.4, "RShoulderRoll": -0.15, "RElbowYaw": 1.2, "RElbowRoll": 0.5,
    "RWristYaw": 0.0, "RHand": 0.25,
}  # fmt: skip
STANDING_POSTURE = np.array([_STANDING[n] for n in JOINT_NAMES], dtype=np.float32)
"""(26,) the standing posture, rad, in ``JOINT_NAMES`` order (within every limit)."""

COUPLED_JOINTS: tuple[str, str] = ("LHipYawPitch", "RHipYawPitch")
"""One motor drives both; RHipYawPitch := LHipYawPitch (LHipYawPitch has priority)."""

# HeadPitch range as a function of HeadYaw: the head anti-collision table of ALD-JOINTS ("H25 -
# Joints V5 & V4", "anti collision"), via shared/reference/nao_h25_kinematics.md section 3.1:
# yaw (deg) -> pitch min / max (deg), symmetric in yaw, linear in between.
_HEAD_ENVELOPE_DEG: tuple[tuple[float, float, float], ...] = (
    (0.0, -38.5, 29.51),
    (27.85, -38.5, 24.18),
    (43.32, -31.40, 21.20),
    (51.74, -27.50, 18.91),
    (62.45, -24.64, 17.19),
    (87.49, -18.91, 11.46),
    (119.52, -25.73, 18.91),
)
_ENV = np.array(_HEAD_ENVELOPE_DEG[:0:-1] + _HEAD_ENVELOPE_DEG, np.float64)
_ENV[: len(_HEAD_ENVELOPE_DEG) - 1, 0] *= -1.0  # mirror: yaw -119.52 .. 119.52 deg
HEAD_ENVELOPE_YAW = np.radians(_ENV[:, 0]).astype(np.float32)
"""(13,) HeadYaw knots of the head envelope, rad (-119.52 .. 119.52 deg, symmetric)."""
HEAD_ENVELOPE_PITCH_MIN = np.radians(_ENV[:, 1]).astype(np.float32)
"""(13,) lowest HeadPitch at each knot of ``HEAD_ENVELOPE_YAW``, rad."""
HEAD_ENVELOPE_PITCH_MAX = np.radians(_ENV[:, 2]).astype(np.float32)
"""(13,) highest HeadPitch at each knot of ``HEAD_ENVELOPE_YAW``, rad. NAOqi clips HeadPitch to
``[min, max]`` interpolated linearly at the current HeadYaw (the head shell would hit the
shoulders otherwise); ``HEAD_ENVELOPE`` is this table as a ``CoupledLimit``."""
for _a in (HEAD_ENVELOPE_YAW, HEAD_ENVELOPE_PITCH_MIN, HEAD_ENVELOPE_PITCH_MAX):
    _a.flags.writeable = False

HEAD_ENVELOPE = CoupledLimit(
    joint="HeadPitch",
    by="HeadYaw",
    knots=HEAD_ENVELOPE_YAW,
    lower=HEAD_ENVELOPE_PITCH_MIN,
    upper=HEAD_ENVELOPE_PITCH_MAX,
    source='Aldebaran, "H25 - Joints V5 & V4", head anti collision table '
    "(shared/reference/nao_h25_kinematics.md section 3.1)",
)
"""NAOqi's head anti-collision envelope as robot data: HeadPitch's range as a function of
HeadYaw (``Robot.coupled_limits`` of ``jaxproj.robots.NAO_H25``; the IK clips to it too)."""

# Link lengths (m), ALD-LINKS H25 V3.3 (= V4/V5 URDF).
NECK_OFFSET_Z = 0.1265
SHOULDER_OFFSET_Y = 0.098
SHOULDER_OFFSET_Z = 0.100
UPPER_ARM_LENGTH = 0.105
ELBOW_OFFSET_Y = 0.015
LOWER_ARM_LENGTH = 0.05595
HAND_OFFSET_X = 0.05775
HAND_OFFSET_Z = 0.01231
HIP_OFFSET_Y = 0.050
HIP_OFFSET_Z = 0.085
THIGH_LENGTH = 0.100
TIBIA_LENGTH = 0.1029
FOOT_HEIGHT = 0.04519


# --- MJCF model ---

_FREE_JOINT = "root"
_TORSO_BODY = "torso"


def mjcf_path() -> Path:
    """Absolute path of the bundled MJCF ``jaxproj/assets/nao_h25.xml`` (NAO H25 V5)."""
    return (Path(__file__).parent / "nao_h25.xml").resolve()


def load_model(
    mount: Literal["free", "fixed"] = "free", without: Sequence[str] = ()
) -> mujoco.MjModel:
    """Compile the bundled NAO H25 MJCF.

    Args:
      mount: ``"free"``: the torso is a floating base (free joint ``root``; nq = 33, nv = 32).
        ``"fixed"``: the free joint is removed, so the torso is welded to the world at the origin
        with identity orientation (nq = nv = 26; for upper-body rollouts).
      without: names of bodies removed with their whole subtrees (fixed mount only), e.g.
        ``LEG_ROOTS`` for the head and arms alone, ``UPPER_ROOTS`` for the legs alone; the
        actuators, joint equalities and contact excludes that refer to a removed joint or body go
        with them. With the torso welded the subtrees share no degree of freedom, so each part
        keeps exactly the dynamics it has in the whole model, less the contacts across parts.

    Returns:
      The compiled ``mujoco.MjModel`` (all of it: 26 hinge joints named as ``JOINT_NAMES``, 25
      position actuators, the HipYawPitch joint equality).

    Raises:
      ConfigError: ``mount`` is not ``"free"`` or ``"fixed"``; ``without`` with the free mount,
        or naming a body the model does not have (or the torso).
      InputError: the MJCF is missing or MuJoCo cannot compile it.
    """
    return _mjcf.load(mjcf_path(), mount, without, free_joint=_FREE_JOINT, root_body=_TORSO_BODY)


LEG_ROOTS: tuple[str, str] = ("LPelvis", "RPelvis")
"""Bodies at the root of the two legs (``load_model("fixed", without=LEG_ROOTS)``: head, arms)."""

UPPER_ROOTS: tuple[str, str, str] = ("Neck", "LShoulder", "RShoulder")
"""Bodies at the root of the head and the two arms (``without=UPPER_ROOTS``: the legs)."""


def _joint_ids(model: mujoco.MjModel) -> np.ndarray:
    """(26,) MuJoCo joint id of each of ``JOINT_NAMES``; ConfigError if one is missing."""
    return mj_joint_ids(model, JOINT_NAMES)


def joint_qpos_index(model: mujoco.MjModel) -> np.ndarray:
    """(26,) int: address in ``qpos`` of each joint of ``JOINT_NAMES`` in ``model``."""
    return _qpos_index(model, JOINT_NAMES)


def joint_dof_index(model: mujoco.MjModel) -> np.ndarray:
    """(26,) int: address in ``qvel`` (dof index) of each joint of ``JOINT_NAMES`` in ``model``."""
    return np.asarray(model.jnt_dofadr[_joint_ids(model)], dtype=np.int64)


def actuator_index(model: mujoco.MjModel) -> np.ndarray:
    """(26,) int: id of the actuator driving each joint of ``JOINT_NAMES``.

    RHipYawPitch has no actuator of its own (one motor drives both hips): it maps to the
    LHipYawPitch actuator, so the returned ids are not unique. When scattering a configuration
    into ``ctrl`` with ``ctrl[actuator_index(m)] = q``, the RHipYawPitch entry (later in the
    order) overwrites the LHipYawPitch one: set ``q[RHipYawPitch] = q[LHipYawPitch]`` first.
    ConfigError if some joint is not driven.
    """
    jids = _joint_ids(model)
    by_joint: dict[int, int] = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            by_joint.setdefault(int(model.actuator_trnid[a, 0]), a)
    out = np.empty(N_JOINTS, dtype=np.int64)
    for i, name in enumerate(JOINT_NAMES):
        jid = int(jids[i])
        if jid not in by_joint and name == COUPLED_JOINTS[1]:
            jid = int(jids[IDX[COUPLED_JOINTS[0]]])
        if jid not in by_joint:
            raise ConfigError(f"no actuator drives joint {name!r}")
        out[i] = by_joint[jid]
    return out


def _free_qpos_addr(model: mujoco.MjModel) -> int | None:
    """qpos address of the (first) free joint, or None for a fixed-base model."""
    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    return None if free.size == 0 else int(model.jnt_qposadr[free[0]])


def config_to_qpos(model: mujoco.MjModel, angles: np.ndarray) -> np.ndarray:
    """MuJoCo ``qpos`` for one robot configuration.

    Args:
      model: a model from ``load_model`` (either mount).
      angles: (26,) joint angles in ``JOINT_NAMES`` order, rad.

    Returns:
      (nq,) float64: ``model.qpos0`` with the joint angles placed, RHipYawPitch set to the
      LHipYawPitch value (the coupled hip), and, for the free mount, the torso at the origin with
      identity orientation.
    """
    q = np.asarray(angles, dtype=np.float64)
    if q.shape != (N_JOINTS,):
        raise ConfigError(f"angles must have shape ({N_JOINTS},), got {q.shape}")
    q = q.copy()
    q[IDX[COUPLED_JOINTS[1]]] = q[IDX[COUPLED_JOINTS[0]]]
    qpos = np.array(model.qpos0, dtype=np.float64)
    free = _free_qpos_addr(model)
    if free is not None:
        qpos[free : free + 7] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    qpos[joint_qpos_index(model)] = q
    return qpos


def site_positions(model: mujoco.MjModel, angles: np.ndarray, sites: Sequence[str]) -> np.ndarray:
    """Forward kinematics of named sites with CPU MuJoCo (``mj_kinematics``).

    Args:
      model: a model from ``load_model`` (either mount).
      angles: (26,) or (T, 26) joint angles in ``JOINT_NAMES`` order, rad (RHipYawPitch is
        overridden by LHipYawPitch, see ``config_to_qpos``).
      sites: names of MJCF sites, e.g. ``("l_shoulder", "l_elbow", "l_hand")``.

    Returns:
      (len(sites), 3) or (T, len(sites), 3) float64 site positions in the torso frame, m.
    """
    q = np.asarray(angles, dtype=np.float64)
    if q.ndim not in (1, 2) or q.shape[-1] != N_JOINTS:
        raise ConfigError(f"angles must have shape (26,) or (T, 26), got {q.shape}")
    sids = mj_site_ids(model, sites)
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, _TORSO_BODY)
    data = mujoco.MjData(model)
    frames = q.reshape(-1, N_JOINTS)
    out = np.empty((frames.shape[0], len(sids), 3), dtype=np.float64)
    for t, frame in enumerate(frames):
        data.qpos[:] = config_to_qpos(model, frame)
        mujoco.mj_kinematics(model, data)
        rot = data.xmat[torso].reshape(3, 3)
        out[t] = (data.site_xpos[sids] - data.xpos[torso]) @ rot
    return out[0] if q.ndim == 1 else out
