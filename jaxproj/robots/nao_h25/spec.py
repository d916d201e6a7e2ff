"""The NAO H25 as a ``Robot``: built from the constants of ``robot`` and ``ik`` (no copies).

``jaxproj.robots.NAO_H25`` (registered as ``"nao_h25"``, the default robot) is ``NAO_H25`` here.
"""

from __future__ import annotations

import jax

from jaxproj.robots.base import Figure, Mjcf, Robot
from jaxproj.robots.generic_ik import BonePair, Correspondence
from jaxproj.robots.nao_h25 import ik, naoqi, robot

ARM_SITES: dict[str, tuple[str, str, str]] = {
    "left": ("l_shoulder", "l_elbow", "l_wrist"),
    "right": ("r_shoulder", "r_elbow", "r_wrist"),
}
"""MJCF sites (shoulder, elbow, wrist) of each arm: the joint origins of LShoulderPitch /
LElbowYaw / LWristYaw (and the right ones); the task-space metrics' points."""

ARM_CORRESPONDENCE = Correspondence(
    "torso",
    tuple(
        BonePair(f"{bone}_{side}", a, b)
        for side, (shoulder, elbow, wrist) in ARM_SITES.items()
        for bone, a, b in (("upper_arm", shoulder, elbow), ("forearm", elbow, wrist))
    ),
    source="the closed form's own choice: the shoulder -> elbow segment and the forearm",
)
"""The NAO's arms as data for the generic IK (``jaxproj.robots.generic_ik``): each upper arm
follows the shoulder -> elbow segment, each forearm the elbow -> wrist, in the torso frame, as
the closed form matches them (its head rule is not a direction and stays the closed form's)."""

HAND_SITES: tuple[str, str] = ("l_hand", "r_hand")
"""End-effector sites (left, right) of ``jaxproj.eval.rollout.hand_error_cm``."""

LOOSE_JOINTS: tuple[str, str] = ("LElbowYaw", "RElbowYaw")
"""Driven joints whose IK truth is ill-conditioned near a straight elbow (``ik`` module doc)."""

HEAD_ROOT = "Neck"
"""The body the head turns about."""

ELBOW_PAIRS: tuple[tuple[str, str], ...] = (
    ("LElbowYaw", "LElbowRoll"),
    ("RElbowYaw", "RElbowRoll"),
)
"""(yaw, roll) of each elbow: the ElbowYaw rules of ``jaxproj.motion.feasible``."""

IK_CONSTANTS: dict[str, float] = {
    "head_pitch_neutral": ik.HEAD_PITCH_NEUTRAL,
    "elbow_yaw_neutral": ik.ELBOW_YAW_NEUTRAL,
}
"""The IK's constants a model file records (meta ``"ik"``)."""


def traced_ik(d: jax.Array, bones: str | tuple[str, ...] = "upper") -> jax.Array:
    """``ik.driven_angles`` for a ``bones`` descriptor: the IK inside a trace (no nested jit)."""
    return ik.driven_angles(d, ik.bone_index(bones))


FIGURE = Figure(
    label="NAO",
    links=(
        ("neck", "l_shoulder"),
        ("l_shoulder", "l_elbow"),
        ("l_elbow", "l_wrist"),
        ("l_wrist", "l_hand"),
        ("neck", "r_shoulder"),
        ("r_shoulder", "r_elbow"),
        ("r_elbow", "r_wrist"),
        ("r_wrist", "r_hand"),
        ("neck", "torso"),
        ("torso", "l_hip"),
        ("l_hip", "l_knee"),
        ("l_knee", "l_ankle"),
        ("l_ankle", "l_sole"),
        ("torso", "r_hip"),
        ("r_hip", "r_knee"),
        ("r_knee", "r_ankle"),
        ("r_ankle", "r_sole"),
    ),  # fmt: skip
    head=("Head", 0.09),
    parents={"LShoulder": "Neck", "RShoulder": "Neck"},  # as the skeleton's from ShoulderCenter
    feet=(("l_ankle", "l_sole"), ("r_ankle", "r_sole")),
    head_geom="head_geom",
)
"""How ``jaxproj.viz`` draws the NAO: the report's sketch (sites from the neck down the arms and
from the torso down the legs, the head 9 cm along the Head body's z axis) and the render's stick
panel (shoulders hung from the neck, ankles to soles, the head geom's centre)."""

MJCF = Mjcf(
    path=robot.mjcf_path(),
    load=robot.load_model,
    free_joint="root",
    arm_sites=ARM_SITES,
    fk_without=(HEAD_ROOT, *robot.LEG_ROOTS),  # head and legs: they cannot move the arms
    hand_sites=HAND_SITES,
    split={"upper": robot.LEG_ROOTS, "legs": robot.UPPER_ROOTS},
    head_root=HEAD_ROOT,
    figure=FIGURE,
    warp_validated=True,  # 256 random motions on one H100 against C MuJoCo, 2026-11-26 (results)
)

NAO_H25 = Robot(
    name="nao_h25",
    title=robot.NAME,
    joint_names=robot.JOINT_NAMES,
    lower=robot.LOWER,
    upper=robot.UPPER,
    standing=robot.STANDING_POSTURE,
    driven_joints=robot.DRIVEN_JOINTS,
    chains=ik.CHAINS,
    ik=ik.solve_driven,
    velocity_limits=robot.VELOCITY_LIMITS,
    rated_speeds=robot.RATED_SPEEDS,
    acceleration_limits=robot.ACCELERATION_LIMITS,
    coupled_joints=(robot.COUPLED_JOINTS,),
    loose_joints=LOOSE_JOINTS,
    mjcf=MJCF,
    exports={naoqi.EXPORT.suffix: naoqi.EXPORT},
    traced_ik=traced_ik,
    whole_chain=ik.WHOLE_BODY,
    elbow_pairs=ELBOW_PAIRS,
    ik_constants=IK_CONSTANTS,
    coupled_limits=(robot.HEAD_ENVELOPE,),
)
"""The NAO H25 V5: 26 joints, 10 driven (head, arms to the elbow), three chains, NAOqi JSON."""
