"""The rollout's models: settings, the fixed-torso MJX model of each part, its index tables.

Part of ``jaxproj.eval.rollout`` (see its docstring for the protocol): ``RolloutConfig``,
``RolloutResult``, the contact groups, and ``_setup(config, part, robot)``, the device-side model
and index tables of one part (``"whole"``, or the two halves of ``RolloutConfig.split_legs``:
``robot.mjcf.split``), with the split's certificate (``_head_ball``, ``_guard``).

The contact groups come from the robot's kinematic tree, not from geom names
(``_geom_classes``): an arm is every geom below the trunk on the way to that side's elbow site
(``Mjcf.arm_sites``), the torso the geoms of the trunk body itself (the deepest body both
elbows hang from), the head every geom below the figure's head body (``Figure.head``). On the
default robot that is exactly its ``torso_*`` / ``head_*`` / ``l_upperarm*`` ... geoms; on a
robot whose geoms are named otherwise, it is what the names missed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxproj.errors import ConfigError
from jaxproj.robots import Robot

CONTACT_GROUPS: tuple[str, ...] = ("arm_torso", "arm_head", "arm_arm")
"""The self-contact groups reported, in the order of the last axis of ``RolloutResult.contact``."""


@dataclass(frozen=True)
class RolloutConfig:
    """Static settings of a rollout (hashable: one compiled program per distinct config).

    Attributes:
      frame_dt: seconds per target frame (1/15 for MSR Action3D); each frame is held for
        ``round(frame_dt / timestep)`` physics steps of 2 ms.
      kp_scale: multiplies the position gain ``kp`` of every servo (1 = the MJCF's gains).
      gravity: gravity on (-9.81 m/s^2 along the torso's -z) or off.
      solver_iterations: cap on the Newton constraint-solver iterations per step (set on the
        model every backend runs: MJX, Warp and C MuJoCo; the MJCF keeps MuJoCo's 100, with
        early exit).
      ls_iterations: cap on the line-search iterations per solver iteration (every backend, as
        above; MJCF 50).
      contact_friction: self-contacts with friction (the MJCF's ``condim=3``, pyramidal cone: 4
        constraint rows per contact slot). ``False`` makes every contact frictionless
        (``condim=1``, one row per slot: 80 constraint rows instead of 239), a speed option that
        changes the physics only while parts touch; contact detection, penetration depth and
        every contact-free frame are unaffected. Measured effect in ``benchmarks/RESULTS.md``.
      split_legs: simulate the head and arms (the default robot's: 14 joints) and the legs (12) as
        two separate models (``robot.mjcf.split``: ``robot.load_model("fixed", without)``), the legs
        once per distinct leg motion of the batch (retargeted motions hold the legs still: once per
        batch). With the torso welded the two parts share no degree of freedom and only the head can
        touch a leg; each batch is certified (below) to keep every leg geom out of the head's reach,
        and otherwise runs the whole model. The answers equal the whole model's to the constraint
        solver's tolerance (the solver's stopping test and line search act on each part alone);
        measured in ``benchmarks/RESULTS.md``; ``False`` runs the whole model.
      interpolate: the servos' targets ramp linearly within each frame from the previous
        frame's target to this frame's, reached at the frame's last physics step (a first-order
        hold, as the default robot's software (``angleInterpolation``) plays a trajectory);
        ``False``: each frame's target from its first physics step (zero-order hold, the protocol
        before 0.3: a servo handed a step accelerates hard, so its peak speed overshoots the frame's
        mean speed).
    The split's certificate: the head turns about the neck, so its geoms stay inside a ball
    about the neck (radius: the farthest head-geom point, computed from the MJCF); the legs'
    rollout checks at every physics step that each leg geom's bounding sphere (plus the contact
    margins) lies outside that ball, so no head-leg contact can arise in the whole model either.

    Why the caps: under ``vmap`` MJX's line search (a ``lax.cond`` per iteration inside a scan)
    evaluates every one of its ``ls_iterations`` and the solver loop runs until the slowest motion
    of the batch stops, so the caps set the cost (8 / 4 runs ~4x faster than 100 / 50 on CPU).
    On this model (equality, joint limits, arm-body contacts) the solver converges within them:
    64 random benchmark motions (many with self-contact) give bit-identical rollouts with 8 / 4
    and with 100 / 50 on CPU (1.5e-5 and 6.2e-4 rad in two H200 runs); 4 / 8, the caps before, gave
    2.6e-3 rad on three of them (the solver needed a 5th iteration), 8 / 3 gave 8.4e-4 rad (H200)
    (``python benchmarks/bench_rollout.py --check-solver 64``).
    """

    frame_dt: float = 1.0 / 15.0
    kp_scale: float = 1.0
    gravity: bool = True
    solver_iterations: int = 8
    ls_iterations: int = 4
    contact_friction: bool = True
    split_legs: bool = True
    interpolate: bool = True

    def __post_init__(self) -> None:
        if not (np.isfinite(self.frame_dt) and self.frame_dt > 0):
            raise ConfigError(f"frame_dt must be a positive number of seconds, got {self.frame_dt}")
        if not (np.isfinite(self.kp_scale) and self.kp_scale > 0):
            raise ConfigError(f"kp_scale must be positive, got {self.kp_scale}")
        for flag in ("contact_friction", "split_legs", "interpolate"):
            if not isinstance(getattr(self, flag), bool):
                raise ConfigError(f"{flag} must be a bool, got {getattr(self, flag)!r}")
        for name in ("solver_iterations", "ls_iterations"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ConfigError(f"{name} must be a positive int, got {value!r}")


class RolloutResult(NamedTuple):
    """What the simulated robot did, per motion ``b`` and frame ``t`` (``t < lengths[b]`` valid).

    Attributes:
      qpos: (B, T, n_joints) float32 joint angles at the end of each frame,
        ``robot.joint_names`` order, rad.
      qvel: (B, T, n_joints) float32 joint speeds at the end of each frame, rad/s.
      contact: (B, T, 3) bool, self-contact during the frame per ``CONTACT_GROUPS``
        (False on padded frames).
      penetration: (B, T) float32 deepest self-contact penetration during the frame, m (>= 0;
        0 on padded frames).
      max_speed: (B, n_joints) float32 peak |qvel| per joint over every physics step of the valid
        frames, rad/s.
      contact_frames: (B, 3) int32 number of valid frames with self-contact, per group.
      tracking_rms: (B, n_joints) float32 RMS over valid frames of ``qpos - target``, per
        joint, rad.
    """

    qpos: jax.Array
    qvel: jax.Array
    contact: jax.Array
    penetration: jax.Array
    max_speed: jax.Array
    contact_frames: jax.Array
    tracking_rms: jax.Array


class _Setup(NamedTuple):
    """Device-side model and index tables of one part for one config (all pytrees of arrays).

    A part is the whole robot or one of the two halves of ``RolloutConfig.split_legs``; its ``n``
    joints are listed in ``robot.joint_names`` order (``joints``), so the whole robot's rows come
    out in that order as they are.
    """

    mx: mjx.Model
    d0: mjx.Data
    joints: jax.Array  # (n,) index into joint_names of each joint of the part, ascending
    qidx: jax.Array  # (n,) qpos address of each joint
    didx: jax.Array  # (n,) dof address of each joint
    q0_src: jax.Array  # (n,) index into joint_names of the target each joint starts at
    act_src: jax.Array  # (nu,) index into joint_names of the joint each actuator drives
    ctrl_lo: jax.Array  # (nu,)
    ctrl_hi: jax.Array  # (nu,)
    q_lo: jax.Array  # (n,) joint range, for the initial pose
    q_hi: jax.Array  # (n,)
    pair_group: jax.Array  # (ngeom, ngeom) int32: index into CONTACT_GROUPS, -1 not reported
    force_limited: jax.Array  # (nu,) bool actuator_forcelimited
    guard_geom: jax.Array  # (k,) int32 geoms that could touch the head (legs part; else k = 0)
    guard_radius: jax.Array  # (k,) float32 their clearance radius about guard_center, m
    guard_center: jax.Array  # (3,) float32 the neck: the point the head turns about, m
    ramp: jax.Array  # (substeps,) float32 share of the step to this frame's target per physics step


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and its ancestors up to (not including) the world body, deepest first."""
    out = []
    while body > 0:
        out.append(body)
        body = int(model.body_parentid[body])
    return out


def _geom_classes(model: mujoco.MjModel, robot: Robot) -> list[str]:
    """Each geom's contact class, ``"torso"`` | ``"head"`` | ``"arm_<side>"`` | ``"other"``, from
    the kinematic tree (the module doc). A model without both elbow sites (a legs part) has no
    arm, so no geom is reported."""
    classes = ["other"] * model.ngeom
    if robot.mjcf is None:
        return classes
    paths = {}
    for side, (_, elbow, _) in robot.mjcf.arm_sites.items():
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, elbow)
        if site >= 0:
            paths[side] = _ancestors(model, int(model.site_bodyid[site]))
    if len(paths) < 2:
        return classes
    first = next(iter(paths.values()))
    trunk = next((b for b in first if all(b in p for p in paths.values())), -1)
    if trunk < 0:
        return classes
    roots = {side: p[p.index(trunk) - 1] for side, p in paths.items() if p[0] != trunk}
    figure = robot.mjcf.figure
    head_body = None if figure is None or figure.head is None else figure.head[0]
    body = mujoco.mjtObj.mjOBJ_BODY
    head = -1 if head_body is None else mujoco.mj_name2id(model, body, head_body)
    for g in range(model.ngeom):
        chain = _ancestors(model, int(model.geom_bodyid[g]))
        arm = next((s for s, r in roots.items() if r in chain), None)
        if arm is not None:
            classes[g] = f"arm_{arm}"
        elif chain and chain[0] == trunk:
            classes[g] = "torso"
        elif head > 0 and head != trunk and head in chain:
            classes[g] = "head"
    return classes


def _pair_group(model: mujoco.MjModel, robot: Robot) -> np.ndarray:
    """(ngeom, ngeom) int32: the CONTACT_GROUPS index of a geom pair, -1 when not reported."""
    cls = _geom_classes(model, robot)
    out = np.full((model.ngeom, model.ngeom), -1, dtype=np.int32)
    for i, a in enumerate(cls):
        for j, b in enumerate(cls):
            pair = {a, b}
            if a.startswith("arm") and b.startswith("arm") and a != b:
                out[i, j] = CONTACT_GROUPS.index("arm_arm")
            elif "torso" in pair and (a.startswith("arm") or b.startswith("arm")):
                out[i, j] = CONTACT_GROUPS.index("arm_torso")
            elif "head" in pair and (a.startswith("arm") or b.startswith("arm")):
                out[i, j] = CONTACT_GROUPS.index("arm_head")
    return out


def _actuated_joint(model: mujoco.MjModel, robot: Robot) -> np.ndarray:
    """(nu,) index into ``robot.joint_names`` of the joint each actuator drives."""
    src = np.full(model.nu, -1, dtype=np.int64)
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.actuator_trnid[a, 0])
            src[a] = robot.index(name) if name and robot.has_joint(name) else -1
    if np.any(src < 0):
        raise ConfigError("some actuator of the model drives none of the robot's joints")
    return src


def _part_joints(model: mujoco.MjModel, robot: Robot) -> np.ndarray:
    """(n,) MuJoCo joint ids of the model's joints, ordered as ``robot.joint_names``."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in
             range(model.njnt)]  # fmt: skip
    unknown = [n for n in names if not robot.has_joint(n)]
    if unknown:
        raise ConfigError(f"the rollout model has joints outside the robot's: {unknown}")
    return np.array(sorted(range(model.njnt), key=lambda j: robot.index(names[j])), dtype=np.int64)


def _subtree(model: mujoco.MjModel, root: int) -> np.ndarray:
    """(nbody,) bool: the bodies of ``root``'s subtree (``root`` included)."""
    inside = np.zeros(model.nbody, dtype=bool)
    inside[root] = True
    for b in range(root + 1, model.nbody):  # MuJoCo lists a parent before its children
        inside[b] = inside[model.body_parentid[b]]
    return inside


def _can_collide(model: mujoco.MjModel, ga: int, gb: int) -> bool:
    """MuJoCo's contype / conaffinity filter (a superset of the pairs it actually tests)."""
    ct, ca = model.geom_contype, model.geom_conaffinity
    return bool((ct[ga] & ca[gb]) or (ct[gb] & ca[ga]))


@functools.lru_cache(maxsize=4)
def _head_ball(robot: Robot) -> tuple[np.ndarray, float, float, frozenset[str]]:
    """The ball about the neck (``robot.mjcf.head_root``) that holds the head's geoms at every
    head angle.

    Returns ``(center (3,), reach, head_margin, head_geom_names)``: every point of every head
    geom lies within ``reach`` of ``center`` whatever the head joints' angles. Checks that the
    head's joints all turn about the neck's origin (so a geom's distance from it is fixed) and
    that no arm geom can collide with a leg geom (so the head is the parts' only meeting point).
    """
    mjcf = robot.require_mjcf()
    if mjcf.head_root is None or set(mjcf.split) != {"upper", "legs"}:
        raise ConfigError(f"split_legs: robot {robot.name!r} names no head root / split parts")
    whole = robot.load_model("fixed")
    data = mujoco.MjData(whole)
    mujoco.mj_kinematics(whole, data)
    neck = mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, mjcf.head_root)
    head = _subtree(whole, neck)
    center = data.xpos[neck].copy()
    for j in range(whole.njnt):
        if head[whole.jnt_bodyid[j]] and np.linalg.norm(data.xanchor[j] - center) > 1e-9:
            raise ConfigError("split_legs: a head joint does not turn about the neck")
    geoms = [g for g in range(whole.ngeom) if head[whole.geom_bodyid[g]]]
    reach = max(float(np.linalg.norm(data.geom_xpos[g] - center) + whole.geom_rbound[g])
                for g in geoms)  # fmt: skip
    margin = max(float(whole.geom_margin[g]) for g in geoms)
    legs = np.zeros(whole.nbody, dtype=bool)
    for root in mjcf.split["upper"]:  # the upper part is the whole without the legs' roots
        legs |= _subtree(whole, mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, root))
    upper = np.zeros(whole.nbody, dtype=bool)
    for root in mjcf.split["legs"]:  # the legs part is the whole without the upper roots
        upper |= _subtree(whole, mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, root))
    for ga in range(whole.ngeom):
        for gb in range(whole.ngeom):
            b1, b2 = whole.geom_bodyid[ga], whole.geom_bodyid[gb]
            if upper[b1] and not head[b1] and legs[b2] and _can_collide(whole, ga, gb):
                raise ConfigError("split_legs: an arm geom can collide with a leg geom")
    names = frozenset(mujoco.mj_id2name(whole, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in geoms)
    return center, reach, margin, names


def _guard(
    model: mujoco.MjModel, part: str, robot: Robot
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Guard geoms, radii and centre of a part (see ``_Setup``): the legs' geoms that pass the
    collision filter with some head geom; none for the other parts."""
    none = (np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros(3, np.float32))
    if part != "legs":
        return none
    center, reach, head_margin, head_names = _head_ball(robot)
    whole = robot.load_model("fixed")
    heads = [mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_GEOM, n) for n in head_names]
    geom, radius = [], []
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        gw = mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gw >= 0 and any(_can_collide(whole, gw, h) for h in heads):
            geom.append(g)
            radius.append(reach + head_margin + model.geom_margin[g] + model.geom_rbound[g])
    return (np.asarray(geom, np.int32), np.asarray(radius, np.float32),
            np.asarray(center, np.float32))  # fmt: skip


def _parts(robot: Robot) -> dict[str, tuple[str, ...]]:
    """Part name -> bodies removed from the fixed-torso model (``robot.mjcf.split``)."""
    return {"whole": (), **robot.require_mjcf().split}


def _fixed_model(config: RolloutConfig, part: str, robot: Robot) -> mujoco.MjModel:
    """The fixed-torso MjModel of ``part`` (``_parts``) with the config's gains and gravity."""
    model = robot.load_model("fixed", _parts(robot)[part])
    if config.kp_scale != 1.0:
        # position actuator: force = kp * ctrl - kp * qpos - kv * qvel
        model.actuator_gainprm[:, 0] *= config.kp_scale
        model.actuator_biasprm[:, 1] *= config.kp_scale
    if not config.gravity:
        model.opt.gravity[:] = 0.0
    if not config.contact_friction:
        model.geom_condim[:] = 1
    model.opt.iterations = config.solver_iterations
    model.opt.ls_iterations = config.ls_iterations
    return model


def _substeps(config: RolloutConfig, timestep: float) -> int:
    n = round(config.frame_dt / timestep)
    if n < 1:
        raise ConfigError(f"frame_dt must be at least one timestep ({timestep} s), got "
                          f"{config.frame_dt}")  # fmt: skip
    return n


def _check_config(config: RolloutConfig) -> None:
    if not isinstance(config, RolloutConfig):
        raise ConfigError(f"config must be a RolloutConfig, got {type(config).__name__}")


class _Tables(NamedTuple):
    """The host-side model of one part and its index tables (``_Setup`` without MJX; the C
    backend, ``rollout_cpu``, runs on these)."""

    model: mujoco.MjModel
    substeps: int
    joints: np.ndarray  # (n,) int32 index into joint_names of each joint of the part, ascending
    qidx: np.ndarray  # (n,) int32 qpos address of each joint
    didx: np.ndarray  # (n,) int32 dof address of each joint
    q0_src: np.ndarray  # (n,) int32 joint whose target starts each joint (a follower: leader)
    act_src: np.ndarray  # (nu,) int32 index into joint_names of the joint each actuator drives
    ctrl_lo: np.ndarray  # (nu,) float32
    ctrl_hi: np.ndarray  # (nu,) float32
    q_lo: np.ndarray  # (n,) float32 joint range, for the initial pose
    q_hi: np.ndarray  # (n,) float32
    pair_group: np.ndarray  # (ngeom, ngeom) int32: index into CONTACT_GROUPS, -1 not reported
    ramp: np.ndarray  # (substeps,) float32: (k + 1) / substeps with interpolate, else ones


@functools.lru_cache(maxsize=8)
def _tables(config: RolloutConfig, part: str, robot: Robot) -> _Tables:
    """The MjModel of ``part`` for ``config``, checked for what the protocol assumes, with its
    index tables and physics steps per frame."""
    model = _fixed_model(config, part, robot)
    substeps = _substeps(config, float(model.opt.timestep))
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_IMPLICITFAST:
        raise ConfigError("the rollout step assumes the implicitfast integrator of the MJCF")
    if np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED) or np.any(
        model.actuator_biastype != mujoco.mjtBias.mjBIAS_AFFINE
    ):
        raise ConfigError("the rollout step assumes position actuators (fixed gain, affine bias)")
    jids = _part_joints(model, robot)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in jids]
    leader = {follower: lead for lead, follower in robot.coupled_joints}
    pair_group = _pair_group(model, robot)
    if part == "legs" and np.any(pair_group >= 0):
        raise ConfigError("split_legs: a reported contact group involves the legs")
    return _Tables(
        model=model,
        substeps=substeps,
        joints=np.array([robot.index(n) for n in names], dtype=np.int32),
        qidx=model.jnt_qposadr[jids].astype(np.int32),
        didx=model.jnt_dofadr[jids].astype(np.int32),
        q0_src=np.array([robot.index(leader.get(n, n)) for n in names], np.int32),
        act_src=_actuated_joint(model, robot).astype(np.int32),
        ctrl_lo=model.actuator_ctrlrange[:, 0].astype(np.float32),
        ctrl_hi=model.actuator_ctrlrange[:, 1].astype(np.float32),
        q_lo=model.jnt_range[jids, 0].astype(np.float32),
        q_hi=model.jnt_range[jids, 1].astype(np.float32),
        pair_group=pair_group,
        ramp=_ramp(config, substeps),
    )


def _ramp(config: RolloutConfig, substeps: int) -> np.ndarray:
    """``(substeps,)`` float32: how far each physics step's servo target has moved from the
    previous frame's target to this frame's (``RolloutConfig.interpolate``); the last is 1."""
    if not config.interpolate:
        return np.ones(substeps, np.float32)
    return (np.arange(1, substeps + 1) / substeps).astype(np.float32)


@functools.lru_cache(maxsize=8)
def _setup(config: RolloutConfig, part: str, robot: Robot) -> tuple[_Setup, int]:
    """Model of ``part`` on device, its index tables for ``config``, and steps per frame."""
    t = _tables(config, part, robot)
    mx = mjx.put_model(t.model, impl="jax")
    d0 = mjx.make_data(mx, impl="jax")
    guard_geom, guard_radius, guard_center = _guard(t.model, part, robot)
    setup = _Setup(
        mx=mx,
        d0=d0,
        joints=jnp.asarray(t.joints),
        qidx=jnp.asarray(t.qidx),
        didx=jnp.asarray(t.didx),
        q0_src=jnp.asarray(t.q0_src),
        act_src=jnp.asarray(t.act_src),
        ctrl_lo=jnp.asarray(t.ctrl_lo),
        ctrl_hi=jnp.asarray(t.ctrl_hi),
        q_lo=jnp.asarray(t.q_lo),
        q_hi=jnp.asarray(t.q_hi),
        pair_group=jnp.asarray(t.pair_group),
        force_limited=jnp.asarray(t.model.actuator_forcelimited, dtype=bool),
        guard_geom=jnp.asarray(guard_geom),
        guard_radius=jnp.asarray(guard_radius),
        guard_center=jnp.asarray(guard_center),
        ramp=jnp.asarray(t.ramp),
    )
    return setup, t.substeps


def _leg_motions(
    targets: np.ndarray, lengths: np.ndarray, leg_joints: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The distinct leg motions of a batch, as ``RolloutConfig(split_legs=True)`` runs them.

    Args:
      targets: (B, T, n_joints) targets, rad; lengths: (B,) valid frames (frames past a
        motion's length count as its last valid frame, as in the rollout).
      leg_joints: (k,) indices into ``robot.joint_names`` of the legs' joints (12 on the default
        robot).

    Returns:
      ``(rows, inverse)``: rows (U, T, k) float32, the distinct leg target sequences, padded to
      a power of two ``U`` with copies of the first (one compile per size class), and inverse
      (B,) int32, the row of each motion. Retargeted motions hold the legs still: ``U = 1``.
    """
    n_b, n_t = targets.shape[:2]
    frame = np.minimum(np.arange(n_t)[None, :], lengths[:, None] - 1)  # (B, T)
    legs = targets[np.arange(n_b)[:, None], frame][..., leg_joints].reshape(n_b, -1)
    if np.all(legs == legs[:1]):
        rows, inverse = legs[:1], np.zeros(n_b, dtype=np.int64)
    else:
        rows, inverse = np.unique(legs, axis=0, return_inverse=True)
    size = 1 << (len(rows) - 1).bit_length()
    rows = np.concatenate([rows, np.repeat(rows[:1], size - len(rows), axis=0)])
    return rows.reshape(size, n_t, len(leg_joints)).astype(np.float32), inverse.astype(np.int32)
