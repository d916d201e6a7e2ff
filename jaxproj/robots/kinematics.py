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

import functools
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


def points_at(
    model: mujoco.MjModel,
    joint_names: Sequence[str],
    q: np.ndarray,
    points: Sequence[Point],
    base: Point,
) -> np.ndarray:
    """``TreeFK.from_model(model, joint_names, points, base).points(q)`` for ONE configuration
    on the host, by ``mujoco.mj_kinematics`` (build-time constants without a JAX program):
    ``(n_joints,)`` angles -> ``(n_points, 3)`` float64 positions in ``base``'s frame."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    for joint, v in zip(joint_names, np.asarray(q, np.float64), strict=True):
        data.qpos[model.jnt_qposadr[model.joint(joint).id]] = v
    mujoco.mj_kinematics(model, data)
    b = _point(model, base)[0]
    out = []
    for point in points:
        bid, off = _point(model, point)
        world = data.xpos[bid] + data.xmat[bid].reshape(3, 3) @ off
        out.append(data.xmat[b].reshape(3, 3).T @ (world - data.xpos[b]))
    return np.array(out, np.float64).reshape(len(out), 3)


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

    @functools.cached_property
    def _levels(self) -> _Levels:
        """The bodies as one-hinge frames grouped by depth (``_Levels``), built once."""
        return _Levels.of(self.bodies)

    def _forward(self, q: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``((..., F, 3, 3) world rotations, (..., F, 3) origins)`` of the frames of
        ``_levels`` (``F`` frames: each body's joints one frame each, the world last)."""
        if q.shape[-1] != len(self.joint_names):
            raise ConfigError(
                f"configurations must be (..., {len(self.joint_names)}), got {q.shape}"
            )
        lv = self._levels
        batch = q.shape[:-1]
        lead = (1,) * len(batch)  # explicit ranks (jax_numpy_rank_promotion='raise')
        rots: list[jax.Array] = []
        poss: list[jax.Array] = []
        r_p = jnp.broadcast_to(jnp.eye(3, dtype=jnp.float32), (*batch, 1, 3, 3))  # the world
        p_p = jnp.zeros((*batch, 1, 3), jnp.float32)
        for lev in lv.levels:  # all frames of one depth at once: a small program per depth
            # each frame's parent is in the level before (the world for the first)
            r_p, p_p = r_p[..., lev.parent, :, :], p_p[..., lev.parent, :]
            pos = p_p + jnp.einsum("...lij,lj->...li", r_p, lev.pos, precision=_HIGHEST)
            rot = jnp.einsum("...lij,ljk->...lik", r_p, lev.rot, precision=_HIGHEST)
            angle = (q[..., lev.joint] - lev.qpos0.reshape(*lead, -1)) * lev.hinge.reshape(
                *lead, -1
            )  # 0 without a hinge: the identity
            turn = _axis_rotations(
                lev.kx.reshape(*lead, *lev.kx.shape), lev.kk.reshape(*lead, *lev.kk.shape), angle
            )
            anchor = pos + jnp.einsum("...lij,lj->...li", rot, lev.anchor, precision=_HIGHEST)
            rot = jnp.einsum("...lij,...ljk->...lik", rot, turn, precision=_HIGHEST)
            pos = anchor - jnp.einsum("...lij,lj->...li", rot, lev.anchor, precision=_HIGHEST)
            rots.append(rot)
            poss.append(pos)
            r_p, p_p = rot, pos
        # frames are numbered level by level (``_Levels.of``), the world last: one
        # concatenation instead of a scatter per level into a (..., F + 1, 3, 3) buffer
        rots.append(jnp.broadcast_to(jnp.eye(3, dtype=jnp.float32), (*batch, 1, 3, 3)))
        poss.append(jnp.zeros((*batch, 1, 3), jnp.float32))
        return jnp.concatenate(rots, axis=-3), jnp.concatenate(poss, axis=-2)

    def _world_points(self, rots: jax.Array, poss: jax.Array) -> jax.Array:
        frames = self._levels.body_frame[np.asarray(self.point_body, np.int32)]
        off = np.asarray(self.point_offset, np.float32)
        return poss[..., frames, :] + jnp.einsum(
            "...pij,pj->...pi", rots[..., frames, :, :], off, precision=_HIGHEST
        )

    def _base(self, rots: jax.Array, poss: jax.Array) -> tuple[jax.Array, jax.Array]:
        b = int(self._levels.body_frame[self.base_body])
        return rots[..., b, :, :], poss[..., b, :]

    def points(self, q: jax.typing.ArrayLike) -> jax.Array:
        """``(..., n_joints)`` configurations -> ``(..., n_points, 3)`` float32 positions, m, in
        the ``base`` body's frame. Traceable; matrix products at full float32 precision."""
        q = jnp.asarray(q, jnp.float32)
        rots, poss = self._forward(q)
        pts = self._world_points(rots, poss)
        r_b, p_b = self._base(rots, poss)
        # world -> base frame: R_b^T (p - p_b)
        return jnp.einsum("...ji,...pj->...pi", r_b, pts - p_b[..., None, :], precision=_HIGHEST)

    def columns(
        self, columns: Sequence[int]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What ``jacobian_columns`` needs of the joints ``columns`` (positions in ``q``; a
        position that is no hinge of this tree, e.g. ``-1`` for padding, gives a zero column):
        ``((c,) int32 frames, (c, 3) axes, (c, 3) anchors, (c, n_points) float32 signs)``."""
        lv = self._levels
        cols = list(columns)
        frame = np.array([lv.joint_frame.get(qi, lv.n_frames) for qi in cols], np.int32)
        zero = np.zeros(3, np.float32)
        axis = np.stack([lv.joint_axis.get(qi, zero) for qi in cols]).reshape(len(cols), 3)
        anchor = np.stack([lv.joint_anchor.get(qi, zero) for qi in cols]).reshape(len(cols), 3)
        sign = np.stack(
            [
                self._moves(lv.joint_body[qi], self.point_body)
                - float(self._moves(lv.joint_body[qi], (self.base_body,))[0])
                if qi in lv.joint_frame
                else np.zeros(len(self.point_body), np.float32)
                for qi in cols
            ]
        ).reshape(len(cols), len(self.point_body))  # (c, P)
        return frame, axis.astype(np.float32), anchor.astype(np.float32), sign

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
        return self.jacobian_columns(q, *self.columns(columns))

    def jacobian_columns(
        self,
        q: jax.typing.ArrayLike,
        frame: jax.typing.ArrayLike,
        axis: jax.typing.ArrayLike,
        anchor: jax.typing.ArrayLike,
        sign: jax.typing.ArrayLike,
        moved: jax.typing.ArrayLike | None = None,
    ) -> tuple[jax.Array, jax.Array]:
        """``jacobian`` with the columns given by ``columns``' arrays, which may be traced
        (one compiled program for the columns of several chains: ``GenericIK`` scans its
        chains). ``q``: ``(..., n_joints)``; the arrays unbatched.

        ``moved``: ``(m,)`` indices of the points whose derivatives are wanted (``sign`` then
        ``(c, m)``, its columns for them): the derivatives are ``(..., m, 3, c)``, of those
        points only (the others' are zero when ``sign`` is zero for them: a smaller product).
        The positions are always every point's."""
        q = jnp.asarray(q, jnp.float32)
        rots, poss = self._forward(q)
        pts = self._world_points(rots, poss)
        r_b, p_b = self._base(rots, poss)
        local = jnp.einsum("...ji,...pj->...pi", r_b, pts - p_b[..., None, :], precision=_HIGHEST)
        frame = jnp.asarray(frame, jnp.int32)
        sign = jnp.asarray(sign, jnp.float32)
        if moved is not None:
            pts = pts[..., jnp.asarray(moved, jnp.int32), :]
        r_j, p_j = rots[..., frame, :, :], poss[..., frame, :]
        w = jnp.einsum("...cij,cj->...ci", r_j, jnp.asarray(axis), precision=_HIGHEST)
        a = p_j + jnp.einsum("...cij,cj->...ci", r_j, jnp.asarray(anchor), precision=_HIGHEST)
        rel = pts[..., None, :, :] - a[..., :, None, :]  # (..., c, P, 3)
        lead = (1,) * (rel.ndim - 3)
        v = jnp.cross(jnp.broadcast_to(w[..., :, None, :], rel.shape), rel) * sign.reshape(
            *lead, *sign.shape, 1
        )
        dv = jnp.einsum("...ji,...cpj->...pic", r_b, v, precision=_HIGHEST)
        return local, dv

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


def _axis_rotations(kx: np.ndarray, kk: np.ndarray, angle: jax.Array) -> jax.Array:
    """Rotations by ``angle`` ``(..., l)`` about constant unit axes (Rodrigues): ``kx`` ``(l, 3,
    3)`` each axis's cross-product matrix, ``kk = kx @ kx``; returns ``(..., l, 3, 3)``."""
    s, c = jnp.sin(angle)[..., None, None], jnp.cos(angle)[..., None, None]
    eye = np.broadcast_to(np.eye(3, dtype=np.float32), kx.shape)
    return jnp.asarray(eye) + s * kx + (1.0 - c) * kk


@dataclass(frozen=True, eq=False)
class _Level:
    """The frames of one depth: indices and constants, ``l`` frames."""

    frames: np.ndarray  # (l,) their indices (contiguous: frames are numbered level by level)
    parent: np.ndarray  # (l,) their parents' positions in the level before (the world: 0)
    pos: np.ndarray  # (l, 3) offset in the parent
    rot: np.ndarray  # (l, 3, 3) rotation in the parent
    joint: np.ndarray  # (l,) q index of the hinge (0 where none)
    hinge: np.ndarray  # (l,) 1 where a hinge turns the frame, else 0
    qpos0: np.ndarray  # (l,)
    anchor: np.ndarray  # (l, 3) the hinge's anchor in the frame
    kx: np.ndarray  # (l, 3, 3) cross-product matrix of the hinge's unit axis
    kk: np.ndarray  # (l, 3, 3) kx @ kx


@dataclass(frozen=True, eq=False)
class _Levels:
    """``TreeFK``'s bodies as frames of at most one hinge each (a body with ``k`` hinges is
    ``k`` frames, the first with the body's offset, the others at its origin), grouped by depth
    in the tree: the forward pass computes one depth at a time, every frame of it at once."""

    n_frames: int
    levels: tuple[_Level, ...]
    body_frame: np.ndarray  # (n_bodies,) each body's last frame
    joint_frame: dict[int, int]  # q index -> its frame
    joint_body: dict[int, int]  # q index -> its body slot
    joint_axis: dict[int, np.ndarray]  # q index -> unit axis in its frame
    joint_anchor: dict[int, np.ndarray]  # q index -> anchor in its frame

    @classmethod
    def of(cls, bodies: Sequence[_Body]) -> _Levels:
        rows: list[dict] = []
        body_frame: list[int] = []
        depth: list[int] = []
        joint_frame: dict[int, int] = {}
        joint_body: dict[int, int] = {}
        joint_axis: dict[int, np.ndarray] = {}
        joint_anchor: dict[int, np.ndarray] = {}
        for slot, body in enumerate(bodies):
            parent = -1 if body.parent < 0 else body_frame[body.parent]
            hinges = body.joints or ((None, np.zeros(3), np.zeros(3), 0.0),)
            for k, (qi, axis, anchor, qpos0) in enumerate(hinges):
                unit = np.asarray(axis, np.float64)
                unit = unit / np.linalg.norm(unit) if qi is not None else np.array([0.0, 0, 1])
                frame = len(rows)
                rows.append(
                    {
                        "parent": parent,
                        "pos": body.pos if k == 0 else np.zeros(3),
                        "rot": body.rot if k == 0 else np.eye(3),
                        "joint": 0 if qi is None else qi,
                        "hinge": 0.0 if qi is None else 1.0,
                        "qpos0": qpos0,
                        "anchor": np.asarray(anchor, np.float64),
                        "axis": unit,
                    }
                )
                depth.append(0 if parent < 0 else depth[parent] + 1)
                if qi is not None:
                    joint_frame[qi] = frame
                    joint_body[qi] = slot
                    joint_axis[qi] = unit.astype(np.float32)
                    joint_anchor[qi] = np.asarray(anchor, np.float32)
                parent = frame
            body_frame.append(len(rows) - 1)
        n = len(rows)
        # number the frames level by level (a level's frames contiguous, the world last)
        order = sorted(range(n), key=lambda i: depth[i])  # stable: tree order within a level
        new = {old: k for k, old in enumerate(order)}
        start: dict[int, int] = {}  # each level's first frame
        for k, i in enumerate(order):
            start.setdefault(depth[i], k)
        levels = []
        for d in range(max(depth) + 1 if depth else 0):
            idx = [i for i in order if depth[i] == d]
            pick = [rows[i] for i in idx]
            axes = np.stack([r["axis"] for r in pick])
            kx = np.zeros((len(pick), 3, 3))
            kx[:, 0, 1], kx[:, 0, 2] = -axes[:, 2], axes[:, 1]
            kx[:, 1, 0], kx[:, 1, 2] = axes[:, 2], -axes[:, 0]
            kx[:, 2, 0], kx[:, 2, 1] = -axes[:, 1], axes[:, 0]
            levels.append(
                _Level(
                    frames=np.array([new[i] for i in idx], np.int32),
                    parent=np.array(
                        [0 if r["parent"] < 0 else new[r["parent"]] - start[d - 1] for r in pick],
                        np.int32,
                    ),
                    pos=np.stack([r["pos"] for r in pick]).astype(np.float32),
                    rot=np.stack([r["rot"] for r in pick]).astype(np.float32),
                    joint=np.array([r["joint"] for r in pick], np.int32),
                    hinge=np.array([r["hinge"] for r in pick], np.float32),
                    qpos0=np.array([r["qpos0"] for r in pick], np.float32),
                    anchor=np.stack([r["anchor"] for r in pick]).astype(np.float32),
                    kx=kx.astype(np.float32),
                    kk=(kx @ kx).astype(np.float32),
                )
            )
        body_frame = [new[f] for f in body_frame]
        joint_frame = {qi: new[f] for qi, f in joint_frame.items()}
        return cls(
            n_frames=n,
            levels=tuple(levels),
            body_frame=np.array(body_frame, np.int32),
            joint_frame=joint_frame,
            joint_body=joint_body,
            joint_axis=joint_axis,
            joint_anchor=joint_anchor,
        )


def points_named(fk: TreeFK, q: jax.typing.ArrayLike) -> Mapping[Point, jax.Array]:
    """``{point: (..., 3)}`` of ``fk.points(q)`` (notebooks, tests)."""
    p = fk.points(q)
    return {name: p[..., i, :] for i, name in enumerate(fk.point_names)}
