"""``benchmarks/g1_playable.py``'s flip measure on made-up motions: a joint that jumps while the
person's limb holds still is a flip; the same jump right after a step at the joint's speed cap,
the same way (the feasibility filter finishing a move the person made faster than the robot
may), is a catch-up, counted apart; a capped step the other way does not excuse it.

The benchmark is loaded from its file (``benchmarks/`` is not part of the installed package).
"""

from __future__ import annotations

import importlib.util
import types
from pathlib import Path

import numpy as np

from jaxproj import robots
from jaxproj.human.skeleton import BONE_NAMES
from jaxproj.motion.feasible import SPEED_FRACTIONS

ROOT = Path(__file__).resolve().parents[2]
G1 = robots.get("unitree_g1")
KNEE = G1.index("right_knee_joint")


def _benchmark() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location("g1_playable", ROOT / "benchmarks/g1_playable.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


GP = _benchmark()


def _still_person(frames: int) -> np.ndarray:
    """``(T, 19, 3)`` bone units that never turn."""
    bones = np.zeros((frames, len(BONE_NAMES), 3))
    bones[..., 2] = 1.0
    return bones


def _measure(knee_deg: list[float], shin_turns_at: int | None = None) -> dict:
    """Knee angles (deg) at 7.5 fps; the person's right shin turns 90 deg into frame
    ``shin_turns_at`` (and stays), else holds still."""
    t = len(knee_deg)
    angles = np.zeros((t, len(G1.joint_names)), np.float32)
    angles[:, KNEE] = np.radians(knee_deg)
    bones = _still_person(t)
    if shin_turns_at is not None:
        shin = BONE_NAMES.index("shin_right")
        bones[shin_turns_at:, shin] = (1.0, 0.0, 0.0)
    motion = types.SimpleNamespace(
        angles=angles, times=np.arange(t) / 7.5, valid=np.ones(t, bool), positions=None
    )
    return GP.flips(motion, bones, np.ones(t, bool), G1)


def test_a_jump_while_the_limb_holds_is_a_flip_and_a_late_finish_a_catch_up() -> None:
    cap = np.degrees(G1.speed_limits("rated")[KNEE] * SPEED_FRACTIONS["rated"]) / 7.5  # deg/step
    # the person bends the knee 140 deg into frame 2; the robot, at its cap, gets there a frame
    # late: the step after the person stopped moving is a catch-up, not a flip
    late = _measure([0.0, 0.0, cap, 140.0, 140.0], shin_turns_at=2)
    assert (late["flip_steps"], late["catch_up_steps"]) == (0, 1)
    assert late["catch_up_examples"][0]["joint"] == "right_knee_joint"
    # the same 30 deg step with nothing before it: a flip
    jump = _measure([0.0, 0.0, 0.0, 30.0, 30.0])
    assert (jump["flip_steps"], jump["catch_up_steps"]) == (1, 0)
    assert jump["examples"][0] == {
        "step": 2, "joint": "right_knee_joint", "deg": 30.0, "bones_turn": 0.0
    }  # fmt: skip
    # a step at the cap the other way does not excuse the jump back
    back = _measure([cap, cap, 0.0, 30.0, 30.0], shin_turns_at=2)
    assert (back["flip_steps"], back["catch_up_steps"]) == (1, 0)
    # below the cap the step before is the robot's own choice: the jump after it is a flip
    slow = _measure([0.0, 0.0, 0.5 * cap, 0.5 * cap + 30.0, 0.5 * cap + 30.0], shin_turns_at=2)
    assert (slow["flip_steps"], slow["catch_up_steps"]) == (1, 0)
