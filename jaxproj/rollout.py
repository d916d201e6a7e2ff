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

from jaxproj import robot
from jaxproj._jit import jit
from jaxproj.exceptions import ConfigError

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

    def __post_init__(self) -> None:
        if not (np.isfinite(self.frame_dt) and self.frame_dt > 0):
            raise ConfigError(f"frame_dt must be a positive number of seconds, got {self.frame_dt}")
        if not (np.isfinite(self.kp_scale) and self.kp_scale > 0):
            raise ConfigError(f"kp_scale must be positive, got {self.kp_scale}")
        if not isinstance(self.contact_friction, bool):
            raise ConfigError(f"contact_friction must be a bool, got {self.contact_friction!r}")
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
    """Device-side model and index tables for one config (all pytrees of arrays)."""

    mx: mjx.Model
    d0: mjx.Data
    qidx: jax.Array  # (26,) qpos address of each joint
    didx: jax.Array  # (26,) dof address of each joint
    act_src: jax.Array  # (nu,) index into JOINT_NAMES of the joint each actuator drives
    ctrl_lo: jax.Array  # (nu,)
    ctrl_hi: jax.Array  # (nu,)
    q_lo: jax.Array  # (26,) joint range, for the initial pose
    q_hi: jax.Array  # (26,)
    pair_group: jax.Array  # (ngeom, ngeom) int32: index into CONTACT_GROUPS, -1 not reported
    force_limited: jax.Array  # (nu,) bool actuator_forcelimited


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
    """(nu,) index into JOINT_NAMES of the joint each actuator drives (RHipYawPitch: none)."""
    act = robot.actuator_index(model)
    src = np.full(model.nu, -1, dtype=np.int64)
    for i, a in enumerate(act):
        if robot.JOINT_NAMES[i] != robot.COUPLED_JOINTS[1]:
            src[a] = i
    if np.any(src < 0):
        raise ConfigError("some actuator of the model drives none of JOINT_NAMES")
    return src


def _fixed_model(config: RolloutConfig) -> mujoco.MjModel:
    """The fixed-torso MjModel with the config's gains and gravity applied."""
    model = robot.load_model("fixed")
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
def _setup(config: RolloutConfig) -> tuple[_Setup, int]:
    """Model on device + index tables for ``config``, and the physics steps per frame."""
    model = _fixed_model(config)
    substeps = _substeps(config, float(model.opt.timestep))
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_IMPLICITFAST:
        raise ConfigError("the rollout step assumes the implicitfast integrator of the MJCF")
    if np.any(model.actuator_gaintype != mujoco.mjtGain.mjGAIN_FIXED) or np.any(
        model.actuator_biastype != mujoco.mjtBias.mjBIAS_AFFINE
    ):
        raise ConfigError("the rollout step assumes position actuators (fixed gain, affine bias)")
    mx = mjx.put_model(model, impl="jax")
    d0 = mjx.make_data(mx, impl="jax")
    jids = [model.joint(n).id for n in robot.JOINT_NAMES]
    src = _actuated_joint(model)
    setup = _Setup(
        mx=mx,
        d0=d0,
        qidx=jnp.asarray(robot.joint_qpos_index(model), dtype=jnp.int32),
        didx=jnp.asarray(robot.joint_dof_index(model), dtype=jnp.int32),
        act_src=jnp.asarray(src, dtype=jnp.int32),
        ctrl_lo=jnp.asarray(model.actuator_ctrlrange[:, 0], dtype=jnp.float32),
        ctrl_hi=jnp.asarray(model.actuator_ctrlrange[:, 1], dtype=jnp.float32),
        q_lo=jnp.asarray(model.jnt_range[jids, 0], dtype=jnp.float32),
        q_hi=jnp.asarray(model.jnt_range[jids, 1], dtype=jnp.float32),
        pair_group=jnp.asarray(_pair_group(model)),
        force_limited=jnp.asarray(model.actuator_forcelimited, dtype=bool),
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


def _rollout_one(
    s: _Setup, targets: jax.Array, length: jax.Array, substeps: int
) -> tuple[jax.Array, ...]:
    """One motion: targets (T, 26), length () int -> per-frame records and statistics."""
    n_frames = targets.shape[0]
    valid = jnp.arange(n_frames, dtype=jnp.int32) < length  # (T,)
    last = jnp.clip(length - 1, 0, n_frames - 1)
    held = jnp.where(valid[:, None], targets, targets[last][None, :])

    lhyp = robot.IDX[robot.COUPLED_JOINTS[0]]
    rhyp = robot.IDX[robot.COUPLED_JOINTS[1]]
    q0 = held[0].at[rhyp].set(held[0, lhyp])
    q0 = jnp.clip(q0, s.q_lo, s.q_hi)
    d = s.d0.replace(
        qpos=s.d0.qpos.at[s.qidx].set(q0.astype(s.d0.qpos.dtype)),
        qvel=jnp.zeros_like(s.d0.qvel),
        ctrl=jnp.clip(held[0][s.act_src], s.ctrl_lo, s.ctrl_hi).astype(s.d0.ctrl.dtype),
    )
    n_groups = len(CONTACT_GROUPS)

    def substep(carry, _):
        d, vpeak, hit, depth = carry
        d = _mjx_step(s, d)
        h, p = _self_contact(s, d)
        vpeak = jnp.maximum(vpeak, jnp.abs(d.qvel[s.didx]))
        return (d, vpeak, hit | h, jnp.maximum(depth, p)), None

    def frame(carry, xs):
        d, vmax = carry
        target, ok = xs
        ctrl = jnp.clip(target[s.act_src], s.ctrl_lo, s.ctrl_hi).astype(d.ctrl.dtype)
        init = (
            d.replace(ctrl=ctrl),
            jnp.zeros(robot.N_JOINTS, jnp.float32),
            jnp.zeros(n_groups, dtype=bool),
            jnp.zeros((), jnp.float32),
        )
        (d, vpeak, hit, depth), _ = jax.lax.scan(substep, init, None, length=substeps)
        vmax = jnp.where(ok, jnp.maximum(vmax, vpeak), vmax)
        rec = (d.qpos[s.qidx], d.qvel[s.didx], hit & ok, jnp.where(ok, depth, jnp.float32(0.0)))
        return (d, vmax), rec

    init = (d, jnp.zeros(robot.N_JOINTS, jnp.float32))
    (_, vmax), (qpos, qvel, contact, depth) = jax.lax.scan(frame, init, (held, valid))

    n_valid = jnp.maximum(jnp.sum(valid.astype(jnp.float32)), jnp.float32(1.0))
    err = jnp.where(valid[:, None], qpos - held, jnp.float32(0.0))
    rms = jnp.sqrt(jnp.sum(err * err, axis=0) / n_valid)
    frames = jnp.sum(contact.astype(jnp.int32), axis=0)
    return qpos, qvel, contact, depth, vmax, frames, rms


@jit(static_argnames=("substeps",), precision=None)  # MJX keeps its own defaults
def _simulate_jit(
    s: _Setup, targets: jax.Array, lengths: jax.Array, substeps: int
) -> RolloutResult:
    out = jax.vmap(_rollout_one, in_axes=(None, 0, 0, None))(s, targets, lengths, substeps)
    return RolloutResult(*out)


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
    setup, substeps = _setup(config)
    devices = None if devices is None else list(devices)
    if not devices or len(devices) == 1:
        dev = devices[0] if devices else None
        if dev is not None:
            setup = jax.device_put(setup, dev)
        return _simulate_jit(setup, jax.device_put(q, dev), jax.device_put(n, dev), substeps)
    if len(set(devices)) != len(devices):
        raise ConfigError(f"devices lists a device twice: {[str(d) for d in devices]}")
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
