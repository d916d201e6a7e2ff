"""The NAO H25 humanoid: named joints, their order, limits, the standing posture, the MJCF model.

The NAO is a robot file like every robot (``robot.toml`` beside this module, with the MJCF
``nao_h25.xml``): joint order, limits, speeds, the standing posture, the head envelope and the
chains are data there, with their sources. This module gives them to the closed-form IK
(``jaxproj.robots.nao_h25.ik``, which the file names as its IK) and to code that works with
the NAO's arrays directly, as module constants read from that file (``robot_file.describe``:
the file's robot before its IK is attached), plus the IK's link lengths and MuJoCo helpers.

Robot configuration vectors in jaxproj are ``(..., 26)`` arrays of joint angles in radians in the
order of ``JOINT_NAMES`` (the ALMotion "Body" order of the H25). LHand / RHand are the hands'
open/close commands (unitless 0..1, kept as joints so the vector matches ALMotion).

The analytic IK drives ``DRIVEN_JOINTS`` (head and both arms up to the elbow); every other joint
is held at ``STANDING_POSTURE``. Metrics average over ``DRIVEN_JOINTS`` only.
``jaxproj.robots.NAO_H25`` is the ``Robot`` the file gives, with that IK.

All numbers come from ``shared/reference/nao_h25_kinematics.md`` (Aldebaran H25 V4/V5 docs and the
Aldebaran-generated V5 URDF, cross-checked); see the MJCF for the inertials.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import mujoco
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.robots import robot_file
from jaxproj.robots.base import CoupledLimit, mj_joint_ids, mj_site_ids
from jaxproj.robots.base import joint_qpos_index as _qpos_index

FILE = Path(__file__).with_name("robot.toml")
"""The NAO's robot file."""

_DATA = robot_file.describe(FILE)

NAME = _DATA.title

JOINT_NAMES: tuple[str, ...] = _DATA.joint_names
"""The 26 named joints of the H25 in configuration order (ALMotion "Body" order)."""

N_JOINTS = len(JOINT_NAMES)
IDX = {name: i for i, name in enumerate(JOINT_NAMES)}
"""Joint name -> index in ``JOINT_NAMES``."""

LOWER: np.ndarray = _DATA.lower
"""(26,) lower joint limits, rad (LHand/RHand: 0): the official ones (ALD-JOINTS)."""
UPPER: np.ndarray = _DATA.upper
"""(26,) upper joint limits, rad (LHand/RHand: 1)."""
assert _DATA.velocity_limits is not None and _DATA.rated_speeds is not None
assert _DATA.acceleration_limits is not None
VELOCITY_LIMITS: np.ndarray = _DATA.velocity_limits
"""(26,) no-load maximum joint speeds, rad/s (the V5 URDF: motor speed / gear ratio)."""

ACCELERATION_LIMITS: np.ndarray = _DATA.acceleration_limits
"""(26,) rad/s^2, ours: Aldebaran publishes no acceleration limit. 80 on every joint is full speed
in about 0.1 s, chosen on the training subjects (``jaxproj.motion.feasible`` module doc)."""

RATED_SPEEDS: np.ndarray = _DATA.rated_speeds
"""(26,) rated joint speeds, rad/s: Aldebaran's nominal speeds (6.1395 rad/s ShoulderPitch,
ElbowYaw, HeadYaw; 5.3260 ShoulderRoll, ElbowRoll, HeadPitch; 3.2929 / 5.0658 for the legs),
0.75 x no-load for WristYaw and Hand (none published). ``jaxproj.motion.feasible``'s default
cap."""

DRIVEN_JOINTS: tuple[str, ...] = _DATA.driven_joints
"""The joints the analytic IK drives (and the projection engine predicts), in this order."""

DRIVEN_INDEX = np.array([IDX[n] for n in DRIVEN_JOINTS], dtype=np.int32)
"""(10,) indices of ``DRIVEN_JOINTS`` in ``JOINT_NAMES``."""

STANDING_POSTURE: np.ndarray = _DATA.standing
"""(26,) the standing posture, rad, in ``JOINT_NAMES`` order (within every limit): NAO's "Stand"
posture, knees slightly bent, arms hanging by the sides with the elbows a little flexed."""

COUPLED_JOINTS: tuple[str, str] = _DATA.coupled_joints[0]
"""One motor drives both; RHipYawPitch := LHipYawPitch (LHipYawPitch has priority)."""

ARM_SITES = _DATA.require_mjcf().arm_sites
"""MJCF sites (shoulder, elbow, wrist) of each arm (the robot file's ``evaluation.arm_sites``)."""

HEAD_ENVELOPE: CoupledLimit = _DATA.coupled_limits[0]
"""NAOqi's head anti-collision envelope as robot data: HeadPitch's range as a function of
HeadYaw (the file's ``[[joints.coupled_limits]]``; the IK clips to it too)."""
HEAD_ENVELOPE_YAW = HEAD_ENVELOPE.knots
"""(13,) HeadYaw knots of the head envelope, rad (-119.52 .. 119.52 deg, symmetric)."""
HEAD_ENVELOPE_PITCH_MIN = HEAD_ENVELOPE.lower
"""(13,) lowest HeadPitch at each knot of ``HEAD_ENVELOPE_YAW``, rad."""
HEAD_ENVELOPE_PITCH_MAX = HEAD_ENVELOPE.upper
"""(13,) highest HeadPitch at each knot of ``HEAD_ENVELOPE_YAW``, rad. NAOqi clips HeadPitch to
``[min, max]`` interpolated linearly at the current HeadYaw (the head shell would hit the
shoulders otherwise)."""

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

_TORSO_BODY = "torso"


def mjcf_path() -> Path:
    """Absolute path of the bundled MJCF ``nao_h25.xml`` (NAO H25 V5)."""
    return _DATA.require_mjcf().path


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
    return _DATA.load_model(mount, without)  # the robot file's loader (jaxproj.robots.mjcf)


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
