"""Physics check of retargeted motions: batched MuJoCo MJX rollouts of the NAO H25.

(Over 500 lines on purpose: the MJX setup, the batched rollout and its summary share the model
setup and contact groups; splitting them would expose those internals.)

A retargeted motion is a ``(T, 26)`` joint-angle trajectory (rad, ``robot.JOINT_NAMES`` order)
sampled at the Kinect rate. ``simulate`` plays a padded batch of them on the bundled MJCF with the
torso welded to the world (``robot.load_model("fixed")``), gravity on, through the 25 position
servos, and records what the robot actually does; ``summarize`` turns that into plain numbers
(tracking error, self-collisions, joint limits, joint speeds) for reports.

Protocol, for one motion (``lax.scan`` over frames, an inner ``lax.scan`` over physics steps):

* start at rest at the first target frame (``qpos`` = frame 0 clipped to the joint ranges,
  RHipYawPitch := LHipYawPitch, ``qvel`` = 0);
* frame ``t`` (zero-order hold): ``ctrl`` = frame ``t`` clipped to the actuator ``ctrlrange``
  (RHipYawPitch has no actuator: it follows LHipYawPitch through the joint equality) for
  ``substeps = round(frame_dt / timestep)`` physics steps (33 at 15 frames/s and dt = 2 ms);
* at the end of frame ``t`` (time ``(t + 1) * frame_dt``) record the 26 joint angles and speeds;
  the tracking error of frame ``t`` is ``|qpos[t] - target[t]|``, i.e. the servos get one frame
  to reach each new target;
* self-contact: a frame "has" contact of a group when the collision detection of any of its
  physics steps finds a penetrating pair (``dist < margin``, MuJoCo's own inclusion rule; the
  margins are 0) of that group: arm-torso, arm-head, arm-arm (leg contacts are not reported);
* peak joint speed: max |qvel| over every physics step of the valid frames.

Two models (``RolloutConfig.split_legs``, the default): with the torso welded, the head and
arms and the legs share no degree of freedom, so they run as two MJX models — the legs once per
distinct leg motion of the batch — after a per-batch certificate that no leg geom reaches the
head (the only contact pair across the parts); otherwise, or with ``split_legs=False``, the
whole 26-joint model runs. The answers equal the whole model's to the constraint solver's
tolerance (``benchmarks/RESULTS.md``); a step costs about a third.

Padding: a batch is ``(B, T, 26)`` with ``lengths (B,)``. Frames ``t >= lengths[b]`` hold the
motion's last valid frame (whatever the padding contains, even NaN, never reaches the physics)
and are left out of every statistic of ``RolloutResult`` and ``summarize``; their ``qpos`` /
``qvel`` rows are still filled (the robot keeps holding the last pose) but mean nothing.

Strict promotion: the tests (``tests/conftest.py``) trace everything under strict dtype / rank
promotion. MJX 3.17's own code relies on implicit promotion in two of the calls made here:
``mjx.forward`` broadcasts rank-mismatched operands (``smooth.py``: a (3, 3) matrix times a (3,)
vector) and mixes float32 with bool (``support.py``), ``mjx.implicit`` mixes float32 with bool
(``derivative.py``). Only those two calls are traced inside ``_mjx_defaults`` (JAX's default
``"standard"`` dtype / ``"allow"`` rank promotion); ``mjx.kinematics`` is strict-clean and runs
in the caller's mode, and so does all of this module's own code.

Importing ``mujoco.mjx`` logs "Failed to import warp": harmless, the JAX implementation of MJX is
used explicitly (``impl="jax"``, on CPU and GPU alike).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.robots.nao_h25 import robot

CONTACT_GROUPS: tuple[str, ...] = ("arm_torso", "arm_head", "arm_arm")
"""The self-contact groups reported, in the order of the last axis of ``RolloutResult.contact``."""

HAND_SITES: tuple[str, str] = ("l_hand", "r_hand")
"""End-effector sites compared by ``hand_error_cm`` (left, right)."""

LIMIT_TOLERANCE = 1e-3
"""rad: a joint counts as outside its range when it is more than this beyond LOWER / UPPER."""

_ARM_PARTS = frozenset({"upperarm", "forearm", "hand"})


@dataclass(frozen=True)
class RolloutConfig:
    """Static settings of a rollout (hashable: one compiled program per distinct config).

    Attributes:
      frame_dt: seconds per target frame (1/15 for MSR Action3D); each frame is held for
        ``round(frame_dt / timestep)`` physics steps of 2 ms.
      kp_scale: multiplies the position gain ``kp`` of every servo (1 = the MJCF's gains).
      gravity: gravity on (-9.81 m/s^2 along the torso's -z) or off.
      solver_iterations: cap on the Newton constraint-solver iterations per step (MJX only; the
        MJCF keeps MuJoCo's 100, with early exit).
      ls_iterations: cap on the line-search iterations per solver iteration (MJX only; MJCF 50).
      contact_friction: self-contacts with friction (the MJCF's ``condim=3``, pyramidal cone: 4
        constraint rows per contact slot). ``False`` makes every contact frictionless
        (``condim=1``, one row per slot: 80 constraint rows instead of 239), a speed option that
        changes the physics only while parts touch; contact detection, penetration depth and
        every contact-free frame are unaffected. Measured effect in ``benchmarks/RESULTS.md``.
      split_legs: simulate the head and arms (14 joints) and the legs (12) as two separate
        models (``robot.load_model("fixed", without=...)``), the legs once per distinct leg
        motion of the batch (retargeted motions hold the legs still: once per batch). With the
        torso welded the two parts share no degree of freedom and only the head can touch a leg;
        each batch is certified (below) to keep every leg geom out of the head's reach, and
        otherwise runs the whole model. The answers equal the whole model's to the constraint
        solver's tolerance (the solver's stopping test and line search act on each part alone);
        measured in ``benchmarks/RESULTS.md``; ``False`` runs the whole model.

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

    def __post_init__(self) -> None:
        if not (np.isfinite(self.frame_dt) and self.frame_dt > 0):
            raise ConfigError(f"frame_dt must be a positive number of seconds, got {self.frame_dt}")
        if not (np.isfinite(self.kp_scale) and self.kp_scale > 0):
            raise ConfigError(f"kp_scale must be positive, got {self.kp_scale}")
        for flag in ("contact_friction", "split_legs"):
            if not isinstance(getattr(self, flag), bool):
                raise ConfigError(f"{flag} must be a bool, got {getattr(self, flag)!r}")
        for name in ("solver_iterations", "ls_iterations"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ConfigError(f"{name} must be a positive int, got {value!r}")


class RolloutResult(NamedTuple):
    """What the simulated robot did, per motion ``b`` and frame ``t`` (``t < lengths[b]`` valid).

    Attributes:
      qpos: (B, T, 26) float32 joint angles at the end of each frame, ``JOINT_NAMES`` order, rad.
      qvel: (B, T, 26) float32 joint speeds at the end of each frame, rad/s.
      contact: (B, T, 3) bool, self-contact during the frame per ``CONTACT_GROUPS``
        (False on padded frames).
      penetration: (B, T) float32 deepest self-contact penetration during the frame, m (>= 0;
        0 on padded frames).
      max_speed: (B, 26) float32 peak |qvel| per joint over every physics step of the valid
        frames, rad/s.
      contact_frames: (B, 3) int32 number of valid frames with self-contact, per group.
      tracking_rms: (B, 26) float32 RMS over valid frames of ``qpos - target``, per joint, rad.
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
    joints are listed in ``JOINT_NAMES`` order (``joints``), so the whole robot's rows come out
    in ``JOINT_NAMES`` order as they are.
    """

    mx: mjx.Model
    d0: mjx.Data
    joints: jax.Array  # (n,) index into JOINT_NAMES of each joint of the part, ascending
    qidx: jax.Array  # (n,) qpos address of each joint
    didx: jax.Array  # (n,) dof address of each joint
    q0_src: jax.Array  # (n,) index into JOINT_NAMES of the target each joint starts at
    act_src: jax.Array  # (nu,) index into JOINT_NAMES of the joint each actuator drives
    ctrl_lo: jax.Array  # (nu,)
    ctrl_hi: jax.Array  # (nu,)
    q_lo: jax.Array  # (n,) joint range, for the initial pose
    q_hi: jax.Array  # (n,)
    pair_group: jax.Array  # (ngeom, ngeom) int32: index into CONTACT_GROUPS, -1 not reported
    force_limited: jax.Array  # (nu,) bool actuator_forcelimited
    guard_geom: jax.Array  # (k,) int32 geoms that could touch the head (legs part; else k = 0)
    guard_radius: jax.Array  # (k,) float32 their clearance radius about guard_center, m
    guard_center: jax.Array  # (3,) float32 the neck: the point the head turns about, m


_PARTS: dict[str, tuple[str, ...]] = {
    "whole": (),
    "upper": robot.LEG_ROOTS,
    "legs": robot.UPPER_ROOTS,
}
"""Part name -> bodies removed from the fixed-torso model (``robot.load_model(without=...)``)."""

_HEAD_ROOT = "Neck"


def _geom_class(name: str) -> str:
    """ "torso" | "head" | "arm_l" | "arm_r" | "other" from an MJCF geom name."""
    parts = name.split("_")
    if parts[0] in ("torso", "head"):
        return parts[0]
    if parts[0] in ("l", "r") and len(parts) > 1 and parts[1] in _ARM_PARTS:
        return "arm_" + parts[0]
    return "other"


def _pair_group(model: mujoco.MjModel) -> np.ndarray:
    """(ngeom, ngeom) int32: the CONTACT_GROUPS index of a geom pair, -1 when not reported."""
    names = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(model.ngeom)
    ]
    cls = [_geom_class(n) for n in names]
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


def _actuated_joint(model: mujoco.MjModel) -> np.ndarray:
    """(nu,) index into JOINT_NAMES of the joint each actuator drives."""
    src = np.full(model.nu, -1, dtype=np.int64)
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.actuator_trnid[a, 0])
            src[a] = robot.IDX.get(name or "", -1)
    if np.any(src < 0):
        raise ConfigError("some actuator of the model drives none of JOINT_NAMES")
    return src


def _part_joints(model: mujoco.MjModel) -> np.ndarray:
    """(n,) MuJoCo joint ids of the model's joints, ordered as ``JOINT_NAMES``."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in
             range(model.njnt)]  # fmt: skip
    unknown = [n for n in names if n not in robot.IDX]
    if unknown:
        raise ConfigError(f"the rollout model has joints outside JOINT_NAMES: {unknown}")
    return np.array(sorted(range(model.njnt), key=lambda j: robot.IDX[names[j]]), dtype=np.int64)


def _subtree(model: mujoco.MjModel, root: int) -> np.ndarray:
    """(nbody,) bool: the bodies of ``root``'s subtree (``root`` included)."""
    inside = np.zeros(model.nbody, dtype=bool)
    inside[root] = True
    for b in range(root + 1, model.nbody):  # MuJoCo lists a parent before its children
        inside[b] = inside[model.body_parentid[b]]
    return inside


def _can_collide(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """MuJoCo's contype / conaffinity filter (a superset of the pairs it actually tests)."""
    ct, ca = model.geom_contype, model.geom_conaffinity
    return bool((ct[g1] & ca[g2]) or (ct[g2] & ca[g1]))


@functools.lru_cache(maxsize=1)
def _head_ball() -> tuple[np.ndarray, float, float, frozenset[str]]:
    """The ball about the neck that holds the head's geoms at every head angle.

    Returns ``(center (3,), reach, head_margin, head_geom_names)``: every point of every head
    geom lies within ``reach`` of ``center`` whatever the head joints' angles. Checks that the
    head's joints all turn about the neck's origin (so a geom's distance from it is fixed) and
    that no arm geom can collide with a leg geom (so the head is the parts' only meeting point).
    """
    whole = robot.load_model("fixed")
    data = mujoco.MjData(whole)
    mujoco.mj_kinematics(whole, data)
    neck = mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, _HEAD_ROOT)
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
    for root in robot.LEG_ROOTS:
        legs |= _subtree(whole, mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, root))
    upper = np.zeros(whole.nbody, dtype=bool)
    for root in robot.UPPER_ROOTS:
        upper |= _subtree(whole, mujoco.mj_name2id(whole, mujoco.mjtObj.mjOBJ_BODY, root))
    for g1 in range(whole.ngeom):
        for g2 in range(whole.ngeom):
            b1, b2 = whole.geom_bodyid[g1], whole.geom_bodyid[g2]
            if upper[b1] and not head[b1] and legs[b2] and _can_collide(whole, g1, g2):
                raise ConfigError("split_legs: an arm geom can collide with a leg geom")
    names = frozenset(mujoco.mj_id2name(whole, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in geoms)
    return center, reach, margin, names


def _guard(model: mujoco.MjModel, part: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Guard geoms, radii and centre of a part (see ``_Setup``): the legs' geoms that pass the
    collision filter with some head geom; none for the other parts."""
    none = (np.zeros(0, np.int32), np.zeros(0, np.float32), np.zeros(3, np.float32))
    if part != "legs":
        return none
    center, reach, head_margin, head_names = _head_ball()
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


def _fixed_model(config: RolloutConfig, part: str = "whole") -> mujoco.MjModel:
    """The fixed-torso MjModel of ``part`` (``_PARTS``) with the config's gains and gravity."""
    model = robot.load_model("fixed", without=_PARTS[part])
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


@functools.lru_cache(maxsize=8)
def _setup(config: RolloutConfig, part: str = "whole") -> tuple[_Setup, int]:
    """Model of ``part`` on device, its index tables for ``config``, and steps per frame."""
    model = _fixed_model(config, part)
    substeps = _substeps(config, float(model.opt.timestep))
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_IMPLICITFAST:
        raise ConfigError("the rollout step assumes the implicitfast integrator of the MJCF")
    if np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED) or np.any(
        model.actuator_biastype != mujoco.mjtBias.mjBIAS_AFFINE
    ):
        raise ConfigError("the rollout step assumes position actuators (fixed gain, affine bias)")
    mx = mjx.put_model(model, impl="jax")
    d0 = mjx.make_data(mx, impl="jax")
    jids = _part_joints(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or "" for j in jids]
    joints = np.array([robot.IDX[n] for n in names], dtype=np.int32)
    lhyp, rhyp = robot.COUPLED_JOINTS
    q0_src = np.array([robot.IDX[lhyp] if n == rhyp else robot.IDX[n] for n in names], np.int32)
    pair_group = _pair_group(model)
    if part == "legs" and np.any(pair_group >= 0):
        raise ConfigError("split_legs: a reported contact group involves the legs")
    guard_geom, guard_radius, guard_center = _guard(model, part)
    setup = _Setup(
        mx=mx,
        d0=d0,
        joints=jnp.asarray(joints),
        qidx=jnp.asarray(model.jnt_qposadr[jids], dtype=jnp.int32),
        didx=jnp.asarray(model.jnt_dofadr[jids], dtype=jnp.int32),
        q0_src=jnp.asarray(q0_src),
        act_src=jnp.asarray(_actuated_joint(model), dtype=jnp.int32),
        ctrl_lo=jnp.asarray(model.actuator_ctrlrange[:, 0], dtype=jnp.float32),
        ctrl_hi=jnp.asarray(model.actuator_ctrlrange[:, 1], dtype=jnp.float32),
        q_lo=jnp.asarray(model.jnt_range[jids, 0], dtype=jnp.float32),
        q_hi=jnp.asarray(model.jnt_range[jids, 1], dtype=jnp.float32),
        pair_group=jnp.asarray(pair_group),
        force_limited=jnp.asarray(model.actuator_forcelimited, dtype=bool),
        guard_geom=jnp.asarray(guard_geom),
        guard_radius=jnp.asarray(guard_radius),
        guard_center=jnp.asarray(guard_center),
    )
    return setup, substeps


@contextlib.contextmanager
def _mjx_defaults() -> Iterator[None]:
    """Trace the block under JAX's default promotion (``"standard"`` dtype, ``"allow"`` rank),
    whatever the caller's mode: only for calls into MJX code that needs it (module docstring)."""
    with jax.numpy_dtype_promotion("standard"), jax.numpy_rank_promotion("allow"):
        yield


def _mjx_step(s: _Setup, d: mjx.Data) -> mjx.Data:
    """One physics step: ``mjx.forward`` + implicitfast integration, as CPU MuJoCo does it.

    ``mjx.step`` (MJX 3.17) puts the velocity gain ``kv`` of every position servo into the
    implicit damping matrix, while CPU MuJoCo 3.17 (``mjd_actuator_vel``) leaves out the servos
    whose force is clamped by ``forcerange``; the NAO servos saturate on every large step, so
    ``mjx.step`` lags CPU MuJoCo by ~0.02 rad within 0.1 s there. Here the ``kv`` of the clamped
    servos is zeroed in the model handed to ``mjx.implicit`` for this step only, which makes the
    two agree to float32 round-off (tests/test_rollout.py).
    """
    mx = s.mx
    with _mjx_defaults():  # MJX internals need implicit promotion; see the module docstring
        d = mjx.forward(mx, d)
    bias = mx.actuator_biasprm
    raw = (
        mx.actuator_gainprm[:, 0] * d.ctrl
        + bias[:, 0]
        + bias[:, 1] * d.actuator_length
        + bias[:, 2] * d._impl.actuator_velocity
    )
    clamped = s.force_limited & (
        (raw < mx.actuator_forcerange[:, 0]) | (raw > mx.actuator_forcerange[:, 1])
    )
    kv = jnp.where(clamped, jnp.zeros_like(bias[:, 2]), bias[:, 2])
    implicit_mx = mx.replace(actuator_biasprm=bias.at[:, 2].set(kv))
    with _mjx_defaults():  # MJX internals need implicit promotion; see the module docstring
        return mjx.implicit(implicit_mx, d)


def _self_contact(s: _Setup, d: mjx.Data) -> tuple[jax.Array, jax.Array]:
    """(3,) bool penetrating self-contact per group, () deepest penetration (m, >= 0).

    MJX (JAX implementation) keeps a fixed-size ``d._impl.contact`` with one slot per candidate
    geom pair (per contact point of its collider); ``geom`` (n, 2) is filled by the collision
    step and ``dist`` holds the signed distance of every slot, so a slot is an actual contact
    when ``dist < includemargin`` (the same rule CPU MuJoCo uses to emit a contact).
    """
    con = d._impl.contact
    if con.dist.shape[0] == 0:
        return jnp.zeros(len(CONTACT_GROUPS), dtype=bool), jnp.zeros((), jnp.float32)
    geom = jnp.maximum(con.geom, 0)
    group = s.pair_group[geom[:, 0], geom[:, 1]]  # (n,)
    active = (con.dist < con.includemargin) & (con.geom[:, 0] >= 0) & (group >= 0)
    ids = jnp.arange(len(CONTACT_GROUPS), dtype=jnp.int32)
    hit = jnp.any(active[:, None] & (group[:, None] == ids[None, :]), axis=0)
    depth = jnp.max(jnp.where(active, -con.dist, jnp.float32(0.0)))
    return hit, jnp.maximum(depth, jnp.float32(0.0))


def _held(targets: jax.Array, length: jax.Array) -> tuple[jax.Array, jax.Array]:
    """targets (T, 26), length () -> (T, 26) with the frames past ``length`` holding the last
    valid one, and (T,) bool valid."""
    n_frames = targets.shape[0]
    valid = jnp.arange(n_frames, dtype=jnp.int32) < length  # (T,)
    last = jnp.clip(length - 1, 0, n_frames - 1)
    return jnp.where(valid[:, None], targets, targets[last][None, :]), valid


def _guard_clearance(s: _Setup, d: mjx.Data) -> jax.Array:
    """() smallest clearance of the guard geoms outside the head's ball, m (inf: none)."""
    if s.guard_geom.shape[0] == 0:
        return jnp.full((), jnp.inf, jnp.float32)
    gap = jnp.linalg.norm(d.geom_xpos[s.guard_geom] - s.guard_center[None, :], axis=-1)
    return jnp.min(gap - s.guard_radius)


def _rollout_one(
    s: _Setup, held: jax.Array, valid: jax.Array, substeps: int
) -> tuple[jax.Array, ...]:
    """One motion of one part: held targets (T, 26), valid (T,) -> per-frame records.

    Returns qpos (T, n), qvel (T, n), contact (T, 3) and depth (T,) (both False / 0 on invalid
    frames), peak |qvel| (T, n) over each frame's physics steps, and the guard clearance (T,)
    (smallest over each frame's physics steps; inf for parts without guard geoms).
    """
    q0 = held[0][s.q0_src]  # RHipYawPitch starts at LHipYawPitch
    q0 = jnp.clip(q0, s.q_lo, s.q_hi)
    d = s.d0.replace(
        qpos=s.d0.qpos.at[s.qidx].set(q0.astype(s.d0.qpos.dtype)),
        qvel=jnp.zeros_like(s.d0.qvel),
        ctrl=jnp.clip(held[0][s.act_src], s.ctrl_lo, s.ctrl_hi).astype(s.d0.ctrl.dtype),
    )
    n_groups = len(CONTACT_GROUPS)
    n_joints = s.joints.shape[0]

    def substep(carry, _):
        d, vpeak, hit, depth, clear = carry
        d = _mjx_step(s, d)
        h, p = _self_contact(s, d)
        vpeak = jnp.maximum(vpeak, jnp.abs(d.qvel[s.didx]))
        clear = jnp.minimum(clear, _guard_clearance(s, d))
        return (d, vpeak, hit | h, jnp.maximum(depth, p), clear), None

    def frame(d, xs):
        target, ok = xs
        ctrl = jnp.clip(target[s.act_src], s.ctrl_lo, s.ctrl_hi).astype(d.ctrl.dtype)
        init = (
            d.replace(ctrl=ctrl),
            jnp.zeros(n_joints, jnp.float32),
            jnp.zeros(n_groups, dtype=bool),
            jnp.zeros((), jnp.float32),
            jnp.full((), jnp.inf, jnp.float32),
        )
        (d, vpeak, hit, depth, clear), _ = jax.lax.scan(substep, init, None, length=substeps)
        rec = (
            d.qpos[s.qidx],
            d.qvel[s.didx],
            hit & ok,
            jnp.where(ok, depth, jnp.float32(0.0)),
            vpeak,
            clear,
        )
        return d, rec

    _, records = jax.lax.scan(frame, d, (held, valid))
    return records


def _motion_stats(
    qpos: jax.Array, vpeak: jax.Array, contact: jax.Array, held: jax.Array, valid: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Per-motion statistics over its valid frames: qpos / vpeak / held (T, n), contact (T, 3),
    valid (T,) -> peak speed (n,), contact frames (3,) int32, tracking RMS (n,)."""
    vmax = jnp.max(jnp.where(valid[:, None], vpeak, jnp.float32(0.0)), axis=0)
    n_valid = jnp.maximum(jnp.sum(valid.astype(jnp.float32)), jnp.float32(1.0))
    err = jnp.where(valid[:, None], qpos - held, jnp.float32(0.0))
    rms = jnp.sqrt(jnp.sum(err * err, axis=0) / n_valid)
    frames = jnp.sum(contact.astype(jnp.int32), axis=0)
    return vmax, frames, rms


@jit(static_argnames=("substeps",), precision=None)  # MJX keeps its own defaults
def _simulate_jit(
    s: _Setup, targets: jax.Array, lengths: jax.Array, substeps: int
) -> RolloutResult:
    """A batch on one part: targets (B, T, 26), lengths (B,) -> ``RolloutResult`` whose joint
    axes are the part's ``n`` joints (``s.joints``; all 26 in order for the whole robot)."""

    def one(targets: jax.Array, length: jax.Array) -> tuple[jax.Array, ...]:
        held, valid = _held(targets, length)
        qpos, qvel, contact, depth, vpeak, _ = _rollout_one(s, held, valid, substeps)
        vmax, frames, rms = _motion_stats(qpos, vpeak, contact, held[:, s.joints], valid)
        return qpos, qvel, contact, depth, vmax, frames, rms

    return RolloutResult(*jax.vmap(one)(targets, lengths))


class _LegRollout(NamedTuple):
    """The legs' rollout of each distinct leg motion (U of them; all frames valid)."""

    qpos: jax.Array  # (U, T, 12)
    qvel: jax.Array  # (U, T, 12)
    vpeak: jax.Array  # (U, T, 12) peak |qvel| per frame
    clearance: jax.Array  # (U,) smallest guard clearance over every physics step, m


@jit(static_argnames=("substeps",), precision=None)  # MJX keeps its own defaults
def _legs_jit(s: _Setup, targets: jax.Array, substeps: int) -> _LegRollout:
    valid = jnp.ones(targets.shape[1], dtype=bool)

    def one(held: jax.Array) -> tuple[jax.Array, ...]:
        qpos, qvel, _, _, vpeak, clear = _rollout_one(s, held, valid, substeps)
        return qpos, qvel, vpeak, jnp.min(clear)

    return _LegRollout(*jax.vmap(one)(targets))


@jit(precision=None)
def _merge_jit(
    upper: RolloutResult,
    legs: _LegRollout,
    inverse: jax.Array,
    upper_joints: jax.Array,
    leg_joints: jax.Array,
    targets: jax.Array,
    lengths: jax.Array,
) -> RolloutResult:
    """The whole robot's ``RolloutResult`` from the head-and-arms part of each motion and its
    leg motion ``legs[inverse[b]]``."""

    def leg_stats(u: jax.Array, targets: jax.Array, length: jax.Array) -> tuple[jax.Array, ...]:
        held, valid = _held(targets, length)
        none = jnp.zeros((targets.shape[0], len(CONTACT_GROUPS)), dtype=bool)
        vmax, _, rms = _motion_stats(legs.qpos[u], legs.vpeak[u], none, held[:, leg_joints],
                                     valid)  # fmt: skip
        return vmax, rms

    leg_vmax, leg_rms = jax.vmap(leg_stats)(inverse, targets, lengths)

    def put(up: jax.Array, lg: jax.Array) -> jax.Array:
        out = jnp.zeros((*up.shape[:-1], robot.N_JOINTS), up.dtype)
        return out.at[..., upper_joints].set(up).at[..., leg_joints].set(lg)

    return RolloutResult(
        qpos=put(upper.qpos, legs.qpos[inverse]),
        qvel=put(upper.qvel, legs.qvel[inverse]),
        contact=upper.contact,
        penetration=upper.penetration,
        max_speed=put(upper.max_speed, leg_vmax),
        contact_frames=upper.contact_frames,
        tracking_rms=put(upper.tracking_rms, leg_rms),
    )


def _as_batch(targets: object, lengths: object | None) -> tuple[np.ndarray, np.ndarray]:
    q = np.asarray(targets, dtype=np.float32)
    if q.ndim != 3 or q.shape[-1] != robot.N_JOINTS or q.shape[0] < 1 or q.shape[1] < 1:
        raise ConfigError(f"targets must have shape (B, T, {robot.N_JOINTS}) with B, T >= 1, got "
                          f"{q.shape}")  # fmt: skip
    n_b, n_t = q.shape[:2]
    if lengths is None:
        n = np.full(n_b, n_t, dtype=np.int32)
    else:
        n = np.asarray(lengths)
        if n.shape != (n_b,) or not np.issubdtype(n.dtype, np.integer):
            raise ConfigError(f"lengths must be ({n_b},) integers, got {n.shape} {n.dtype}")
        n = n.astype(np.int32)
    if np.any(n < 1) or np.any(n > n_t):
        raise ConfigError(f"lengths must lie in [1, {n_t}], got {n.min()}..{n.max()}")
    valid = np.arange(n_t)[None, :] < n[:, None]
    if not np.all(np.isfinite(q[valid])):
        b, t = np.argwhere(valid & ~np.all(np.isfinite(q), axis=-1))[0]
        raise ConfigError(f"targets are not finite: motion {b}, frame {t}")
    return q, n


def simulate(
    targets: np.ndarray | jax.Array,
    lengths: np.ndarray | jax.Array | None = None,
    config: RolloutConfig = RolloutConfig(),
    devices: Sequence[jax.Device] | None = None,
) -> RolloutResult:
    """Play a padded batch of joint-angle motions on the simulated NAO (MJX, jitted, vmapped).

    Args:
      targets: (B, T, 26) target joint angles per frame, ``JOINT_NAMES`` order, rad.
      lengths: (B,) int valid frames per motion, in [1, T] (None: all T). Frames past a
        motion's length may hold anything (even NaN): they are replaced by the last valid frame
        and excluded from every statistic.
      config: frame period, gain scale, gravity (static: one compile per config, B and T).
      devices: ``None`` (default device) or several: the motions are split into one
        contiguous share per device and each device runs the one-device program on its share
        (one host thread per device, so they run at the same time; the model copied to each;
        no collective); the results are concatenated on the first device. Not ``shard_map``:
        XLA's GPU compiler (jax 0.11.2) crashed with a segmentation fault compiling the
        shard_mapped MJX step on two H200s, while the one-device program is the one every
        single-GPU rollout already runs.

    Returns:
      ``RolloutResult`` of device arrays (see its docstring for shapes).

    Raises:
      ConfigError: bad shapes, lengths out of range, non-finite valid frames, bad config.
    """
    _check_config(config)
    q, n = _as_batch(targets, lengths)
    devices = None if devices is None else list(devices)
    if devices and len(set(devices)) != len(devices):
        raise ConfigError(f"devices lists a device twice: {[str(d) for d in devices]}")
    if config.split_legs:
        result = _simulate_split(q, n, config, devices)
        if result is not None:
            return result
    setup, substeps = _setup(config, "whole")
    return _run_shares(setup, q, n, substeps, devices)


def _run_shares(
    setup: _Setup, q: np.ndarray, n: np.ndarray, substeps: int, devices: list | None
) -> RolloutResult:
    """``_simulate_jit`` on one device, or on one contiguous share of the motions per device."""
    if not devices or len(devices) == 1:
        dev = devices[0] if devices else None
        if dev is not None:
            setup = jax.device_put(setup, dev)
        return _simulate_jit(setup, jax.device_put(q, dev), jax.device_put(n, dev), substeps)
    bounds = np.linspace(0, len(q), len(devices) + 1).round().astype(int)
    shares = [(d, lo, hi) for d, lo, hi in zip(devices, bounds[:-1], bounds[1:], strict=True)
              if hi > lo]  # fmt: skip  (more devices than motions: the extra ones get none)

    def run(share: tuple[jax.Device, int, int]) -> RolloutResult:
        dev, lo, hi = share
        s_d = jax.device_put(setup, dev)
        out = _simulate_jit(s_d, jax.device_put(q[lo:hi], dev), jax.device_put(n[lo:hi], dev),
                            substeps)  # fmt: skip
        return jax.block_until_ready(out)

    # one host thread per device: XLA:GPU runs the MJX solver's while loops with the host in
    # the loop, so a call returns only when its device is done; threads let them overlap
    with concurrent.futures.ThreadPoolExecutor(len(shares)) as pool:
        parts = list(pool.map(run, shares))
    if len(parts) == 1:
        return parts[0]
    home = devices[0]
    fields = zip(*parts, strict=True)
    return RolloutResult(*(jnp.concatenate([jax.device_put(x, home) for x in f]) for f in fields))


def _leg_motions(
    targets: np.ndarray, lengths: np.ndarray, leg_joints: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The distinct leg motions of a batch, as ``RolloutConfig(split_legs=True)`` runs them.

    Args:
      targets: (B, T, 26) targets, rad; lengths: (B,) valid frames (frames past a motion's
        length count as its last valid frame, as in the rollout).
      leg_joints: (12,) indices into ``JOINT_NAMES`` of the legs' joints.

    Returns:
      ``(rows, inverse)``: rows (U, T, 12) float32, the distinct leg target sequences, padded to
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


def _simulate_split(
    q: np.ndarray, n: np.ndarray, config: RolloutConfig, devices: list | None
) -> RolloutResult | None:
    """``simulate`` as two parts (``RolloutConfig.split_legs``); None when a leg motion comes
    within the head's reach (the caller then runs the whole model)."""
    legs, substeps = _setup(config, "legs")
    upper, _ = _setup(config, "upper")
    home = devices[0] if devices else None
    leg_joints = np.asarray(legs.joints)
    rows, inverse = _leg_motions(q, n, leg_joints)
    leg_targets = np.tile(robot.STANDING_POSTURE, (*rows.shape[:2], 1))
    leg_targets[..., leg_joints] = rows
    if home is not None:
        legs, upper = jax.device_put(legs, home), jax.device_put(upper, home)
    leg_run = _legs_jit(legs, jax.device_put(leg_targets, home), substeps)
    if not bool(np.all(np.asarray(leg_run.clearance) > 0.0)):
        return None
    up = _run_shares(upper, q, n, substeps, devices)
    return _merge_jit(up, leg_run, jax.device_put(inverse, home), upper.joints, legs.joints,
                      jax.device_put(q, home), jax.device_put(n, home))  # fmt: skip


# --- kinematics -------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _kin_setup() -> tuple[mjx.Model, mjx.Data, jax.Array, jax.Array]:
    model = robot.load_model("fixed")  # torso welded at the origin: world frame = torso frame
    mx = mjx.put_model(model, impl="jax")
    d0 = mjx.make_data(mx, impl="jax")
    sids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n) for n in HAND_SITES]
    qidx = jnp.asarray(robot.joint_qpos_index(model), dtype=jnp.int32)
    return mx, d0, qidx, jnp.asarray(sids, dtype=jnp.int32)


@jit(precision=None)
def _hand_error_jit(
    mx: mjx.Model, d0: mjx.Data, qidx: jax.Array, sids: jax.Array, qa: jax.Array, qb: jax.Array
) -> jax.Array:
    lhyp = robot.IDX[robot.COUPLED_JOINTS[0]]
    rhyp = robot.IDX[robot.COUPLED_JOINTS[1]]

    def sites(q: jax.Array) -> jax.Array:
        q = q.at[rhyp].set(q[lhyp])
        d = d0.replace(qpos=d0.qpos.at[qidx].set(q.astype(d0.qpos.dtype)))
        d = mjx.kinematics(mx, d)  # strict-clean in MJX 3.17: runs in the caller's mode
        return d.site_xpos[sids]  # (2, 3)

    pos = jax.vmap(sites)(jnp.concatenate([qa, qb]))  # one batched FK for both: (2N, 2, 3)
    n = qa.shape[0]
    return jnp.float32(100.0) * jnp.linalg.norm(pos[:n] - pos[n:], axis=-1)


def hand_error_cm(angles_a: np.ndarray | jax.Array, angles_b: np.ndarray | jax.Array) -> jax.Array:
    """Distance between the hand sites of two configurations, with MJX kinematics (jitted).

    Args:
      angles_a: (N, 26) joint angles, ``JOINT_NAMES`` order, rad.
      angles_b: (N, 26) joint angles, same order.

    Returns:
      (N, 2) float32 distances in cm between the ``l_hand`` sites (column 0) and the ``r_hand``
      sites (column 1) of ``angles_a[i]`` and ``angles_b[i]`` (torso frame; RHipYawPitch follows
      LHipYawPitch as in ``robot.config_to_qpos``). One compile per N.

    Raises:
      ConfigError: the shapes differ or are not (N, 26).
    """
    qa = jnp.asarray(angles_a, dtype=jnp.float32)
    qb = jnp.asarray(angles_b, dtype=jnp.float32)
    if qa.ndim != 2 or qa.shape[-1] != robot.N_JOINTS or qa.shape != qb.shape:
        raise ConfigError(f"angles must both have shape (N, {robot.N_JOINTS}), got {qa.shape} and "
                          f"{qb.shape}")  # fmt: skip
    mx, d0, qidx, sids = _kin_setup()
    return _hand_error_jit(mx, d0, qidx, sids, qa, qb)


# --- summary ----------------------------------------------------------------------------------


def summarize(
    result: RolloutResult, lengths: np.ndarray | jax.Array, targets: np.ndarray | jax.Array
) -> dict:
    """Plain-number report of a rollout (JSON-serialisable: floats, ints, strings, lists).

    Args:
      result: the output of ``simulate``.
      lengths: (B,) valid frames per motion, as given to ``simulate``.
      targets: (B, T, 26) the targets given to ``simulate``, rad.

    Returns:
      dict with (over valid frames only; tracking over ``robot.DRIVEN_JOINTS``):

      * ``motions``, ``frames``: B and the number of valid frames;
      * ``tracking_error_deg``: ``mean``, ``p95``, ``max`` of |achieved - target| at frame ends
        (all driven joints of all valid frames pooled), and ``per_joint_p95`` (name -> deg);
      * ``self_collision_frames``: frames with self-contact per group (``arm_torso``,
        ``arm_head``, ``arm_arm``), ``any`` (a frame counted once), ``motions`` with any,
        and ``max_penetration_mm``;
      * ``joint_limit_violations``: ``achieved_frames`` / ``target_frames``, frames where some
        joint is more than ``LIMIT_TOLERANCE`` outside [LOWER, UPPER] in the simulation / in the
        targets themselves, and ``achieved_max_excess_deg``;
      * ``speed``: ``max_ratio`` of peak |qvel| to ``VELOCITY_LIMITS`` (over all joints and
        motions), ``worst_joint``, ``joints_over_limit`` ((motion, joint) pairs with ratio > 1),
        ``motions_over_limit``.
    """
    qpos = np.asarray(result.qpos, dtype=np.float64)
    n_b, n_t = qpos.shape[:2]
    n = np.asarray(lengths).astype(np.int64).reshape(-1)
    tgt = np.asarray(targets, dtype=np.float64)
    if n.shape != (n_b,) or tgt.shape != qpos.shape:
        raise ConfigError(f"lengths {n.shape} / targets {tgt.shape} do not match the result "
                          f"{qpos.shape}")  # fmt: skip
    valid = np.arange(n_t)[None, :] < n[:, None]  # (B, T)

    drv = robot.DRIVEN_INDEX
    err = np.degrees(np.abs(qpos[..., drv] - tgt[..., drv]))[valid]  # (F, 10)
    tracking = {
        "mean": float(err.mean()),
        "p95": float(np.percentile(err, 95)),
        "max": float(err.max()),
        "per_joint_p95": {
            name: float(v)
            for name, v in zip(robot.DRIVEN_JOINTS, np.percentile(err, 95, axis=0), strict=True)
        },
    }

    contact = np.asarray(result.contact, dtype=bool) & valid[..., None]  # (B, T, 3)
    depth = np.where(valid, np.asarray(result.penetration, dtype=np.float64), 0.0)
    collisions: dict[str, int | float] = {
        g: int(contact[..., i].sum()) for i, g in enumerate(CONTACT_GROUPS)
    }
    collisions["any"] = int(contact.any(axis=-1).sum())
    collisions["motions"] = int(contact.any(axis=(1, 2)).sum())
    collisions["max_penetration_mm"] = float(1000.0 * depth.max())

    lo = robot.LOWER.astype(np.float64)
    hi = robot.UPPER.astype(np.float64)

    def excess(q: np.ndarray) -> np.ndarray:
        return np.maximum(np.maximum(lo - q, q - hi), 0.0)  # (..., 26)

    ach = excess(qpos)
    limits = {
        "achieved_frames": int(((ach > LIMIT_TOLERANCE).any(axis=-1) & valid).sum()),
        "target_frames": int(((excess(tgt) > LIMIT_TOLERANCE).any(axis=-1) & valid).sum()),
        "achieved_max_excess_deg": float(np.degrees(ach[valid].max())),
    }

    ratio = np.asarray(result.max_speed, dtype=np.float64) / robot.VELOCITY_LIMITS  # (B, 26)
    worst = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    speed = {
        "max_ratio": float(ratio.max()),
        "worst_joint": robot.JOINT_NAMES[int(worst[1])],
        "joints_over_limit": int((ratio > 1.0).sum()),
        "motions_over_limit": int((ratio > 1.0).any(axis=1).sum()),
    }
    return {
        "motions": int(n_b),
        "frames": int(valid.sum()),
        "tracking_error_deg": tracking,
        "self_collision_frames": collisions,
        "joint_limit_violations": limits,
        "speed": speed,
    }
