"""Forward kinematics of a robot's own MJCF in JAX: points of its bodies and sites.

``TreeFK.from_model(model, joint_names, points, base=...)`` reads the kinematic tree of a
compiled ``mujoco.MjModel`` once (parents, body offsets and rotations, hinge axes and anchors,
site offsets) and returns a small record of NumPy constants; ``TreeFK.points(q)`` is a pure,
traceable JAX function from ``(..., n_joints)`` configurations (``joint_names`` order) to
``(..., n_points, 3)`` positions in the frame of the ``base`` body. It computes only the bodies
the points hang from and their ancestors, and does what ``mujoco.mj_kinematics`` does for them
(``xpos``/``xmat``/``site_xpos``; a hinge turns by ``q - qpos0`` about its axis through its
anchor), with the floating base held at the identity. The generic IK
(``jaxproj.robots.generic_ik``) differentiates it (``jax.jacfwd``); ``tests/robots/
test_kinematics.py`` checks it against ``mujoco.mj_kinematics`` for the NAO and the G1.

Why not ``mjx.kinematics``: it computes every body of the model on ``mjx.Data`` and is built
for a simulation step; the IK needs a handful of points of one subtree, thousands of times per
pose. ``benchmarks/experiments/fk_ab.py`` measures both.

Shapes: ``q`` ``(..., n_joints)`` float32 radians; points ``(..., n_points, 3)`` metres.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj.errors import ConfigError

_HIGHEST = jax.lax.Precision.HIGHEST


def _quat_to_mat(quat: np.ndarray) -> np.ndarray:
    """(w, x, y, z) -> (3, 3) rotation matrix (float64)."""
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(quat, np.float64))
    return m.reshape(3, 3)


Point = str | tuple[str, tuple[float, float, float]]
"""A point of the MJCF: a site or body name, or ``(body name, (x, y, z) offset in the body)``."""


def _point(model: mujoco.MjModel, name: Point) -> tuple[int, np.ndarray]:
    """``(body id, offset in that body)`` of a site (preferred) or a body called ``name``, or
    of a ``(body, offset)`` pair."""
    if not isinstance(name, str):
        body, offset = name
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
        if bid < 0:
            raise ConfigError(f"the MJCF has no body named {body!r}")
        return bid, np.asarray(offset, np.float64).reshape(3)
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return int(model.site_bodyid[sid]), np.array(model.site_pos[sid], np.float64)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid >= 0:
        return bid, np.zeros(3)
    raise ConfigError(f"the MJCF has no site or body named {name!r}")


@dataclass(frozen=True, eq=False)
class _Body:
    parent: int  # index into TreeFK.bodies, -1: the world
    pos: np.ndarray  # (3,) offset in the parent's frame
    rot: np.ndarray  # (3, 3) rotation in the parent's frame
    joints: tuple[tuple[int, np.ndarray, np.ndarray, float], ...]  # (q index, axis, anchor, qpos0)


@dataclass(frozen=True, eq=False)
class TreeFK:
    """Forward kinematics of some points of an MJCF, in JAX (see the module doc).

    Attributes:
      joint_names: the configuration's joints (``q``'s last axis), e.g. ``Robot.joint_names``.
      point_names: the points (``Point``: sites, bodies, body offsets) ``points`` returns.
      base: the body whose frame the points are expressed in (its origin is the origin).
      bodies: the bodies computed, parents before children (internal).
      point_body: ``(n_points,)`` index into ``bodies`` of each point's body (internal).
      point_offset: ``(n_points, 3)`` each point's offset in its body (internal).
      base_body: index into ``bodies`` of ``base`` (internal).
    """

    joint_names: tuple[str, ...]
    point_names: tuple[Point, ...]
    base: str
    bodies: tuple[_Body, ...]
    point_body: tuple[int, ...]
    point_offset: np.ndarray
    base_body: int

    @classmethod
    def from_model(
        cls,
        model: mujoco.MjModel,
        joint_names: Sequence[str],
        points: Sequence[Point],
        base: str,
    ) -> TreeFK:
        """Read the tree of ``model`` for ``points`` (``Point``) seen from ``base``.

        Every hinge joint on the way is one of ``joint_names`` (its angle read from ``q``);
        free joints are held at the identity (the floating base).

        Raises:
          ConfigError: an unknown point or base, a joint on the way that is neither a hinge nor
            free nor in ``joint_names``.
        """
        joint_names = tuple(joint_names)
        index = {n: i for i, n in enumerate(joint_names)}
        base_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base)
        if base_id < 0:
            raise ConfigError(f"the MJCF has no body named {base!r} (the FK's base)")
        located = [_point(model, p) for p in points]

        def ancestors(bid: int) -> list[int]:
            out = []
            while bid > 0:
                out.append(bid)
                bid = int(model.body_parentid[bid])
            return out

        # every point below the base: start the tree at the base (its own joints and those
        # above it move all points alike, so they cancel in the base's frame)
        below = all(base_id in ancestors(b) for b, _ in located)
        needed: set[int] = set()
        for bid in [base_id, *(b for b, _ in located)]:
            needed.update(b for b in ancestors(bid) if not below or base_id in ancestors(b))
        order = sorted(needed)  # MuJoCo numbers parents before children
        slot = {bid: i for i, bid in enumerate(order)}
        bodies = []
        for bid in order:
            if below and bid == base_id:
                bodies.append(_Body(parent=-1, pos=np.zeros(3), rot=np.eye(3), joints=()))
                continue
            joints = []
            for j in range(model.body_jntadr[bid], model.body_jntadr[bid] + model.body_jntnum[bid]):
                kind = model.jnt_type[j]
                if kind == mujoco.mjtJoint.mjJNT_FREE:
                    continue
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
                if kind != mujoco.mjtJoint.mjJNT_HINGE:
                    raise ConfigError(f"joint {name!r}: only hinge and free joints are supported")
                if name not in index:
                    raise ConfigError(f"joint {name!r} moves a point but is not in joint_names")
                axis = np.array(model.jnt_axis[j], np.float64)
                qpos0 = float(model.qpos0[model.jnt_qposadr[j]])
                joints.append((index[name], axis, np.array(model.jnt_pos[j], np.float64), qpos0))
            parent = int(model.body_parentid[bid])
            bodies.append(
                _Body(
                    parent=slot.get(parent, -1),
                    pos=np.array(model.body_pos[bid], np.float64),
                    rot=_quat_to_mat(model.body_quat[bid]),
                    joints=tuple(joints),
                )
            )
        offsets = np.array([o for _, o in located], np.float64).reshape(len(located), 3)
        return cls(
            joint_names=joint_names,
            point_names=tuple(points),
            base=base,
            bodies=tuple(bodies),
            point_body=tuple(slot[b] for b, _ in located),
            point_offset=offsets,
            base_body=slot[base_id],
        )

    @property
    def n_points(self) -> int:
        """Number of points ``points`` returns."""
        return len(self.point_names)

    def _forward(
        self, q: jax.Array
    ) -> tuple[list[jax.Array], list[jax.Array], dict[int, tuple[int, jax.Array, jax.Array]]]:
        """World rotations and origins of ``bodies``, and per joint (``q`` index) its body slot,
        world axis and world anchor."""
        if q.shape[-1] != len(self.joint_names):
            raise ConfigError(
                f"configurations must be (..., {len(self.joint_names)}), got {q.shape}"
            )
        batch = q.shape[:-1]
        eye = jnp.broadcast_to(jnp.eye(3, dtype=jnp.float32), (*batch, 3, 3))
        zero = jnp.zeros((*batch, 3), jnp.float32)
        rots: list[jax.Array] = []
        poss: list[jax.Array] = []
        axes: dict[int, tuple[int, jax.Array, jax.Array]] = {}
        for slot, body in enumerate(self.bodies):
            r_p, p_p = (eye, zero) if body.parent < 0 else (rots[body.parent], poss[body.parent])
            pos = p_p + _apply(r_p, body.pos)
            rot = _matmul(r_p, jnp.asarray(body.rot, jnp.float32))
            for qi, axis, anchor, qpos0 in body.joints:
                world_anchor = pos + _apply(rot, anchor)
                axes[qi] = (slot, _apply(rot, axis / np.linalg.norm(axis)), world_anchor)
                rot = _matmul(rot, _axis_rotation(axis, q[..., qi] - np.float32(qpos0)))
                pos = world_anchor - _apply(rot, anchor)
            rots.append(rot)
            poss.append(pos)
        return rots, poss, axes

    def _world_points(self, rots: list[jax.Array], poss: list[jax.Array]) -> jax.Array:
        return jnp.stack(
            [
                poss[b] + _apply(rots[b], off)
                for b, off in zip(self.point_body, self.point_offset, strict=True)
            ],
            axis=-2,
        )

    def points(self, q: jax.typing.ArrayLike) -> jax.Array:
        """``(..., n_joints)`` configurations -> ``(..., n_points, 3)`` float32 positions, m, in
        the ``base`` body's frame. Traceable; matrix products at full float32 precision."""
        q = jnp.asarray(q, jnp.float32)
        rots, poss, _ = self._forward(q)
        pts = self._world_points(rots, poss)
        r_b, p_b = rots[self.base_body], poss[self.base_body]
        # world -> base frame: R_b^T (p - p_b)
        return jnp.einsum("...ji,...pj->...pi", r_b, pts - p_b[..., None, :], precision=_HIGHEST)

    def jacobian(
        self, q: jax.typing.ArrayLike, columns: Sequence[int]
    ) -> tuple[jax.Array, jax.Array]:
        """Points and their derivatives by the joints ``columns`` (positions in ``q``).

        The geometric Jacobian: a hinge with world axis ``w`` through ``a`` moves a point ``p``
        by ``w x (p - a)`` per radian; seen from the base body, by ``s (w x (p - a))`` turned
        into the base frame, with ``s = [joint moves p] - [joint moves the base]``.

        Returns:
          ``((..., n_points, 3) points, (..., n_points, 3, len(columns)) derivatives)`` in the
          base frame (a joint not on the way to any point, or not a hinge here: zeros).
        """
        q = jnp.asarray(q, jnp.float32)
        rots, poss, axes = self._forward(q)
        pts = self._world_points(rots, poss)
        r_b, p_b = rots[self.base_body], poss[self.base_body]
        rel = pts - p_b[..., None, :]
        local = jnp.einsum("...ji,...pj->...pi", r_b, rel, precision=_HIGHEST)
        cols = []
        for qi in columns:
            if qi not in axes:
                cols.append(jnp.zeros_like(local))
                continue
            slot, w, a = axes[qi]
            sign = self._moves(slot, self.point_body) - float(
                self._moves(slot, (self.base_body,))[0]
            )
            v = jnp.cross(jnp.broadcast_to(w[..., None, :], pts.shape), pts - a[..., None, :])
            v = v * sign.reshape((1,) * (v.ndim - 2) + (-1, 1))
            cols.append(jnp.einsum("...ji,...pj->...pi", r_b, v, precision=_HIGHEST))
        return local, jnp.stack(cols, axis=-1)

    def _moves(self, slot: int, bodies: Sequence[int]) -> np.ndarray:
        """``(len(bodies),)`` float32: 1 where body ``slot`` is ``b`` or one of its ancestors."""
        out = np.zeros(len(bodies), np.float32)
        for i, b in enumerate(bodies):
            while b >= 0:
                if b == slot:
                    out[i] = 1.0
                    break
                b = self.bodies[b].parent
        return out


def _apply(rot: jax.Array, v: np.ndarray) -> jax.Array:
    """``rot @ v`` for a constant vector ``v``: ``(..., 3, 3)`` -> ``(..., 3)``."""
    v32 = np.asarray(v, np.float32)
    return rot[..., 0] * v32[0] + rot[..., 1] * v32[1] + rot[..., 2] * v32[2]


def _matmul(a: jax.Array, b: jax.Array) -> jax.Array:
    """``(..., 3, 3) @ (..., 3, 3)`` at full float32 precision."""
    return jnp.matmul(a, b, precision=_HIGHEST)


def _axis_rotation(axis: np.ndarray, angle: jax.Array) -> jax.Array:
    """Rotation by ``angle`` (``(...,)``) about the constant unit ``axis``: Rodrigues."""
    k = np.asarray(axis, np.float64)
    k = (k / np.linalg.norm(k)).astype(np.float32)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]], np.float32)
    kk = (kx @ kx).astype(np.float32)
    s, c = jnp.sin(angle)[..., None, None], jnp.cos(angle)[..., None, None]
    shape = (*jnp.shape(angle), 3, 3)
    eye, kx_b, kk_b = (jnp.broadcast_to(m, shape) for m in (np.eye(3, dtype=np.float32), kx, kk))
    return eye + s * kx_b + (1.0 - c) * kk_b


def points_named(fk: TreeFK, q: jax.typing.ArrayLike) -> Mapping[Point, jax.Array]:
    """``{point: (..., 3)}`` of ``fk.points(q)`` (notebooks, tests)."""
    p = fk.points(q)
    return {name: p[..., i, :] for i, name in enumerate(fk.point_names)}
