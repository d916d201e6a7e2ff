"""The rollout's physics: one MJX step, self-contact, and the jitted batched rollouts.

Part of ``jaxproj.eval.rollout`` (see its docstring for the protocol and for why only
``mjx.forward`` / ``mjx.implicit`` are traced under JAX's default promotion, ``_mjx_defaults``).
Shapes: ``n_joints`` joints of the robot, ``n`` joints of a part (``_Setup.joints``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import NamedTuple

import jax
import jax.numpy as jnp
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.eval.rollout_model import CONTACT_GROUPS, RolloutResult, _Setup


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
    whose force is clamped by ``forcerange``; the default robot's servos saturate on every large
    step, so ``mjx.step`` lags CPU MuJoCo by ~0.02 rad within 0.1 s there. Here the ``kv`` of the
    clamped servos is zeroed in the model handed to ``mjx.implicit`` for this step only, which makes
    the two agree to float32 round-off (tests/eval/test_rollout.py).
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
    """targets (T, n_joints), length () -> (T, n_joints) with the frames past ``length`` holding
    the last valid one, and (T,) bool valid."""
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
    """One motion of one part: held targets (T, n_joints), valid (T,) -> per-frame records.

    Returns qpos (T, n), qvel (T, n), contact (T, 3) and depth (T,) (both False / 0 on invalid
    frames), peak |qvel| (T, n) over each frame's physics steps, and the guard clearance (T,)
    (smallest over each frame's physics steps; inf for parts without guard geoms).
    """
    q0 = held[0][s.q0_src]  # a coupled follower starts at its leader
    q0 = jnp.clip(q0, s.q_lo, s.q_hi)
    d = s.d0.replace(
        qpos=s.d0.qpos.at[s.qidx].set(q0.astype(s.d0.qpos.dtype)),
        qvel=jnp.zeros_like(s.d0.qvel),
        ctrl=jnp.clip(held[0][s.act_src], s.ctrl_lo, s.ctrl_hi).astype(s.d0.ctrl.dtype),
    )
    n_groups = len(CONTACT_GROUPS)
    n_joints = s.joints.shape[0]

    def frame(d, xs):
        target, prev, ok = xs
        ctrl = jnp.clip(target[s.act_src], s.ctrl_lo, s.ctrl_hi).astype(d.ctrl.dtype)
        c_prev = jnp.clip(prev[s.act_src], s.ctrl_lo, s.ctrl_hi).astype(d.ctrl.dtype)

        def substep(carry, w):
            d, vpeak, hit, depth, clear = carry
            # the ramp's last step is exactly this frame's target (no rounding): with
            # interpolate=False every step is (the zero-order hold)
            u = jnp.where(w >= 1.0, ctrl, c_prev + (ctrl - c_prev) * w.astype(ctrl.dtype))
            d = _mjx_step(s, d.replace(ctrl=u))
            h, p = _self_contact(s, d)
            vpeak = jnp.maximum(vpeak, jnp.abs(d.qvel[s.didx]))
            clear = jnp.minimum(clear, _guard_clearance(s, d))
            return (d, vpeak, hit | h, jnp.maximum(depth, p), clear), None

        init = (
            d,
            jnp.zeros(n_joints, jnp.float32),
            jnp.zeros(n_groups, dtype=bool),
            jnp.zeros((), jnp.float32),
            jnp.full((), jnp.inf, jnp.float32),
        )
        (d, vpeak, hit, depth, clear), _ = jax.lax.scan(substep, init, s.ramp, length=substeps)
        rec = (
            d.qpos[s.qidx],
            d.qvel[s.didx],
            hit & ok,
            jnp.where(ok, depth, jnp.float32(0.0)),
            vpeak,
            clear,
        )
        return d, rec

    prev = jnp.concatenate([held[:1], held[:-1]])  # frame 0 ramps from itself: a hold
    _, records = jax.lax.scan(frame, d, (held, prev, valid))
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
    """A batch on one part: targets (B, T, n_joints), lengths (B,) -> ``RolloutResult`` whose joint
    axes are the part's ``n`` joints (``s.joints``; all of them in order for the whole robot)."""

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

    n_joints = targets.shape[-1]

    def put(up: jax.Array, lg: jax.Array) -> jax.Array:
        out = jnp.zeros((*up.shape[:-1], n_joints), up.dtype)
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
