"""Forward kinematics of a robot's arm sites with MJX (the task-space metrics' points).

``arm_points(angles, robot=...)`` runs ``mjx.kinematics`` (JAX implementation) vmapped over
fixed-size batches of ``FK_BATCH`` frames (the last one padded), so one compile per robot serves
every frame count, on ``arm_model(robot)``: the fixed-mount MJCF without the bodies that cannot
move an arm site (``robot.mjcf.fk_without``). See ``jaxproj.eval.metrics`` for the numbers.

Strict promotion: MJX's own internals rely on implicit promotion, so the ``mjx.kinematics`` call
alone is traced inside ``jax.numpy_dtype_promotion("standard")`` /
``jax.numpy_rank_promotion("allow")``. The rest of this module is strict-clean.
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
from jaxproj.robots.base import mj_site_ids

FK_BATCH = 4096
"""Frames per compiled forward-kinematics call (the last batch is padded)."""


def check_angles(x: np.ndarray | jax.Array, name: str, robot: Robot) -> np.ndarray:
    """``(F, n_driven)`` or ``(F, n_joints)`` finite angles as float64; ConfigError otherwise."""
    a = np.asarray(x, np.float64)
    if a.ndim != 2 or a.shape[1] not in (robot.n_driven, robot.n_joints):
        raise ConfigError(
            f"{name} must have shape (F, {robot.n_driven}) (driven joints) or "
            f"(F, {robot.n_joints}) (configurations), got {a.shape}"
        )
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        raise ConfigError(
            f"{name} has non-finite angles in {int(bad.sum())} of {len(a)} frames "
            f"(first: frame {int(np.argmax(bad))})"
        )
    return a


class _FK(NamedTuple):
    """Device-side arm-only model for ``arm_points`` (pytrees of arrays)."""

    mx: mjx.Model
    d0: mjx.Data
    src: jax.Array  # (nq,) int32: index into joint_names of each qpos entry of the arm model
    sids: jax.Array  # (3 * n_sides,) int32 site ids, arm_sites side after side


def arm_model(robot: Robot) -> mujoco.MjModel:
    """The fixed-mount MJCF without ``robot.mjcf.fk_without``: the model ``arm_points`` evaluates.

    The same bodies, joints and sites as ``robot.load_model("fixed")`` for the torso and the
    arms; the ``fk_without`` subtrees (the default robot's: head and legs), actuators, equalities
    and the contact excludes removed (forward kinematics of the arms reads none of them).

    Raises:
      InputError: the MJCF is missing or does not compile.
      ConfigError: the robot has no MJCF, or it lacks a body / joint this relies on.
    """
    mjcf = robot.require_mjcf()
    path = mjcf.path
    if not path.is_file():
        raise InputError(path, "bundled MJCF model is missing")
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        root = None if mjcf.free_joint is None else spec.joint(mjcf.free_joint)
        if root is not None:
            spec.delete(root)
        for name in mjcf.fk_without:
            body = spec.body(name)
            if body is None:
                raise ConfigError(f"{path}: no body {name!r} to leave out of the arm model")
            spec.delete(body)
        for items in (spec.equalities, spec.actuators, spec.excludes):
            for item in list(items):
                spec.delete(item)
        return spec.compile()
    except ValueError as err:  # mujoco reports XML / compile errors as ValueError
        if isinstance(err, (ConfigError, InputError)):
            raise
        raise InputError(path, f"MuJoCo cannot compile the arm model: {err}") from err


@functools.lru_cache(maxsize=4)
def _fk_setup(robot: Robot) -> _FK:
    model = arm_model(robot)
    src = []
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            raise ConfigError("the arm model must have hinge joints only")
        src.append(robot.index(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or ""))
    order = np.argsort(model.jnt_qposadr)  # qpos entry k <- joint with the k-th address
    arm_sites = robot.require_mjcf().arm_sites.values()
    sids = mj_site_ids(model, [n for names in arm_sites for n in names])
    mx = mjx.put_model(model, impl="jax")
    return _FK(
        mx=mx,
        d0=mjx.make_data(mx, impl="jax"),
        src=jnp.asarray(np.asarray(src)[order], dtype=jnp.int32),
        sids=jnp.asarray(sids, dtype=jnp.int32),
    )


def _arm_points(fk: _FK, q: jax.Array) -> jax.Array:
    """``(B, n_joints)`` float32 configurations -> ``(B, n_sides, 3, 3)`` float32 positions, m."""
    n_sides = fk.sids.shape[0] // 3

    def one(qi: jax.Array) -> jax.Array:
        d = fk.d0.replace(qpos=qi[fk.src].astype(fk.d0.qpos.dtype))
        # MJX internals need implicit promotion; see the module docstring.
        with jax.numpy_dtype_promotion("standard"), jax.numpy_rank_promotion("allow"):
            d = mjx.kinematics(fk.mx, d)
        return d.site_xpos[fk.sids].astype(jnp.float32).reshape(n_sides, 3, 3)

    return jax.vmap(one)(q)


# The policy's full float32 matmul precision: the FK is compared with CPU MuJoCo to 1e-5 m, which
# a TF32 product on a GPU would not keep (MJX's kinematics is mostly elementwise anyway).
_arm_points_jit = jit(_arm_points)


def _configurations(x: np.ndarray | jax.Array, name: str, robot: Robot) -> np.ndarray:
    """``(F, n_driven | n_joints)`` -> ``(F, n_joints)`` float32 (driven joints into the
    standing posture)."""
    a = check_angles(x, name, robot).astype(np.float32)
    if a.shape[1] == robot.n_joints:
        return a
    full = np.tile(robot.standing, (len(a), 1))
    full[:, robot.driven_index] = a
    return full


def arm_points(angles: np.ndarray | jax.Array, *, robot: Robot) -> np.ndarray:
    """Forward kinematics of the arm sites (MJX, jitted, ``FK_BATCH`` frames per call).

    Args:
      angles: ``(F, n_driven)`` driven angles (``robot.driven_joints`` order; the other joints
        at ``robot.standing``, as ``robot.driven_to_full``) or ``(F, n_joints)`` configurations
        (``robot.joint_names`` order), rad.
      robot: the robot; it needs an MJCF with ``arm_sites``.

    Returns:
      ``(F, n_sides, 3, 3)`` float32 positions in the torso frame, m: ``[frame, side
      (robot.mjcf.arm_sites order, ``metrics.sides(robot)``), point (shoulder, elbow, wrist),
      xyz]``.

    Raises:
      ConfigError: bad shape or non-finite angles; a robot without an MJCF.
    """
    q = _configurations(angles, "angles", robot)
    n = len(q)
    if n == 0:
        return np.zeros((0, len(robot.require_mjcf().arm_sites), 3, 3), np.float32)
    fk = _fk_setup(robot)
    out = []
    for s in range(0, n, FK_BATCH):
        chunk = q[s : s + FK_BATCH]
        pad = FK_BATCH - len(chunk)
        if pad:
            chunk = np.concatenate([chunk, np.repeat(chunk[:1], pad, axis=0)])
        out.append(np.asarray(_arm_points_jit(fk, jnp.asarray(chunk)))[: FK_BATCH - pad])
    return np.concatenate(out)
