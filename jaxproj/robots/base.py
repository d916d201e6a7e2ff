"""The robot spec: a ``Robot`` is data (joints, limits, posture, chains, IK, MJCF, export hooks).

A robot module builds one ``Robot`` from its own constants and registers it in
``jaxproj.robots`` (``register``); everything above ``robots/`` takes a ``robot: Robot``
argument instead of reaching for one robot's module constants. The NAO H25
(``jaxproj.robots.nao_h25``) is the one instance shipped; ``tests/toy_robot.py`` is a second.

Models: PyRoki's ``Robot.from_urdf`` (one frozen record of the kinematic data), mink's small
base classes, GMR's per-(source, robot) IK configs (here: a ``Chain`` holds the human bones it
reads and its own IK).

A ``Robot`` is not a pytree: its arrays are constants of the traces that use them (as module
constants were before), and it hashes by identity (``eq=False``), so it can be a static argument
of a jitted function or a key of a cache. Its arrays are read-only float32 copies.

Shapes: a configuration is ``(..., n_joints)`` joint angles in ``joint_names`` order (rad); the
driven angles (what the IK computes and the projection predicts) are ``(..., n_driven)`` in
``driven_joints`` order.

Size: over 500 lines: the one Robot spec (fields, validation, limits, rated speeds, coupled
ranges and their clip, the MJCF loading) that every layer above reads; split the coupled ranges
out when a second kind of limit comes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj._internal.shards import over_rows
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONE_NAMES, resolve_bones

ChainIK = Callable[[np.ndarray], np.ndarray]
"""IK of one chain: ``(N, 3 * len(bones))`` bone directions (the chain's descriptor columns,
bone after bone, body frame) -> ``(N, len(joints))`` float32 angles, rad."""

DescriptorIK = Callable[..., jax.Array]
"""IK of all driven joints: ``(d, bones)`` with ``d`` ``(..., 3 * n_bones)`` descriptors of the
bone subset ``bones`` -> ``(..., n_driven)`` float32 angles, rad (within limits, finite)."""

SPEED_KINDS: tuple[str, ...] = ("rated", "no-load")
"""Names of ``Robot.speed_limits``: ``"rated"``, the speeds a joint keeps at its motor's nominal
torque (what a motion meant for the robot should respect); ``"no-load"``, the theoretical maxima
(``Robot.velocity_limits``)."""

RATED_FRACTION = 0.75
"""Rated / no-load speed of a joint whose rated speed is not published (``Robot.speed_limits``,
and robot data filling the gaps of ``rated_speeds``). The NAO's published ratios lie on both
sides: 0.74 for its arm and head motors, 0.79 for its leg motors."""

CHAIN_SETS: tuple[str, ...] = ("upper", "whole")
"""Names of ``Robot.chain_set``: ``"upper"``, one projector per chain (``Robot.chains``);
``"whole"``, one chain over all driven joints (``Robot.whole_chain``)."""


def chain_columns(chain: Chain, bones: str | tuple[str, ...] = "upper") -> tuple[int, ...]:
    """The columns of a ``bones`` descriptor that hold ``chain``'s bones (3 per bone).

    Raises:
      ConfigError: a bone of the chain is not in ``bones``.
    """
    names = resolve_bones(bones)
    missing = [b for b in chain.bones if b not in names]
    if missing:
        raise ConfigError(f"chain {chain.name!r} needs the bones {missing}, absent from {bones!r}")
    return tuple(3 * names.index(b) + i for b in chain.bones for i in range(3))


@dataclass(frozen=True)
class Chain:
    """A kinematic chain: the human bones it reads and the robot joints it drives.

    Attributes:
      name: e.g. ``"head"``, ``"left_arm"``.
      bones: the descriptor bones (``skeleton.BONE_NAMES``) the chain's angles depend on.
      joints: the driven joints it determines (a subset of ``Robot.driven_joints``, in that order).
      ik: its IK from its own descriptor columns to its joints (``ChainIK``), or ``None``. Not part
        of a chain's equality or hash (chains compare by name, bones and joints).
      bandwidth: the mean-shift bandwidth its projector's landmarks take by default (tuned on
        training people; ``BuildConfig``), or ``None``: ``config.DEFAULT_LANDMARKS`` landmarks.
        Not part of equality or hash either.
      keep_bandwidth: the chain keeps ``bandwidth`` when ``BuildConfig.landmarks`` is one
        number (that number then sizes the other chains): for a chain whose input varies so
        little that a count target would bisect the bandwidth over many mean-shift runs (the
        NAO's head: the neck direction lies on a small cap of the sphere).
    """

    name: str
    bones: tuple[str, ...]
    joints: tuple[str, ...]
    ik: ChainIK | None = field(default=None, compare=False, repr=False)
    bandwidth: float | None = field(default=None, compare=False)
    keep_bandwidth: bool = field(default=False, compare=False)

    def solve(self, x: np.ndarray) -> np.ndarray:
        """``(N, 3 * len(bones))`` -> ``(N, len(joints))`` angles (``ik``); ConfigError if none."""
        if self.ik is None:
            raise ConfigError(f"chain {self.name!r} has no IK function")
        return self.ik(x)


@dataclass(frozen=True)
class Figure:
    """How the plots and videos of ``jaxproj.viz`` draw a robot as a stick figure (names in its
    MJCF). The defaults draw a plain figure: every body joined to its parent, no feet, no head.

    Attributes:
      label: the robot's name in captions and legends (e.g. ``"NAO"``; empty: ``Robot.title``).
      links: site pairs joined by a line in the report's sketch (``jaxproj.viz.report``);
        a site named ``l_*`` / ``r_*`` draws orange / blue.
      head: ``(body, length)``: the sketch's head point lies ``length`` m along the body's z
        axis from its origin, or ``None``: no head point.
      parents: the render's stick panel (``jaxproj.viz.panels``) joins each body named here to
        the body it maps to instead of its MJCF parent.
      feet: ``(body, site)`` pairs the stick panel joins (ankle to sole); the lowest of these
        sites in the standing posture sets its floor.
      head_geom: the geom whose centre is the stick panel's head marker, or ``None``.
    """

    label: str = ""
    links: tuple[tuple[str, str], ...] = ()
    head: tuple[str, float] | None = None
    parents: Mapping[str, str] = field(default_factory=dict)
    feet: tuple[tuple[str, str], ...] = ()
    head_geom: str | None = None


@dataclass(frozen=True)
class Mjcf:
    """A robot's MuJoCo model and the names in it that the evaluation uses.

    Attributes:
      path: the MJCF file.
      load: ``load(mount="free" | "fixed", without=())`` -> compiled ``mujoco.MjModel`` (the
        ``"fixed"`` mount welds the base to the world; ``without``: bodies removed with their
        subtrees).
      free_joint: name of the floating-base joint, or ``None``.
      arm_sites: side -> (shoulder, elbow, wrist) site names: the task-space metrics'
        points (``jaxproj.eval.metrics``); sides in the order of the metrics' side axis.
      fk_without: bodies that cannot move any ``arm_sites`` site (removed from the model the
        metrics' forward kinematics runs; speed only).
      hand_sites: end-effector sites (``jaxproj.eval.rollout.hand_error_cm``).
      split: rollout parts, part name -> bodies removed for it (``"upper"``: the legs' roots,
        ``"legs"``: the head's and arms' roots); empty: no split rollout.
      head_root: the body the head turns about (the split rollout's certificate), or ``None``.
      figure: how plots and videos draw the robot (``Figure``).
      warp_validated: whether the robot's Warp rollout was checked against C MuJoCo on a GPU
        (``jaxproj.eval.rollout``'s ``backend="auto"`` picks Warp only then).
    """

    path: Path
    load: Callable[..., mujoco.MjModel]
    free_joint: str | None = None
    arm_sites: Mapping[str, tuple[str, str, str]] = field(default_factory=dict)
    fk_without: tuple[str, ...] = ()
    hand_sites: tuple[str, ...] = ()
    split: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    head_root: str | None = None
    figure: Figure = field(default_factory=Figure)
    warp_validated: bool = False


@dataclass(frozen=True)
class Export:
    """A trajectory document a robot's own controller reads (e.g. NAOqi JSON for the NAO).

    ``jaxproj.io.motion_files`` dispatches ``save_motion`` / ``load_motion`` to it by ``suffix``.

    Attributes:
      name: e.g. ``"naoqi"``.
      suffix: the file extension, e.g. ``".json"``.
      check: ``check(robot, joints, lead_in)`` validates the export options (ConfigError)
        and returns them resolved.
      write: ``write(robot, angles (T, n_joints), times (T,), valid (T,), meta, options,
        confidence=None | (T,))`` -> the document's text.
      read: ``read(robot, path)`` -> ``(angles (T, n_joints) float32, times (T,) float64,
        valid (T,) bool, meta dict, confidence (T,) float32 or None)``; ``InputError`` /
        ``ConfigError`` for a bad file.
    """

    name: str
    suffix: str
    check: Callable[..., Any]
    write: Callable[..., str]
    read: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any], Any]]


@dataclass(frozen=True)
class CoupledLimit:
    """A joint's range as a piecewise-linear function of another joint's angle.

    The range of ``joint`` at a configuration is ``[lower(q_by), upper(q_by)]``, each the linear
    interpolation of its knots at the angle of ``by`` (``jnp.interp``: constant beyond the end
    knots), intersected with ``joint``'s own ``[Robot.lower, Robot.upper]``. A controller that
    enforces such an envelope (NAOqi's head anti-collision table) clips the follower to it; so
    does ``clip_coupled``.

    Attributes:
      joint: the limited joint (the follower).
      by: the joint whose angle sets the range (the leader); never itself a follower.
      knots: ``(k,)`` angles of ``by``, rad, strictly increasing (k >= 2).
      lower, upper: ``(k,)`` the range of ``joint`` at each knot, rad (``lower <= upper``).
      source: where the table comes from (a citation).
    """

    joint: str
    by: str
    knots: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        k = np.asarray(self.knots).shape
        arrays = {}
        for what in ("knots", "lower", "upper"):
            a = np.array(getattr(self, what), dtype=np.float32)
            if a.ndim != 1 or a.shape != k or len(a) < 2 or not np.isfinite(a).all():
                raise ConfigError(f"coupled limit of {self.joint!r}: {what} must be (k >= 2,) "
                                  f"finite, like knots {k}, got {a.shape}")  # fmt: skip
            a.flags.writeable = False
            arrays[what] = a
        if (np.diff(arrays["knots"]) <= 0).any():
            raise ConfigError(f"coupled limit of {self.joint!r}: knots must increase strictly")
        if (arrays["lower"] > arrays["upper"]).any():
            raise ConfigError(f"coupled limit of {self.joint!r}: lower > upper at some knot")
        if self.joint == self.by:
            raise ConfigError(f"coupled limit of {self.joint!r}: a joint cannot limit itself")
        for what, a in arrays.items():
            object.__setattr__(self, what, a)

    def bounds(self, lead: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``(lo, hi)``: the follower's range at leader angles ``lead`` (``(...,)``, jnp)."""
        lead = jnp.asarray(lead, jnp.float32)
        lo = jnp.interp(lead, jnp.asarray(self.knots), jnp.asarray(self.lower))
        hi = jnp.interp(lead, jnp.asarray(self.knots), jnp.asarray(self.upper))
        return lo, hi


def clip_coupled(robot: Robot, angles: jax.typing.ArrayLike, *, driven: bool = False) -> jax.Array:
    """Clip each follower of ``robot.coupled_limits`` to its range at its leader's angle.

    Traceable (jnp only, no host sync); float32. Only followers move: their leaders (and every
    other joint) are returned unchanged, so clip the leaders to their own limits first
    (``Robot.clip`` / ``Robot.clip_driven`` do both).

    Args:
      robot: the robot.
      angles: ``(..., n_joints)`` configurations, or with ``driven`` ``(..., n_driven)`` driven
        angles (a leader that is not driven is read at ``robot.standing``; a follower that is
        not driven is left alone: the standing posture lies inside every coupled range).
      driven: whether ``angles`` are driven angles.

    Returns:
      ``angles`` as float32 with every follower inside its coupled range.
    """
    q = jnp.asarray(angles, dtype=jnp.float32)
    names = robot.driven_joints if driven else robot.joint_names
    for limit in robot.coupled_limits:
        if limit.joint not in names:
            continue
        j = names.index(limit.joint)
        if limit.by in names:
            lead = q[..., names.index(limit.by)]
        else:
            lead = jnp.full(q.shape[:-1], robot.standing[robot.index(limit.by)], jnp.float32)
        lo, hi = limit.bounds(lead)
        q = q.at[..., j].set(jnp.clip(q[..., j], lo, hi))
    return q


def _vector(value: object, n: int, what: str) -> np.ndarray:
    a = np.array(value, dtype=np.float32)
    if a.shape != (n,):
        raise ConfigError(f"{what} must have shape ({n},) (one per joint), got {a.shape}")
    if not np.isfinite(a).all():
        raise ConfigError(f"{what} must be finite")
    a.flags.writeable = False
    return a


def _unique_names(names: Sequence[str], what: str) -> tuple[str, ...]:
    names = tuple(names)
    if not names or not all(isinstance(n, str) and n for n in names):
        raise ConfigError(f"{what} must be a non-empty tuple of non-empty str, got {names!r}")
    if len(set(names)) != len(names):
        raise ConfigError(f"{what} names a joint twice: {names}")
    return names


def driven_to_full(
    standing: np.ndarray, driven_index: np.ndarray, q_driven: jax.Array
) -> jax.Array:
    """``(..., n_driven)`` driven angles -> ``(..., n_joints)``; the rest at ``standing``.

    Args:
      standing: ``(n_joints,)`` the posture of the other joints, rad.
      driven_index: ``(n_driven,)`` positions of the driven joints in the configuration.
      q_driven: ``(..., n_driven)`` angles, rad.

    Returns:
      ``(..., n_joints)`` float32 configurations.
    """
    q_driven = jnp.asarray(q_driven, dtype=jnp.float32)
    base = jnp.broadcast_to(jnp.asarray(standing), (*q_driven.shape[:-1], len(standing)))
    return base.at[..., driven_index].set(q_driven)


def mj_joint_ids(model: mujoco.MjModel, joint_names: Sequence[str]) -> np.ndarray:
    """``(len(joint_names),)`` int64 MuJoCo joint id of each name; ConfigError if one is missing."""
    ids = np.empty(len(joint_names), dtype=np.int64)
    for i, name in enumerate(joint_names):
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise ConfigError(f"model has no joint named {name!r}")
        ids[i] = jid
    return ids


def mj_site_ids(model: mujoco.MjModel, site_names: Sequence[str]) -> list[int]:
    """MuJoCo site id of each name, in order; ConfigError if one is missing."""
    ids = []
    for name in site_names:
        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
        if sid < 0:
            raise ConfigError(f"model has no site named {name!r}")
        ids.append(int(sid))
    return ids


def joint_qpos_index(model: mujoco.MjModel, joint_names: Sequence[str]) -> np.ndarray:
    """``(len(joint_names),)`` int64: address in ``qpos`` of each named joint of ``model``."""
    return np.asarray(model.jnt_qposadr[mj_joint_ids(model, joint_names)], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class Robot:
    """A robot as data: what retargeting, evaluation and export need to know about it.

    Attributes:
      name: registry key, e.g. ``"nao_h25"``.
      title: human-readable name, e.g. ``"NAO H25 V5"``.
      joint_names: every joint, in configuration order (``n_joints``).
      lower, upper: ``(n_joints,)`` joint limits, rad (``lower <= upper``).
      standing: ``(n_joints,)`` the standing posture, rad (within the limits): every joint the IK
        does not drive is held there.
      driven_joints: the joints the IK drives (and the projection predicts), in driven order.
      chains: how the IK factorises (``Chain``); together they drive each driven joint once.
      ik: IK of all driven joints from a descriptor (``DescriptorIK``), or ``None``.
      velocity_limits: ``(n_joints,)`` maximum joint speeds, rad/s (> 0), or ``None``.
      rated_speeds: ``(n_joints,)`` joint speeds at the motors' nominal torque, rad/s
        (``0 < rated <= velocity_limits``), or ``None`` (``speed_limits("rated")`` then takes
        ``RATED_FRACTION`` of ``velocity_limits``).
      acceleration_limits: ``(n_joints,)`` rad/s^2 (> 0), or ``None``.
      coupled_joints: ``(leader, follower)`` pairs driven by one motor (follower := leader).
      loose_joints: driven joints whose IK truth is ill-conditioned in some poses (left out of
        ``jaxproj.eval.metrics.m_max_without`` by default).
      mjcf: the MuJoCo model (``Mjcf``), or ``None``.
      exports: controller documents by file suffix (``Export``), e.g. ``{".json": naoqi}``.
      traced_ik: the IK of all driven joints as a traceable function (``DescriptorIK``, called
        inside the jitted motion pipeline), or ``None`` when ``ik`` itself is traceable.
      whole_chain: the ``"whole"`` chain set's one chain (all driven joints), or ``None``: a
        chain over every bone of ``chains`` (in chain order) solved by ``ik``.
      elbow_pairs: ``(yaw, roll)`` joint pairs of elbows whose yaw is ill-defined when the
        elbow is straight (``jaxproj.motion.feasible``'s elbow rules); none: no such rule.
      ik_constants: constants of the IK that model files record (meta ``"ik"``); JSON numbers.
      coupled_limits: ranges of joints that depend on another joint's angle (``CoupledLimit``,
        e.g. the NAO's head anti-collision envelope), applied by ``clip`` / ``clip_driven``
        (``clip_coupled``); a follower is limited by one leader, never itself a leader.
      separate: a traceable ``separate(q, start=None)``: ``(..., n_driven) -> (..., n_driven)``
        that moves a pose out of the robot's self-collisions, changing it as little as it can,
        searching from ``q`` and, given a ``start`` of ``q``'s shape, from there too (the
        G1's: ``GenericIK.separate``), applied by ``playable`` after the clip (and by
        ``playable_motion`` from the previous frame's answer); ``None``: no such step.
      deviation_scale: the ``projection.confidence`` scale of the robot's default model (the
        p90 of its relaxed deviation on training people it did not see), or ``None``: the
        NAO's ``DEVIATION_SCALE``.
      track: a traceable ``((T, n_driven) answers, (T,) valid, (T, m) descriptors or None,
        bones) -> (T, n_driven)`` continuity
        pass over one motion's per-frame answers (the G1's: ``GenericIK.track``: each frame
        re-chosen, among poses with the same bone directions, nearest the previous output),
        applied by ``continuous`` before the smoother; ``None``: no such pass.
      track_step: the same pass one frame at a time, for streaming: a traceable ``((n_driven,)
        last output, (n_driven,) last valid answer, (n_driven,) this frame's answer, (m,) last
        valid descriptor, (m,) this frame's, bones) -> (n_driven,)`` (the G1's:
        ``GenericIK.track_step``); ``None``: no such pass. A robot with ``track`` gives both.
      track_bounds: a traceable ``((T,) valid, (T, m) descriptors, bones) -> (T, n_driven)``:
        how far each joint may move into each frame by ``track``'s rule (rad, ``inf``: no
        bound; the G1's: ``GenericIK.step_bounds``), applied by ``bound_steps`` after the
        smoother; ``None``: no bound.
      generic: the generic IK behind the hooks above (``jaxproj.robots.generic.GenericSolver``:
        its correspondence, settings and built solver), or ``None`` (a robot with its own IK).
      file: the robot file it was read from (``jaxproj.robots.robot_file``), or ``None``.

    Raises:
      ConfigError: any inconsistency (shapes, unknown or repeated names, limits, posture outside
        them, chains not covering the driven joints once, unknown bones, bad exports).
    """

    name: str
    title: str
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    standing: np.ndarray
    driven_joints: tuple[str, ...]
    chains: tuple[Chain, ...]
    ik: DescriptorIK | None = None
    velocity_limits: np.ndarray | None = None
    rated_speeds: np.ndarray | None = None
    acceleration_limits: np.ndarray | None = None
    coupled_joints: tuple[tuple[str, str], ...] = ()
    loose_joints: tuple[str, ...] = ()
    mjcf: Mjcf | None = None
    exports: Mapping[str, Export] = field(default_factory=dict)
    traced_ik: DescriptorIK | None = None
    whole_chain: Chain | None = None
    elbow_pairs: tuple[tuple[str, str], ...] = ()
    ik_constants: Mapping[str, float] = field(default_factory=dict)
    coupled_limits: tuple[CoupledLimit, ...] = ()
    separate: Callable[..., jax.Array] | None = field(default=None, compare=False)
    deviation_scale: float | None = None
    track: Callable[..., jax.Array] | None = field(default=None, compare=False)
    track_step: Callable[..., jax.Array] | None = field(default=None, compare=False)
    track_bounds: Callable[..., jax.Array] | None = field(default=None, compare=False)
    generic: Any = field(default=None, compare=False, repr=False)  # GenericSolver | None
    file: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if (self.track is None) != (self.track_step is None):
            raise ConfigError(f"robot {self.name!r}: give both track and track_step or neither "
                              "(retarget runs the one, streaming the other)")  # fmt: skip
        if not (isinstance(self.name, str) and self.name.isidentifier()):
            raise ConfigError(f"robot name must be an identifier (registry key), got {self.name!r}")
        if self.deviation_scale is not None and not (
            math.isfinite(self.deviation_scale) and self.deviation_scale > 0
        ):
            raise ConfigError(f"deviation_scale must be finite and > 0, got {self.deviation_scale}")
        joints = _unique_names(self.joint_names, "joint_names")
        n = len(joints)
        index = {j: i for i, j in enumerate(joints)}
        lower = _vector(self.lower, n, "lower")
        upper = _vector(self.upper, n, "upper")
        if (lower > upper).any():
            bad = [joints[i] for i in np.flatnonzero(lower > upper)]
            raise ConfigError(f"lower > upper for joints {bad}")
        standing = _vector(self.standing, n, "standing")
        outside = (standing < lower) | (standing > upper)
        if outside.any():
            bad = [joints[i] for i in np.flatnonzero(outside)]
            raise ConfigError(f"the standing posture is outside the limits at {bad}")
        driven = _unique_names(self.driven_joints, "driven_joints")
        unknown = [j for j in driven if j not in index]
        if unknown:
            raise ConfigError(f"driven_joints {unknown} are not in joint_names")
        self._check_chains(driven)
        limits = {}
        for what in ("velocity_limits", "rated_speeds", "acceleration_limits"):
            value = getattr(self, what)
            if value is not None:
                value = _vector(value, n, what)
                if (value <= 0).any():
                    raise ConfigError(f"{what} must be > 0")
            limits[what] = value
        rated, vmax = limits["rated_speeds"], limits["velocity_limits"]
        if rated is not None and (vmax is None or (rated > vmax).any()):
            raise ConfigError("rated_speeds need velocity_limits and must not exceed them")
        for pair in self.coupled_joints:
            if len(pair) != 2 or any(j not in index for j in pair):
                raise ConfigError(f"coupled_joints: {pair!r} is not a (leader, follower) of joints")
        loose = tuple(self.loose_joints)
        if any(j not in driven for j in loose):
            raise ConfigError(f"loose_joints {loose} must be driven joints")
        for suffix, export in self.exports.items():
            ok = isinstance(export, Export) and suffix == export.suffix
            if not (ok and suffix.startswith(".")):
                raise ConfigError(f"exports[{suffix!r}] must be an Export with that suffix")
        for pair in self.elbow_pairs:
            if len(pair) != 2 or any(j not in index for j in pair):
                raise ConfigError(f"elbow_pairs: {pair!r} is not a (yaw, roll) pair of joints")
        self._check_coupled_limits(index, standing)
        whole = self.whole_chain
        if whole is None:
            bones = tuple(dict.fromkeys(b for c in self.chains for b in c.bones))
            whole = Chain("whole", bones, driven)
        if not isinstance(whole, Chain) or tuple(whole.joints) != driven:
            raise ConfigError("whole_chain must be a Chain over all driven_joints, in order")
        if self.mjcf is not None and not isinstance(self.mjcf, Mjcf):
            raise ConfigError(f"mjcf must be an Mjcf or None, got {type(self.mjcf).__name__}")
        set_ = object.__setattr__
        set_(self, "joint_names", joints)
        set_(self, "driven_joints", driven)
        set_(self, "chains", tuple(self.chains))
        set_(self, "lower", lower)
        set_(self, "upper", upper)
        set_(self, "standing", standing)
        set_(self, "loose_joints", loose)
        set_(self, "coupled_joints", tuple((a, b) for a, b in self.coupled_joints))
        set_(self, "exports", dict(self.exports))
        set_(self, "whole_chain", whole)
        set_(self, "elbow_pairs", tuple((a, b) for a, b in self.elbow_pairs))
        set_(self, "ik_constants", dict(self.ik_constants))
        set_(self, "coupled_limits", tuple(self.coupled_limits))
        for what, value in limits.items():
            set_(self, what, value)
        set_(self, "_index", index)
        driven_index = np.array([index[j] for j in driven], dtype=np.int32)
        driven_index.flags.writeable = False
        set_(self, "_driven_index", driven_index)

    def _check_coupled_limits(self, index: Mapping[str, int], standing: np.ndarray) -> None:
        limits = tuple(self.coupled_limits)
        if not all(isinstance(c, CoupledLimit) for c in limits):
            raise ConfigError("coupled_limits must be a tuple of CoupledLimit")
        followers = [c.joint for c in limits]
        if len(set(followers)) != len(followers):
            raise ConfigError(f"coupled_limits limit a joint twice: {followers}")
        for c in limits:
            if c.joint not in index or c.by not in index:
                raise ConfigError(f"coupled limit {c.joint!r} by {c.by!r}: unknown joint")
            if c.by in followers:
                raise ConfigError(f"coupled limit by {c.by!r}: a leader cannot be a follower")
            lo, hi = (
                float(np.interp(standing[index[c.by]], c.knots, b)) for b in (c.lower, c.upper)
            )
            if not lo <= standing[index[c.joint]] <= hi:
                raise ConfigError(f"the standing posture is outside the coupled range of "
                                  f"{c.joint!r}")  # fmt: skip

    def _check_chains(self, driven: tuple[str, ...]) -> None:
        chains = tuple(self.chains)
        if not chains or not all(isinstance(c, Chain) for c in chains):
            raise ConfigError("chains must be a non-empty tuple of Chain")
        names = [c.name for c in chains]
        if len(set(names)) != len(names):
            raise ConfigError(f"chain names repeat: {names}")
        covered = [j for c in chains for j in c.joints]
        if sorted(covered) != sorted(driven):
            raise ConfigError(
                f"the chains must drive each driven joint exactly once; they drive {covered}, "
                f"the driven joints are {driven}"
            )
        for c in chains:
            if list(c.joints) != sorted(c.joints, key=driven.index):
                raise ConfigError(f"chain {c.name!r}: joints must be in driven_joints order")
            bad = [b for b in c.bones if b not in BONE_NAMES]
            if not c.bones or bad:
                raise ConfigError(f"chain {c.name!r}: unknown or no bones {bad}; use {BONE_NAMES}")

    # --- derived helpers ---------------------------------------------------------------------

    @property
    def n_joints(self) -> int:
        """Number of joints (the length of a configuration)."""
        return len(self.joint_names)

    @property
    def n_driven(self) -> int:
        """Number of driven joints."""
        return len(self.driven_joints)

    @property
    def driven_index(self) -> np.ndarray:
        """``(n_driven,)`` int32 positions of ``driven_joints`` in ``joint_names`` (read-only)."""
        return self._driven_index  # type: ignore[attr-defined]

    def index(self, name: str) -> int:
        """Position of joint ``name`` in ``joint_names``; ConfigError for an unknown name."""
        index: dict[str, int] = self._index  # type: ignore[attr-defined]
        if name not in index:
            raise ConfigError(f"{self.name} has no joint {name!r}; joints: {self.joint_names}")
        return index[name]

    def has_joint(self, name: str) -> bool:
        """Whether ``name`` is one of ``joint_names``."""
        return name in self._index  # type: ignore[attr-defined]

    def chain(self, name: str) -> Chain:
        """The chain called ``name``; ConfigError for an unknown one."""
        for c in self.chains:
            if c.name == name:
                return c
        known = [c.name for c in self.chains]
        raise ConfigError(f"{self.name} has no chain {name!r}; chains: {known}")

    def chain_set(self, name: str) -> tuple[Chain, ...]:
        """The chains of a ``BuildConfig.chains`` name (``CHAIN_SETS``): ``"upper"``, ``chains``;
        ``"whole"``, ``(whole_chain,)``. ConfigError for an unknown name."""
        if name == "upper":
            return self.chains
        if name == "whole":
            return (self.whole_chain,)  # type: ignore[return-value]
        raise ConfigError(f"unknown chain set {name!r}; use one of {sorted(CHAIN_SETS)}")

    def chain_joints(self, chain: Chain) -> tuple[int, ...]:
        """Positions of ``chain.joints`` in ``driven_joints``."""
        return tuple(self.driven_joints.index(j) for j in chain.joints)

    def chain_columns(
        self, chain: Chain, bones: str | tuple[str, ...] = "upper"
    ) -> tuple[int, ...]:
        """The columns of a ``bones`` descriptor holding ``chain``'s bones (``chain_columns``)."""
        return chain_columns(chain, bones)

    @property
    def ik_bones(self) -> tuple[str, ...]:
        """Every bone the IK reads: the chains' bones, in chain order."""
        return tuple(dict.fromkeys(b for c in self.chains for b in c.bones))

    def check_bones(self, bones: str | tuple[str, ...]) -> None:
        """ConfigError unless a ``bones`` descriptor holds every bone the IK reads."""
        names = resolve_bones(bones)
        missing = [b for b in self.ik_bones if b not in names]
        if missing:
            raise ConfigError(
                f"the IK needs the bones {self.ik_bones}; the descriptor lacks {missing}"
            )

    def solve_ik(
        self, d: jax.typing.ArrayLike, bones: str | tuple[str, ...] = "upper"
    ) -> jax.Array:
        """``ik``: ``(..., 3 * n_bones)`` descriptors -> ``(..., n_driven)`` angles, rad."""
        if self.ik is None:
            raise ConfigError(f"robot {self.name!r} has no IK function")
        return self.ik(d, bones)

    def solve_ik_traced(
        self, d: jax.Array, bones: str | tuple[str, ...] = "upper", shards: int = 1
    ) -> jax.Array:
        """``traced_ik`` (or ``ik``), inside a trace: ``(..., 3 * n_bones)`` descriptors ->
        ``(..., n_driven)`` angles. ``shards > 1``: ``(T, 3 * n_bones)`` rows split over that
        many CPU devices (``jaxproj._internal.shards.over_rows``; the same answers), where
        ``T`` is a multiple of it (else on one)."""
        fn = self.traced_ik if self.traced_ik is not None else self.ik
        if fn is None:
            raise ConfigError(f"robot {self.name!r} has no IK function")
        if shards > 1 and d.ndim == 2 and d.shape[0] % shards == 0:
            return over_rows(lambda x: fn(x, bones), shards)(d)
        return fn(d, bones)

    @property
    def lower_driven(self) -> np.ndarray:
        """``(n_driven,)`` float32 lower limits of the driven joints."""
        return self.lower[self.driven_index]

    @property
    def upper_driven(self) -> np.ndarray:
        """``(n_driven,)`` float32 upper limits of the driven joints."""
        return self.upper[self.driven_index]

    @property
    def standing_driven(self) -> np.ndarray:
        """``(n_driven,)`` float32 standing posture of the driven joints."""
        return self.standing[self.driven_index]

    def require_velocity_limits(self) -> np.ndarray:
        """``velocity_limits``, or ConfigError naming the robot when it has none."""
        if self.velocity_limits is None:
            raise ConfigError(f"robot {self.name!r} has no velocity limits (needed here)")
        return self.velocity_limits

    def speed_limits(self, speeds: str = "rated") -> np.ndarray:
        """``(n_joints,)`` float32 speed limits, rad/s, of a ``SPEED_KINDS`` name: ``"rated"``,
        ``rated_speeds`` (``RATED_FRACTION * velocity_limits`` where the robot has none);
        ``"no-load"``, ``velocity_limits``. ConfigError for an unknown name or a robot without
        velocity limits."""
        if speeds not in SPEED_KINDS:
            raise ConfigError(f"speeds must be one of {SPEED_KINDS}, got {speeds!r}")
        vmax = self.require_velocity_limits()
        if speeds == "no-load":
            return vmax
        if self.rated_speeds is not None:
            return self.rated_speeds
        return (np.float32(RATED_FRACTION) * vmax).astype(np.float32)

    def driven_to_full(self, q_driven: jax.Array) -> jax.Array:
        """``(..., n_driven)`` driven angles -> ``(..., n_joints)`` float32; the rest standing."""
        return driven_to_full(self.standing, self.driven_index, q_driven)

    def clip(self, angles: jax.Array) -> jax.Array:
        """``(..., n_joints)`` configurations clipped to ``[lower, upper]``, then every follower
        of ``coupled_limits`` to its range (``clip_coupled``); jnp, float32, traceable."""
        q = jnp.asarray(angles, dtype=jnp.float32)
        lo = jnp.broadcast_to(self.lower, q.shape)
        return clip_coupled(self, jnp.clip(q, lo, jnp.broadcast_to(self.upper, q.shape)))

    def clip_driven(self, angles: jax.Array) -> jax.Array:
        """``(..., n_driven)`` driven angles clipped to their limits, then to the coupled
        ranges (``clip_coupled``); jnp, float32, traceable."""
        q = jnp.asarray(angles, dtype=jnp.float32)
        lo = jnp.broadcast_to(self.lower[self.driven_index], q.shape)
        q = jnp.clip(q, lo, jnp.broadcast_to(self.upper[self.driven_index], q.shape))
        return clip_coupled(self, q, driven=True)

    def playable(self, angles: jax.Array) -> jax.Array:
        """``(..., n_driven)`` driven angles -> what the robot can play: ``clip_driven``, then
        ``separate`` (its self-collisions pushed apart) where the robot has it, then
        ``clip_driven`` again; jnp, float32, traceable."""
        q = self.clip_driven(angles)
        if self.separate is None:
            return q
        return self.clip_driven(self.separate(q))

    def playable_motion(self, angles: jax.Array) -> jax.Array:
        """One motion's ``(T, n_driven)`` driven angles -> ``playable`` frame by frame in time
        order, each frame's ``separate`` also started from the previous frame's answer
        (``lax.scan``; the first frame from its own angles): where a limb went deep into
        another, a search from the given pose alone can stop inside, while one from the
        previous answer (already clear) stops at the robot's margin, next to it. A robot
        without ``separate``: ``clip_driven``. jnp, float32, traceable."""
        q = self.clip_driven(angles)
        separate = self.separate
        if separate is None:
            return q

        def step(prev: jax.Array, row: jax.Array) -> tuple[jax.Array, jax.Array]:
            out = self.clip_driven(separate(row, start=prev))
            return out, out

        _, out = jax.lax.scan(step, q[0], q)
        return out

    def continuous(
        self,
        q: jax.Array,
        valid: jax.Array,
        d: jax.Array | None = None,
        bones: str | tuple[str, ...] = "full",
        shards: int = 1,
    ) -> jax.Array:
        """One motion's ``(T, n_driven)`` per-frame answers made continuous by ``track`` (with
        ``(T,)`` bool ``valid`` and, if given, the person's ``(T, m)`` descriptors of ``bones``:
        how far each limb turned), or returned as they are when the robot has no such pass.
        ``shards``: CPU devices the pass may spread over (passed on as ``shards=`` only when
        more than 1; the same answers)."""
        if self.track is None:
            return q
        if shards > 1:
            return self.track(q, valid, d, bones, shards=shards)
        return self.track(q, valid, d, bones)

    def bound_steps(
        self,
        q: jax.Array,
        valid: jax.Array,
        d: jax.Array | None = None,
        bones: str | tuple[str, ...] = "full",
    ) -> jax.Array:
        """One motion's ``(T, n_driven)`` angles with each step between two valid frames held
        within ``track_bounds`` (in time order: a step over its bound is shortened to it and
        the frames after follow from there), so that a later stage (the smoother's overshoot)
        cannot move a joint further than the continuity pass lets it while the limb hardly
        turns. Steps within their bound, and every step of a robot without ``track_bounds`` or
        a call without ``d``, are kept to the bit. ``(T,)`` bool ``valid``, ``(T, m)``
        descriptors of ``bones``. Traceable."""
        if self.track_bounds is None or d is None:
            return q
        bound = self.track_bounds(valid, d, bones)

        def step(prev: jax.Array, xs: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
            q_t, r_t = xs
            delta = q_t - prev
            out = jnp.where(jnp.abs(delta) <= r_t, q_t, prev + jnp.clip(delta, -r_t, r_t))
            return out, out

        _, rest = jax.lax.scan(step, q[0], (q[1:], bound[1:]))
        return jnp.concatenate([q[:1], rest])

    def continuous_step(
        self,
        y: jax.Array,
        q_prev: jax.Array,
        q_t: jax.Array,
        d_prev: jax.Array,
        d_t: jax.Array,
        bones: str | tuple[str, ...] = "full",
    ) -> jax.Array:
        """One frame of ``continuous`` (streaming): ``(n_driven,)`` last output ``y``, last
        valid answer ``q_prev`` and this frame's answer ``q_t``, with the person's ``(m,)``
        last valid and current descriptors of ``bones`` -> ``(n_driven,)`` this frame's output
        (``q_t`` as it is when the robot has no such pass). Traceable."""
        if self.track_step is None:
            return q_t
        return self.track_step(y, q_prev, q_t, d_prev, d_t, bones)

    def from_columns(self, names: Sequence[str], columns: np.ndarray) -> np.ndarray:
        """``(T, len(names))`` angle columns placed by joint name into ``(T, n_joints)`` float32
        configurations, every joint not named at ``standing``.

        Raises:
          ConfigError: an unknown or repeated joint name.
        """
        unknown = [str(n) for n in names if not self.has_joint(n)]
        if unknown:
            raise ConfigError(f"unknown joint names {unknown}")
        if len(set(names)) != len(names):
            dup = sorted({str(n) for n in names if list(names).count(n) > 1})
            raise ConfigError(f"joint names repeated: {dup}")
        out = np.tile(self.standing, (columns.shape[0], 1))
        out[:, [self.index(n) for n in names]] = columns
        return out

    def couple(self, angles: np.ndarray) -> np.ndarray:
        """``(..., n_joints)`` -> a copy with every coupled follower set to its leader (NumPy)."""
        q = np.array(angles)
        for leader, follower in self.coupled_joints:
            q[..., self.index(follower)] = q[..., self.index(leader)]
        return q

    def load_model(self, mount: str = "free", without: Sequence[str] = ()) -> mujoco.MjModel:
        """The compiled MJCF (``mjcf.load``); ConfigError when the robot has no MJCF."""
        return self.require_mjcf().load(mount, without)

    def require_mjcf(self) -> Mjcf:
        """``mjcf``, or ConfigError naming the robot when it has none."""
        if self.mjcf is None:
            raise ConfigError(f"robot {self.name!r} has no MJCF model (needed for physics / FK)")
        return self.mjcf
