"""The feet of a whole-body motion (``jaxproj.motion.whole_body``): the robot's geometry on
the host (MuJoCo's kinematics: each geom's lowest points) and the stance IK that plants each
foot in contact where it touched down, level, and lifts a swing foot that went below the floor,
run as one compiled program (``jaxproj.motion.stance``: a scan over the frames, one
Levenberg-Marquardt solve a frame over the root's position and the stance legs' joints).

``_plant_feet`` prepares one motion's plan on the host (which run of contact each frame takes,
its weight, the root's budget) and runs the program on it, its frames padded to a length bucket
(``fine_bucket``: few compiled shapes); ``plan_feet`` and ``plant_planned`` split the two, so
that a batch plants many motions in one call (``stance.plant_many``).
"""

from __future__ import annotations

import jax
import mujoco
import numpy as np

from jaxproj._internal import executables
from jaxproj._internal.buckets import bucket, packed_calls, pad_rows
from jaxproj.motion.stance import (
    PLANT_ITERATIONS,
    PLANT_ORIENTATION,
    PLANT_PULL,
    PLANT_REACH,
    PLANT_ROOT_PULL,
    UNBOUNDED,
    Plan,
    _foot_points,
    plant_jit,
    plant_many_jit,
)
from jaxproj.robots import Robot, identity
from jaxproj.robots.base import joint_qpos_index

__all__ = ["PLANT_ITERATIONS", "PLANT_ORIENTATION", "PLANT_PULL", "PLANT_RAMP_S", "PLANT_REACH",
           "PLANT_ROOT_PULL", "ROOT_SLACK", "plan_feet", "plant_planned"]  # fmt: skip


def _set(model: mujoco.MjModel, data: mujoco.MjData, adr: np.ndarray, q: np.ndarray) -> None:
    """``q`` (the robot's joints) into ``data.qpos`` at ``adr`` (``joint_qpos_index``), then the
    kinematics."""
    data.qpos[adr] = q
    mujoco.mj_kinematics(model, data)


PLANT_RAMP_S = 0.1
"""s: a stance foot's correction fades in before touchdown and out after lift-off over this (at
least 2 frames); the root's height blends over the same."""
ROOT_SLACK = 0.015
"""m: the root's step in one frame is at most the person's scaled pelvis step plus this
(``_plant_feet``). Where the stance rule or the IK would move it further (a body frame that
turns 30-50 deg in one Kinect frame while the feet are planted swings the root around them; a
lost leg drops it), the root stops at the bound and the stance legs are solved again from
there."""


SINGLE_ROWS = 256
"""The fewest frames one motion's stance program is compiled for: a motion alone is padded to
``bucket(T, SINGLE_ROWS)`` (one program for every motion up to 256 frames; a padding frame
solves nothing there, where in a batch's vmapped program every frame costs a solve)."""


def plan_feet(
    q: np.ndarray,
    root_pos: np.ndarray,
    rot_root: np.ndarray,
    stance: np.ndarray,
    ramp: int,
    budget: np.ndarray | None = None,
) -> Plan:
    """One motion's ``stance.Plan`` (host, float32): ``q`` ``(T, J)`` angles, ``root_pos``
    ``(T, 3)`` and ``rot_root`` ``(T, 3, 3)`` the root by the height and stance rules,
    ``stance`` ``(T, K)`` bool contacts, ``ramp`` frames of fade, ``budget`` ``(T,)`` m (or
    ``None``: unbounded)."""
    n, feet = stance.shape
    which, weight = _stance_weights(stance, ramp)
    start = np.zeros((n, feet), np.int32)
    end = np.zeros((n, feet), np.int32)
    for k in range(feet):
        for i, (t0, t1) in enumerate(_runs(stance[:, k])):
            start[which[:, k] == i, k], end[which[:, k] == i, k] = t0, t1
    bound = np.full(n, UNBOUNDED) if budget is None else np.minimum(budget, UNBOUNDED)
    return Plan(np.asarray(q, np.float32), np.asarray(root_pos, np.float32),
                np.asarray(rot_root, np.float32), which.astype(np.int32),
                weight.astype(np.float32), start, end, bound.astype(np.float32),
                ~np.asarray(stance, bool))  # fmt: skip


def _padded(plan: Plan, rows: int) -> Plan:
    """``plan`` with its frames padded to ``rows``: no run, no lift, the last pose held."""

    def held(a: np.ndarray) -> np.ndarray:  # the last frame repeated
        return np.concatenate([a, np.repeat(a[-1:], rows - len(a), axis=0)])

    return Plan(held(plan.angles), held(plan.root), held(plan.rot), pad_rows(plan.which, rows, -1),
                pad_rows(plan.weight, rows), held(plan.start), held(plan.end), held(plan.budget),
                pad_rows(plan.swing, rows))  # fmt: skip


def plant_planned(
    robot: Robot, plans: list[Plan], together: bool | None = None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every plan's motion planted (``stance.plant``): ``((T, J) angles, (T, 3) root)`` each,
    float64. One at a time: ``stance.plant``, the frames padded to ``bucket(T, SINGLE_ROWS)``
    (a padding frame costs little there). ``together`` (``None``: on an accelerator, with
    several plans): ``stance.plant_many`` over stacks of motions of one padded length
    (``buckets.packed_calls``, as ``retarget_many`` packs), a batch's recordings in a few
    programs. A CPU plants one at a time: there a stack's vmapped program pays every frame's
    solves (the padding's, a frame's with no foot down) and compiles a program per length and
    stack size; measured on the 2-core VM, 67 bundled recordings' whole-body stage stacked
    took 35.6 s from the cache and 132 s more compiling."""
    out: list[tuple[np.ndarray, np.ndarray]] = [(np.zeros(0), np.zeros(0))] * len(plans)
    key = identity(robot)
    coarse = jax.default_backend() != "cpu"
    if len(plans) == 1 or not (coarse if together is None else together):
        return [_plant_one(robot, plan) for plan in plans]
    calls = packed_calls([len(p.angles) for p in plans], coarse=coarse, frames=PACK_FRAMES)
    for rows, members, count in calls:
        padded = [_padded(plans[i], rows) for i in members]
        padded += [padded[-1]] * (count - len(padded))
        stacked = Plan(*(np.stack(a) for a in zip(*padded, strict=True)))
        got = executables.call(plant_many_jit, (stacked,), static={"robot": robot},
                               name="stance_many", identity=key)  # fmt: skip
        angles, pos = (np.asarray(a) for a in got)
        for j, i in enumerate(members):
            n = len(plans[i].angles)
            out[i] = (angles[j, :n].astype(np.float64), pos[j, :n].astype(np.float64))
    return out


PACK_FRAMES = 131072
"""Padded frames of a batch's stance program a call at most (``plant_planned``)."""


def _plant_one(robot: Robot, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """``stance.plant`` of one plan, its frames padded to ``bucket(T, SINGLE_ROWS)``."""
    n = len(plan.angles)
    padded = _padded(plan, bucket(n, SINGLE_ROWS))
    got = executables.call(plant_jit, (padded,), static={"robot": robot}, name="stance",
                           identity=identity(robot))  # fmt: skip
    angles, pos = (np.asarray(a)[:n].astype(np.float64) for a in got)
    return angles, pos


def _plant_feet(
    robot: Robot,
    q: np.ndarray,
    root_pos: np.ndarray,
    rot_root: np.ndarray,
    stance: np.ndarray,
    ramp: int,
    budget: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Each stance foot held where it touched down, level: per run of contact frames of a foot,
    its sole's reference point (the mean of its geoms' lowest points) and heading at the run's
    first frame are the target (the point at its standing height above the floor, the sole
    level), reached on every frame by one IK over the root's position and the stance legs'
    joints (the root only where every foot it holds is in contact, its horizontal steps
    otherwise as given), from the root's and the retargeted angles; a foot's rows fade in over
    ``ramp`` frames of swing before touchdown and out over as many after lift-off (the nearer
    run's target; never inside a stance, where it would slide the foot). A target the IK
    misses by more than ``PLANT_REACH`` is moved to where the foot is on the next frame. With
    ``budget`` (``(T,)`` m), the root's step into frame ``t`` is at most ``budget[t]``: a
    longer one is cut to that length (its vertical part first) and the stance legs solved
    again with the root held there. A swing foot below the floor is then lifted onto it. The
    solver: ``jaxproj.motion.stance``. Returns ``((T, n_joints) angles, (T, 3) root
    positions)``, float64."""
    return plant_planned(robot, [plan_feet(q, root_pos, rot_root, stance, ramp, budget)])[0]


def _runs(x: np.ndarray) -> list[tuple[int, int]]:
    """``(start, end)`` of each run of true values of ``(T,)`` bool ``x``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], x.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _stance_weights(stance: np.ndarray, ramp: int) -> tuple[np.ndarray, np.ndarray]:
    """Per frame and foot of ``(T, K)`` ``stance``: the run of contact whose target the frame
    takes (``-1``: none) and its weight, 1 inside the run, falling linearly to 0 over ``ramp``
    frames before and after it (the nearer run where two ramps meet): ``((T, K) int, (T, K)
    float)``."""
    n, feet = stance.shape
    which = np.full((n, feet), -1)
    weight = np.zeros((n, feet))
    for k in range(feet):
        for i, (t0, t1) in enumerate(_runs(stance[:, k])):
            for t in range(max(0, t0 - ramp), min(n, t1 + ramp)):
                d = t0 - t if t < t0 else (t - t1 + 1 if t >= t1 else 0)
                w = 1.0 - d / (ramp + 1)
                if w > weight[t, k]:
                    which[t, k], weight[t, k] = i, w
    return which, weight


def _below_floor(
    robot: Robot, q: np.ndarray, root_pos: np.ndarray, rot_root: np.ndarray
) -> np.ndarray:
    """``(T,)`` m: how far the lowest point of any of the robot's geoms (boxes, spheres,
    capsules) is below the floor in each frame (0 if none is), the root's pose and the angles
    as given: what the root is lifted by."""
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    root = _root_body(model)
    bodies = list(range(1, model.nbody))
    adr = joint_qpos_index(model, robot.joint_names)
    out = np.zeros(len(q))
    for t in range(len(q)):
        _set(model, data, adr, q[t])
        pts, rad = _foot_points(model, data, bodies, root)
        out[t] = max(0.0, -(root_pos[t, 2] + np.min((pts @ rot_root[t].T)[:, 2] - rad)))
    return out


def _root_body(model: mujoco.MjModel) -> int:
    """The fixed model's root body: the world's first child."""
    return int(next(b for b in range(1, model.nbody) if model.body_parentid[b] == 0))
