"""Physics check of retargeted motions: batched MuJoCo rollouts of a robot.

Three backends behind ``simulate(backend=)``: MuJoCo MJX (jitted, vmapped, on any JAX device;
the default on accelerators other than a CUDA GPU with warp-lang), CPU MuJoCo (the C library,
a host thread per motion; the default on a CPU-only machine, where MJX would spend tens of
seconds compiling each batch shape) and MJX's Warp implementation (``backend="warp"``: MuJoCo
Warp's kernels on one CUDA GPU, the optional ``warp`` extra; the default there). Five modules:
this one (``simulate``, ``hand_error_cm``, ``summarize``: the public entry points),
``rollout_model`` (``RolloutConfig``, ``RolloutResult``, the per-part models and index tables),
``rollout_physics`` (the MJX step and the jitted batched rollouts), ``rollout_cpu`` (the CPU
MuJoCo backend) and ``rollout_warp`` (the Warp backend).
Every entry point takes ``robot=``: a ``Robot`` (``jaxproj.robots``; its ``mjcf``) or a
registered name, ``None`` the default robot (``robots.get()``).

A retargeted motion is a ``(T, n_joints)`` joint-angle trajectory (rad, ``robot.joint_names`` order)
sampled at the Kinect rate. ``simulate`` plays a padded batch of them on the robot's MJCF with the
torso welded to the world (``robot.load_model("fixed")``), gravity on, through the position servos
(the default robot's: 25), and records what the robot actually does; ``summarize`` turns that into
plain numbers (tracking error, self-collisions, joint limits, joint speeds) for reports.

Protocol, for one motion (``lax.scan`` over frames, an inner ``lax.scan`` over physics steps):

* start at rest at the first target frame (``qpos`` = frame 0 clipped to the joint ranges,
  each coupled follower at its leader, ``robot.coupled_joints``; ``qvel`` = 0);
* frame ``t`` lasts ``substeps = round(frame_dt / timestep)`` physics steps (33 at 15
  frames/s and dt = 2 ms); at its step ``k`` (``1 .. substeps``) ``ctrl`` = ``c[t-1] + (c[t] -
  c[t-1]) * k / substeps``, where ``c[t]`` is frame ``t`` clipped to the actuator ``ctrlrange``
  and ``c[-1] = c[0]`` (``RolloutConfig.interpolate``, the default: a first-order hold, as
  the default robot's software (``angleInterpolation``) plays a trajectory; ``interpolate=False``:
  ``c[t]`` on every step, the zero-order hold). A coupled follower has no actuator: it follows its
  leader through the joint equality;
* at the end of frame ``t`` (time ``(t + 1) * frame_dt``) record the joint angles and speeds;
  the tracking error of frame ``t`` is ``|qpos[t] - target[t]|``, i.e. the servos get one frame
  to reach each new target (with the ramp: the frame's target is reached by the command only at
  its last step);
* self-contact: a frame "has" contact of a group when the collision detection of any of its
  physics steps finds a penetrating pair (``dist < margin``, MuJoCo's own inclusion rule; the
  margins are 0) of that group: arm-torso, arm-head, arm-arm (leg contacts are not reported);
* peak joint speed: max |qvel| over every physics step of the valid frames.

Two models (``RolloutConfig.split_legs``, the default, for a robot with ``mjcf.split``): with the
torso welded, the head and arms and the legs share no degree of freedom, so they run as two MJX
models — the legs once per
distinct leg motion of the batch — after a per-batch certificate that no leg geom reaches the
head (the only contact pair across the parts); otherwise, or with ``split_legs=False``, the
whole model runs. The answers equal the whole model's to the constraint solver's
tolerance (``benchmarks/RESULTS.md``); a step costs about a third.

Padding: a batch is ``(B, T, n_joints)`` with ``lengths (B,)``. Frames ``t >= lengths[b]`` hold the
motion's last valid frame (whatever the padding contains, even NaN, never reaches the physics)
and are left out of every statistic of ``RolloutResult`` and ``summarize``; their ``qpos`` /
``qvel`` rows are still filled (the robot keeps holding the last pose) but mean nothing.

Strict promotion: the tests (``tests/conftest.py``) trace everything under strict dtype / rank
promotion. MJX 3.17's own code relies on implicit promotion in two of the calls made here:
``mjx.forward`` broadcasts rank-mismatched operands (``smooth.py``: a (3, 3) matrix times a (3,)
vector) and mixes float32 with bool (``support.py``), ``mjx.implicit`` mixes float32 with bool
(``derivative.py``). Only those two calls are traced inside ``_mjx_defaults``
(``rollout_physics``; JAX's default
``"standard"`` dtype / ``"allow"`` rank promotion); ``mjx.kinematics`` is strict-clean and runs
in the caller's mode, and so does all of this module's own code.

Importing ``mujoco.mjx`` logs "Failed to import warp" where warp-lang is absent: harmless, the
JAX implementation of MJX is used explicitly (``impl="jax"``, on CPU and GPU alike) unless
``backend="warp"`` is asked for.
"""

from __future__ import annotations

import concurrent.futures
import functools
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.eval.rollout_cpu import simulate_mujoco
from jaxproj.eval.rollout_model import (
    CONTACT_GROUPS,
    RolloutConfig,
    RolloutResult,
    _check_config,
    _Setup,
    _setup,
)
from jaxproj.eval.rollout_model import (
    _fixed_model as _fixed_model,
)
from jaxproj.eval.rollout_model import (
    _head_ball as _head_ball,
)
from jaxproj.eval.rollout_model import (
    _leg_motions as _leg_motions,
)
from jaxproj.eval.rollout_physics import _legs_jit, _merge_jit, _simulate_jit
from jaxproj.eval.rollout_warp import simulate_warp, warp_usable
from jaxproj.robots import Robot
from jaxproj.robots import get as get_robot
from jaxproj.robots.base import joint_qpos_index

__all__ = ["BACKENDS", "CONTACT_GROUPS", "LIMIT_TOLERANCE", "RolloutConfig",
           "RolloutResult", "hand_error_cm", "resolve_backend", "simulate",
           "summarize"]  # fmt: skip
# (``_setup``, ``_fixed_model``, ``_head_ball``, ``_leg_motions`` are re-exported for the tests.)

_DEFAULT_CONFIG = RolloutConfig()

LIMIT_TOLERANCE = 1e-3
"""rad: a joint counts as outside its range when it is more than this beyond lower / upper."""


def _as_batch(
    targets: object, lengths: object | None, robot: Robot
) -> tuple[np.ndarray, np.ndarray]:
    q = np.asarray(targets, dtype=np.float32)
    if q.ndim != 3 or q.shape[-1] != robot.n_joints or q.shape[0] < 1 or q.shape[1] < 1:
        raise ConfigError(f"targets must have shape (B, T, {robot.n_joints}) with B, T >= 1, got "
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
    config: RolloutConfig = _DEFAULT_CONFIG,
    devices: Sequence[jax.Device] | None = None,
    *,
    robot: Robot | str | None = None,
    backend: str = "auto",
    threads: int | None = None,
) -> RolloutResult:
    """Play a padded batch of joint-angle motions on the simulated robot (MJX or CPU MuJoCo).

    Args:
      targets: (B, T, n_joints) target joint angles per frame, ``robot.joint_names`` order, rad.
      lengths: (B,) int valid frames per motion, in [1, T] (None: all T). Frames past a
        motion's length may hold anything (even NaN): they are replaced by the last valid frame
        and excluded from every statistic.
      config: frame period, gain scale, gravity (static: one compile per config, B and T).
      devices: ``None`` (default device) or several: the motions are split into one
        contiguous share per device and each device runs the one-device program on its share
        (one host thread per device, so they run at the same time; the model copied to each;
        no collective); the results are concatenated on the first device. Not ``shard_map``:
        XLA's GPU partitioner (Shardy, jax 0.11.2) segfaults on any zero-sized array in a
        ``shard_map`` program, and an MJX model holds some (measured on two H200s; with the
        older partitioner it compiles); the one-device program is the one every single-GPU
        rollout already runs.
      robot: the robot (a ``Robot`` or a registered name; ``None``: the default robot); it
        needs an MJCF (and ``mjcf.split`` for ``split_legs``; without it the whole model runs).
      backend: ``"mjx"`` (MuJoCo MJX: jitted, vmapped, on JAX devices), ``"mujoco"`` (CPU
        MuJoCo, the C library in float64, one host thread per motion, ``rollout_cpu``; no
        compile; ``devices`` must be None), ``"warp"`` (MJX's Warp implementation: MuJoCo
        Warp's kernels on one CUDA GPU, ``rollout_warp``; needs the ``warp`` extra, ``pip
        install "jaxproj[warp]"``) or ``"auto"`` (default): ``"mujoco"`` when no ``devices``
        are given and JAX's default backend is the CPU; else ``"warp"`` where it can run (the
        default device or the one device given is a CUDA GPU, warp-lang imports and the robot's
        Warp rollout was validated against C MuJoCo, ``Mjcf.warp_validated``); else
        ``"mjx"``. All follow the same protocol. Contact-free motions agree with C MuJoCo to
        float32 round-off on every backend; in self-contact Warp stayed within 6.4e-5 rad of
        C MuJoCo over 206 random motions, where MJX-JAX's own constraint solver parted from
        it by up to 0.14 rad (``docs/results.md``).
      threads: ``"mujoco"`` only: motions stepped at a time (default: the CPU count).

    Returns:
      ``RolloutResult`` of device arrays (see its docstring for shapes).

    Raises:
      ConfigError: bad shapes, lengths out of range, non-finite valid frames, bad config;
        ``backend="warp"`` without warp-lang or a CUDA GPU.
    """
    _check_config(config)
    robot = get_robot(robot)
    q, n = _as_batch(targets, lengths, robot)
    devices = None if devices is None else list(devices)
    if devices and len(set(devices)) != len(devices):
        raise ConfigError(f"devices lists a device twice: {[str(d) for d in devices]}")
    chosen = resolve_backend(backend, devices, robot)
    if chosen == "mujoco":
        if devices is not None:
            raise ConfigError("backend='mujoco' runs on the host's threads: devices must be None")
        return simulate_mujoco(q, n, config, robot, threads)
    if chosen == "warp":
        return simulate_warp(q, n, config, robot, devices)
    if config.split_legs and robot.require_mjcf().split:
        result = _simulate_split(q, n, config, devices, robot)
        if result is not None:
            return result
    setup, substeps = _setup(config, "whole", robot)
    return _run_shares(setup, q, n, substeps, devices)


BACKENDS: tuple[str, ...] = ("auto", "mjx", "mujoco", "warp")
"""``simulate``'s backends (see its docstring)."""


def resolve_backend(
    backend: str,
    devices: Sequence[jax.Device] | None = None,
    robot: Robot | str | None = None,
) -> str:
    """``"mjx"``, ``"mujoco"`` or ``"warp"``: the backend ``simulate(backend=..., devices=...,
    robot=...)`` runs (``"auto"``: see ``simulate``; Warp only for a robot whose
    ``Mjcf.warp_validated``).

    Raises:
      ConfigError: an unknown backend.
    """
    if backend not in BACKENDS:
        raise ConfigError(f"unknown rollout backend {backend!r}; use one of {BACKENDS}")
    if backend != "auto":
        return backend
    if not devices and jax.default_backend() == "cpu":
        return "mujoco"
    mj = get_robot(robot).mjcf
    validated = mj is not None and mj.warp_validated
    return "warp" if validated and warp_usable(devices) else "mjx"


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
    shares = [
        (d, lo, hi) for d, lo, hi in zip(devices, bounds[:-1], bounds[1:], strict=True) if hi > lo
    ]  # fmt: skip  (more devices than motions: the extra ones get none)

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


def _simulate_split(
    q: np.ndarray, n: np.ndarray, config: RolloutConfig, devices: list | None, robot: Robot
) -> RolloutResult | None:
    """``simulate`` as two parts (``RolloutConfig.split_legs``); None when a leg motion comes
    within the head's reach (the caller then runs the whole model)."""
    legs, substeps = _setup(config, "legs", robot)
    upper, _ = _setup(config, "upper", robot)
    home = devices[0] if devices else None
    leg_joints = np.asarray(legs.joints)
    rows, inverse = _leg_motions(q, n, leg_joints)
    leg_targets = np.tile(robot.standing, (*rows.shape[:2], 1))
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


@functools.lru_cache(maxsize=4)
def _kin_setup(robot: Robot) -> tuple[mjx.Model, mjx.Data, jax.Array, jax.Array]:
    model = robot.load_model("fixed")  # torso welded at the origin: world frame = torso frame
    mx = mjx.put_model(model, impl="jax")
    d0 = mjx.make_data(mx, impl="jax")
    sids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, n)
            for n in robot.require_mjcf().hand_sites]  # fmt: skip
    qidx = jnp.asarray(joint_qpos_index(model, robot.joint_names), dtype=jnp.int32)
    return mx, d0, qidx, jnp.asarray(sids, dtype=jnp.int32)


@jit(static_argnames=("coupled",), precision=None)
def _hand_error_jit(
    mx: mjx.Model,
    d0: mjx.Data,
    qidx: jax.Array,
    sids: jax.Array,
    qa: jax.Array,
    qb: jax.Array,
    coupled: tuple[tuple[int, int], ...],
) -> jax.Array:
    """``coupled``: (leader, follower) joint indices; the follower takes the leader's angle."""

    def sites(q: jax.Array) -> jax.Array:
        for lead, follower in coupled:
            q = q.at[follower].set(q[lead])
        d = d0.replace(qpos=d0.qpos.at[qidx].set(q.astype(d0.qpos.dtype)))
        d = mjx.kinematics(mx, d)  # strict-clean in MJX 3.17: runs in the caller's mode
        return d.site_xpos[sids]  # (2, 3)

    pos = jax.vmap(sites)(jnp.concatenate([qa, qb]))  # one batched FK for both: (2N, 2, 3)
    n = qa.shape[0]
    return jnp.float32(100.0) * jnp.linalg.norm(pos[:n] - pos[n:], axis=-1)


def hand_error_cm(
    angles_a: np.ndarray | jax.Array,
    angles_b: np.ndarray | jax.Array,
    *,
    robot: Robot | str | None = None,
) -> jax.Array:
    """Distance between the hand sites of two configurations, with MJX kinematics (jitted).

    Args:
      angles_a: (N, n_joints) joint angles, ``robot.joint_names`` order, rad.
      angles_b: (N, n_joints) joint angles, same order.
      robot: the robot (a ``Robot`` or a registered name; ``None``: the default robot); its
        ``mjcf.hand_sites`` are compared.

    Returns:
      (N, n_hands) float32 distances in cm between the hand sites (``robot.mjcf.hand_sites``;
      the default robot's: ``l_hand``, ``r_hand``) of ``angles_a[i]`` and ``angles_b[i]`` (torso
      frame; each coupled follower joint takes its leader's angle, ``robot.coupled_joints``). One
      compile per N.

    Raises:
      ConfigError: the shapes differ or are not (N, n_joints).
    """
    robot = get_robot(robot)
    qa = jnp.asarray(angles_a, dtype=jnp.float32)
    qb = jnp.asarray(angles_b, dtype=jnp.float32)
    if qa.ndim != 2 or qa.shape[-1] != robot.n_joints or qa.shape != qb.shape:
        raise ConfigError(f"angles must both have shape (N, {robot.n_joints}), got {qa.shape} and "
                          f"{qb.shape}")  # fmt: skip
    mx, d0, qidx, sids = _kin_setup(robot)
    coupled = tuple((robot.index(a), robot.index(b)) for a, b in robot.coupled_joints)
    return _hand_error_jit(mx, d0, qidx, sids, qa, qb, coupled=coupled)


# --- summary ----------------------------------------------------------------------------------


def summarize(
    result: RolloutResult,
    lengths: np.ndarray | jax.Array,
    targets: np.ndarray | jax.Array,
    *,
    robot: Robot | str | None = None,
) -> dict:
    """Plain-number report of a rollout (JSON-serialisable: floats, ints, strings, lists).

    Args:
      result: the output of ``simulate``.
      lengths: (B,) valid frames per motion, as given to ``simulate``.
      targets: (B, T, n_joints) the targets given to ``simulate``, rad.
      robot: the robot simulated (a ``Robot`` or a registered name; ``None``: the default
        robot); it needs ``velocity_limits``.

    Returns:
      dict with (over valid frames only; tracking over ``robot.driven_joints``):

      * ``motions``, ``frames``: B and the number of valid frames;
      * ``tracking_error_deg``: ``mean``, ``p95``, ``max`` of |achieved - target| at frame ends
        (all driven joints of all valid frames pooled), and ``per_joint_p95`` (name -> deg);
      * ``self_collision_frames``: frames with self-contact per group (``arm_torso``,
        ``arm_head``, ``arm_arm``: the groups found from the robot's kinematic tree,
        ``rollout_model._geom_classes``), ``any`` (a frame counted once), ``motions`` with any,
        and ``max_penetration_mm``;
      * ``joint_limit_violations``: ``achieved_frames`` / ``target_frames``, frames where some
        joint is more than ``LIMIT_TOLERANCE`` outside [lower, upper] in the simulation / in the
        targets themselves, and ``achieved_max_excess_deg``;
      * ``speed``: ``max_ratio`` of peak |qvel| to ``velocity_limits`` (over all joints and
        motions), ``worst_joint``, ``joints_over_limit`` ((motion, joint) pairs with ratio > 1),
        ``motions_over_limit``.

    Raises:
      ConfigError: shapes not matching the result; a robot without velocity limits.
    """
    robot = get_robot(robot)
    if robot.velocity_limits is None:
        raise ConfigError(f"summarize needs the velocity limits of robot {robot.name!r}")
    qpos = np.asarray(result.qpos, dtype=np.float64)
    n_b, n_t = qpos.shape[:2]
    n = np.asarray(lengths).astype(np.int64).reshape(-1)
    tgt = np.asarray(targets, dtype=np.float64)
    if n.shape != (n_b,) or tgt.shape != qpos.shape:
        raise ConfigError(f"lengths {n.shape} / targets {tgt.shape} do not match the result "
                          f"{qpos.shape}")  # fmt: skip
    valid = np.arange(n_t)[None, :] < n[:, None]  # (B, T)

    drv = robot.driven_index
    err = np.degrees(np.abs(qpos[..., drv] - tgt[..., drv]))[valid]  # (F, n_driven)
    tracking = {
        "mean": float(err.mean()),
        "p95": float(np.percentile(err, 95)),
        "max": float(err.max()),
        "per_joint_p95": {
            name: float(v)
            for name, v in zip(robot.driven_joints, np.percentile(err, 95, axis=0), strict=True)
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

    lo = robot.lower.astype(np.float64)
    hi = robot.upper.astype(np.float64)

    def excess(q: np.ndarray) -> np.ndarray:
        return np.maximum(np.maximum(lo - q, q - hi), 0.0)  # (..., n_joints)

    ach = excess(qpos)
    limits = {
        "achieved_frames": int(((ach > LIMIT_TOLERANCE).any(axis=-1) & valid).sum()),
        "target_frames": int(((excess(tgt) > LIMIT_TOLERANCE).any(axis=-1) & valid).sum()),
        "achieved_max_excess_deg": float(np.degrees(ach[valid].max())),
    }

    ratio = np.asarray(result.max_speed, dtype=np.float64) / robot.velocity_limits  # (B, n_joints)
    worst = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    speed = {
        "max_ratio": float(ratio.max()),
        "worst_joint": robot.joint_names[int(worst[1])],
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
