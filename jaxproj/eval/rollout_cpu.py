"""The rollout on CPU MuJoCo: ``simulate(..., backend="mujoco")``.

Part of ``jaxproj.eval.rollout`` (see its docstring for the protocol). The same protocol as the
MJX rollout, on MuJoCo's C library in float64: ``mujoco.mj_step`` once per physics step, with
the records of each step (peak joint speed, self-contact by group, deepest penetration) read
from ``MjData`` in between; one host thread per motion (MuJoCo releases the GIL while it steps),
``threads`` at a time. No compilation, so on a CPU-only machine it beats MJX by the compile
time alone (MJX on XLA:CPU compiles one rollout program for tens of seconds per batch shape).

Not MuJoCo's ``mujoco.rollout`` module: that one returns the state after each step but not the
contacts found during it, which the protocol records per physics step.

The whole robot always runs as one model (``RolloutConfig.split_legs`` is an MJX-only saving);
everything else in ``RolloutConfig`` applies as in MJX. CPU MuJoCo is the reference the MJX step
is written to match (``rollout_physics._mjx_step``): contact-free motions agree to float32
round-off; in self-contact MJX's own constraint solver (float32) parts from the C one, by up to
~0.06 rad in the tests' colliding motion (``tests/eval/test_rollout.py``).
"""

from __future__ import annotations

import concurrent.futures
import os

import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj.eval.rollout_model import (
    CONTACT_GROUPS,
    RolloutConfig,
    RolloutResult,
    _Tables,
    _tables,
)
from jaxproj.robots import Robot


def _one(
    t: _Tables, held: np.ndarray, n_valid: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One motion: held targets (T, n_joints) float64 (frames past ``n_valid`` hold the last
    valid one) -> qpos (T, n), qvel (T, n), contact (T, 3) bool, depth (T,), peak |qvel| over
    the valid frames (n,), all float64 / bool, the joints of ``t.joints`` (the whole robot)."""
    model = t.model
    data = mujoco.MjData(model)
    n_frames = held.shape[0]
    n = len(t.qidx)
    q0 = np.clip(held[0][t.q0_src], t.q_lo, t.q_hi)
    data.qpos[t.qidx] = q0
    data.qvel[:] = 0.0
    lo, hi = t.ctrl_lo.astype(np.float64), t.ctrl_hi.astype(np.float64)
    qpos = np.empty((n_frames, n))
    qvel = np.empty((n_frames, n))
    contact = np.zeros((n_frames, len(CONTACT_GROUPS)), dtype=bool)
    depth = np.zeros(n_frames)
    vmax = np.zeros(n)
    vpeak = np.zeros(n)
    prev = np.clip(held[0][t.act_src], lo, hi)
    for f in range(n_frames):
        ctrl = np.clip(held[f][t.act_src], lo, hi)
        vpeak[:] = 0.0
        for k in range(t.substeps):
            w = float(t.ramp[k])  # RolloutConfig.interpolate: a ramp from the last target
            data.ctrl[:] = ctrl if w >= 1.0 else prev + (ctrl - prev) * w
            mujoco.mj_step(model, data)
            np.maximum(vpeak, np.abs(data.qvel[t.didx]), out=vpeak)
            nc = data.ncon
            if nc:
                con = data.contact
                geom = con.geom[:nc]
                dist = con.dist[:nc]
                group = t.pair_group[geom[:, 0], geom[:, 1]]
                active = (dist < con.includemargin[:nc]) & (group >= 0)
                if active.any():
                    contact[f, group[active]] = True
                    depth[f] = max(depth[f], float(np.max(-dist[active])), 0.0)
        prev = ctrl
        qpos[f] = data.qpos[t.qidx]
        qvel[f] = data.qvel[t.didx]
        if f < n_valid:
            np.maximum(vmax, vpeak, out=vmax)
    contact[n_valid:] = False
    depth[n_valid:] = 0.0
    return qpos, qvel, contact, depth, vmax


def simulate_mujoco(
    q: np.ndarray,
    n: np.ndarray,
    config: RolloutConfig,
    robot: Robot,
    threads: int | None = None,
) -> RolloutResult:
    """The rollout of a checked batch (``rollout._as_batch``): q (B, T, n_joints) float32, n (B,)
    int32 -> ``RolloutResult`` (float32 / int32 / bool device arrays, as the MJX backend's).
    ``threads``: motions stepped at a time (default ``os.cpu_count()``)."""
    t = _tables(config, "whole", robot)
    n_b, n_frames = q.shape[:2]
    frame = np.minimum(np.arange(n_frames)[None, :], n[:, None] - 1)  # (B, T) held frame
    held = q[np.arange(n_b)[:, None], frame].astype(np.float64)
    workers = max(1, min(threads or os.cpu_count() or 1, n_b))
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        parts = list(pool.map(_one, [t] * n_b, held, [int(v) for v in n]))
    qpos, qvel, contact, depth, vmax = (np.stack(x) for x in zip(*parts, strict=True))
    valid = np.arange(n_frames)[None, :] < n[:, None]  # (B, T)
    err = np.where(valid[..., None], qpos - held[..., t.joints], 0.0)
    rms = np.sqrt(np.sum(err * err, axis=1) / np.maximum(valid.sum(axis=1), 1)[:, None])
    # the whole model's joints are all of the robot's, in its order (_part_joints)
    assert np.array_equal(t.joints, np.arange(robot.n_joints))
    return RolloutResult(
        qpos=jnp.asarray(qpos, dtype=jnp.float32),
        qvel=jnp.asarray(qvel, dtype=jnp.float32),
        contact=jnp.asarray(contact),
        penetration=jnp.asarray(depth, dtype=jnp.float32),
        max_speed=jnp.asarray(vmax, dtype=jnp.float32),
        contact_frames=jnp.asarray(contact.sum(axis=1), dtype=jnp.int32),
        tracking_rms=jnp.asarray(rms, dtype=jnp.float32),
    )
