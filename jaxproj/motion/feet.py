"""The feet of a whole-body motion (``jaxproj.motion.whole_body``): the robot's geometry on
the host (MuJoCo's kinematics: each geom's lowest points, a foot's leg joints) and the stance
IK that plants each foot in contact where it touched down, level, and lifts a swing foot that
went below the floor.

Per frame, one Levenberg-Marquardt solve over the root's position and the joints of the legs
whose feet hold a target (``_stance_ik``): residuals are each foot's reference point against its
target (m), its orientation against level at its touchdown heading (``PLANT_ORIENTATION`` m per
rad), and pulls of the root (``PLANT_ROOT_PULL``) and of each joint (``PLANT_PULL``) toward the
values it was given; steps of at most 0.2, within the joint limits.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from jaxproj.robots import Robot
from jaxproj.robots.base import joint_qpos_index


def _set(model: mujoco.MjModel, data: mujoco.MjData, adr: np.ndarray, q: np.ndarray) -> None:
    """``q`` (the robot's joints) into ``data.qpos`` at ``adr`` (``joint_qpos_index``), then the
    kinematics."""
    data.qpos[adr] = q
    mujoco.mj_kinematics(model, data)


def _foot_points(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: list[int], root: int
) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(K, 3)`` in the root body's frame and radii ``(K,)`` whose lowest surface is
    every geom's of ``bodies``: box corners (radius 0), sphere centres, capsule ends."""
    r_root, x_root = data.xmat[root].reshape(3, 3), data.xpos[root]
    pts, rad = [], []
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) not in bodies:
            continue
        kind, size = int(model.geom_type[g]), model.geom_size[g]
        c, r = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
            local = c + (signs * size[:3]) @ r.T
            radius = np.zeros(8)
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            local, radius = c[None], np.array([size[0]])
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = r[:, 2] * size[1]
            local, radius = np.stack([c - axis, c + axis]), np.full(2, size[0])
        else:
            continue
        pts.append((local - x_root) @ r_root)
        rad.append(radius)
    if not pts:
        return np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(pts), np.concatenate(rad)


PLANT_ITERATIONS = 30
"""Levenberg-Marquardt steps of each frame's stance IK (``_stance_ik``)."""
PLANT_RAMP_S = 0.1
"""s: a stance foot's correction fades in before touchdown and out after lift-off over this (at
least 2 frames); the root's height blends over the same."""
PLANT_ORIENTATION = 0.05
"""m per rad: the weight of the sole's orientation error against its position error. Low, so
that where an ankle at its limit cannot hold the sole level at its target the sole tilts
rather than the foot slides: at 0.2, on the CMU bend-over clip 131_01 (120 fps), the left
ankle's pitch sat at its -50 deg limit and the right ankle's roll at its 15 deg over frames
348-362, the feet missed their targets by 2-5 cm, and the re-anchored targets slid them up
to 12 m/s (stance sliding p95 15.4 cm/s; 3.3 at 0.05, 9.3 at 0.1; the stance soles' tilt
median 4.3 -> 3.8 deg there, 0.1 -> 1.1-1.4 deg on the Kinect recordings, whose sliding p95
fell from 1.8-4.7 to 1.1-2.2 cm/s; ``benchmarks.whole_body``). A second solve at a low weight
only where the first missed by more than 5 mm left 6.3 cm/s: the switch between the two
moves the foot."""
PLANT_PULL = 0.01
"""m per rad: the pull of each leg joint toward the retargeted angle."""
PLANT_ROOT_PULL = 0.5
"""The pull of the root's position toward where the height and stance rules put it (m per m):
the stance IK moves the root rather than slide a foot."""
ROOT_SLACK = 0.015
"""m: the root's step in one frame is at most the person's scaled pelvis step plus this
(``_plant_feet``). Where the stance rule or the IK would move it further (a body frame that
turns 30-50 deg in one Kinect frame while the feet are planted swings the root around them; a
lost leg drops it), the root stops at the bound and the stance legs are solved again from
there."""
PLANT_REACH = 0.03
"""m: a stance foot the IK leaves farther than this from its target is anchored anew at the
next frame, where it is then (a slide, not a leg stretched after an unreachable point)."""


def _leg_dofs(model: mujoco.MjModel, foot: int, root: int) -> list[int]:
    """The hinge joints between the root body and ``foot`` (joint ids), root first."""
    out: list[int] = []
    body = foot
    while body not in (root, 0):
        out = [j for j in range(model.njnt) if model.jnt_bodyid[j] == body
               and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE] + out  # fmt: skip
        body = int(model.body_parentid[body])
    return out


class _Leg(NamedTuple):
    """One foot's leg in the free model: the foot body, its sole's reference point and lowest
    points in the foot's frame, the leg's joints (qpos and dof addresses, columns of the
    robot's angles) and their limits."""

    foot: int
    ref: np.ndarray
    pts: np.ndarray
    rad: np.ndarray
    height: float
    qadr: np.ndarray
    dadr: np.ndarray
    cols: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _stance_ik(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    legs: list[_Leg],
    weights: list[float],
    targets: list[tuple[np.ndarray, np.ndarray]],
    free: int,
    move_root: bool = True,
) -> tuple[np.ndarray, list[float]]:
    """One frame's stance feet at their targets: Levenberg-Marquardt over the root's position
    (the free joint's first three coordinates; only with ``move_root``) and the stance legs'
    joints, from ``data.qpos``
    (which it leaves at the answer), each foot's rows weighted by its ``weights`` entry, the
    root pulled toward where it was (``PLANT_ROOT_PULL``) and each joint toward its given angle
    (``PLANT_PULL``); steps of at most 0.2 rad (m), within the joint limits. Returns ``(qpos,
    each foot's position error, m)``."""
    r3 = 3 if move_root else 0
    qadr = np.concatenate([np.arange(free, free + r3), *[leg.qadr for leg in legs]])
    dadr = np.concatenate([np.arange(r3), *[leg.dadr for leg in legs]])
    lo = np.concatenate([np.full(r3, -np.inf), *[leg.lo for leg in legs]])
    hi = np.concatenate([np.full(r3, np.inf), *[leg.hi for leg in legs]])
    pull = np.concatenate([np.full(r3, PLANT_ROOT_PULL), np.full(len(qadr) - r3, PLANT_PULL)])
    given = data.qpos[qadr].copy()

    def residual(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[float]]:
        data.qpos[qadr] = x
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        rows, jacs, miss = [pull * (x - given)], [np.diag(pull)], []
        for leg, w, (target_p, target_r) in zip(legs, weights, targets, strict=True):
            r = data.xmat[leg.foot].reshape(3, 3)
            point = data.xpos[leg.foot] + r @ leg.ref
            err_r = -0.5 * sum(np.cross(r[:, i], target_r[:, i]) for i in range(3))
            jp, jr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
            mujoco.mj_jac(model, data, jp, jr, point, leg.foot)
            rows += [w * (point - target_p), w * PLANT_ORIENTATION * err_r]
            jacs += [w * jp[:, dadr], w * PLANT_ORIENTATION * jr[:, dadr]]
            miss.append(float(np.linalg.norm(point - target_p)))
        return np.concatenate(rows), np.concatenate(jacs), miss

    x = given.copy()
    res, jac, miss = residual(x)
    mu = 1e-4
    for _ in range(PLANT_ITERATIONS):
        step = np.linalg.solve(jac.T @ jac + mu * np.eye(len(x)), -jac.T @ res)
        step *= min(1.0, 0.2 / max(float(np.abs(step).max()), 1e-12))
        trial = np.clip(x + step, lo, hi)
        res_t, jac_t, miss_t = residual(trial)
        if res_t @ res_t < res @ res:
            x, res, jac, miss, mu = trial, res_t, jac_t, miss_t, mu * 0.3
        else:
            mu *= 10.0
    data.qpos[qadr] = x
    return data.qpos.copy(), miss


def _lift(model: mujoco.MjModel, data: mujoco.MjData, leg: _Leg, given: np.ndarray) -> np.ndarray:
    """The leg's joints from ``given`` with its foot's lowest point lifted onto the floor where
    it is below it (Gauss-Newton on that point's height, pulled toward ``given``)."""
    x = given.copy()
    data.qpos[leg.qadr] = x
    mujoco.mj_kinematics(model, data)
    r = data.xmat[leg.foot].reshape(3, 3)
    i = int(np.argmin((data.xpos[leg.foot] + leg.pts @ r.T)[:, 2] - leg.rad))
    for _ in range(PLANT_ITERATIONS):
        data.qpos[leg.qadr] = x
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        point = data.xpos[leg.foot] + data.xmat[leg.foot].reshape(3, 3) @ leg.pts[i]
        below = point[2] - leg.rad[i]
        if below >= -1e-4:
            break
        jp = np.zeros((3, model.nv))
        mujoco.mj_jac(model, data, jp, None, point, leg.foot)
        jac = np.concatenate([jp[2:3, leg.dadr], PLANT_PULL * np.eye(len(x))])
        res = np.concatenate([[below], PLANT_PULL * (x - given)])
        step = np.linalg.solve(jac.T @ jac + 1e-6 * np.eye(len(x)), -jac.T @ res)
        step *= min(1.0, 0.2 / max(float(np.abs(step).max()), 1e-12))
        x = np.clip(x + step, leg.lo, leg.hi)
    return x


def _plant_feet(
    robot: Robot,
    q: np.ndarray,
    root_pos: np.ndarray,
    rot_root: np.ndarray,
    stance: np.ndarray,
    ramp: int,
    feet_trees: list[list[int]],
    budget: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Each stance foot held where it touched down, level: per run of contact frames of a foot,
    its sole's reference point (the mean of its geoms' lowest points) and heading at the run's
    first frame are the target (the point at its standing height above the floor, the sole
    level), reached on every frame by one IK over the root's position and the stance legs'
    joints (``_stance_ik``; the root only where every foot it holds is in contact, its
    horizontal steps otherwise as given), from the root's and the retargeted angles; a foot's
    rows fade in
    over ``ramp`` frames of swing before touchdown and out over as many after lift-off (the
    nearer run's target; never inside a stance, where it would slide the foot). A target the
    IK misses by more than ``PLANT_REACH`` is moved to where the foot is on the next frame.
    With ``budget`` (``(T,)`` m), the root's step into frame ``t`` is at most ``budget[t]``:
    a longer one is cut to that length (``_bounded``) and the stance legs solved again
    with the root held there. A swing foot below the floor is then lifted onto it
    (``_lift``). Returns ``((T, n_joints)
    angles, (T, 3) root positions)``, float64."""
    model = robot.load_model("free")
    data = mujoco.MjData(model)
    adr = joint_qpos_index(model, robot.joint_names).tolist()
    free = int(model.jnt_qposadr[0])
    root = int(model.jnt_bodyid[0])
    out = np.array(q, np.float64)
    pos = np.array(root_pos, np.float64)
    which, weight = _stance_weights(stance, ramp)

    def pose(t: int, angles: np.ndarray, at: np.ndarray) -> None:
        data.qpos[free : free + 3] = at
        wxyz = np.zeros(4)
        mujoco.mju_mat2Quat(wxyz, rot_root[t].ravel())
        data.qpos[free + 3 : free + 7] = wxyz
        data.qpos[adr] = angles
        mujoco.mj_kinematics(model, data)

    data.qpos[:] = model.qpos0
    data.qpos[adr] = robot.standing
    mujoco.mj_kinematics(model, data)
    legs = []
    for tree in feet_trees[: stance.shape[1]]:
        foot = tree[0]
        pts, rad = _foot_points(model, data, tree, foot)  # standing, in the foot's frame
        ref = pts.mean(axis=0)
        joints = _leg_dofs(model, foot, root)
        qadr = np.array([model.jnt_qposadr[j] for j in joints])
        cols = np.array([adr.index(int(a)) for a in qadr])
        legs.append(_Leg(foot, ref, pts, rad, float(ref[2] - np.min(pts[:, 2] - rad)), qadr,
                         np.array([model.jnt_dofadr[j] for j in joints]), cols,
                         robot.lower[cols], robot.upper[cols]))  # fmt: skip

    def anchor(t: int, leg: _Leg, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The target at frame ``t``: where the uncorrected foot is with the root ``at``,
        level, its heading."""
        pose(t, q[t], at)
        r0 = data.xmat[leg.foot].reshape(3, 3)
        here = data.xpos[leg.foot] + r0 @ leg.ref
        c, s_ = r0[0, 0], r0[1, 0]
        norm = max(float(np.hypot(c, s_)), 1e-12)
        c, s_ = c / norm, s_ / norm
        turn = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
        return np.array([here[0], here[1], leg.height]), turn

    runs = [_runs(stance[:, k]) for k in range(len(legs))]
    targets: list[dict[int, tuple[np.ndarray, np.ndarray]]] = [{} for _ in legs]
    for t in range(len(q)):
        if t > 0:  # the root's horizontal steps as given, from where the IK left it
            pos[t, :2] = pos[t - 1, :2] + root_pos[t, :2] - root_pos[t - 1, :2]
            if budget is not None:
                pos[t] = _bounded(pos[t - 1], pos[t], budget[t])
        active = [k for k in range(len(legs)) if which[t, k] >= 0]
        if not active:
            continue
        for k in active:  # a run's target, when first needed: its touchdown, from here on
            i = int(which[t, k])
            if i not in targets[k]:
                t0 = runs[k][i][0]
                at = pos[t] + root_pos[t0] - root_pos[t] if t0 > t else pos[t]
                targets[k][i] = anchor(max(t0, t), legs[k], at)
        pose(t, out[t], pos[t])
        solve = ([legs[k] for k in active], [float(weight[t, k]) for k in active],
                 [targets[k][int(which[t, k])] for k in active], free)  # fmt: skip
        qpos, miss = _stance_ik(model, data, *solve, all(weight[t, k] >= 1 for k in active))
        if budget is not None and t > 0:
            held = _bounded(pos[t - 1], qpos[free : free + 3], budget[t])
            if not np.array_equal(held, qpos[free : free + 3]):  # solved again, the root held
                pose(t, out[t], held)
                qpos, miss = _stance_ik(model, data, *solve, False)
        out[t] = qpos[adr]
        pos[t] = qpos[free : free + 3]
        for k, m in zip(active, miss, strict=True):
            t0, t1 = runs[k][which[t, k]]
            if t0 <= t < t1 - 1 and m > PLANT_REACH:
                at = pos[t] + root_pos[t + 1] - root_pos[t]
                targets[k][int(which[t, k])] = anchor(t + 1, legs[k], at)  # out of reach
    for k, leg in enumerate(legs):
        for t in map(int, np.flatnonzero(~stance[:, k])):
            pose(t, out[t], pos[t])
            out[t, leg.cols] = _lift(model, data, leg, out[t, leg.cols].copy())
    return out, pos


def _bounded(last: np.ndarray, here: np.ndarray, step: float) -> np.ndarray:
    """``(3,)`` ``here`` moved toward ``last`` until it is at most ``step`` from it: the
    vertical part of the move is cut first (the horizontal steps follow the person's pelvis;
    the height rules' steps are the robot's own), then the horizontal one."""
    d = here - last
    if float(np.linalg.norm(d)) <= step:
        return here
    flat = float(np.linalg.norm(d[:2]))
    if flat >= step:
        return last + np.array([d[0] * step / flat, d[1] * step / flat, 0.0])
    return last + np.array([d[0], d[1], np.copysign(np.sqrt(step * step - flat * flat), d[2])])


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


def _sole_heights(
    model: mujoco.MjModel, data: mujoco.MjData, robot: Robot, trees: list[list[int]]
) -> list[float]:
    """Per foot (``trees``: each foot body's subtree), how high its sole's reference point (the
    mean of its geoms' lowest points) is above the sole when the foot is level (the standing
    posture, the foot's own frame); what ``_plant_feet`` holds it at."""
    _set(model, data, joint_qpos_index(model, robot.joint_names), robot.standing)
    out = []
    for tree in trees:
        pts, rad = _foot_points(model, data, tree, tree[0])
        out.append(float(pts.mean(axis=0)[2] - np.min(pts[:, 2] - rad)))
    return out


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


def _subtree(model: mujoco.MjModel, body: int) -> list[int]:
    out = [body]
    for b in range(model.nbody):
        if b not in out and int(model.body_parentid[b]) in out:
            out.append(b)
    return out
