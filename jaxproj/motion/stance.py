"""The stance IK of a whole-body motion as one JAX program (``jaxproj.motion.feet``'s solver).

``plant(feet, plan)`` runs, for one motion of ``T`` frames, what ``feet._plant_feet`` describes:
a ``lax.scan`` over the frames whose step is one Levenberg-Marquardt solve (``PLANT_ITERATIONS``
steps, a fixed count) over the root's position and the stance legs' joints, a target for each
stance foot anchored when its run of contact is first needed and anchored anew where the solve
left the foot out of reach, the root's step bounded by the plan's budget (a longer one cut, the
stance legs solved again with the root held there); then every swing foot below the floor
lifted onto it (a Gauss-Newton solve per frame and foot, ``vmap``ped over both). ``plant_many``
is the same ``vmap``ped over motions padded to one length: many recordings in one program.

The residuals and their weights are ``feet``'s (its module doc): each foot's reference point
against its target (m), its orientation against level at its touchdown heading
(``PLANT_ORIENTATION`` m per rad), pulls of the root (``PLANT_ROOT_PULL``) and of each leg joint
(``PLANT_PULL``) toward the values given; steps of at most 0.2 rad (m), within the joint limits.
The Jacobian comes from one forward pass (``robots.kinematics.TreeFK.jacobian_columns``, in
the root body's frame): the position rows' exact, the orientation rows' the foot's angular
velocity per unit of each joint (the error's derivative at the target, as the host solver this
replaced had it; the exact derivative of the error moved the answers where a sole cannot be
level, and measured worse: UTKinect s07 e01's stance sliding p95 4.12 cm/s against 2.83). A
variable a frame does not solve for (the root where a foot fades in or out, a leg not in
contact) has its column zeroed and stays. Against that host solver (NumPy float64 and MuJoCo's
``mj_jac``) on the same inputs (s07 e01, 1,018 frames, the 2-core VM): roots within 0.72 mm,
angles within 0.77 deg (median 4.5e-5 deg).

Shapes (one motion; ``plant_many`` adds a leading ``B``): ``T`` frames, ``J`` robot joints, ``K``
feet. Float32 throughout.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.robots import Robot
from jaxproj.robots.base import joint_qpos_index
from jaxproj.robots.kinematics import TreeFK

_HIGHEST = jax.lax.Precision.HIGHEST

PLANT_ITERATIONS = 30
"""Levenberg-Marquardt steps of each frame's stance IK, and at most as many Gauss-Newton steps
of a swing foot's lift."""
PLANT_ORIENTATION = 0.05
"""m per rad: the weight of the sole's orientation error against its position error. Low, so
that where an ankle at its limit cannot hold the sole level at its target the sole tilts
rather than the foot slides: at 0.2, on the CMU bend-over clip 131_01 (120 fps), the left
ankle's pitch sat at its -50 deg limit and the right ankle's roll at its 15 deg over frames
348-362, the feet missed their targets by 2-5 cm, and the re-anchored targets slid them up
to 12 m/s (stance sliding p95 15.4 cm/s; 3.3 at 0.05, 9.3 at 0.1; the stance soles' tilt
median 4.3 -> 3.8 deg there, 0.1 -> 1.1-1.4 deg on the Kinect recordings, whose sliding p95
fell from 1.8-4.7 to 1.1-2.2 cm/s; ``benchmarks.whole_body``; measured with the host solver
this one replaced, 2026-11-29). A second solve at a low weight only where the first missed by
more than 5 mm left 6.3 cm/s: the switch between the two moves the foot."""
PLANT_PULL = 0.01
"""m per rad: the pull of each leg joint toward the retargeted angle."""
PLANT_ROOT_PULL = 0.5
"""The pull of the root's position toward where the height and stance rules put it (m per m):
the stance IK moves the root rather than slide a foot."""
PLANT_REACH = 0.03
"""m: a stance foot the IK leaves farther than this from its target is anchored anew at the
next frame, where it is then (a slide, not a leg stretched after an unreachable point)."""
UNBOUNDED = 1e9
"""m: a budget that bounds nothing (a recording centred on its pelvis)."""
MAX_STEP = 0.2
"""rad (m): the largest change of one variable in one solver step."""
LIFT_TOLERANCE = 1e-4
"""m: a swing foot's lowest point this far below the floor counts as on it."""


def _foot_points(
    model: mujoco.MjModel, data: mujoco.MjData, bodies: list[int], root: int
) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(P, 3)`` in body ``root``'s frame and radii ``(P,)`` whose lowest surface is
    every geom's of ``bodies`` (``data``'s pose): box corners (radius 0), sphere centres,
    capsule ends."""
    r_root, x_root = data.xmat[root].reshape(3, 3), data.xpos[root]
    pts, rad = [], []
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) not in bodies:
            continue
        kind, size = int(model.geom_type[g]), model.geom_size[g]
        c, r = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
            local = c + (signs * size[:3]) @ r.T
            radius = np.zeros(8)
        elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            local, radius = c[None], np.array([size[0]])
        elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = r[:, 2] * size[1]
            local, radius = np.stack([c - axis, c + axis]), np.full(2, size[0])
        else:
            continue
        pts.append((local - x_root) @ r_root)
        rad.append(radius)
    if not pts:
        return np.zeros((0, 3)), np.zeros(0)
    return np.concatenate(pts), np.concatenate(rad)


def _leg_joints(model: mujoco.MjModel, foot: int, root: int) -> list[int]:
    """The hinge joints between the root body and ``foot`` (joint ids), root first."""
    out: list[int] = []
    body = foot
    while body not in (root, 0):
        out = [j for j in range(model.njnt) if model.jnt_bodyid[j] == body
               and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE] + out  # fmt: skip
        body = int(model.body_parentid[body])
    return out


def subtree(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and every body below it (ids, ``body`` first)."""
    out = [body]
    for b in range(model.nbody):
        if b not in out and int(model.body_parentid[b]) in out:
            out.append(b)
    return out


@dataclass(frozen=True, eq=False)
class Feet:
    """A robot's feet for the stance IK, read from its MJCF at its standing posture (``of``).

    The solver's variables ``x`` ``(V,)`` are the root's position (3) then each leg's joints
    (``cols``: their columns of the robot's angles, leg after leg).

    Attributes:
      fk: each foot's points in the root body's frame: its sole's reference point (the mean of
        its geoms' lowest points), that point plus each unit axis of the foot's frame, then its
        geoms' lowest points (``P`` per foot, a shorter foot's list padded with its first).
      cols: ``(V - 3,)`` int, the legs' joints' columns.
      owner: ``(V,)`` int, each variable's foot (``-1``: the root).
      lo, hi: ``(V,)`` the variables' bounds (the root's infinite).
      height: ``(K,)`` m, how high each sole's reference point is above its lowest point when the
        foot is level (standing): where a stance foot's point is held.
      radius: ``(K, P)`` m, the radii of the feet's lowest points (0 for a box corner).
    """

    fk: TreeFK
    cols: np.ndarray
    owner: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    height: np.ndarray
    radius: np.ndarray

    @property
    def n_feet(self) -> int:
        """``K``."""
        return len(self.height)

    @staticmethod
    @functools.cache
    def of(robot: Robot, feet: tuple[str, ...]) -> Feet:
        """The feet named ``feet`` (foot bodies of ``robot``'s MJCF, ``Figure.feet``'s first
        entries) read once per robot.

        Raises:
          ConfigError: a foot body the MJCF lacks, a foot without geoms, legs sharing a joint.
        """
        model = robot.load_model("fixed")
        data = mujoco.MjData(model)
        data.qpos[joint_qpos_index(model, robot.joint_names)] = robot.standing
        mujoco.mj_kinematics(model, data)
        root = int(next(b for b in range(1, model.nbody) if model.body_parentid[b] == 0))
        names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j): j
                 for j in range(model.njnt)}  # fmt: skip
        column = {names[n]: i for i, n in enumerate(robot.joint_names) if n in names}
        points: list[tuple[str, tuple[float, float, float]]] = []
        cols: list[int] = []
        owner: list[int] = [-1, -1, -1]
        heights, radii, clouds = [], [], []
        for k, name in enumerate(feet):
            foot = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            if foot < 0:
                raise ConfigError(f"{robot.name}: the MJCF has no foot body {name!r}")
            pts, rad = _foot_points(model, data, subtree(model, foot), foot)
            if not len(pts):
                raise ConfigError(f"{robot.name}: foot {name!r} has no box, sphere or capsule")
            ref = pts.mean(axis=0)
            heights.append(float(ref[2] - np.min(pts[:, 2] - rad)))
            clouds.append((name, ref, pts))
            radii.append(rad)
            for j in _leg_joints(model, foot, root):
                if column[j] in cols:
                    raise ConfigError(f"{robot.name}: two feet's legs share a joint")
                cols.append(column[j])
                owner.append(k)
        n = max(len(r) for r in radii)
        for name, ref, pts in clouds:
            pts = np.concatenate([pts, np.repeat(pts[:1], n - len(pts), axis=0)])
            axes = [ref + e for e in np.eye(3)]
            points += [(name, (float(p[0]), float(p[1]), float(p[2]))) for p in (ref, *axes, *pts)]
        radius = np.stack([np.concatenate([r, np.repeat(r[:1], n - len(r))]) for r in radii])
        root_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, root)
        fk = TreeFK.from_model(model, robot.joint_names, points, base=root_name)
        c = np.array(cols, np.int64)
        inf = np.full(3, np.inf)
        return Feet(fk, c, np.array(owner, np.int64),
                    np.concatenate([-inf, robot.lower[c]]).astype(np.float32),
                    np.concatenate([inf, robot.upper[c]]).astype(np.float32),
                    np.array(heights, np.float32), radius.astype(np.float32))  # fmt: skip

    def frames(self, q: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        """``(J,)`` angles -> each foot's reference point ``(K, 3)``, rotation ``(K, 3, 3)``
        and lowest points ``(K, P, 3)``, in the root body's frame."""
        pts = self.fk.points(q).reshape(self.n_feet, -1, 3)
        ref = pts[:, 0]
        rot = jnp.swapaxes(pts[:, 1:4] - ref[:, None], -1, -2)  # columns: the foot's axes
        return ref, rot, pts[:, 4:]

    @functools.cached_property
    def _columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.fk.columns(self.cols.tolist())

    def linear(self, q: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``(J,)`` angles -> every point of ``fk`` ``(K, 4 + P, 3)`` in the root body's frame
        and its derivatives by the legs' joints ``(K, 4 + P, 3, V - 3)`` (``TreeFK``'s
        geometric Jacobian: one forward pass)."""
        pts, d = self.fk.jacobian_columns(q, *self._columns)
        k = self.n_feet
        return pts.reshape(k, -1, 3), d.reshape(k, -1, 3, d.shape[-1])


class Plan(NamedTuple):
    """What the stance IK needs of one motion (host arrays, or ``(B, ...)`` for ``plant_many``).

    Attributes:
      angles: ``(T, J)`` the robot's joint angles as retargeted, rad.
      root: ``(T, 3)`` m, the root's positions by the height and stance rules.
      rot: ``(T, 3, 3)`` the root body's orientation in the world.
      which: ``(T, K)`` int, the run of contact whose target each frame and foot takes (a
        number that rises with the runs; ``-1``: none).
      weight: ``(T, K)`` each foot's weight, 1 inside its runs, fading to 0 around them.
      start, end: ``(T, K)`` int, that run's first frame and the frame after its last.
      budget: ``(T,)`` m, the most the root may move into each frame (``UNBOUNDED``: no bound).
      swing: ``(T, K)`` bool, frames whose foot is lifted onto the floor where below it.
    """

    angles: Any
    root: Any
    rot: Any
    which: Any
    weight: Any
    start: Any
    end: Any
    budget: Any
    swing: Any


def _bounded(last: jax.Array, here: jax.Array, step: jax.Array) -> jax.Array:
    """``(3,)`` ``here`` moved toward ``last`` until it is at most ``step`` from it: the
    vertical part of the move cut first, then the horizontal one."""
    d = here - last
    flat = jnp.sqrt(d[0] ** 2 + d[1] ** 2)
    scale = step / jnp.maximum(flat, 1e-30)
    horizontal = last + jnp.stack([d[0] * scale, d[1] * scale, jnp.zeros_like(d[2])])
    rise = jnp.sqrt(jnp.maximum(step * step - flat * flat, 0.0))
    vertical = last + jnp.stack([d[0], d[1], jnp.where(d[2] < 0, -rise, rise)])
    short = jnp.sqrt(jnp.sum(d * d)) <= step
    return jnp.where(short, here, jnp.where(flat >= step, horizontal, vertical))


def foot_jacobians(
    feet: Feet, x: jax.Array, q: jax.Array, rot: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """The feet in the world with the root at ``x[:3]`` turned by ``rot`` ``(3, 3)`` and the
    legs' joints ``x[3:]`` (the rest of the angles ``q`` ``(J,)``): each sole's reference point
    ``(K, 3)`` and its Jacobian by ``x`` ``(K, 3, V)`` (MuJoCo's ``mj_jac`` translation part),
    each foot's axes (columns, ``(K, 3, 3)``) and its angular velocity per unit of each
    variable ``(K, 3, V)`` (``mj_jac``'s rotation part; 0 for the root's position)."""
    pts, d = feet.linear(q.at[jnp.asarray(feet.cols)].set(x[3:]))
    ref, d_ref = pts[:, 0], d[:, 0]  # (K, 3), (K, 3, C)
    frame = jnp.swapaxes(pts[:, 1:4] - ref[:, None], -1, -2)  # (K, 3, 3): columns
    d_frame = jnp.swapaxes(d[:, 1:4] - d_ref[:, None], 1, 2)  # (K, 3, 3, C)
    r = rot @ frame
    d_r = jnp.einsum("ij,kjlc->kilc", rot, d_frame, precision=_HIGHEST)
    # a rotation's rate w turns each axis r_i by w x r_i: w = 1/2 sum_i r_i x dr_i
    turn = 0.5 * jnp.sum(jnp.cross(jnp.broadcast_to(r[..., None], d_r.shape), d_r, axis=1), axis=2)
    eye = jnp.broadcast_to(jnp.eye(3), (feet.n_feet, 3, 3))
    j_point = jnp.concatenate(
        [eye, jnp.einsum("ij,kjc->kic", rot, d_ref, precision=_HIGHEST)], axis=-1
    )
    return x[None, :3] + ref @ rot.T, j_point, r, jnp.concatenate([0.0 * eye, turn], axis=-1)


def _levenberg_marquardt(
    feet: Feet,
    x0: jax.Array,
    mask: jax.Array,
    q: jax.Array,
    rot: jax.Array,
    weight: jax.Array,
    target_p: jax.Array,
    target_r: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    """One frame's stance IK from ``x0`` (which the pulls hold to), the variables ``mask``
    solves for: ``(V,)`` answer and each foot's distance to its target ``(K,)``, m."""
    pull = jnp.where(jnp.arange(len(mask)) < 3, PLANT_ROOT_PULL, PLANT_PULL)

    def linear(x: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        """The residual ``(R,)``, its Jacobian ``(R, V)`` (the masked columns zero) and each
        foot's miss ``(K,)`` at ``x``."""
        point, j_point, r, j_turn = foot_jacobians(feet, x, q, rot)
        off = point - target_p
        err_r = -0.5 * jnp.sum(jnp.cross(r, target_r, axis=1), axis=2)  # -1/2 sum_i r_i x t_i
        w = weight[:, None, None]
        res = jnp.concatenate([pull * (x - x0), (weight[:, None] * off).ravel(),
                               (weight[:, None] * PLANT_ORIENTATION * err_r).ravel()])  # fmt: skip
        jac = jnp.concatenate([jnp.diag(pull), (w * j_point).reshape(-1, len(x)),
                               (w * PLANT_ORIENTATION * j_turn).reshape(-1, len(x))])  # fmt: skip
        return res, jac * mask[None], jnp.sqrt(jnp.sum(off * off, axis=-1))

    keep = jnp.diag(1.0 - mask)
    lo, hi = jnp.asarray(feet.lo), jnp.asarray(feet.hi)

    def step(_: int, state: tuple) -> tuple:
        x, res, jac, miss, mu = state
        a = jac.T @ jac + mu * jnp.eye(len(x)) + keep
        d = jnp.linalg.solve(a, -jac.T @ res)
        d = d * jnp.minimum(1.0, MAX_STEP / jnp.maximum(jnp.max(jnp.abs(d)), 1e-12))
        trial = jnp.clip(x + d, lo, hi)
        res_t, jac_t, miss_t = linear(trial)
        better = res_t @ res_t < res @ res
        pick = functools.partial(jnp.where, better)
        return (pick(trial, x), pick(res_t, res), pick(jac_t, jac), pick(miss_t, miss),
                jnp.where(better, mu * 0.3, mu * 10.0))  # fmt: skip

    res, jac, miss = linear(x0)
    state = (x0, res, jac, miss, jnp.float32(1e-4))
    x, _, _, miss, _ = jax.lax.fori_loop(0, PLANT_ITERATIONS, step, state)
    return x, miss


def _anchor(
    feet: Feet, angles: jax.Array, rot: jax.Array, at: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Each foot's target from its frame's ``angles`` ``(K, J)`` and root orientation ``rot``
    ``(K, 3, 3)`` with the root ``at`` ``(K, 3)``: where the uncorrected sole's reference point
    is, at its standing height, level, with the foot's heading: ``((K, 3), (K, 3, 3))``."""
    k = jnp.arange(feet.n_feet)
    ref, frame, _ = jax.vmap(feet.frames)(angles)  # (K, K, ...): foot k's from frame k's angles
    here = at + jnp.einsum("kij,kj->ki", rot, ref[k, k])
    r0 = jnp.einsum("kij,kjl->kil", rot, frame[k, k])
    c, s = r0[:, 0, 0], r0[:, 1, 0]
    norm = jnp.maximum(jnp.sqrt(c * c + s * s), 1e-12)
    c, s = c / norm, s / norm
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    turn = jnp.stack([jnp.stack(r, -1) for r in rows], axis=-2)
    return jnp.concatenate([here[:, :2], jnp.asarray(feet.height)[:, None]], axis=1), turn


def _lift(
    feet: Feet, k: jax.Array, angles: jax.Array, root: jax.Array, rot: jax.Array, swing: jax.Array
) -> jax.Array:
    """Foot ``k``'s leg joints (returned as all ``V - 3`` leg variables, the other legs' as
    given) with its lowest point lifted onto the floor where it is below it and ``swing``:
    Gauss-Newton on that point's height (the point lowest at the start), pulled toward the
    given angles, stopped once it is within ``LIFT_TOLERANCE``."""
    cols = jnp.asarray(feet.cols)
    mask = (jnp.asarray(feet.owner[3:]) == k).astype(jnp.float32)
    given = angles[cols]
    radius = jnp.asarray(feet.radius)[k]

    def heights(x: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Foot ``k``'s lowest points' heights ``(P,)`` and their derivatives ``(P, V - 3)``."""
        pts, d = feet.linear(angles.at[cols].set(x))
        z = root[2] + pts[k, 4:] @ rot[2] - radius
        return z, jnp.einsum("j,pjc->pc", rot[2], d[k, 4:], precision=_HIGHEST)

    i = jnp.argmin(heights(given)[0])
    lo, hi = jnp.asarray(feet.lo[3:]), jnp.asarray(feet.hi[3:])
    keep = jnp.diag(1.0 - mask)

    def below(x: jax.Array) -> tuple[jax.Array, jax.Array]:
        z, dz = heights(x)
        return z[i], dz[i]

    def step(state: tuple) -> tuple:
        n, x, h, g = state
        jac = jnp.concatenate([(g * mask)[None], PLANT_PULL * jnp.diag(mask)])
        res = jnp.concatenate([h[None], PLANT_PULL * (x - given)])
        d = jnp.linalg.solve(jac.T @ jac + 1e-6 * jnp.eye(len(x)) + keep, -jac.T @ res)
        d = d * jnp.minimum(1.0, MAX_STEP / jnp.maximum(jnp.max(jnp.abs(d)), 1e-12))
        x = jnp.clip(x + d, lo, hi)
        return (n + 1, x, *below(x))

    def going(state: tuple) -> jax.Array:
        n, _, h, _ = state
        return swing & (n < PLANT_ITERATIONS) & (h < -LIFT_TOLERANCE)

    return jax.lax.while_loop(going, step, (0, given, *below(given)))[1]


def plant(feet: Feet, plan: Plan) -> tuple[jax.Array, jax.Array]:
    """One motion's stance feet planted and swing feet lifted (module doc): ``((T, J)
    angles, (T, 3) root positions)``. Traceable; ``feet`` static."""
    p = Plan(*(jnp.asarray(a) for a in plan))
    n, k = p.which.shape
    cols = jnp.asarray(feet.cols)
    owner = jnp.asarray(feet.owner)

    def frame(carry: tuple, t: jax.Array) -> tuple[tuple, tuple[jax.Array, jax.Array]]:
        last, target_p, target_r, run, far, far_at = carry
        given = p.root[t]
        moved = jnp.concatenate([last[:2] + given[:2] - p.root[t - 1, :2], given[2:]])
        pos = jnp.where(t > 0, _bounded(last, moved, p.budget[t]), given)
        which, weight, t0 = p.which[t], p.weight[t], p.start[t]
        active = which >= 0
        # a run's target, when first needed: its touchdown (the root where it will be then);
        # or, where the last frame left the foot out of reach, where the foot is here
        new = active & (run != which)
        at_frame = jnp.where(new, jnp.maximum(t0, t), t)
        at = jnp.where((new & (t0 > t))[:, None], pos[None] + p.root[t0] - given[None], pos[None])
        at = jnp.where(new[:, None], at, far_at)
        new_p, new_r = _anchor(feet, p.angles[at_frame], p.rot[at_frame], at)
        fresh = new | far
        target_p = jnp.where(fresh[:, None], new_p, target_p)
        target_r = jnp.where(fresh[:, None, None], new_r, target_r)
        run = jnp.where(new, which, run)
        q = p.angles[t]
        legs = active[jnp.maximum(owner, 0)]
        move_root = jnp.any(active) & jnp.all(~active | (weight >= 1.0))
        mask = jnp.where(owner < 0, move_root, legs).astype(jnp.float32)
        solve = functools.partial(_levenberg_marquardt, feet, q=q, rot=p.rot[t], weight=weight,
                                  target_p=target_p, target_r=target_r)  # fmt: skip

        def attempt(state: tuple) -> tuple:
            # the first solve; then, where its root steps past the budget, again with the root
            # held at the bound: one copy of the solver in the program, and in a vmapped
            # batch a second pass only while some motion's frame needs one
            i, _, _, start, free = state
            x, miss = solve(jnp.concatenate([start, q[cols]]), free)
            held = jnp.where(t > 0, _bounded(last, x[:3], p.budget[t]), x[:3])
            return i + 1, x, miss, held, free * (owner >= 0).astype(jnp.float32)

        def more(state: tuple) -> jax.Array:
            i, x, _, start, _ = state
            return jnp.any(active) & ((i == 0) | ((i == 1) & jnp.any(start != x[:3])))

        x0 = jnp.concatenate([pos, q[cols]])
        state = (0, x0, jnp.zeros(k, jnp.float32), pos, mask)
        _, x, miss, _, _ = jax.lax.while_loop(more, attempt, state)
        pos = x[:3]
        out = q.at[cols].set(x[3:])
        # a target out of reach inside its run: anchored anew next frame, where the foot is
        far = active & (t0 <= t) & (t < p.end[t] - 1) & (miss > PLANT_REACH)
        after = jnp.minimum(t + 1, n - 1)
        far_at = jnp.broadcast_to(pos + p.root[after] - given, (k, 3))
        return (pos, target_p, target_r, run, far, far_at), (out, pos)

    start = (p.root[0], jnp.zeros((k, 3)), jnp.broadcast_to(jnp.eye(3), (k, 3, 3)),
             jnp.full((k,), -1, p.which.dtype), jnp.zeros(k, bool), jnp.zeros((k, 3)))  # fmt: skip
    _, (out, pos) = jax.lax.scan(frame, start, jnp.arange(n))
    # the swing feet below the floor, every frame and foot at once
    feet_k = jnp.arange(k)
    each_foot = jax.vmap(functools.partial(_lift, feet), (0, None, None, None, 0))
    lifted = jax.vmap(each_foot, (None, 0, 0, 0, 0))(feet_k, out, pos, p.rot, p.swing)
    own = feet.owner[3:]  # each leg variable's foot
    mine = lifted[:, own, np.arange(len(own))]  # (T, V - 3): by the variable's own foot
    return out.at[:, cols].set(jnp.where(p.swing[:, own], mine, out[:, cols])), pos


def plant_many(feet: Feet, plan: Plan) -> tuple[jax.Array, jax.Array]:
    """``plant`` over ``B`` motions padded to one length (``plan``'s arrays ``(B, T, ...)``;
    a padding frame takes no run, ``which = -1``, and no lift): ``((B, T, J), (B, T, 3))``."""
    return jax.vmap(functools.partial(plant, feet))(plan)


@functools.cache
def feet_of(robot: Robot) -> Feet:
    """``Feet.of`` the robot's first two feet (``Figure.feet``), read once per robot (the
    stance IK's programs and ``whole_body``'s host stage share it)."""
    assert robot.mjcf is not None
    return Feet.of(robot, tuple(b for b, _ in robot.mjcf.figure.feet)[:2])


def _plant_robot(plan: Plan, robot: Robot) -> tuple[jax.Array, jax.Array]:
    return plant(feet_of(robot), plan)


def _plant_many_robot(plan: Plan, robot: Robot) -> tuple[jax.Array, jax.Array]:
    return plant_many(feet_of(robot), plan)


plant_jit = jit(_plant_robot, static_argnames=("robot",))
"""``plant`` of ``robot``'s feet, compiled (``robot`` static: one program per robot and length)."""
plant_many_jit = jit(_plant_many_robot, static_argnames=("robot",))
"""``plant_many`` of ``robot``'s feet, compiled."""
