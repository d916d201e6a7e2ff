"""The Unitree G1 (29-DoF body, revision 1.0): joints, limits, speeds, its MJCF.

Configurations are ``(..., 29)`` joint angles in radians in ``JOINT_NAMES`` order, Unitree's SDK
order (``../shared/reference/unitree_g1_kinematics.md``, "Joint order used by Unitree's SDK"),
which is also the joints' order in ``unitree_g1.xml``. The limits are that fact sheet's (from
"Unitree G1 29-DoF description", Unitree Robotics, BSD-3-Clause); the MJCF (written by this
project from the same sheet) holds the rest.

Maximum joint speeds: the ``velocity`` of each joint's ``<limit>`` in Unitree's URDF of the
29-DoF G1, revision 1.0 (``unitreerobotics/unitree_ros``, ``robots/g1_description/
g1_29dof_rev_1_0.urdf`` at commit ``1ab5f1e22adeeef39b3a2171b56f99ccd9c0f149``, BSD-3-Clause):
hips and waist yaw 32, hip roll and knee 20, ankles and waist roll / pitch 30, shoulders, elbows
and wrist roll 37, wrist pitch / yaw 22 rad/s. An earlier version of that file (commit
``adb48c7910ef8404ca34a07df95fc3acbb09f318``), ``unitree_rl_gym``'s copy and the fact sheet give
37 for the ankles and waist roll / pitch (with 50 N m, where the newer file says 35 N m; the
MJCF's torques are still the sheet's).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from jaxproj.robots import mjcf as _mjcf

NAME = "Unitree G1 (29 DoF)"

_SIDE_JOINTS = {
    "leg": ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll"),
    "arm": ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow",
            "wrist_roll", "wrist_pitch", "wrist_yaw"),
}  # fmt: skip

JOINT_NAMES: tuple[str, ...] = (
    *(f"left_{j}_joint" for j in _SIDE_JOINTS["leg"]),
    *(f"right_{j}_joint" for j in _SIDE_JOINTS["leg"]),
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    *(f"left_{j}_joint" for j in _SIDE_JOINTS["arm"]),
    *(f"right_{j}_joint" for j in _SIDE_JOINTS["arm"]),
)  # fmt: skip
"""The 29 joints in Unitree's SDK order (0-5 left leg, 6-11 right leg, 12-14 waist, 15-21 left
arm, 22-28 right arm)."""

# (lower, upper) rad, the fact sheet's table, and maximum speed rad/s, Unitree's URDF (the module
# doc); right = left except the roll joints' ranges, mirrored.
_LEFT: dict[str, tuple[float, float, float]] = {
    "hip_pitch": (-2.5307, 2.8798, 32.0),
    "hip_roll": (-0.5236, 2.9671, 20.0),
    "hip_yaw": (-2.7576, 2.7576, 32.0),
    "knee": (-0.087267, 2.8798, 20.0),
    "ankle_pitch": (-0.87267, 0.5236, 30.0),
    "ankle_roll": (-0.2618, 0.2618, 30.0),
    "shoulder_pitch": (-3.0892, 2.6704, 37.0),
    "shoulder_roll": (-1.5882, 2.2515, 37.0),
    "shoulder_yaw": (-2.618, 2.618, 37.0),
    "elbow": (-1.0472, 2.0944, 37.0),
    "wrist_roll": (-1.97222, 1.97222, 37.0),
    "wrist_pitch": (-1.61443, 1.61443, 22.0),
    "wrist_yaw": (-1.61443, 1.61443, 22.0),
}
_RIGHT_RANGE = {"hip_roll": (-2.9671, 0.5236), "shoulder_roll": (-2.2515, 1.5882)}
_WAIST: dict[str, tuple[float, float, float]] = {
    "waist_yaw": (-2.618, 2.618, 32.0),
    "waist_roll": (-0.52, 0.52, 30.0),
    "waist_pitch": (-0.52, 0.52, 30.0),
}


def _row(name: str) -> tuple[float, float, float]:
    base = name.removesuffix("_joint")
    if base in _WAIST:
        return _WAIST[base]
    side, joint = base.split("_", 1)
    lo, hi, v = _LEFT[joint]
    if side == "right" and joint in _RIGHT_RANGE:
        lo, hi = _RIGHT_RANGE[joint]
    return lo, hi, v


LOWER = np.array([_row(n)[0] for n in JOINT_NAMES], np.float32)
"""(29,) lower joint limits, rad."""
UPPER = np.array([_row(n)[1] for n in JOINT_NAMES], np.float32)
"""(29,) upper joint limits, rad."""
VELOCITY_LIMITS = np.array([_row(n)[2] for n in JOINT_NAMES], np.float32)
"""(29,) maximum joint speeds, rad/s (Unitree's URDF, the module doc; no rated speeds published:
the rated speeds are ``base.RATED_FRACTION`` of these)."""

_ACCEL: dict[str, float] = {
    "hip_pitch": 92.0, "hip_roll": 163.0, "hip_yaw": 342.0, "knee": 807.0,
    "ankle_pitch": 4368.0, "ankle_roll": 6334.0,
    "shoulder_pitch": 133.0, "shoulder_roll": 144.0, "shoulder_yaw": 501.0, "elbow": 577.0,
    "wrist_roll": 2139.0, "wrist_pitch": 406.0, "wrist_yaw": 630.0,
    "waist_yaw": 85.0, "waist_roll": 27.0, "waist_pitch": 29.0,
}  # fmt: skip
ACCELERATION_LIMITS = np.array(
    [_ACCEL[n.removesuffix("_joint").removeprefix("left_").removeprefix("right_")]
     for n in JOINT_NAMES], np.float32,
)  # fmt: skip
"""(29,) rad/s^2: each joint's peak torque (Unitree's URDF, the fact sheet's table) over the
largest joint-space inertia it moves (this MJCF's masses and armatures, fixed base, 4,096
postures within the limits): ``jaxproj.robots.mjcf.torque_accelerations``, the smaller
of the two sides rounded down to whole rad/s^2 (``tests/robots/test_robots.py`` recomputes
them). An upper bound (no gravity, no
load): the waist moves the whole upper body (27-85 rad/s^2), the ankles almost nothing. The
feasibility filter's bound for the G1 (``FeasibleConfig.accel`` left out)."""

STANDING_POSTURE = np.zeros(len(JOINT_NAMES), np.float32)
"""(29,) zero angles: legs straight, upper arms hanging, elbows bent 90 deg (forearms forward),
wrists straight; inside every limit."""

DRIVEN_JOINTS: tuple[str, ...] = tuple(
    n for n in JOINT_NAMES if not n.removesuffix("_joint").endswith(
        ("ankle_roll", "wrist_roll", "wrist_pitch", "wrist_yaw"))
)  # fmt: skip
"""The 21 joints the IK drives: legs without the ankle roll (not observable from a Kinect v1
skeleton), the waist, the arms to the elbow (the wrists: see ``spec.py``)."""

FREE_JOINT = "floating_base_joint"
ROOT_BODY = "pelvis"
LEG_ROOTS: tuple[str, str] = ("left_hip_pitch_link", "right_hip_pitch_link")
"""Bodies at the root of the two legs."""


def mjcf_path() -> Path:
    """Absolute path of the bundled MJCF ``unitree_g1.xml``."""
    return (Path(__file__).parent / "unitree_g1.xml").resolve()


def load_model(mount: str = "free", without: Sequence[str] = ()) -> mujoco.MjModel:
    """Compile the bundled G1 MJCF (``jaxproj.robots.mjcf.load``): ``"free"`` (the pelvis on
    the free joint ``floating_base_joint``) or ``"fixed"`` (the pelvis welded to the world at
    0.793 m), ``without`` bodies removed with their subtrees (fixed mount only)."""
    return _mjcf.load(mjcf_path(), mount, without, free_joint=FREE_JOINT, root_body=ROOT_BODY)
