"""A whole-body motion replayed kinematically in MJX, contacts on: per frame, how far the robot
goes into the floor and how far two of its own geoms go into each other (issue 59's physics
check, batched: every frame of every recording of a dataset in one compiled program a batch).

``replay_depths(robot, root_pos, root_rot, angles)`` poses the robot's free-base MJCF with a
floor plane added at z = 0 (``floor_model``) at each frame (the root at ``root_pos`` turned by
``root_rot``, the joints at ``angles``), runs ``mjx.kinematics`` and ``mjx.collision`` (MJX's
JAX implementation) and returns the deepest penetration of each kind. The contact pairs are
MuJoCo's own: the MJCF's ``contype`` / ``conaffinity``, its excludes and the parent-child
filter, so a count over ``self_m > 1e-3`` is the count of frames where ``mj_forward`` finds two
of the robot's geoms more than 1 mm into each other (``tests/eval/test_replay.py`` compares
them with MuJoCo's, ``host_depths``, pose by pose). Frames are independent: any number of
frames from any number of recordings are concatenated and run ``REPLAY_BATCH`` at a time (the
last batch padded), one compile per robot.

Strict promotion: MJX's internals rely on implicit promotion, so its calls are traced inside
``jax.numpy_dtype_promotion("standard")`` / ``jax.numpy_rank_promotion("allow")`` (as
``jaxproj.eval.fk``).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError, InputError
from jaxproj.robots import Robot
from jaxproj.robots.base import joint_qpos_index

FLOOR = "jaxproj_floor"
"""The name of the floor plane ``floor_model`` adds."""

REPLAY_BATCH = 2048
"""Frames per compiled replay call (the last batch is padded)."""


class Depths(NamedTuple):
    """``replay_depths``' answer for ``F`` frames.

    Attributes:
      floor_m: ``(F,)`` float32 m, the deepest any robot geom goes below the floor (0: none).
      self_m: ``(F,)`` float32 m, the deepest two of the robot's geoms go into each other.
    """

    floor_m: np.ndarray
    self_m: np.ndarray


class _Replay(NamedTuple):
    mx: mjx.Model
    d0: mjx.Data
    floor: jax.Array  # () int32: the floor's geom id


def floor_model(robot: Robot) -> mujoco.MjModel:
    """The robot's free-base MJCF with a plane at z = 0 named ``FLOOR`` in the world body
    (MuJoCo's default ``contype`` / ``conaffinity`` of 1: it meets every geom of bit 1).

    Raises:
      ConfigError: the robot has no MJCF, or its MJCF has no free joint.
      InputError: the MJCF is missing or does not compile.
    """
    mjcf = robot.require_mjcf()
    if mjcf.free_joint is None:
        raise ConfigError(f"robot {robot.name!r}: its MJCF has no free joint to replay a root")
    if not mjcf.path.is_file():
        raise InputError(mjcf.path, "bundled MJCF model is missing")
    try:
        spec = mujoco.MjSpec.from_file(str(mjcf.path))
        floor = spec.worldbody.add_geom()
        floor.name = FLOOR
        floor.type = mujoco.mjtGeom.mjGEOM_PLANE
        floor.size = [0.0, 0.0, 1.0]  # infinite; the third number is the grid spacing
        return spec.compile()
    except ValueError as err:  # mujoco reports XML / compile errors as ValueError
        raise InputError(mjcf.path, f"MuJoCo cannot compile the replay model: {err}") from err


@functools.lru_cache(maxsize=4)
def _setup(robot: Robot) -> tuple[_Replay, np.ndarray, np.ndarray]:
    model = floor_model(robot)
    mx = mjx.put_model(model, impl="jax")
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
    free = int(model.jnt_qposadr[0])
    adr = joint_qpos_index(model, robot.joint_names)
    rep = _Replay(mx, mjx.make_data(mx, impl="jax"), jnp.asarray(floor, jnp.int32))
    return rep, np.asarray(model.qpos0, np.float32), np.asarray([free, *adr])


def _depths(rep: _Replay, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``(B, nq)`` float32 configurations -> ``(B,)`` floor and ``(B,)`` self depths, m."""

    def one(q: jax.Array) -> tuple[jax.Array, jax.Array]:
        d = rep.d0.replace(qpos=q.astype(rep.d0.qpos.dtype))
        with jax.numpy_dtype_promotion("standard"), jax.numpy_rank_promotion("allow"):
            d = mjx.collision(rep.mx, mjx.kinematics(rep.mx, d))
        contact = d._impl.contact  # the JAX implementation's (``d.contact``: deprecated)
        depth = jnp.maximum(-contact.dist, 0.0).astype(jnp.float32)  # (ncon,)
        on_floor = jnp.any(contact.geom == rep.floor, axis=1)
        zero = jnp.zeros((), jnp.float32)
        return (jnp.max(jnp.where(on_floor, depth, zero), initial=0.0),
                jnp.max(jnp.where(on_floor, zero, depth), initial=0.0))  # fmt: skip

    return jax.vmap(one)(qpos)


_depths_jit = jit(_depths)


def replay_depths(
    robot: Robot, root_pos: np.ndarray, root_rot: np.ndarray, angles: np.ndarray
) -> Depths:
    """Replay ``F`` frames (module doc): the deepest floor and self penetration of each.

    Args:
      robot: a robot whose MJCF has a free joint.
      root_pos: ``(F, 3)`` m, the root body's origin in the world (floor at z = 0).
      root_rot: ``(F, 4)`` its orientation, quaternion ``(x, y, z, w)`` (as written by
        ``jaxproj retarget --root world``).
      angles: ``(F, n_joints)`` rad, every joint in ``robot.joint_names`` order.

    Returns:
      ``Depths`` of ``(F,)`` float32 arrays, m.

    Raises:
      ConfigError: shapes that disagree, or non-finite values (naming the first frame).
    """
    pos = np.asarray(root_pos, np.float32)
    rot = np.asarray(root_rot, np.float32)
    q = np.asarray(angles, np.float32)
    f = len(pos)
    if pos.shape != (f, 3) or rot.shape != (f, 4) or q.shape != (f, robot.n_joints):
        raise ConfigError(
            f"replay_depths: root_pos {pos.shape}, root_rot {rot.shape} and angles {q.shape} "
            f"must be (F, 3), (F, 4), (F, {robot.n_joints})"
        )
    bad = ~(np.isfinite(pos).all(1) & np.isfinite(rot).all(1) & np.isfinite(q).all(1))
    if bad.any():
        raise ConfigError(f"replay_depths: frame {int(np.argmax(bad))} holds NaN or inf "
                          f"({int(bad.sum())} of {f} frames)")  # fmt: skip
    rep = _setup(robot)[0]
    qpos = _qpos(robot, pos, rot, q).astype(np.float32)
    floor = np.zeros(f, np.float32)
    own = np.zeros(f, np.float32)
    for s in range(0, f, REPLAY_BATCH):
        part = qpos[s : s + REPLAY_BATCH]
        k = len(part)
        if k < REPLAY_BATCH:  # padded with the first frame: one compile for every count
            part = np.concatenate([part, np.repeat(part[:1], REPLAY_BATCH - k, axis=0)])
        a, b = _depths_jit(rep, jnp.asarray(part))
        floor[s : s + k] = np.asarray(a)[:k]
        own[s : s + k] = np.asarray(b)[:k]
    return Depths(floor, own)


def _qpos(robot: Robot, pos: np.ndarray, rot: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``(F, nq)`` float64 configurations of ``floor_model(robot)``: the root at ``pos`` turned
    by ``rot`` (x, y, z, w), the joints at ``q``, the rest at ``qpos0``."""
    _, qpos0, adr = _setup(robot)
    qpos = np.tile(qpos0.astype(np.float64), (len(pos), 1))
    free = adr[0]
    qpos[:, free : free + 3] = pos
    qpos[:, free + 3 : free + 7] = np.roll(rot, 1, axis=1)  # xyzw -> wxyz
    qpos[:, adr[1:]] = q
    return qpos


def host_depths(
    robot: Robot, root_pos: np.ndarray, root_rot: np.ndarray, angles: np.ndarray
) -> Depths:
    """``replay_depths``' answer by MuJoCo's ``mj_forward`` on the host, one frame after the
    other (float64; the reference the MJX replay is checked against, for a few frames)."""
    model = floor_model(robot)
    data = mujoco.MjData(model)
    floor_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, FLOOR)
    qpos = _qpos(robot, np.asarray(root_pos), np.asarray(root_rot), np.asarray(angles))
    out = np.zeros((2, len(qpos)), np.float32)
    for t, x in enumerate(qpos):
        data.qpos[:] = x
        mujoco.mj_forward(model, data)
        for c in data.contact[: data.ncon]:
            k = 0 if floor_id in c.geom else 1
            out[k, t] = max(out[k, t], -c.dist)
    return Depths(out[0], out[1])
