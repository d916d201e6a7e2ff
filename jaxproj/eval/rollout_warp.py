"""The rollout on MJX's Warp implementation: ``simulate(..., backend="warp")``.

Part of ``jaxproj.eval.rollout`` (see its docstring for the protocol). MuJoCo MJX 3.17 vendors
MuJoCo Warp (NVIDIA Warp kernels called from JAX through XLA's FFI); it runs when
``warp-lang`` is installed (the optional extra: ``pip install "jaxproj[warp]"``) on a CUDA GPU.
The protocol, the ``RolloutResult``, the padding, the contact groups and the split into
head-and-arms and legs (``RolloutConfig.split_legs``) are the MJX backend's; what differs:

* **The step is one call**, ``mjx.step`` of the Warp model: MuJoCo Warp's implicitfast
  integrator already leaves the velocity gain of a force-clamped servo out of the implicit
  damping (``derivative.py``: "skip if force is clamped by forcerange"), as C MuJoCo does, so
  the servo-damping fix the JAX implementation needs (``rollout_physics._mjx_step``) is MuJoCo
  Warp's own behaviour here; nothing is patched.
* **Batched explicitly, not with ``vmap``**: MuJoCo Warp keeps the contacts of every world in
  one pool (``naconmax`` slots, each tagged with its world), so the frame and physics-step
  scans run over the whole batch, the step is called on batched ``Data`` (MJX's Warp call takes
  a leading world axis as it is) and each step's self-contacts are scattered to their motions.
  The pool holds as many slots per motion as MJX-JAX's fixed contact list (one per candidate
  contact point: the default robot's head-and-arms 27, the whole robot 53) and each world as many
  constraint rows (122 / 239), far more than the arms can touch at once; should MuJoCo Warp
  still drop a contact or constraint (its ``Data.overflow`` bits), ``simulate`` raises.
* **The solver caps** are the config's (``RolloutConfig.solver_iterations`` /
  ``ls_iterations``, 8 / 4), as for the other backends. MuJoCo Warp's line search is its own,
  and a plain ``mjx.step`` probe of the default robot once warned that it hit 4 iterations; in the
  rollout protocol no motion did (256 random motions, every step: MuJoCo Warp records it in
  ``Data.overflow``, whose printed warnings are turned off here), and caps of 8 and 16 gave
  the same largest errors at the same speed (``docs/results.md``).
* One device: ``devices`` is ``None`` or a single CUDA device.

Validated against C MuJoCo in ``tests/eval/test_rollout.py`` (run where a CUDA GPU and
warp-lang are present; CPU CI skips it) and ``benchmarks/bench_rollout.py --backend warp``;
the numbers are on the results page (``docs/results.md``).
"""

from __future__ import annotations

import functools
import importlib.util
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError, JaxprojError
from jaxproj.eval.rollout_model import (
    CONTACT_GROUPS,
    RolloutConfig,
    RolloutResult,
    _leg_motions,
    _Setup,
    _setup,
    _tables,
)
from jaxproj.eval.rollout_physics import (
    _held,
    _LegRollout,
    _merge_jit,
    _mjx_defaults,
    _motion_stats,
)
from jaxproj.robots import Robot

WARP_EXTRA = 'pip install "jaxproj[warp]"'
"""How to install what the Warp backend needs (warp-lang, the version mujoco-mjx pins)."""

# MuJoCo Warp's OverflowType bits in Data.overflow: a capacity overflow drops constraints or
# contacts (nefc > njmax, njmax_nnz, broadphase, narrowphase); the solver's iteration caps
# being reached (ITERATIONS, LS_ITERATIONS) is the capped solver working as configured
OVERFLOW_CAPACITY = (1 << 0) | (1 << 1) | (1 << 2) | (1 << 3)
OVERFLOW_ITERATIONS = 1 << 9
OVERFLOW_LS_ITERATIONS = 1 << 10


def _warp_installed() -> bool:
    """warp-lang importable (checked without importing it: cheap where it is absent)."""
    return importlib.util.find_spec("warp") is not None


def warp_usable(devices: Sequence[jax.Device] | None = None) -> bool:
    """Whether ``backend="warp"`` can run on ``devices`` (None: JAX's default device): warp-lang
    imports and the device is a CUDA GPU (one device). Cheap: nothing is compiled or put."""
    if not _warp_installed():
        return False
    from mujoco.mjx import warp as mjx_warp  # noqa: PLC0415  (imported with mujoco.mjx)

    if not mjx_warp.WARP_INSTALLED:
        return False
    try:
        cuda = jax.devices("cuda")
    except RuntimeError:
        return False
    if devices:
        return len(devices) == 1 and devices[0] in cuda
    return jax.default_backend() == "gpu" and jax.devices()[0] in cuda


def check_warp(devices: list | None) -> jax.Device:
    """The CUDA device the Warp backend runs on; ConfigError when it cannot run here."""
    if not _warp_installed():
        raise ConfigError(f"backend='warp' needs warp-lang, MJX's Warp implementation: "
                          f"{WARP_EXTRA} (CUDA GPUs only)")  # fmt: skip
    from mujoco.mjx import warp as mjx_warp  # noqa: PLC0415  (prints "Failed to import warp")

    if not mjx_warp.WARP_INSTALLED:
        raise ConfigError(f"backend='warp': warp-lang is installed but does not import; "
                          f"reinstall it with {WARP_EXTRA}")  # fmt: skip
    try:
        cuda = jax.devices("cuda")
    except RuntimeError:
        cuda = []
    if not cuda:
        raise ConfigError("backend='warp' needs a CUDA GPU visible to JAX (jax.devices('cuda') "
                          "is empty); use backend='mjx' or 'mujoco' elsewhere")  # fmt: skip
    if devices is None:
        return cuda[0]
    if len(devices) != 1 or devices[0] not in cuda:
        names = [str(d) for d in devices]
        raise ConfigError(f"backend='warp' runs on one CUDA device; got {names}")
    return devices[0]


def _batch_dim(path: tuple) -> bool:
    """Whether a field of MJX's Warp ``Data`` has a per-world axis (else: the contact pool and
    its counters, shared by all worlds)."""
    from mujoco.mjx._src.types import tree_path_to_attr_str  # noqa: PLC0415
    from mujoco.mjx.warp import types as mjx_warp_types  # noqa: PLC0415

    table: dict[str, Any] = mjx_warp_types._BATCH_DIM["Data"]
    return bool(table.get(tree_path_to_attr_str(path), True))


def _batched(d0: mjx.Data, n_b: int) -> mjx.Data:
    """``d0`` with every per-world field broadcast to a leading axis of ``n_b`` worlds."""
    return jax.tree_util.tree_map_with_path(
        lambda p, x: jnp.broadcast_to(x, (n_b, *x.shape)) if _batch_dim(p) else x, d0
    )


@functools.lru_cache(maxsize=8)
def _setup_warp(
    config: RolloutConfig, part: str, robot: Robot, n_b: int, device: jax.Device
) -> tuple[_Setup, int]:
    """``rollout_model._setup`` for Warp: the model put by MJX's Warp implementation and its
    ``Data`` sized for ``n_b`` worlds (the contact pool is shared by the batch)."""
    jax_setup, substeps = _setup(config, part, robot)  # its index tables are the backend's
    # per world: as many contact slots and constraint rows as MJX-JAX's fixed-size lists (one
    # slot per candidate contact point): an upper bound on what any state of the model needs
    slots = int(jax_setup.d0._impl.contact.dist.shape[0])
    rows = int(jax_setup.d0._impl.efc_J.shape[0])
    model = _tables(config, part, robot).model  # not modified: put_model copies it
    mx = mjx.put_model(model, device=device, impl="warp")
    opt_impl = mx.opt._impl.replace(warn_overflow=0)  # counted in Data.overflow instead
    mx = mx.replace(opt=mx.opt.replace(_impl=opt_impl))
    d0 = mjx.make_data(model, device=device, impl="warp", naconmax=max(slots * n_b, 1),
                       njmax=max(rows, 1))  # fmt: skip
    setup = jax.device_put(jax_setup, device)._replace(mx=mx, d0=d0)
    return setup, substeps


def _self_contact(s: _Setup, d: mjx.Data, n_b: int) -> tuple[jax.Array, jax.Array]:
    """(B, 3) bool penetrating self-contact per group and (B,) deepest penetration (m, >= 0)
    of one step, from MuJoCo Warp's contact pool: slots below ``nacon`` are this step's
    contacts, each of world ``worldid``; an actual contact has ``dist < includemargin``."""
    impl = d._impl
    dist = impl.contact__dist  # (naconmax,)
    none = (jnp.zeros((n_b, len(CONTACT_GROUPS)), bool), jnp.zeros(n_b, jnp.float32))
    if dist.shape[0] == 0:
        return none
    geom = impl.contact__geom  # (naconmax, 2)
    g = jnp.maximum(geom, 0)
    group = s.pair_group[g[:, 0], g[:, 1]]
    slot = jnp.arange(dist.shape[0], dtype=jnp.int32)
    n_used = jnp.reshape(impl.nacon, (-1,))[0].astype(jnp.int32)
    active = (
        (slot < n_used) & (dist < impl.contact__includemargin) & (geom[:, 0] >= 0) & (group >= 0)
    )
    world = jnp.where(active, impl.contact__worldid.astype(jnp.int32), jnp.int32(n_b))
    hit = none[0].at[world, jnp.maximum(group, 0)].set(True, mode="drop")
    depth = none[1].at[world].max(jnp.where(active, -dist, jnp.float32(0.0)), mode="drop")
    return hit, jnp.maximum(depth, jnp.float32(0.0))


def _guard_clearance(s: _Setup, d: mjx.Data, n_b: int) -> jax.Array:
    """(B,) smallest clearance of the guard geoms outside the head's ball, m (inf: none)."""
    if s.guard_geom.shape[0] == 0:
        return jnp.full((n_b,), jnp.inf, jnp.float32)
    gap = jnp.linalg.norm(d.geom_xpos[:, s.guard_geom] - s.guard_center[None, None, :], axis=-1)
    return jnp.min(gap - s.guard_radius[None, :], axis=-1)


def _rollout_batch(
    s: _Setup, held: jax.Array, valid: jax.Array, substeps: int
) -> tuple[tuple[jax.Array, ...], jax.Array]:
    """The batch of one part: held targets (B, T, n_joints), valid (B, T) -> the per-frame
    records of ``rollout_physics._rollout_one`` with a leading batch axis, and (B,) int32
    ``Data.overflow`` bits (MuJoCo Warp ORs them in at every step and never clears them;
    ``OVERFLOW_*``)."""
    n_b = held.shape[0]
    lo, hi = s.ctrl_lo[None, :], s.ctrl_hi[None, :]
    d = _batched(s.d0, n_b)
    q0 = jnp.clip(held[:, 0][:, s.q0_src], s.q_lo[None, :], s.q_hi[None, :])
    d = d.replace(
        qpos=d.qpos.at[:, s.qidx].set(q0.astype(d.qpos.dtype)),
        qvel=jnp.zeros_like(d.qvel),
        ctrl=jnp.clip(held[:, 0][:, s.act_src], lo, hi).astype(d.ctrl.dtype),
    )
    n_groups = len(CONTACT_GROUPS)
    n_joints = s.joints.shape[0]

    def frame(d, xs):
        target, prev, ok = xs  # (B, n_joints), (B, n_joints), (B,)
        ctrl = jnp.clip(target[:, s.act_src], lo, hi).astype(d.ctrl.dtype)
        c_prev = jnp.clip(prev[:, s.act_src], lo, hi).astype(d.ctrl.dtype)

        def substep(carry, w):
            d, vpeak, hit, depth, clear = carry
            u = jnp.where(w >= 1.0, ctrl, c_prev + (ctrl - c_prev) * w.astype(ctrl.dtype))
            with _mjx_defaults():
                d = mjx.step(s.mx, d.replace(ctrl=u))
            h, p = _self_contact(s, d, n_b)
            vpeak = jnp.maximum(vpeak, jnp.abs(d.qvel[:, s.didx]))
            clear = jnp.minimum(clear, _guard_clearance(s, d, n_b))
            return (d, vpeak, hit | h, jnp.maximum(depth, p), clear), None

        init = (
            d,
            jnp.zeros((n_b, n_joints), jnp.float32),
            jnp.zeros((n_b, n_groups), dtype=bool),
            jnp.zeros((n_b,), jnp.float32),
            jnp.full((n_b,), jnp.inf, jnp.float32),
        )
        (d, vpeak, hit, depth, clear), _ = jax.lax.scan(substep, init, s.ramp, length=substeps)
        rec = (
            d.qpos[:, s.qidx],
            d.qvel[:, s.didx],
            hit & ok[:, None],
            jnp.where(ok, depth, jnp.float32(0.0)),
            vpeak,
            clear,
        )
        return d, rec

    prev = jnp.concatenate([held[:, :1], held[:, :-1]], axis=1)  # frame 0 ramps from itself
    tmajor = (jnp.swapaxes(held, 0, 1), jnp.swapaxes(prev, 0, 1), jnp.swapaxes(valid, 0, 1))
    d, records = jax.lax.scan(frame, d, tmajor)
    overflow = jnp.reshape(d._impl.overflow, (n_b, -1))[:, 0].astype(jnp.int32)
    return tuple(jnp.swapaxes(r, 0, 1) for r in records), overflow


@jit(static_argnames=("substeps",), precision=None)  # MJX keeps its own defaults
def _simulate_jit(
    s: _Setup, targets: jax.Array, lengths: jax.Array, substeps: int
) -> tuple[RolloutResult, jax.Array]:
    """``rollout_physics._simulate_jit`` on Warp, and the (B,) overflow bits."""
    held, valid = jax.vmap(_held)(targets, lengths)
    (qpos, qvel, contact, depth, vpeak, _), overflow = _rollout_batch(s, held, valid, substeps)
    vmax, frames, rms = jax.vmap(_motion_stats)(qpos, vpeak, contact, held[..., s.joints], valid)
    return RolloutResult(qpos, qvel, contact, depth, vmax, frames, rms), overflow


@jit(static_argnames=("substeps",), precision=None)  # MJX keeps its own defaults
def _legs_jit(s: _Setup, targets: jax.Array, substeps: int) -> tuple[_LegRollout, jax.Array]:
    valid = jnp.ones(targets.shape[:2], dtype=bool)
    (qpos, qvel, _, _, vpeak, clear), overflow = _rollout_batch(s, targets, valid, substeps)
    return _LegRollout(qpos, qvel, vpeak, jnp.min(clear, axis=1)), overflow


def simulate_warp(
    q: np.ndarray,
    n: np.ndarray,
    config: RolloutConfig,
    robot: Robot,
    devices: list | None = None,
    *,
    with_overflow: bool = False,
) -> Any:
    """The rollout of a checked batch (``rollout._as_batch``) on MJX's Warp implementation:
    q (B, T, n_joints) float32, n (B,) int32 -> ``RolloutResult`` (device arrays); with
    ``with_overflow`` also (B,) int32: each motion's MuJoCo Warp overflow bits over all its
    steps (``OVERFLOW_*``; diagnostics of ``benchmarks/bench_rollout.py``).

    Raises:
      ConfigError: warp-lang or a CUDA GPU is missing, or ``devices`` names other devices.
      JaxprojError: MuJoCo Warp dropped contacts or constraints of some motion (its contact
        pool or constraint rows overflowed; waits for the rollout to check).
    """

    device = check_warp(devices)
    n_b = len(q)
    result = None
    if config.split_legs and robot.require_mjcf().split:
        legs_jax, _ = _setup(config, "legs", robot)
        leg_joints = np.asarray(legs_jax.joints)
        rows, inverse = _leg_motions(q, n, leg_joints)
        leg_targets = np.tile(robot.standing, (*rows.shape[:2], 1))
        leg_targets[..., leg_joints] = rows
        legs, substeps = _setup_warp(config, "legs", robot, len(rows), device)
        leg_run, leg_over = _legs_jit(legs, jax.device_put(leg_targets, device), substeps)
        if bool(np.all(np.asarray(leg_run.clearance) > 0.0)):
            upper, _ = _setup_warp(config, "upper", robot, n_b, device)
            up, overflow = _simulate_jit(upper, jax.device_put(q, device),
                                         jax.device_put(n, device), substeps)  # fmt: skip
            result = _merge_jit(up, leg_run, jax.device_put(inverse, device), upper.joints,
                                legs.joints, jax.device_put(q, device),
                                jax.device_put(n, device))  # fmt: skip
            overflow = overflow | leg_over[jax.device_put(inverse, device)]
    if result is None:
        whole, substeps = _setup_warp(config, "whole", robot, n_b, device)
        result, overflow = _simulate_jit(whole, jax.device_put(q, device),
                                         jax.device_put(n, device), substeps)  # fmt: skip
    dropped = np.asarray(overflow) & OVERFLOW_CAPACITY
    if np.any(dropped):
        bits = int(np.bitwise_or.reduce(dropped))
        raise JaxprojError(f"MuJoCo Warp dropped contacts or constraints in "
                           f"{int(np.sum(dropped > 0))} of {n_b} motions (overflow bits {bits}); "
                           "use backend='mjx'")  # fmt: skip
    if with_overflow:
        return result, overflow
    return result
