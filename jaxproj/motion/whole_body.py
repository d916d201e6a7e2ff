"""Whole-body motion: the robot's root (its floating base) in a world frame with the floor at
``z = 0``, the feet on the floor while the person's are (issue 59).

``retarget`` gives joint angles in the torso's frame; a legged robot that walks, turns or bends
also needs where its root body (the MJCF's free-joint body, a humanoid's pelvis) is and how it is
turned. ``root_trajectory`` adds them (the rules on the host, NumPy and MuJoCo's kinematics,
about 1 ms a frame; the stance IK compiled, ``jaxproj.motion.stance``; ``root_trajectories``
for a batch, its stance IKs in one call per length), for any robot whose correspondence
matches the thighs and shins (the generic IK's rows ``thigh_<side>``, ``shin_<side>``) and
whose figure names its feet (``Figure.feet``: the foot bodies whose geoms touch the floor).

The world frame (``WorldFrame``), found from the recording alone:

* **up** is the capture's up axis (+y: Kinect camera space and every reader's output). A camera's
  own pitch is not removed (a Kinect tilted by 10 deg makes a walk towards it climb 10 deg).
* **the floor** (person's units): each foot joint's (ankle and foot point, both sides) 5th
  percentile height over the valid frames is where that joint sits when its foot stands on the
  floor; a foot's clearance in a frame is the smaller excess of its two joints over theirs.
* **x** points along the person's horizontal forward direction (the median over the first
  ``HEADING_FRAMES`` valid frames of the body frame's forward axis, ``skeleton.body_frame``), the
  origin on the floor below the person's HipCenter at the first valid frame: a motion starts at
  the origin facing +x.
* **scale**: robot metres per person unit, the ratio of the legs' lengths (the robot's thigh and
  shin rows at its standing posture over the median of the person's hip -> knee -> ankle, both
  sides, valid frames).

Contacts (``ContactConfig``, ``contacts_of``) come from the person: a foot is in contact where
its clearance, scaled to the robot, is below ``height`` (m) and its foot point's horizontal
speed, scaled, below ``speed`` (m/s); runs shorter than ``min_frames`` are dropped.
``root_trajectory`` plants no foot on an invalid frame.

The root, frame by frame:

* **orientation**: the robot's torso (the correspondence's base) takes the person's body frame in
  the world (up along HipCenter -> ShoulderCenter), so the robot's trunk leans as the person's
  does; the root body's orientation follows through the waist joints (forward kinematics of the
  angles). Frames whose body frame is degenerate or invalid hold the last good one. The angles
  should come from ``retarget(..., level_legs=False)`` (``jaxproj retarget --root world`` does
  so): by default ``retarget`` turns every bone against the trunk by the recording's median
  shin (``skeleton.level_body``'s first step, up to 19 deg on the bundled clips), which a fixed
  base needs and which would tilt every limb by that angle in the world (measured on the CMU
  clips: the legs 13-19 deg off the person's, against 5-6 without it). ``level_soles`` instead
  turns the whole recording so that its stance soles are level on the median.
* **height**: with no foot in contact, the lowest foot point (each foot geom's lowest point: a
  box's corners, a sphere's or capsule's lowest surface point) at the person's scaled clearance
  less ``ContactConfig.height`` (continuous through a touchdown); with feet in contact, the
  higher stance foot on the floor, level (its sole's reference point at the height it has over
  the floor when the sole is level; the other leg is then shortened by the stance IK, which a
  leg can always do, where lengthening it may be past its reach); each foot's rule
  blends in and out over ``PLANT_RAMP_S`` around its contact, so the root does not jump.
* **horizontal position**: the person's scaled HipCenter, moved by its frame-to-frame steps;
  while a foot is in contact in two consecutive frames the root instead moves so that the stance
  feet (their mean, with two) stay where they were.

Then ``jaxproj.motion.feet`` plants each stance foot where it touched down, level, by one IK a
frame over the root's position and the stance legs' joints (the root moves rather than a foot
slides; only the legs' joints change) and lifts a swing foot that went below the floor;
``retarget``'s last stage then runs once more on the planted angles (``separate``: a leg the IK
moved into a hand hanging at the hip; the arms yield first), and the root is raised by whatever
of the robot is still below the floor: no geom of the output is below it.

**No jump in the root.** Each frame's root step is at most the person's scaled pelvis step plus
``feet.ROOT_SLACK`` (1.5 cm) in the stance IK (a longer step is cut to that length and the
stance legs solved again with the root held: a body frame that turns 30-50 deg in one Kinect
frame would otherwise swing the root around the planted feet), and the final lift rises and
falls over neighbouring frames (``LIFT_SLACK``), so that no step exceeds the pelvis's by 1.9
cm. What it costs: where a tracker's lost leg leaves a foot out of reach, that foot slides or
stands above the floor for a while instead of the root jumping. A recording centred on its
pelvis (``CENTRED``: MediaPipe's world landmarks) has no pelvis steps to bound by: its root's
steps are bounded by the planned root's horizontal steps (the stance feet's) plus the slack, so
the feet can carry the root while its height does not jump. The angles returned
(``RootMotion.angles``) are the given ones with the legs so moved (and the arms where they
touched): after ``retarget``'s feasibility filter, so a joint's speed can exceed its bound there
(``benchmarks.whole_body`` counts it).

Size: over 500 lines: the world frame, the contacts and the root's rules of one recording,
and the batch's split around the compiled stance IK (``root_trajectories``: the host stages
before and after it), which share the recording's host arrays; the stance IK itself and the
feet's geometry live in ``jaxproj.motion.stance`` and ``jaxproj.motion.feet``.

Quaternions are written ``(x, y, z, w)`` (scalar last: GMR's ``root_rot`` and the LAFAN1
retargeting CSVs that motion-tracking trainers read, sources in the guide's "Whole-body motion";
MuJoCo's own ``qpos`` is scalar first).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import body_frame
from jaxproj.motion.feet import (
    PLANT_RAMP_S,
    ROOT_SLACK,
    _below_floor,
    _foot_points,
    _root_body,
    _set,
    _stance_weights,
    plan_feet,
    plant_planned,
)
from jaxproj.motion.stance import Plan, feet_of
from jaxproj.motion.stance import subtree as _subtree
from jaxproj.robots import Robot
from jaxproj.robots.base import joint_qpos_index

__all__ = ["HEADING_FRAMES", "ContactConfig", "RootMotion", "WorldFrame", "check_robot",
           "contacts_of", "robot_leg_length", "root_trajectories", "root_trajectory",
           "world_frame"]  # fmt: skip

HEADING_FRAMES = 15
"""Valid frames at the start of a recording whose median forward direction is the world's +x."""

LIFT_SLACK = 0.004
"""m: what the root's step may gain from the final lift beyond ``feet.ROOT_SLACK``. The lift
(whatever of the robot is still below the floor after planting: a leg the tracker lost, its
foot out of reach with the root held by its step bound) rises and falls over as many frames as
it takes to keep each step within the person's scaled pelvis step plus ``ROOT_SLACK +
LIFT_SLACK`` (1.9 cm; issue 59 asks for 2): the frames around it are raised too, their feet
above the floor rather than below it."""

CENTRED = 1e-3
"""m (robot scale): a recording whose pelvis stays within this of one point on every frame is
centred on it (MediaPipe's world landmarks are hip-centred in every frame): its pelvis steps
say nothing of how the person travels, so the root's steps are not bounded by them there (the
stance feet alone move the root; bounded, they would slide: measured on the bundled MediaPipe
excerpt of CMU 131_03, sliding median 3.1 cm/s against 0.03)."""

FLOOR_PERCENTILE = 5.0
"""Percentile of a foot joint's height over the valid frames taken as its height on the floor."""

SIDES = ("left", "right")
_FOOT_JOINTS = {"left": ("AnkleLeft", "FootLeft"), "right": ("AnkleRight", "FootRight")}
_LEG_JOINTS = {"left": ("HipLeft", "KneeLeft", "AnkleLeft"),
               "right": ("HipRight", "KneeRight", "AnkleRight")}  # fmt: skip


@dataclass(frozen=True)
class ContactConfig:
    """When a person's foot is in contact with the floor (robot scale).

    Attributes:
      height: m, the foot's clearance (scaled) below which it may be in contact.
      speed: m/s, the foot point's horizontal speed (scaled) below which it may be.
      min_frames: shorter runs of contact, or of no contact between two, are dropped (filled).
    """

    height: float = 0.05
    speed: float = 0.35
    min_frames: int = 2

    def __post_init__(self) -> None:
        if not (self.height > 0 and self.speed > 0 and self.min_frames >= 1):
            raise ConfigError("ContactConfig: height and speed > 0, min_frames >= 1")


@dataclass(frozen=True)
class WorldFrame:
    """One recording's world frame (module doc).

    Attributes:
      axes: ``(3, 3)`` rows: the world's x, y, z axes in the capture's coordinates.
      origin: ``(3,)`` the capture point at the world's origin (on the floor).
      scale: robot metres per person unit.
      foot_floor: ``(2, 2)`` per side (left, right), the ankle's and the foot point's heights on
        the floor (person units, along ``axes[2]``).
    """

    axes: np.ndarray
    origin: np.ndarray
    scale: float
    foot_floor: np.ndarray

    def to_world(self, positions: np.ndarray) -> np.ndarray:
        """``(..., 3)`` capture points -> the world frame, robot metres."""
        return (np.asarray(positions, np.float64) - self.origin) @ self.axes.T * self.scale


class RootMotion(NamedTuple):
    """``root_trajectory``'s answer for one motion of ``T`` frames.

    Attributes:
      root_pos: ``(T, 3)`` float32 m, the root body's origin in the world.
      root_rot: ``(T, 4)`` float32, its orientation, quaternion ``(x, y, z, w)``.
      contacts: ``(T, 2)`` bool, the person's left and right foot in contact.
      world: the recording's ``WorldFrame``.
      angles: ``(T, n_joints)`` float32 rad: the given angles with each stance foot planted
        (``_plant_feet``: the legs' joints moved, the rest as given).
    """

    root_pos: np.ndarray
    root_rot: np.ndarray
    contacts: np.ndarray
    world: WorldFrame
    angles: np.ndarray


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0)


def _hold(ok: np.ndarray) -> np.ndarray:
    """``(T,)`` index of the last ``ok`` frame at or before each frame (leading: the first)."""
    idx = np.where(ok, np.arange(len(ok)), -1)
    last = np.maximum.accumulate(idx)
    first = int(np.flatnonzero(ok)[0])
    return np.where(last < 0, first, last)


def check_robot(robot: Robot) -> None:
    """``ConfigError`` naming what is missing unless ``robot`` can have a whole-body motion:
    correspondence rows of both thighs and shins (the generic IK's) and ``Figure.feet``."""
    _leg_rows(robot)


def _leg_rows(robot: Robot) -> dict[str, tuple[str, str]]:
    corr = None if robot.generic is None else robot.generic.correspondence
    rows = {} if corr is None else {r.bone: (r.start, r.end) for r in corr.pairs}
    need = [f"{b}_{s}" for s in SIDES for b in ("thigh", "shin")]
    if any(n not in rows for n in need) or not robot.mjcf or not robot.mjcf.figure.feet:
        raise ConfigError(
            f"robot {robot.name!r}: whole-body motion needs correspondence rows {need} (the "
            "generic IK's) and the figure's feet (Figure.feet)"
        )
    return {n: rows[n] for n in need}


def _point(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return np.array(data.site_xpos[sid])
    return np.array(data.xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)])


def robot_leg_length(robot: Robot) -> float:
    """m: the robot's thigh + shin (its correspondence rows' points) at the standing posture,
    the mean of the two sides."""
    rows = _leg_rows(robot)
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    _set(model, data, joint_qpos_index(model, robot.joint_names), robot.standing)
    length = [
        np.linalg.norm(_point(model, data, b) - _point(model, data, a))
        for a, b in rows.values()
    ]  # fmt: skip
    return float(np.sum(length) / 2)


def world_frame(
    positions: np.ndarray, valid: np.ndarray, robot: Robot, *,
    skeleton: skeletons.SkeletonLike = skeletons.DEFAULT,
) -> WorldFrame:  # fmt: skip
    """The world frame of one recording (module doc): ``(T, n, 3)`` positions of ``skeleton``
    (the readers' Kinect v1 layout), ``(T,)`` valid.

    Raises:
      ConfigError: no valid frame with finite hips, knees, ankles and feet; a robot without
        leg rows or feet.
    """
    s = skeletons.get(skeleton)
    p = np.asarray(positions, np.float64)
    ok = np.asarray(valid, bool) & np.isfinite(p).all(axis=(1, 2))
    if not ok.any():
        raise ConfigError("whole-body motion needs at least one valid frame")
    up = np.array([0.0, 1.0, 0.0])
    legs = []
    for side in SIDES:
        h, k, a = (p[:, s.index[j]] for j in _LEG_JOINTS[side])
        legs.append(np.linalg.norm(k - h, axis=-1) + np.linalg.norm(a - k, axis=-1))
    person_leg = float(np.median(np.mean(legs, axis=0)[ok]))
    if not person_leg > 0:
        raise ConfigError("whole-body motion: the person's legs have no length")
    scale = robot_leg_length(robot) / person_leg
    foot_floor = np.array(
        [[np.percentile(p[ok, s.index[j]] @ up, FLOOR_PERCENTILE) for j in _FOOT_JOINTS[side]]
         for side in SIDES]
    )  # fmt: skip
    rot, fine = body_frame(jnp.asarray(p, jnp.float32), skeleton=skeleton)
    good = ok & np.asarray(fine)
    fwd = np.asarray(rot, np.float64)[good][:HEADING_FRAMES, 0]
    fwd = np.median(fwd - np.outer(fwd @ up, up), axis=0)
    if np.linalg.norm(fwd) < 1e-6:
        fwd = np.array([0.0, 0.0, -1.0])  # a person seen from the front faces the camera (-z)
    x = _unit(fwd)
    axes = np.stack([x, np.cross(up, x), up])
    first = p[int(np.flatnonzero(ok)[0]), s.index["HipCenter"]]
    origin = first - (first @ up - foot_floor[:, 1].min()) * up
    return WorldFrame(axes=axes, origin=origin, scale=float(scale), foot_floor=foot_floor)


def contacts_of(
    positions: np.ndarray, valid: np.ndarray, times: np.ndarray, world: WorldFrame, *,
    skeleton: skeletons.SkeletonLike = skeletons.DEFAULT,
    config: ContactConfig | None = None,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The person's foot contacts (module doc): ``((T, 2) bool contacts, (T, 2) float64
    clearance, robot metres)``, left then right."""
    cfg = ContactConfig() if config is None else config
    s = skeletons.get(skeleton)
    p = np.asarray(positions, np.float64)
    ok = np.asarray(valid, bool) & np.isfinite(p).all(axis=(1, 2))
    keep = _hold(ok)
    p = p[keep]
    t = np.asarray(times, np.float64)
    dt = np.gradient(t) if len(t) > 1 else np.ones(1)
    up = world.axes[2]
    clear = np.zeros((len(p), 2))
    speed = np.zeros((len(p), 2))
    for k, side in enumerate(SIDES):
        ankle, foot = (p[:, s.index[j]] for j in _FOOT_JOINTS[side])
        clear[:, k] = np.maximum(
            0.0, np.minimum(ankle @ up - world.foot_floor[k, 0], foot @ up - world.foot_floor[k, 1])
        ) * world.scale  # fmt: skip
        horizontal = foot - np.outer(foot @ up, up)
        vel = np.gradient(horizontal, axis=0) / dt[:, None] if len(p) > 1 else 0 * horizontal
        speed[:, k] = np.linalg.norm(vel, axis=-1) * world.scale
    contact = (clear < cfg.height) & (speed < cfg.speed)
    for k in range(2):
        contact[:, k] = _drop_short(contact[:, k], cfg.min_frames)
    return contact, clear


def _drop_short(x: np.ndarray, n: int) -> np.ndarray:
    """``(T,)`` bool with runs (of either value) shorter than ``n`` frames flipped, the
    shortest first; the first and last runs are kept."""
    x = x.copy()
    if n <= 1 or len(x) < 3:
        return x
    for length in range(1, n):
        edges = np.flatnonzero(np.diff(x.astype(np.int8))) + 1
        starts = np.concatenate([[0], edges])
        ends = np.concatenate([edges, [len(x)]])
        for a, b in zip(starts[1:-1], ends[1:-1], strict=True):
            if b - a == length:
                x[a:b] = ~x[a]
    return x


LEVEL_SOLES = False
"""``root_trajectory``'s default: turn each recording by the one rotation that levels its
stance soles on the median (the planting IK levels each frame's)."""


def root_trajectory(
    positions: np.ndarray,
    valid: np.ndarray,
    times: np.ndarray,
    angles: np.ndarray,
    robot: Robot,
    *,
    skeleton: skeletons.SkeletonLike = skeletons.DEFAULT,
    contact: ContactConfig | None = None,
    level_soles: bool = LEVEL_SOLES,
    separate: bool = True,
) -> RootMotion:
    """The root of one motion in the world, and its stance feet planted (module doc).

    Args:
      positions: ``(T, n, 3)`` the person's joints (``skeleton``'s order), any units.
      valid: ``(T,)`` bool.
      times: ``(T,)`` s, strictly increasing.
      angles: ``(T, n_joints)`` the robot's joint angles (``robot.joint_names``), rad, as
        ``retarget`` wrote them (the same frames).
      robot: the robot (leg rows, feet, MJCF with a free joint).
      skeleton: the positions' skeleton.
      contact: ``ContactConfig()`` by default.
      level_soles: turn the whole recording by the one rotation that levels its stance soles
        on the median (``LEVEL_SOLES``).
      separate: after planting, ``retarget``'s last stage once more
        (``retarget.separate_motion``: the robot's self-contacts pushed apart in time order,
        the limbs before the trunk): the stance IK moves the legs, into a hand that hangs at
        the hip (measured, CMU 131_03: 64 frames with a hand in a thigh or hip). ``False``:
        the planted angles as they are.

    Returns:
      ``RootMotion``.

    Raises:
      ConfigError: shapes that disagree, no valid frame, a robot without legs or feet.
    """
    return root_trajectories([(positions, valid, times, angles)], robot, skeleton=skeleton,
                             contact=contact, level_soles=level_soles, separate=separate,
                             raise_errors=True)[0]  # fmt: skip


def root_trajectories(
    motions: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    robot: Robot,
    *,
    skeleton: skeletons.SkeletonLike = skeletons.DEFAULT,
    contact: ContactConfig | None = None,
    level_soles: bool = LEVEL_SOLES,
    separate: bool = True,
    raise_errors: bool = False,
    together: bool | None = None,
) -> list[Any]:
    """``root_trajectory`` of each of several motions, ``(positions, valid, times, angles)``
    each: a batch's whole-body stage. On an accelerator their stance IKs run stacked, in one
    compiled call per length bucket (``feet.plant_planned``), and so do their last separations
    (``retarget.separate_many``); a CPU runs both one motion at a time. One entry per motion,
    in order: its ``RootMotion``, or the ``ConfigError`` ``root_trajectory`` raises for it
    (raised here with ``raise_errors``).
    ``together``: ``feet.plant_planned``'s (``None``: stacked on an accelerator, one at a time
    on a CPU)."""
    out: list[Any] = [None] * len(motions)
    ready: list[tuple[int, _Prepared]] = []
    for i, (positions, valid, times, angles) in enumerate(motions):
        try:
            ready.append((i, _prepare(positions, valid, times, angles, robot, skeleton=skeleton,
                                      contact=contact, level_soles=level_soles)))  # fmt: skip
        except ConfigError as err:
            if raise_errors:
                raise
            out[i] = err
    planted = plant_planned(robot, [pre.plan for _, pre in ready], together)
    angles_out = [q for q, _ in planted]
    if separate and ready:
        from jaxproj.motion.retarget import separate_many  # the fixed base's compiled pass

        angles_out = separate_many(angles_out, robot)
    for (i, pre), q_out, (_, root_pos) in zip(ready, angles_out, planted, strict=True):
        out[i] = _finish(robot, pre, np.asarray(q_out, np.float64), root_pos)
    return out


class _Prepared(NamedTuple):
    """One motion between ``root_trajectories``' host stages."""

    plan: Plan
    rot_root: np.ndarray
    contacts: np.ndarray
    world: WorldFrame
    budget: np.ndarray


def _prepare(
    positions: np.ndarray,
    valid: np.ndarray,
    times: np.ndarray,
    angles: np.ndarray,
    robot: Robot,
    *,
    skeleton: skeletons.SkeletonLike = skeletons.DEFAULT,
    contact: ContactConfig | None = None,
    level_soles: bool = LEVEL_SOLES,
) -> _Prepared:
    """``root_trajectory``'s host stage before the stance IK: the world frame, contacts, the
    root's orientation, its positions by the height and stance rules, and the stance plan."""
    p = np.asarray(positions, np.float64)
    q = np.asarray(angles, np.float64)
    n = len(p)
    if q.shape != (n, robot.n_joints) or np.shape(times) != (n,) or np.shape(valid) != (n,):
        raise ConfigError(f"root_trajectory: positions {p.shape}, angles {q.shape}, times "
                          f"{np.shape(times)}, valid {np.shape(valid)} disagree")  # fmt: skip
    _leg_rows(robot)
    assert robot.mjcf is not None and robot.generic is not None
    world = world_frame(p, valid, robot, skeleton=skeleton)
    cfg = ContactConfig() if contact is None else contact
    ok = np.asarray(valid, bool) & np.isfinite(p).all(axis=(1, 2))
    contacts, clear = contacts_of(p, valid, times, world, skeleton=skeleton, config=cfg)
    contacts &= ok[:, None]  # nothing is known of an invalid frame's feet: none planted
    fps = 1.0 / float(np.median(np.diff(times))) if n > 1 else 30.0
    ramp = max(2, round(PLANT_RAMP_S * fps))
    # the torso's orientation in the world: the person's body frame
    rot, fine = body_frame(jnp.asarray(p, jnp.float32), skeleton=skeleton)
    rot = np.asarray(rot, np.float64)[_hold(ok & np.asarray(fine))]
    world_torso = world.axes[None] @ np.swapaxes(rot, 1, 2)  # (T, 3, 3)
    # the robot's kinematics, fixed base: torso and feet in the root body's frame
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    root = _root_body(model)
    torso = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, robot.generic.correspondence.base)
    feet = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b)
            for b, _ in robot.mjcf.figure.feet][:2]  # fmt: skip
    trees = [_subtree(model, f) for f in feet]
    stance = contacts[:, : len(feet)]
    root_torso = np.zeros((n, 3, 3))
    foot_pts: list[list[tuple[np.ndarray, np.ndarray]]] = []
    foot_up = np.zeros((n, len(feet), 3))
    adr = joint_qpos_index(model, robot.joint_names)
    for t in range(n):
        _set(model, data, adr, q[t])
        r_root = data.xmat[root].reshape(3, 3)
        root_torso[t] = r_root.T @ data.xmat[torso].reshape(3, 3)
        foot_pts.append([_foot_points(model, data, tree, root) for tree in trees])
        for k, f in enumerate(feet):
            foot_up[t, k] = r_root.T @ data.xmat[f].reshape(3, 3)[:, 2]
    rot_root = world_torso @ np.swapaxes(root_torso, 1, 2)
    if level_soles and stance.any():
        ups = np.einsum("tij,tkj->tki", rot_root, foot_up)[stance]
        rot_root = _flat(np.median(ups, axis=0))[None] @ rot_root
    low = np.zeros((n, len(feet)))
    centre = np.zeros((n, len(feet), 3))
    for t in range(n):
        for k, (pts, rad) in enumerate(foot_pts[t]):
            w = pts @ rot_root[t].T
            low[t, k] = np.min(w[:, 2] - rad)
            centre[t, k] = w.mean(axis=0)
    # height: without contact the lowest foot point at the scaled clearance less the contact
    # height (continuous, where a switch to 0 at touchdown would drop the root); with a foot in
    # contact, the higher stance foot's lowest point on the floor (a leg the IK may have to
    # shorten, bending it, rather than lengthen past its reach); each foot's height blends
    # with the free one over the ramps around its contact (no jump at a touchdown)
    target = np.maximum(0.0, clear.min(axis=1) - cfg.height)
    weight = _stance_weights(stance, ramp)[1]
    free = target - low.min(axis=1)
    # a stance foot: its sole's reference point at its height above the floor when level (the
    # planting IK levels it: a tilted foot's lowest corner would leave the root too high, and
    # the IK would straighten the leg to reach down)
    flat = np.asarray(feet_of(robot).height, np.float64)  # the stance IK's own
    stand = flat[None] - centre[:, :, 2]
    z = np.min(weight * stand + (1.0 - weight) * free[:, None], axis=1)
    # horizontal: the scaled pelvis's steps, or the stance feet held
    hip = world.to_world(p[_hold(ok), skeletons.get(skeleton).index["HipCenter"]])
    xy = np.zeros((n, 2))
    xy[0] = hip[0, :2]
    for t in range(1, n):
        both = stance[t] & stance[t - 1]
        if both.any():
            xy[t] = xy[t - 1] - (centre[t, both, :2] - centre[t - 1, both, :2]).mean(axis=0)
        else:
            xy[t] = xy[t - 1] + hip[t, :2] - hip[t - 1, :2]
    root_pos = np.concatenate([xy, z[:, None]], axis=1)
    budget = np.concatenate([[0.0], np.linalg.norm(np.diff(hip, axis=0), axis=1)]) + ROOT_SLACK
    if np.ptp(hip, axis=0).max() < CENTRED:  # the pelvis is the recording's origin: its steps
        # say nothing; the stance feet's horizontal steps (the plan's) stand in for them
        budget[1:] = np.linalg.norm(np.diff(xy, axis=0), axis=1) + ROOT_SLACK
    plan = plan_feet(q, root_pos, rot_root, stance, ramp, budget)
    return _Prepared(plan, rot_root, contacts, world, budget)


def _finish(robot: Robot, pre: _Prepared, q_out: np.ndarray, root_pos: np.ndarray) -> RootMotion:
    """``root_trajectory``'s host stage after the stance IK (and the last separation, already
    run on ``q_out``): the root raised by whatever of the robot is below the floor, spread over
    the frames around it; the quaternions."""
    rot_root, budget, n = pre.rot_root, pre.budget, len(q_out)
    root_pos = np.array(root_pos, np.float64)
    planted = np.concatenate([[0.0], np.linalg.norm(np.diff(root_pos, axis=0), axis=1)])
    lift = _below_floor(robot, q_out, root_pos, rot_root)
    root_pos[:, 2] += _spread(lift, np.maximum(budget + LIFT_SLACK - planted, 0.0))
    quat = np.zeros((n, 4))
    for t in range(n):
        wxyz = np.zeros(4)
        mujoco.mju_mat2Quat(wxyz, rot_root[t].ravel())
        quat[t] = np.roll(wxyz, -1)
    quat *= np.where(quat[:, 3:] < 0, -1.0, 1.0)  # w >= 0: one of the two
    return RootMotion(root_pos.astype(np.float32), quat.astype(np.float32), pre.contacts,
                      pre.world, q_out.astype(np.float32))  # fmt: skip


def _spread(lift: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """The least ``(T,)`` profile at or above ``lift`` whose step into frame ``t`` is at most
    ``rate[t]`` either way: ``lift`` dilated by a cone, one pass each way (a distance
    transform on a line)."""
    out = np.array(lift, np.float64)
    for t in range(1, len(out)):
        out[t] = max(out[t], out[t - 1] - rate[t])
    for t in range(len(out) - 2, -1, -1):
        out[t] = max(out[t], out[t + 1] - rate[t + 1])
    return out


def _flat(u: np.ndarray) -> np.ndarray:
    """``(3, 3)`` the smallest rotation taking the direction ``u`` to the world's +z."""
    u = _unit(u)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(u, z)
    s, c = np.linalg.norm(axis), float(u @ z)
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx
