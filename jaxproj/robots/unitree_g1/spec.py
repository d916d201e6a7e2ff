"""The Unitree G1 as a ``Robot``: its correspondence table and chains, solved by the generic IK.

``jaxproj.robots.get("unitree_g1")`` is ``UNITREE_G1`` here. Adding a robot is an MJCF plus one
module like this one: the ``Robot`` (joints, limits, speeds: ``robot.py``), a ``Correspondence``
(which human bone each robot direction follows) and the chains (bones read, joints driven).

The table (``CORRESPONDENCE``; directions compared in ``torso_link``'s frame, the counterpart of
the human body frame, x forward, y left, z up):

=================  ===========================================  ======  =========
human bone         robot direction (MJCF sites / bodies)        weight  chain
=================  ===========================================  ======  =========
hip line (*)       right_hip_pitch_link -> left_hip_pitch_link   1       waist
spine_lower (**)   pelvis -> torso_link (the waist pivot)        1       waist
upper_arm_<side>   <side>_shoulder_site -> <side>_elbow_site     1       <side>_arm
forearm_<side>     <side>_elbow_site -> <side>_wrist_site        1       <side>_arm
thigh_<side>       <side>_hip_site -> <side>_knee_site           1       <side>_leg
shin_<side>        <side>_knee_site -> <side>_ankle_site         1       <side>_leg
foot_<side> (**)   <side>_ankle_site -> <side>_toe_site          0.5     <side>_leg
=================  ===========================================  ======  =========

(*) ``pelvis_left`` minus ``pelvis_right`` (``BonePair.minus``): the line from the right hip to
the left one; it sets the waist's yaw and roll without the Kinect hip points' forward and
upward offset from the hip centre (which the two bones share, and which would pitch the waist).
(**) calibrated (``BonePair.rest``): ``SPINE_REST``, ``FOOT_REST``.

Chains are solved in the order waist, arms, legs: the legs hang from the pelvis, which the waist
turns against the torso, so the leg chains list the waist's bones too (their IK runs the waist's
first; they read none of the waist's rows: ``generic_ik.chain_rows``). The waist reads the hip
line although its points hang from the hips: its joints turn the torso, the frame the
directions are compared in, against them. The feet weigh half: the
Kinect foot point is the noisiest joint of the skeleton. Not driven: the ankle rolls (no
Kinect v1 bone fixes them) and the wrists (the Kinect hand point, a few cm from the wrist, is
too noisy to set the wrist's pitch and yaw; not measured yet), held at zero.

Self-collision (``collision_pairs="mjcf"``): the IK keeps every pair of capsules and spheres
of ``unitree_g1.xml`` that MuJoCo's own contact filter lets collide (262 pairs: its
``<exclude>`` list leaves out the adjacent links) ``IK_CONFIG.margin`` (1 cm) apart, so what
the IK, the continuity pass and ``separate`` keep apart is what MuJoCo reports as a
self-contact (the sole boxes aside: the soles' capsules stand in for them).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.buckets import call_bucketed
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.robots.base import Chain, Figure, Mjcf, Robot
from jaxproj.robots.generic_ik import BonePair, Correspondence, GenericIK, IKConfig, own_chains
from jaxproj.robots.unitree_g1 import robot

_WAIST_BONES = ("pelvis_left", "pelvis_right", "spine_lower")


def _side_pairs(s: str) -> tuple[BonePair, ...]:
    return (
        BonePair(f"upper_arm_{s}", f"{s}_shoulder_site", f"{s}_elbow_site"),
        BonePair(f"forearm_{s}", f"{s}_elbow_site", f"{s}_wrist_site"),
        BonePair(f"thigh_{s}", f"{s}_hip_site", f"{s}_knee_site"),
        BonePair(f"shin_{s}", f"{s}_knee_site", f"{s}_ankle_site"),
        BonePair(f"foot_{s}", f"{s}_ankle_site", f"{s}_toe_site", weight=0.5, rest=FOOT_REST[s]),
    )


SPINE_REST = (-0.468, 0.010, 0.884)
"""The Kinect spine_lower (HipCenter -> Spine) direction that the G1's pelvis -> waist pivot
direction takes in the standing posture: the normalised median over the 11,280 valid frames of
the bundled MSR Action3D training subjects (1, 3, 5, 7, 9); the Kinect spine point sits 28 deg
behind the hip -> shoulder axis."""

FOOT_REST = {"left": (0.965, 0.020, 0.260), "right": (0.968, -0.029, 0.250)}
"""The Kinect foot (ankle -> foot point) directions matched to the G1's ankle -> toe direction
standing: the same medians (the Kinect foot point sits 15 deg above the ankle's horizontal)."""


HUMAN_RANGES: tuple[tuple[str, float, float], ...] = (
    *((f"{s}_elbow_joint", -math.inf, math.pi / 2) for s in ("left", "right")),
    ("left_shoulder_roll_joint", -math.inf, math.pi / 2),
    ("right_shoulder_roll_joint", -math.pi / 2, math.inf),
    ("left_hip_roll_joint", -math.inf, math.pi / 2),
    ("right_hip_roll_joint", -math.pi / 2, math.inf),
    *((f"{s}_knee_joint", 0.0, math.inf) for s in ("left", "right")),
    *((f"{s}_hip_yaw_joint", -math.pi / 4, math.pi / 4) for s in ("left", "right")),
    ("waist_yaw_joint", -math.pi / 4, math.pi / 4),
)
"""Where the IK's box is narrower than the G1's limits (``Correspondence.ranges``): the elbow
stops at the straight arm (G1 elbow +90 deg; the robot over-extends 30 deg more, a person does
not: AAOS elbow extension 0 deg) and the knee at the straight leg (the G1's goes 5 deg past it);
shoulder and hip roll stop at the arm or leg held out sideways (90 deg; the G1's go to 129 and
170 deg); the hip yaw stops at the thigh's internal and external rotation (45 deg each way; the
G1's go to 158 deg) and the waist yaw at the trunk's rotation (45 deg; the G1's 150 deg). Without
these each bone direction near them has a second solution, the limb turned half
a turn about itself (e.g. an over-extended elbow with the upper arm twisted by 180 deg), and the
IK's answer jumps between the two on capture noise; a yaw past a person's range is what the IK
reached for when the person bent over (a thigh turned 136 deg about itself on CMU 131_01) and
when a Kinect hip line was noisy (waist yaw bursts to 138 deg on UTKinect s09 e02). The
shoulder and hip pitch still reach every direction a person's limb can take. (Human ranges:
American Academy of Orthopaedic Surgeons, *Joint Motion: Method of Measuring and Recording*,
1965; Greene & Heckman, *The Clinical Measurement of Joint Motion*, AAOS 1994: hip
internal and external rotation 45 deg each, thoracolumbar rotation 45 deg.)"""

CORRESPONDENCE = Correspondence(
    base="torso_link",
    pairs=(
        BonePair(
            "pelvis_left", "right_hip_pitch_link", "left_hip_pitch_link", minus="pelvis_right"
        ),
        BonePair("spine_lower", "pelvis", "torso_link", rest=SPINE_REST),
        *_side_pairs("left"),
        *_side_pairs("right"),
    ),
    collision_pairs="mjcf",
    ranges=HUMAN_RANGES,
    source="the project's choice (jaxproj.robots.unitree_g1.spec module doc)",
)
"""The G1's correspondence with the human skeleton (the table of the module doc)."""

IK_CONFIG = IKConfig(iterations=24, starts=4, neutral=1e-4, collision=1e4, margin=0.01)
"""The G1's generic IK settings: the pull toward the standing posture decides the shoulder yaw
of a straight arm and the hip yaw of a straight leg; the collision term weighs a 1 cm
penetration like a 0.1 rad direction error."""


def _chain_ik(x: np.ndarray, *, name: str) -> np.ndarray:
    """``Chain.ik`` of the chain called ``name``: ``(N, 3 * len(bones))`` its own descriptor
    columns -> ``(N, len(joints))`` angles (the generic IK of that chain and of the chains it
    reads before it: the waist for a leg)."""
    fn = _chain_solver(name)
    return np.asarray(call_bucketed(fn, np.asarray(x, np.float32), 1))


@functools.cache
def _chain_solver(name: str) -> jax.stages.Wrapped:
    chain = UNITREE_G1.chain(name)
    needed = own_chains(UNITREE_G1.chains, chain)
    ik = GenericIK.build(UNITREE_G1, CORRESPONDENCE, IK_CONFIG, chains=needed)
    cols = np.array(UNITREE_G1.chain_joints(chain), np.int32)
    return jit(lambda d: ik.solve(d, chain.bones)[..., cols])


def _joints(*names: str) -> tuple[str, ...]:
    return tuple(f"{n}_joint" for n in names)


BANDWIDTHS: dict[str, float] = {
    "waist": 0.0179,
    "left_arm": 0.0326,
    "right_arm": 0.0486,
    "left_leg": 0.0608,
    "right_leg": 0.0588,
}
"""Mean-shift bandwidths of the chains (``Chain.bandwidth``): those that give about 4,000
landmarks per chain on the default training set (16,005 valid frames; found by
``BuildConfig(landmarks=4000)``'s search). 4,000 is the least of 1,000 / 2,000 / 4,000 / 8,000
whose relaxed projection is within 1 deg (median M_avg) of the IK on training people a model
of the others did not see (``benchmarks/experiments/g1_landmarks.py``: trained on MSR 1, 3, 5
and UTKinect 3, 4, scored on MSR 7, 9 and UTKinect 6: 2.44 / 1.37 / 0.85 / 0.67 deg; one
NVIDIA H200, ``benchmarks/results/g1_landmarks_h200.json``)."""

DEVIATION_SCALE = 0.965
"""``Robot.deviation_scale``: the p90 of the relaxed deviation of the 4,000-landmark model of
that experiment on the people it did not see (0.9652; the NAO's default model: 0.174). Measured
with the IK of 2026-11-26, before the waist read the hip line and before a chain's per-frame
answer depended on its own columns only (both 2026-11-28): not re-measured since."""

LOOSE_JOINTS: tuple[str, ...] = tuple(
    f"{s}_{j}_joint" for s in ("left", "right") for j in ("hip_yaw", "shoulder_yaw")
)
"""``Robot.loose_joints``: a straight leg's hip yaw and a straight arm's shoulder yaw turn the
limb about its own axis, which no bone direction sees (the pull toward standing decides
them), so near the straight limb a small change of the bones turns them far (as the NAO's
ElbowYaw)."""


def _leg(s: str) -> Chain:
    return Chain(
        f"{s}_leg",
        (f"thigh_{s}", f"shin_{s}", f"foot_{s}", *_WAIST_BONES),
        _joints(*(f"{s}_{j}" for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch"))),
        functools.partial(_chain_ik, name=f"{s}_leg"),
        bandwidth=BANDWIDTHS[f"{s}_leg"],
    )


def _arm(s: str) -> Chain:
    return Chain(
        f"{s}_arm",
        (f"upper_arm_{s}", f"forearm_{s}"),
        _joints(
            *(f"{s}_{j}" for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow"))
        ),
        functools.partial(_chain_ik, name=f"{s}_arm"),
        bandwidth=BANDWIDTHS[f"{s}_arm"],
    )


CHAINS: tuple[Chain, ...] = (
    Chain(
        "waist",
        _WAIST_BONES,
        _joints("waist_yaw", "waist_roll", "waist_pitch"),
        functools.partial(_chain_ik, name="waist"),
        bandwidth=BANDWIDTHS["waist"],
    ),
    _arm("left"),
    _arm("right"),
    _leg("left"),
    _leg("right"),
)
"""The chains, in the order the IK solves them."""


@functools.cache
def generic_ik(collision: bool = True) -> GenericIK:
    """The G1's generic IK (built once: it reads the MJCF), with or without the collision term."""
    cfg = IK_CONFIG if collision else dataclasses.replace(IK_CONFIG, collision=0.0)
    return GenericIK.build(UNITREE_G1, CORRESPONDENCE, cfg)


def traced_ik(d: jax.Array, bones: str | tuple[str, ...] = "full") -> jax.Array:
    """The generic IK inside a trace: ``(..., 3 * n_bones)`` -> ``(..., 21)`` angles, rad."""
    return generic_ik().solve(d, bones)


def track(
    q: jax.Array,
    valid: jax.Array,
    d: jax.Array | None = None,
    bones: str | tuple[str, ...] = "full",
) -> jax.Array:
    """``Robot.track`` of the G1: ``(T, 21)`` per-frame driven angles, ``(T,)`` valid and the
    person's ``(T, m)`` descriptors (or ``None``) -> ``(T, 21)``, each frame re-chosen near the
    previous output among the poses with the same bone directions (``GenericIK.track``).
    Traceable."""
    return generic_ik().track(q, valid, d, bones)


def track_step(
    y: jax.Array,
    q_prev: jax.Array,
    q_t: jax.Array,
    d_prev: jax.Array,
    d_t: jax.Array,
    bones: str | tuple[str, ...] = "full",
) -> jax.Array:
    """``Robot.track_step`` of the G1: one frame of ``track`` (``GenericIK.track_step``) from
    the last output, the last valid answer, this frame's answer (``(21,)`` each) and the
    person's last valid and current ``(m,)`` descriptors of ``bones``. Traceable."""
    return generic_ik().track_step(y, q_prev, q_t, None, (d_prev, d_t, resolve_bones(bones)))


def separate(q: jax.Array, start: jax.Array | None = None) -> jax.Array:
    """``Robot.separate`` of the G1: ``(..., 21)`` driven angles (and optionally a second
    start per pose, e.g. the previous frame's answer) -> the same with the collision pairs
    (``collision_pairs="mjcf"``) pushed ``IK_CONFIG.margin`` apart (``GenericIK.separate``, 8
    steps per chain). Traceable."""
    return generic_ik().separate(q, start=start)


@functools.cache
def _jitted(bones: str | tuple[str, ...]) -> jax.stages.Wrapped:
    return jit(lambda d: generic_ik().solve(d, bones))


def solve_driven(d: ArrayLike, bones: str | tuple[str, ...] = "full") -> jax.Array:
    """The G1's IK: ``(..., 3 * n_bones)`` descriptors (``bones`` layout, which must hold every
    bone of the chains) -> ``(..., 21)`` float32 driven angles, rad, within limits, finite.

    Compiled once per shape; host arrays are padded to a bucket of rows (one compile each)."""
    fn = _jitted(bones)
    if isinstance(d, jax.Array):
        return fn(d)
    x = np.asarray(d, np.float32)
    if x.ndim == 0:
        raise ConfigError(f"descriptors must be (..., 3 * n_bones), got a scalar {x!r}")
    return call_bucketed(fn, x, 1)


FIGURE = Figure(
    label="G1",
    links=(
        *(
            link
            for side in ("left", "right")
            for link in (
                ("neck_site", f"{side}_shoulder_site"),
                (f"{side}_shoulder_site", f"{side}_elbow_site"),
                (f"{side}_elbow_site", f"{side}_wrist_site"),
                (f"{side}_wrist_site", f"{side}_hand_site"),
                ("pelvis_site", f"{side}_hip_site"),
                (f"{side}_hip_site", f"{side}_knee_site"),
                (f"{side}_knee_site", f"{side}_ankle_site"),
                (f"{side}_ankle_site", f"{side}_toe_site"),
            )
        ),
        ("torso_site", "neck_site"),
        ("pelvis_site", "torso_site"),
        ("neck_site", "head_site"),
    ),
    head=("head_link", 0.0),
    feet=(("left_ankle_roll_link", "left_toe_site"), ("right_ankle_roll_link", "right_toe_site")),
    head_geom="head_geom",
)
"""How ``jaxproj.viz`` draws the G1 (the report's sketch and the render's stick panel): the
MJCF's sites joined neck -> shoulder -> elbow -> wrist -> palm, pelvis -> hip -> knee -> ankle
-> toe, pelvis -> waist pivot -> neck -> head centre; the floor at the soles."""

MJCF = Mjcf(
    path=robot.mjcf_path(),
    load=robot.load_model,
    free_joint=robot.FREE_JOINT,
    arm_sites={
        "left": ("left_shoulder_site", "left_elbow_site", "left_wrist_site"),
        "right": ("right_shoulder_site", "right_elbow_site", "right_wrist_site"),
    },
    fk_without=robot.LEG_ROOTS,
    hand_sites=("left_hand_site", "right_hand_site"),
    figure=FIGURE,
)

UNITREE_G1 = Robot(
    name="unitree_g1",
    title=robot.NAME,
    joint_names=robot.JOINT_NAMES,
    lower=robot.LOWER,
    upper=robot.UPPER,
    standing=robot.STANDING_POSTURE,
    driven_joints=robot.DRIVEN_JOINTS,
    chains=CHAINS,
    ik=solve_driven,
    velocity_limits=robot.VELOCITY_LIMITS,
    acceleration_limits=robot.ACCELERATION_LIMITS,
    mjcf=MJCF,
    traced_ik=traced_ik,
    separate=separate,
    track=track,
    track_step=track_step,
    loose_joints=LOOSE_JOINTS,
    deviation_scale=DEVIATION_SCALE,
)
"""The Unitree G1 (29 joints, 21 driven: waist, legs to the ankle pitch, arms to the elbow)."""
