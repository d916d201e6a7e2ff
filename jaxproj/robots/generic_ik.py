"""One generic IK: human bone directions -> a robot's joint angles, over the robot's own MJCF.

Correspondence is data (``Correspondence``): each row (``BonePair``) says which canonical human
bone (``jaxproj.human.skeleton.BONE_NAMES``) the direction between two points of the robot's
MJCF (sites or bodies) follows, with a weight; the directions are compared in the frame of one
robot body (``Correspondence.base``, e.g. the torso), which plays the human body frame's part
(x forward, y left, z up). Each ``Chain`` of the robot is solved on its own, in chain order,
from the rows it reads (``chain_rows``): those of its bones whose direction, seen from the base,
one of its joints changes, i.e. a joint on the path between a row's point and the base body
(``row_turned_by``; the waist reads the hip line although its points hang from the hips, as the
waist turns the base). Chains after it see its answer (a leg chain solved after the waist sees
the waist's angles), chains before it do not see it. Building the IK fails (``ConfigError``)
for a chain that reads no row and for a row that no chain reads.

A chain's per-frame answer depends on its own descriptor columns only: its collision term counts
the pairs that its joints and those of its ``own_chains`` move (an arm against the torso and
the head; a leg against the pelvis and, through the waist it reads, the torso), not the pairs
that another chain's joints move too (an arm against a leg or the pelvis, which the waist turns;
the two arms; the two legs). So the IK of a chain alone from its columns (``Chain.ik``: the
landmarks' ground truth of a per-chain model) is the whole IK's answer for that chain, and a
per-chain projection can learn it. The pairs between chains are ``separate``'s and ``track``'s,
which count every pair. The solve computes its own pairs only (a chain's pairs are built with
them first): on the G1 1 / 9 / 9 / 28 / 28 of the chains' 149 / 85 / 85 / 133 / 133.

The problem of one chain with joints ``x`` (box ``[lo, hi]``, the robot's limits)::

    minimise   sum_k w_k |dir_k(x) - t_k|^2  +  lam * |x - x_0|^2  +  collision(x)
    dir_k(x)   unit vector from the row's first point to its second, base frame (TreeFK)
    t_k        the human bone's unit direction (descriptor columns, normalised)
    x_0        the robot's standing posture (the pull toward it, ``IKConfig.neutral``, decides
               the joints the skeleton cannot see: a straight arm's twist)
    collision  sum over capsule pairs of  w_c * max(0, margin - gap)^2  (``IKConfig.collision``;
               off unless the robot gives ``Correspondence.capsules`` and pairs)

solved by box-constrained Levenberg-Marquardt: Gauss-Newton steps on the free joints (a joint at
a bound whose gradient points outward is held: the active set), the damping adapted by the
gain of each step (accept a step only if it lowers the objective), a fixed number of iterations
(``IKConfig.iterations``) from ``IKConfig.starts`` deterministic starting points (the standing
posture and quasi-random points of the box drawn once from ``IKConfig.seed`` and the chain's
name); the start with the least final objective wins (the first on exact ties). Bones whose
input is zero-length or non-finite get weight 0 (the pull holds their joints at standing): never
NaN.

Stationarity, stated: a solution is *stationary* when its projected gradient ``|x - clip(x -
g)|_inf`` is below ``IKConfig.gtol`` (``g`` the objective's gradient); ``solve_info`` returns it
per pose, with the objective.

Traceable and jit-compatible (``jax.vmap`` over poses inside); float32; matrix products at full
float32 precision; deterministic (fixed iterations, fixed starts, no data-dependent host sync).

One program for every chain: the chains' problems are arrays padded to the largest chain's sizes
and stacked (``_ChainData``), every chain's points in one ``TreeFK``, and the solvers run through
the chains with ``lax.scan`` (in chain order, each seeing the answers before it). A padded joint
has the box ``[0, 0]`` and a zero Jacobian column, a padded row or pair weight 0, so padding
changes no answer but the rounding; the compiled program is the size of one chain's, not the sum
of all of them (the G1's five chains: 0.5 MB of StableHLO per solver instead of 2.1-2.8 MB, XLA
compiling each in 7-9 s instead of 21-31 s on two cores). Derivatives are taken of the points a
chain moves only, and of its ``COLLISION_ROWS`` deepest collision pairs only.

Shapes: descriptors ``(..., 3 * n_bones)`` (``skeleton.descriptor`` layout of ``bones``);
answers ``(..., n_driven)`` in ``Robot.driven_joints`` order.

Size: over 500 lines: the correspondence records, the problem per chain, its residual with
the analytic Jacobian (directions, pull, collisions), the solver and its small dense helpers
(Cholesky, closest points) are one unit that a reader checks together; split the collision
geometry out when a second kind of penalty comes.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, Literal, NamedTuple, TypeVar

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxproj._internal.jit import full_precision
from jaxproj._internal.shards import over_rows
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONE_NAMES, resolve_bones
from jaxproj.robots.base import Chain, Robot
from jaxproj.robots.kinematics import Point, TreeFK, _point, points_at

_HIGHEST = jax.lax.Precision.HIGHEST
_A = TypeVar("_A", np.ndarray, jax.Array)

COLLISION_ROWS = 8
"""The collision pairs of a chain whose derivatives one solver step takes: the deepest (see
``GenericIK._collision_terms``)."""

JOIN_CHAINS = 6
"""``track`` both ways joins chain by chain (``2^C`` combinations) for up to this many chains;
a robot with more joins whole poses (the forward or the backward output, all chains at once)."""


@dataclass(frozen=True)
class BonePair:
    """One correspondence row: the robot direction ``start -> end`` follows human ``bone``.

    Attributes:
      bone: a canonical bone name (``skeleton.BONE_NAMES``), e.g. ``"upper_arm_left"``.
      start, end: MJCF site (or body) names; the direction between them, in the base body's
        frame, is compared with the bone's.
      weight: the row's weight (> 0).
      minus: a second bone, or ``None``: the human direction is then ``unit(b - m)`` of the two
        bones' unit vectors (e.g. ``pelvis_left`` minus ``pelvis_right``: the hip line, from the
        right hip to the left one, for two bones of equal length).
      rest: the human direction (body frame) that corresponds to the robot's direction in its
        standing posture, or ``None`` (they are the same). With it, every human direction is
        turned by the rotation taking ``rest`` onto the robot's standing direction before the
        comparison: a calibration of a constant offset between where a capture system puts a
        joint and where the robot's points sit (e.g. the Kinect spine and foot points), measured
        as a median over training people.
    """

    bone: str
    start: Point
    end: Point
    weight: float = 1.0
    minus: str | None = None
    rest: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.bone not in BONE_NAMES:
            raise ConfigError(f"unknown bone {self.bone!r}; use one of {BONE_NAMES}")
        if not (math.isfinite(self.weight) and self.weight > 0):
            raise ConfigError(f"bone pair {self.bone!r}: weight must be > 0, got {self.weight}")
        if self.start == self.end:
            raise ConfigError(f"bone pair {self.bone!r}: start and end are the same point")
        if self.minus is not None and (self.minus not in BONE_NAMES or self.minus == self.bone):
            raise ConfigError(f"bone pair {self.bone!r}: minus must be another bone name")
        if self.rest is not None:
            r = np.asarray(self.rest, np.float64)
            if r.shape != (3,) or not np.isfinite(r).all() or np.linalg.norm(r) < 1e-6:
                raise ConfigError(f"bone pair {self.bone!r}: rest must be a non-zero 3-vector")

    @property
    def bones(self) -> tuple[str, ...]:
        """The human bones the row reads."""
        return (self.bone,) if self.minus is None else (self.bone, self.minus)


def _rotation(model: mujoco.MjModel, gid: int) -> np.ndarray:
    """``(3, 3)`` rotation of geom ``gid`` in its body's frame."""
    flat = np.zeros(9)
    mujoco.mju_quat2Mat(flat, np.array(model.geom_quat[gid], np.float64))
    return flat.reshape(3, 3)


def _segment(model: mujoco.MjModel, gid: int) -> tuple[np.ndarray, np.ndarray]:
    """The axis ends of capsule or sphere geom ``gid`` in its body's frame."""
    pos = np.array(model.geom_pos[gid], np.float64)
    half = np.zeros(3)
    if model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_CAPSULE:
        half = _rotation(model, gid)[:, 2] * float(model.geom_size[gid][1])
    return pos - half, pos + half


def box_overhang(model: mujoco.MjModel, geom: str) -> float:
    """How far (m) a box of ``geom``'s body that holds ``geom``'s axis stands out of the
    capsules and spheres of that body inside it: the largest, over points of the box's 12
    edges (11 a edge, corners included), of the distance to the nearest of those capsules
    less its radius; 0 for a capsule in no box.

    The collision term takes segments, so a robot gives capsules along a box that matters (the
    G1's soles: three inside each box, `unitree_g1.xml`); their round sides leave the box's
    edges out (4.1 mm along a sole's long edges, up to 9.1 mm on its short ends). The term adds the
    overhang to such a capsule's radius, so that two boxes, edges included, stay apart."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if gid < 0:
        raise ConfigError(f"the MJCF has no geom named {geom!r}")
    body = int(model.geom_bodyid[gid])
    on_body = [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) == body]
    mine = [g for g in on_body if int(model.geom_type[g]) in _CAPSULE_KINDS]
    boxes = [g for g in on_body if int(model.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_BOX)]
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    edges = [(i, j) for i in range(8) for j in range(i + 1, 8)
             if np.abs(corners[i] - corners[j]).sum() == 2]  # fmt: skip
    out = 0.0
    for b in boxes:
        rot = _rotation(model, b)
        centre, half = np.array(model.geom_pos[b], np.float64), np.array(model.geom_size[b])

        def inside(x: np.ndarray, centre: np.ndarray = centre, rot: np.ndarray = rot,
                   half: np.ndarray = half) -> bool:  # fmt: skip
            return bool((np.abs(rot.T @ (x - centre)) <= half + 1e-9).all())

        inner = [g for g in mine if all(inside(e) for e in _segment(model, g))]
        if gid not in inner:
            continue
        t = np.linspace(0.0, 1.0, 11)[:, None]
        local = np.concatenate([corners[i] + t * (corners[j] - corners[i]) for i, j in edges])
        points = centre + (local * half) @ rot.T  # (132, 3) in the body's frame
        gap = np.full(len(points), np.inf)
        for g in inner:
            a, e = _segment(model, g)
            d = e - a
            s = np.clip((points - a) @ d / max(float(d @ d), 1e-18), 0.0, 1.0)
            dist = np.linalg.norm(points - (a + s[:, None] * d), axis=1)
            gap = np.minimum(gap, dist - float(model.geom_size[g][0]))
        out = max(out, float(gap.max()))
    return out


def capsule_points(model: mujoco.MjModel, geom: str) -> tuple[Point, Point, float]:
    """The segment ends (``(body, offset)`` points) and radius of a capsule or sphere geom of
    ``model`` (a sphere's ends coincide); ConfigError for another type or an unknown name."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if gid < 0:
        raise ConfigError(f"the MJCF has no geom named {geom!r}")
    body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[gid]))
    if int(model.geom_type[gid]) not in _CAPSULE_KINDS:
        raise ConfigError(f"geom {geom!r}: only capsules and spheres are collision capsules")
    a, b = _segment(model, gid)
    start: Point = (str(body), (float(a[0]), float(a[1]), float(a[2])))
    end: Point = (str(body), (float(b[0]), float(b[1]), float(b[2])))
    return start, end, float(model.geom_size[gid][0])


@dataclass(frozen=True)
class Correspondence:
    """A robot's correspondence with the human skeleton, as data.

    Attributes:
      base: the MJCF body whose frame the directions are compared in (the human body frame's
        counterpart: x forward, y left, z up).
      pairs: the rows (``BonePair``).
      collision_pairs: pairs of the MJCF's capsule / sphere geoms (names) that must stay apart
        by ``IKConfig.margin`` (the collision term), or ``"mjcf"``: every pair of capsule /
        sphere geoms that the MJCF's own contact filter lets collide (``mjcf_collision_pairs``:
        what MuJoCo itself would report as a self-contact, boxes and meshes aside).
      ranges: per joint name, a ``(lower, upper)`` range (rad) that narrows the IK's box to the
        range the human counterpart of the joint can take (e.g. an elbow that does not
        over-extend): a robot joint whose range exceeds the human's gives one bone direction
        two solutions (an over-extended elbow with the upper arm turned half a turn), between
        which an IK answer would jump on noise. ``-inf`` / ``inf``: no bound on that side.
        Intersected with the robot's limits.
      source: where the table's choices come from (a sentence).
    """

    base: str
    pairs: tuple[BonePair, ...]
    collision_pairs: tuple[tuple[str, str], ...] | Literal["mjcf"] = ()
    ranges: tuple[tuple[str, float, float], ...] = ()
    source: str = ""

    def __post_init__(self) -> None:
        if not self.pairs:
            raise ConfigError("a correspondence needs at least one bone pair")
        if isinstance(self.collision_pairs, str) and self.collision_pairs != "mjcf":
            raise ConfigError(
                f"collision_pairs: pairs of geoms or 'mjcf', got {self.collision_pairs!r}"
            )
        for pair in () if isinstance(self.collision_pairs, str) else self.collision_pairs:
            if len(pair) != 2 or pair[0] == pair[1]:
                raise ConfigError(f"collision pair {pair!r}: two different geoms")
        for name, lo, hi in self.ranges:
            if not lo < hi:  # NaN fails too
                raise ConfigError(f"range of {name!r}: need lower < upper, got {lo}, {hi}")

    def box(self, robot: Robot, joints: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """``(lower, upper)`` float32 IK box of ``joints``: the robot's limits narrowed by
        ``ranges``. Raises ConfigError for a range of an unknown joint or an empty box."""
        lo = np.array([robot.lower[robot.index(j)] for j in joints], np.float32)
        hi = np.array([robot.upper[robot.index(j)] for j in joints], np.float32)
        for name, r_lo, r_hi in self.ranges:
            if not robot.has_joint(name):
                raise ConfigError(f"range of {name!r}: {robot.name} has no such joint")
            if name in joints:
                k = list(joints).index(name)
                lo[k], hi[k] = max(lo[k], r_lo), min(hi[k], r_hi)
                if lo[k] >= hi[k]:
                    raise ConfigError(f"range of {name!r} does not meet the robot's limits")
        return lo, hi

    def rows(self, bones: Sequence[str]) -> tuple[BonePair, ...]:
        """The rows whose bone is one of ``bones``."""
        return tuple(p for p in self.pairs if all(b in bones for b in p.bones))


@dataclass(frozen=True)
class IKConfig:
    """Settings of ``GenericIK`` (see the module doc).

    Attributes:
      iterations: LM iterations per start.
      starts: starting points per chain (the standing posture first, then quasi-random ones).
      neutral: ``lam``, the pull toward the standing posture (per joint, rad^-2 units of the
        direction residual).
      collision: ``w_c``, the collision term's weight (0: off).
      margin: the gap (m) below which two capsules of a collision pair are penalised.
      damping: the initial LM damping (relative to the Gauss-Newton matrix's diagonal).
      gtol: the stationarity test's bound on the projected gradient.
      seed: the seed of the quasi-random starts (explicit; same seed, same answers).
    """

    iterations: int = 24
    starts: int = 4
    neutral: float = 1e-6
    collision: float = 0.0
    margin: float = 0.01
    damping: float = 1e-3
    gtol: float = 1e-5
    seed: int = 0

    def __post_init__(self) -> None:
        if self.iterations < 1 or self.starts < 1:
            raise ConfigError("IKConfig: iterations and starts must be >= 1")
        for name in ("neutral", "collision", "margin", "damping", "gtol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"IKConfig.{name} must be finite and >= 0, got {v}")


SIDE_BY_SIDE: bool | None = None
"""``track``'s two ways side by side (``vmap``, ``True``) or one after the other in one scan
(``False``), read when a program is traced; ``None`` (the default): side by side on any backend
but the CPU (``benchmarks/experiments/batch_timeline.py`` compares the two)."""


def _side_by_side() -> bool:
    return jax.default_backend() != "cpu" if SIDE_BY_SIDE is None else SIDE_BY_SIDE


@dataclass(frozen=True)
class TrackConfig:
    """Settings of ``GenericIK.track`` (the continuity pass).

    Attributes:
      continuity: ``c``, the weight of ``|x - y|^2`` (rad^-2, in units of the squared direction
        residual): a step of ``s`` rad costs as much as a direction error of ``sqrt(c) * s``
        rad, so with 0.05 a half turn of a loose joint (3.1 rad) is taken only where it fits
        the directions better by about 0.7 rad (40 deg) of error, while following a limb that
        turns costs a lag of about ``c`` (5 %) of one frame's step.
      iterations: Levenberg-Marquardt iterations per start.
      min_step: ``r_0``, rad: how far a joint may move in one frame whatever its limb did.
      step_gain: ``g``: how far a joint may move in one frame per radian its limb turned. With
        15 deg and 1.8, a joint whose limb turned less than 10 deg moves at most 18 deg.
      follow: ``p``, the weight of ``|x - q_t|^2`` (rad^-2): a pull toward the frame's own
        answer, for a chain whose last output is off the answer's directions. Without it a
        chain that took another branch during a fast move (another solution of the same
        directions, e.g. the shoulder's other Euler branch) keeps it while it fits; where that
        branch then meets a joint limit the output is stuck in a local minimum of the
        direction fit, the limb 30-40 deg off for seconds (measured, UTKinect s07: the arms'
        p90 27 deg, 7 deg per frame). The pull walks it back, at most the step bound a frame.
        0 turns it off.
      both_ways: run the pass forward and backward in time and keep, per chain and frame, the
        one of the two outputs that follows the person's directions better over the motion,
        switching only where a step from one to the other is within the step bound (a Viterbi
        path over the two; ``GenericIK.track``). Offline only (streaming is causal).
      switch_slack: rad: a joint changes pass only with a step no larger than either pass's
        own step into that frame plus this (and within the step bound).
      follow_error: ``e``, rad: the pull's full weight applies where the last output's worst
        row is ``e`` or more off the answer's directions, none below ``e / 2``, linear
        between: a loose joint whose answers flip while the directions stay (a straight arm's
        yaw) is not pulled along.
    """

    continuity: float = 0.05
    iterations: int = 12
    min_step: float = math.radians(15.0)
    step_gain: float = 1.8
    follow: float = 0.05
    follow_error: float = math.radians(10.0)
    both_ways: bool = True
    switch_slack: float = math.radians(3.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.continuity) and self.continuity > 0):
            raise ConfigError(
                f"TrackConfig.continuity must be finite and > 0, got {self.continuity}"
            )
        if self.iterations < 1:
            raise ConfigError("TrackConfig.iterations must be >= 1")
        if not (0 < self.min_step <= math.pi and 0 < self.step_gain < math.inf):
            raise ConfigError("TrackConfig: min_step in (0, pi] rad and step_gain > 0")
        if not (math.isfinite(self.follow) and self.follow >= 0):
            raise ConfigError(f"TrackConfig.follow must be finite and >= 0, got {self.follow}")
        if not 0 < self.follow_error <= math.pi:
            raise ConfigError(f"TrackConfig.follow_error must be in (0, pi] rad, "
                              f"got {self.follow_error}")  # fmt: skip


class IKInfo(NamedTuple):
    """Per-pose diagnostics of ``GenericIK.solve_info``: ``(..., n_chains)`` each."""

    objective: jax.Array
    stationary: jax.Array


class _ChainData(NamedTuple, Generic[_A]):
    """One chain's problem as arrays, padded to the sizes of the robot's largest chain (``N``
    joints, ``R`` rows, ``K`` capsules, ``Q`` pairs, ``S`` starts; ``P`` the FK's points, shared
    by every chain). Stacked over the chains (a leading axis) in ``_Chains.data``: the solvers
    scan over the chains, so one chain's program is compiled once for all of them. Padding is
    inert: a padded joint has the box ``[0, 0]`` and a zero Jacobian column (it stays 0), a
    padded row or pair weight 0. ``_A``: ``np.ndarray`` as built, ``jax.Array`` in the solvers."""

    joints: _A  # (N,) int32 positions in robot.joint_names; padding: n_joints
    lo: _A  # (N,) the IK's box (``Correspondence.box``)
    hi: _A
    lim_lo: _A  # (N,) the robot's limits (``separate``)
    lim_hi: _A
    frame: _A  # (N,) TreeFK.columns of the joints
    axis: _A  # (N, 3)
    anchor: _A  # (N, 3)
    sign: _A  # (N, M) for the moved points
    moved: _A  # (M,) the points the chain's joints move (padding: 0)
    row_points: _A  # (R, 2) indices into the FK's points
    row_slots: _A  # (R, 2) their places among the moved points (not moved: M, a zero row)
    row_mask: _A  # (R,) bool: a real row
    weights: _A  # (R,) 0 for padding
    rest: _A  # (R, 3, 3) human rest -> robot rest (identity: none)
    capsule_points: _A  # (K, 2) indices into the FK's points
    capsule_slots: _A  # (K, 2) their places among the moved points (not moved: M)
    radii: _A  # (K,)
    collide: _A  # (Q, 2) indices into the chain's capsules
    pair_mask: _A  # (Q,) bool: a real pair
    own_mask: _A  # (Q,) bool: a pair the per-frame solve counts (they come first)
    starts: _A  # (S, N) starting points


@dataclass(frozen=True, eq=False)
class _Chains:
    """Every chain's problem (``_ChainData`` stacked over the chains) and what the host needs
    to read a descriptor for it."""

    chains: tuple[Chain, ...]
    rows: tuple[tuple[BonePair, ...], ...]  # per chain, the rows it reads
    fk: TreeFK  # every chain's points, base frame
    data: _ChainData[np.ndarray]  # stacked: (C, ...)
    has_pairs: np.ndarray  # (C,) bool: the chain moves a collision pair
    n_own: int  # the most pairs a chain's per-frame solve counts (its first pairs: own_mask)

    def __len__(self) -> int:
        return len(self.chains)

    def take(self, index: np.ndarray) -> _ChainData[np.ndarray]:
        """The stacked data of the chains ``index``."""
        return _ChainData(*(a[index] for a in self.data))

    def bone_index(self, bones: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``((C, R) bone, (C, R) minus bone, (C, R) bool has-minus)`` column blocks of each
        row in a descriptor of ``bones`` (padding: 0, 0, False)."""
        c, r = self.data.weights.shape
        bone = np.zeros((c, r), np.int32)
        minus = np.zeros((c, r), np.int32)
        has = np.zeros((c, r), bool)
        for i, rows in enumerate(self.rows):
            for k, row in enumerate(rows):
                bone[i, k] = bones.index(row.bone)
                if row.minus is not None:
                    minus[i, k], has[i, k] = bones.index(row.minus), True
        return bone, minus, has


def _pad(rows: Sequence[np.ndarray], shape: tuple[int, ...], fill: float | bool = 0) -> np.ndarray:
    """``rows`` (arrays of the same dtype, each no larger than ``shape`` along every axis)
    stacked, each padded at its end with ``fill``: ``(len(rows), *shape)``."""
    out = np.full((len(rows), *shape), fill, dtype=np.asarray(rows[0]).dtype)
    for i, a in enumerate(rows):
        a = np.asarray(a)
        index: tuple[int | slice, ...] = (i, *(slice(0, n) for n in a.shape))
        out[index] = a
    return out


@dataclass(frozen=True, eq=False)
class GenericIK:
    """The generic IK of a robot (see the module doc); build it with ``GenericIK.build``."""

    robot: Robot
    correspondence: Correspondence
    config: IKConfig
    problems: _Chains = field(repr=False)

    @classmethod
    def build(
        cls,
        robot: Robot,
        correspondence: Correspondence,
        config: IKConfig | None = None,
        chains: Sequence[Chain] | None = None,
        model: mujoco.MjModel | None = None,
    ) -> GenericIK:
        """The IK of ``chains`` (default ``robot.chains``) of ``robot`` from its MJCF.

        Args:
          robot: the robot (its joints, limits, standing posture, MJCF).
          correspondence: the table.
          config: solver settings (``IKConfig()``).
          chains: the chains to solve, in order (each needs at least one row).
          model: a compiled ``mujoco.MjModel`` (default ``robot.load_model("fixed")``).

        Raises:
          ConfigError: a chain that reads no row (``chain_rows``), a row that no chain reads (of
            all rows when ``chains`` is the robot's; else of the rows of their bones), or a
            name the MJCF lacks.
        """
        config = IKConfig() if config is None else config
        every = chains is None
        chains = tuple(robot.chains if chains is None else chains)
        if model is None:
            model = robot.load_model("fixed")
        read = _rows_read(model, correspondence, chains, every)
        collision_pairs = (
            mjcf_collision_pairs(model)
            if isinstance(correspondence.collision_pairs, str)
            else correspondence.collision_pairs
        )
        moved_by = {pr: _pair_moved_by(model, pr) for pr in collision_pairs}
        names: list[Point] = []  # every chain's FK points, in one list

        def point(name: Point) -> int:
            if name not in names:
                names.append(name)
            return names.index(name)

        per: list[dict[str, np.ndarray]] = []
        for chain, rows in zip(chains, read, strict=True):
            joints = np.array([robot.index(j) for j in chain.joints], np.int32)
            lo, hi = correspondence.box(robot, chain.joints)
            # capsules this chain can move, and the pairs among the correspondence's
            pairs = [pr for pr in collision_pairs if set(chain.joints) & moved_by[pr]]
            # the pairs the per-frame solve counts first (it reads only the first ``n_own``)
            others = _other_chains_joints(robot, chains, chain)
            own = [pr for pr in pairs if not (moved_by[pr] & others)]
            pairs = own + [pr for pr in pairs if pr not in own]
            used = sorted({n for p in pairs for n in p})
            caps = {n: capsule_points(model, n) for n in used}
            cap_idx = {n: i for i, n in enumerate(used)}
            starts = [np.clip(robot.standing[joints], lo, hi)]
            # drawn per chain from the seed and the chain's name: the same starts whichever
            # chains are built with it (a chain's own IK is the whole IK's answer for it)
            rng = np.random.default_rng([config.seed, zlib.crc32(chain.name.encode())])
            for _ in range(config.starts - 1):
                starts.append(
                    lo + rng.uniform(0.1, 0.9, len(joints)).astype(np.float32) * (hi - lo)
                )
            per.append(
                {
                    "joints": joints,
                    "lo": lo,
                    "hi": hi,
                    "lim_lo": robot.lower[joints].astype(np.float32),
                    "lim_hi": robot.upper[joints].astype(np.float32),
                    "row_points": np.array(
                        [[point(r.start), point(r.end)] for r in rows], np.int32
                    ).reshape(len(rows), 2),
                    "weights": np.array([r.weight for r in rows], np.float32),
                    "capsule_points": np.array(
                        [[point(caps[n][0]), point(caps[n][1])] for n in used], np.int32
                    ).reshape(len(used), 2),
                    # a capsule inside a box: widened by the box's overhang (box_overhang)
                    "radii": np.array(
                        [caps[n][2] + box_overhang(model, n) for n in used], np.float32
                    ),  # fmt: skip
                    "collide": np.array(
                        [[cap_idx[a], cap_idx[b]] for a, b in pairs], np.int32
                    ).reshape(len(pairs), 2),
                    "own": np.arange(len(pairs)) < len(own),
                    "starts": np.stack(starts).astype(np.float32),
                }
            )
        fk = TreeFK.from_model(model, robot.joint_names, names, correspondence.base)
        # on the host (MuJoCo): no JAX operation at build time, inside a caller's trace or not
        at_rest = points_at(model, robot.joint_names, robot.standing, names, correspondence.base)
        n_j = max(len(p["joints"]) for p in per)
        n_r = max(len(p["weights"]) for p in per)
        n_k = max(len(p["radii"]) for p in per)
        n_q = max(len(p["collide"]) for p in per)
        n_s = config.starts
        rests, cols = [], []
        for p, rows in zip(per, read, strict=True):
            rest = np.tile(np.eye(3, dtype=np.float32), (len(rows), 1, 1))
            for k, (r, (s, e)) in enumerate(zip(rows, p["row_points"], strict=True)):
                if r.rest is not None:
                    rest[k] = _rotation_between(np.asarray(r.rest), at_rest[e] - at_rest[s])
            rests.append(rest)
            cols.append(fk.columns([*p["joints"], *[-1] * (n_j - len(p["joints"]))]))
        # the points each chain's joints move (a non-zero sign): only their derivatives are
        # computed (the arms move 11 of the G1's 66 points, the waist 40)
        moved = [np.flatnonzero(np.abs(c[3]).sum(0) > 0) for c in cols]
        n_m = max(1, max(len(m) for m in moved))
        for p, m in zip(per, moved, strict=True):
            slot = np.full(fk.n_points, n_m, np.int32)
            slot[m] = np.arange(len(m), dtype=np.int32)
            p["row_slots"] = slot[p["row_points"]]
            p["capsule_slots"] = slot[p["capsule_points"]]
            p["moved"] = m.astype(np.int32)
        pad_rest = np.tile(np.eye(3, dtype=np.float32), (len(per), n_r, 1, 1))
        for i, rest in enumerate(rests):
            pad_rest[i, : len(rest)] = rest

        def stack(key: str, shape: tuple[int, ...], fill: float | int = 0) -> np.ndarray:
            return _pad([p[key] for p in per], shape, fill)

        data = _ChainData(
            joints=stack("joints", (n_j,), len(robot.joint_names)),
            lo=stack("lo", (n_j,)),
            hi=stack("hi", (n_j,)),
            lim_lo=stack("lim_lo", (n_j,)),
            lim_hi=stack("lim_hi", (n_j,)),
            frame=np.stack([c[0] for c in cols]),
            axis=np.stack([c[1] for c in cols]),
            anchor=np.stack([c[2] for c in cols]),
            sign=_pad([c[3][:, m] for c, m in zip(cols, moved, strict=True)], (n_j, n_m)),
            moved=stack("moved", (n_m,)),
            # padded rows: points 0 -> 0, masked out where a direction is taken
            row_points=stack("row_points", (n_r, 2)),
            row_slots=stack("row_slots", (n_r, 2), n_m),
            row_mask=_pad([np.ones(len(p["weights"]), bool) for p in per], (n_r,), False),
            weights=stack("weights", (n_r,)),
            rest=pad_rest,
            capsule_points=stack("capsule_points", (n_k, 2)),
            capsule_slots=stack("capsule_slots", (n_k, 2), n_m),
            radii=stack("radii", (n_k,)),
            collide=stack("collide", (n_q, 2)),
            pair_mask=_pad([np.ones(len(p["collide"]), bool) for p in per], (n_q,), False),
            own_mask=_pad([p["own"] for p in per], (n_q,), False),
            starts=stack("starts", (n_s, n_j)),
        )
        problems = _Chains(
            chains=chains,
            rows=tuple(read),
            fk=fk,
            data=data,
            has_pairs=np.array([len(p["collide"]) > 0 for p in per], bool),
            n_own=max(1, max(int(p["own"].sum()) for p in per)),
        )
        return cls(robot, correspondence, config, problems)

    # --- solving -----------------------------------------------------------------------------

    def _extended(self, q_full: jax.Array) -> jax.Array:
        """``(n_joints,)`` -> ``(n_joints + 1,)``: the padded joints' slot appended (0)."""
        return jnp.concatenate([q_full, jnp.zeros((1,), q_full.dtype)])

    def _targets(self, d: jax.Array, bones: tuple[str, ...]) -> tuple[jax.Array, jax.Array]:
        """``(3 * n_bones,)`` one descriptor -> every chain's ``(C, R, 3)`` unit human
        directions and ``(C, R)`` weights (0: no usable input, or a padded row)."""
        vec = d.reshape(d.shape[-1] // 3, 3)
        bone, minus, has = self.problems.bone_index(bones)

        def unit(v: jax.Array) -> tuple[jax.Array, jax.Array]:
            n = jnp.sqrt(jnp.sum(v * v, axis=-1))
            ok = jnp.isfinite(n) & (n > 1e-6)
            return jnp.where(ok[..., None], v / jnp.where(ok, n, 1.0)[..., None], 0.0), ok

        t, ok = unit(vec[bone])
        t_m, ok_m = unit(vec[minus])
        t_d, ok_d = unit(t - t_m)
        t = jnp.where(has[..., None], t_d, t)
        ok = jnp.where(has, ok & ok_m & ok_d, ok)
        c = self.problems.data.rest
        t = t[..., 0:1] * c[..., :, 0] + t[..., 1:2] * c[..., :, 1] + t[..., 2:3] * c[..., :, 2]
        return t, jnp.where(ok, jnp.asarray(self.problems.data.weights), 0.0)

    def _chain_points(
        self, x: jax.Array, q_ext: jax.Array, c: _ChainData[jax.Array]
    ) -> tuple[jax.Array, jax.Array]:
        """The FK points ``(P, 3)`` at chain angles ``x`` (the other joints ``q_ext``'s) and
        the derivatives by ``x`` of the points the chain moves, a zero row appended ``(M + 1,
        3, N)`` (``row_slots`` / ``capsule_slots`` index it)."""
        q = q_ext.at[c.joints].set(x)[:-1]
        p, dm = self.problems.fk.jacobian_columns(
            q, c.frame, c.axis, c.anchor, c.sign, moved=c.moved
        )
        return p, jnp.concatenate([dm, jnp.zeros((1, *dm.shape[1:]), dm.dtype)])

    def _residual(
        self,
        x: jax.Array,
        q_ext: jax.Array,
        t: jax.Array,
        w: jax.Array,
        c: _ChainData[jax.Array],
        own: bool = False,
    ) -> tuple[jax.Array, jax.Array]:
        """The chain's residual vector at chain angles ``x`` (one pose) and its derivative
        ``(n_res, N)`` (analytic: ``TreeFK.jacobian_columns``); ``own``: only the pairs the
        per-frame solve counts (``own_mask``), else every pair."""
        n = x.shape[-1]
        p, dp = self._chain_points(x, q_ext, c)
        sw = jnp.sqrt(w)
        s_i, e_i = c.row_points[:, 0], c.row_points[:, 1]
        seg = jnp.where(c.row_mask[:, None], p[e_i] - p[s_i], jnp.float32(1.0))
        length = jnp.sqrt(jnp.sum(seg * seg, axis=-1, keepdims=True))
        u = seg / length
        parts = [(sw[:, None] * (u - t)).reshape(-1)]
        dseg = dp[c.row_slots[:, 1]] - dp[c.row_slots[:, 0]]  # (R, 3, N)
        proj = jnp.eye(3, dtype=jnp.float32)[None] - u[:, :, None] * u[:, None, :]
        du = jnp.einsum("rij,rjk->rik", proj, dseg, precision=_HIGHEST) / length[:, :, None]
        jacs = [(sw[:, None, None] * du).reshape(-1, n)]
        lam = np.float32(math.sqrt(self.config.neutral))
        parts.append(lam * (x - c.starts[0]))
        jacs.append(lam * jnp.eye(n, dtype=jnp.float32))
        if self.config.collision > 0 and self.problems.has_pairs.any():
            pen, dpen = self._collision_terms(p, dp, c, own)
            assert dpen is not None
            parts.append(pen)
            jacs.append(dpen)
        return jnp.concatenate(parts), jnp.concatenate(jacs, axis=0)

    def _collision_terms(
        self, p: jax.Array, dp: jax.Array | None, c: _ChainData[jax.Array], own: bool = False
    ) -> tuple[jax.Array, jax.Array | None]:
        """The collision residuals ``sqrt(w_c) max(0, margin - gap)`` of a chain at FK points
        ``p`` (``own``: of the pairs ``own_mask`` keeps, else of every pair): without ``dp``,
        ``(Q,)``, one per pair (0 for padding); with ``dp``, the ``COLLISION_ROWS`` deepest
        pairs' and one row for the rest (the root of their squares' sum: the objective stays
        exact), ``(COLLISION_ROWS + 1,)``, and their derivative
        ``(COLLISION_ROWS + 1, N)`` (the rest's row 0: exact while at most ``COLLISION_ROWS``
        pairs are closer than the margin; a chain's Q is 85-149 pairs on the G1, of which a
        pose has a few in contact, so the derivatives of the others, all zero, are not
        computed)."""
        q = self.problems.n_own if own else c.collide.shape[0]
        i, j = c.collide[:q, 0], c.collide[:q, 1]
        ca, cb = c.capsule_points[:, 0], c.capsule_points[:, 1]
        a1, b1, a2, b2 = p[ca[i]], p[cb[i]], p[ca[j]], p[cb[j]]
        s1, s2 = _closest(a1, b1, a2, b2)
        c1 = a1 + (b1 - a1) * s1[:, None]
        c2 = a2 + (b2 - a2) * s2[:, None]
        diff = c1 - c2
        dist = jnp.sqrt(jnp.sum(diff * diff, -1) + 1e-12)
        gap = dist - c.radii[i] - c.radii[j]
        pen = jnp.maximum(np.float32(self.config.margin) - gap, 0.0)
        pen = jnp.where((c.own_mask if own else c.pair_mask)[:q], pen, 0.0)
        sc = np.float32(math.sqrt(self.config.collision))
        if dp is None:
            return sc * pen, None
        k = min(COLLISION_ROWS, pen.shape[0])
        deep, top = jax.lax.top_k(pen, k)
        rest = jnp.sqrt(jnp.maximum(jnp.sum(pen * pen) - jnp.sum(deep * deep), 0.0))
        i, j, s1, s2 = i[top], j[top], s1[top], s2[top]
        # envelope theorem: the closest points' parameters held fixed
        da, db = c.capsule_slots[:, 0], c.capsule_slots[:, 1]
        dc1 = dp[da[i]] * (1 - s1)[:, None, None] + dp[db[i]] * s1[:, None, None]
        dc2 = dp[da[j]] * (1 - s2)[:, None, None] + dp[db[j]] * s2[:, None, None]
        normal = diff[top] / dist[top][:, None]
        dgap = jnp.einsum("ci,cik->ck", normal, dc1 - dc2, precision=_HIGHEST)
        dpen = -sc * jnp.where(deep > 0, 1.0, 0.0)[:, None] * dgap
        return (
            sc * jnp.concatenate([deep, rest[None]]),
            jnp.concatenate([dpen, jnp.zeros((1, dpen.shape[1]), dpen.dtype)]),
        )

    def _solve_chain(
        self, q_ext: jax.Array, t: jax.Array, w: jax.Array, c: _ChainData[jax.Array]
    ) -> tuple[jax.Array, jax.Array, jax.Array]:
        """One pose, one chain: ``(x, objective, stationary)``."""

        def res_jac(x: jax.Array) -> tuple[jax.Array, jax.Array]:
            return self._residual(x, q_ext, t, w, c, own=True)

        def run(x0: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
            x, r, jac = _levenberg_marquardt(
                res_jac, x0, c.lo, c.hi, self.config.iterations, self.config.damping
            )
            return x, jnp.sum(r * r), 2.0 * jnp.matmul(jac.T, r, precision=_HIGHEST)

        xs, fs, gs = jax.vmap(run)(c.starts)
        k = jnp.argmin(fs)
        x, f, g = xs[k], fs[k], gs[k]
        pg = jnp.max(jnp.abs(x - jnp.clip(x - g, c.lo, c.hi)))
        return x, f, pg < self.config.gtol

    @full_precision
    def solve_info(
        self, d: jax.typing.ArrayLike, bones: str | tuple[str, ...] = "upper"
    ) -> tuple[jax.Array, IKInfo]:
        """``(..., 3 * n_bones)`` descriptors -> ``((..., n_driven) angles, IKInfo)``.

        Joints of no solved chain stay at the standing posture. Traceable.
        """
        names = resolve_bones(bones)
        need = [b for rows in self.problems.rows for r in rows for b in r.bones if b not in names]
        if need:
            raise ConfigError(f"the IK needs the bones {sorted(set(need))}; absent from {bones!r}")
        d = jnp.asarray(d, jnp.float32)
        batch = d.shape[:-1]
        flat = d.reshape(-1, d.shape[-1])
        data = jax.tree.map(jnp.asarray, self.problems.data)

        def one(row: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
            t, w = self._targets(row, names)

            def chain(
                q: jax.Array, xs: tuple[_ChainData[jax.Array], jax.Array, jax.Array]
            ) -> tuple[jax.Array, tuple[jax.Array, jax.Array]]:
                c, t_c, w_c = xs
                x, f, ok = self._solve_chain(q, t_c, w_c, c)
                return q.at[c.joints].set(x), (f, ok)

            q0 = _varying_as(self._extended(jnp.asarray(self.robot.standing)), row[0])
            q, (objective, stationary) = jax.lax.scan(chain, q0, (data, t, w))
            return q[self.robot.driven_index], objective, stationary

        q, f, ok = jax.vmap(one)(flat)
        q = jnp.where(jnp.isfinite(q), q, jnp.asarray(self.robot.standing_driven))
        n = len(self.problems)
        return q.reshape(*batch, -1), IKInfo(f.reshape(*batch, n), ok.reshape(*batch, n))

    @full_precision
    def separate(
        self,
        q: jax.typing.ArrayLike,
        iterations: int = 8,
        stay: float = 1.0,
        start: jax.typing.ArrayLike | None = None,
        keep_rows: bool = False,
    ) -> jax.Array:
        """Push a robot pose's collision pairs apart, moving its joints as little as it can.

        Per chain, those that move the fewest collision pairs first (later chains see earlier
        chains' answers: a limb yields before the trunk; among as many pairs, with ``start``,
        the chain farthest from ``start`` first, the limb that came into the contact; then
        chain order), from the given
        angles ``x_in`` (and, with ``start``, from ``start``'s angles too, keeping the end
        with the lower objective), ``iterations`` Levenberg-Marquardt steps on::

            minimise   stay * |x - x_in|^2  +  collision(x)     x within the robot's limits

        (``collision`` the IK's term: ``IKConfig.collision`` and ``margin``). With
        ``keep_rows``, also ``sum_k w_k |dir_k(x) - dir_k(x_in)|^2 + lam * |x - x_0|^2`` (the
        chain's rows and weights, the IK's ``neutral`` pull): the pose moves where its rows'
        directions change least (an arm swung out from the shoulder as a whole rather than its
        elbow bent), which is what ``track`` wants of an answer whose directions it then
        follows; without it every joint costs the same, so a loose joint (a straight leg's hip
        yaw), which turns no row, is not the first to swing. A pose whose
        pairs are all ``margin`` apart is returned unchanged; a chain without collision pairs
        is not touched. For poses that did not come from this IK (a projection's answers),
        which the IK's collision term never saw. Traceable.

        From ``x_in`` alone a limb deep inside another (a forearm 4-6 cm into the torso, joints
        at their limits) can end in a local minimum still inside; ``start``, a pose without
        contact nearby (the previous frame's answer: ``Robot.playable_motion``), approaches
        ``x_in`` from outside and stops at the margin.

        Args:
          q: ``(..., n_driven)`` angles, rad (``Robot.driven_joints`` order).
          iterations: LM steps per chain.
          stay: weight of the pull toward the given angles (rad^-2).
          start: ``(..., n_driven)`` a second start per pose, or ``None`` (``x_in`` only).
          keep_rows: also keep the rows' directions (above).

        Returns:
          ``(..., n_driven)`` float32 angles within the robot's limits.

        Raises:
          ConfigError: the IK has no collision term (``IKConfig.collision`` 0).
        """
        if not self.config.collision > 0:
            raise ConfigError("separate needs an IK with a collision term (IKConfig.collision)")
        q = jnp.asarray(q, jnp.float32)
        n_driven = self.robot.n_driven
        if q.shape[-1:] != (n_driven,):
            raise ConfigError(f"separate: angles must be (..., {n_driven}), got {q.shape}")
        batch = q.shape[:-1]
        flat = q.reshape(-1, n_driven)
        if not self.problems.has_pairs.any():
            return flat.reshape(*batch, n_driven)
        sq = np.float32(math.sqrt(stay))
        standing = self._extended(jnp.asarray(self.robot.standing))
        didx = self.robot.driven_index
        # the chains with a collision pair (the others are not touched), those that move the
        # fewest pairs first, ties in chain order: a chain that moves much of the body (the
        # waist turns the pelvis and legs against the torso) is left what the limbs could not
        # clear; first, it would clear a hand in the hip by turning the trunk. With ``start``,
        # among chains that move as many pairs, the one that moved most from ``start`` first:
        # the limb that came into the contact (a tracker's glitching leg) yields, not the one
        # it came into
        n_pairs = self.problems.data.pair_mask.sum(axis=1)
        with_pairs = np.flatnonzero(self.problems.has_pairs)
        with_pairs = with_pairs[np.argsort(n_pairs[with_pairs], kind="stable")]
        data = jax.tree.map(jnp.asarray, self.problems.take(with_pairs))

        def one(row: jax.Array, other: jax.Array | None = None) -> jax.Array:
            other_ext = None if other is None else standing.at[didx].set(other)
            chains = data
            if other_ext is not None:
                q_in = standing.at[didx].set(row)
                moved = jnp.max(jnp.abs(q_in[data.joints] - other_ext[data.joints]), axis=1)
                # by pair count, then the farthest moved first, then chain order (stable)
                order = jnp.lexsort((-moved, jnp.asarray(n_pairs[with_pairs], jnp.int32)))
                chains = jax.tree.map(lambda a: a[order], data)

            def chain(q_ext: jax.Array, c: _ChainData[jax.Array]) -> tuple[jax.Array, None]:
                x_in = jnp.clip(q_ext[c.joints], c.lim_lo, c.lim_hi)
                p_in = self._chain_points(x_in, q_ext, c)[0]
                t_in = _row_directions(p_in, c)  # the rows' directions as given: kept

                def res_jac(x: jax.Array) -> tuple[jax.Array, jax.Array]:
                    if keep_rows:
                        r, jac = self._residual(x, q_ext, t_in, c.weights, c)
                    else:
                        p, dp = self._chain_points(x, q_ext, c)
                        r, d_pen = self._collision_terms(p, dp, c)
                        assert d_pen is not None
                        jac = d_pen
                    eye = jnp.eye(x.shape[-1], dtype=jnp.float32)
                    return (
                        jnp.concatenate([r, sq * (x - x_in)]),
                        jnp.concatenate([jac, sq * eye], axis=0),
                    )

                def run(x_start: jax.Array) -> tuple[jax.Array, jax.Array]:
                    x, r, _ = _levenberg_marquardt(
                        res_jac, x_start, c.lim_lo, c.lim_hi, iterations, self.config.damping
                    )
                    return x, jnp.sum(r * r)

                def search() -> jax.Array:
                    if other_ext is None:  # no second start: the plain solve
                        return run(x_in)[0]
                    x0 = jnp.stack([x_in, jnp.clip(other_ext[c.joints], c.lim_lo, c.lim_hi)])
                    xs, fs = jax.vmap(run)(x0)
                    return xs[jnp.argmin(fs)]

                # where every pair is `margin` apart at x_in, the search returns x_in itself
                # (its objective is 0 there, and no step lowers it; the start x_in wins a tie):
                # skipped then (a real branch for one pose, as `playable_motion` passes them;
                # under vmap both branches run and the answer is the same)
                pen, _ = self._collision_terms(p_in, None, c)
                x = jax.lax.cond(jnp.any(pen > 0), search, lambda: x_in)
                return q_ext.at[c.joints].set(x), None

            q_ext, _ = jax.lax.scan(chain, standing.at[didx].set(row), chains)
            return q_ext[didx]

        st = None
        if start is not None:
            st = jnp.broadcast_to(jnp.asarray(start, jnp.float32), q.shape).reshape(-1, n_driven)
        if flat.shape[0] == 1:  # one pose: no vmap, so that the skip above is a real branch
            out = one(flat[0], None if st is None else st[0])[None]
        elif st is None:
            out = jax.vmap(one)(flat)
        else:
            out = jax.vmap(one)(flat, st)
        lo_d, hi_d = self.robot.lower_driven[None], self.robot.upper_driven[None]
        out = jnp.where(jnp.isfinite(out), out, jnp.clip(flat, lo_d, hi_d))
        return out.reshape(*batch, n_driven)

    @full_precision
    def track(
        self,
        q: jax.typing.ArrayLike,
        valid: jax.typing.ArrayLike,
        d: jax.typing.ArrayLike | None = None,
        bones: str | tuple[str, ...] = "full",
        config: TrackConfig | None = None,
        shards: int = 1,
    ) -> jax.Array:
        """One motion's per-frame answers made continuous: each frame's pose re-chosen, among
        the poses with (nearly) the same bone directions, near the previous output.

        A per-frame answer (the IK's or a projection's) fixes the directions of the
        correspondence rows, not the joints that turn a limb about its own axis (a straight
        arm's shoulder yaw, a straight leg's hip yaw) nor which of two branches reaches a
        direction; frame by frame it can jump between them while the person hardly moves. This
        pass runs through the frames in order (``lax.scan``), carrying the last output ``y`` and
        the last valid answer ``q_prev``; per chain, in chain order, it solves from two starts
        (``y``'s angles and the frame's own answer ``q_t``) by the IK's Levenberg-Marquardt::

            minimise   sum_k w_k |dir_k(x) - dir_k(q_t)|^2  +  c * |x - y|^2
                       +  p * s(err) * |x - q_t|^2  +  lam * |x - x_0|^2  +  collision(x)
            within     the IK's box  and  |x - y|_inf <= max(r_0, g * turn)

        (``dir_k(q)``: the chain's row directions at ``q``, base frame; ``turn``: how far the
        person's limb turned since the last valid frame, the largest angle between a row's
        human directions in the two frames (``d``; without it, between ``dir_k(q_prev)`` and
        ``dir_k(q_t)``); ``c``, ``r_0``, ``g``: ``TrackConfig``; ``lam``, ``collision``: the IK's)
        and keeps the start with the least objective. A joint then moves at most ``g`` times as
        far as its limb turned (at least ``r_0``): a flip cannot enter where the person hardly
        moved; where a limb needs more (near a singular pose) the output follows over the next
        frames. A frame that is not valid, and frames before the first valid one, output the
        frame's answer (``fill_invalid`` replaces them later) and leave the state as it was; the
        first valid frame is a step from its own answer (so it too leaves ``separate``'s pairs
        apart).
        Causal: frame ``t``'s output depends on frames ``<= t`` only (``track_step``).
        Traceable. With ``TrackConfig.both_ways`` the pass also runs over the motion reversed
        (``_join_ways``): on a CPU one scan of ``2T`` steps (or the two ways on two CPU
        devices, ``shards``), elsewhere the two ways side by side in one scan of ``T`` steps
        (``vmap``), since on a GPU a step costs its kernels' launches, not their width (one G1
        motion of 128 frames on an H200: 1.58 s against 2.52 s, answers 2.2e-4 rad apart by
        rounding, ``Robot.continuous`` timed alone, 2026-11-30; on the 2-core CPU the ``vmap`` was
        slower, 1.59 s against 1.23 s).

        Args:
          q: ``(T, n_driven)`` per-frame answers, rad (``Robot.driven_joints`` order).
          valid: ``(T,)`` bool.
          d: ``(T, 3 * n_bones)`` the person's descriptors (``bones`` layout), or ``None``.
          bones: the descriptor's bones.
          config: ``TrackConfig()`` by default.

        Returns:
          ``(T, n_driven)`` float32, within the IK's box.
        """
        cfg = TrackConfig() if config is None else config
        q = jnp.asarray(q, jnp.float32)
        n_driven = self.robot.n_driven
        if q.ndim != 2 or q.shape[-1] != n_driven:
            raise ConfigError(f"track: answers must be (T, {n_driven}), got {q.shape}")
        valid = jnp.asarray(valid, bool)
        names = resolve_bones(bones)
        h = jnp.zeros((len(q), 0), jnp.float32) if d is None else jnp.asarray(d, jnp.float32)
        Carry = tuple[jax.Array, jax.Array, jax.Array, jax.Array]

        def body(
            carry: Carry, xs: tuple[jax.Array, jax.Array, jax.Array]
        ) -> tuple[Carry, jax.Array]:
            y, q_prev, h_prev, started = carry
            q_t, h_t, ok = xs
            # the first valid frame steps from itself (its answer, cleared of contact)
            y, q_prev = jnp.where(started, y, q_t), jnp.where(started, q_prev, q_t)
            h_prev = jnp.where(started, h_prev, h_t)
            human = None if d is None else (h_prev, h_t, names)
            out = self.track_step(y, q_prev, q_t, cfg, human)
            out = jnp.where(ok, out, q_t)
            nxt = (jnp.where(ok, out, y), jnp.where(ok, q_t, q_prev), jnp.where(ok, h_t, h_prev))
            return (*nxt, started | ok), out

        standing = jnp.asarray(self.robot.standing_driven, jnp.float32)
        init = (standing, standing, h[0], jnp.asarray(False))
        if not cfg.both_ways:
            _, out = jax.lax.scan(body, init, (q, h, valid))
            return out
        n_t = len(q)
        if shards >= 2:  # the two ways on two CPU devices at once (the same answers)

            def one_way(qs: jax.Array, hs: jax.Array, vs: jax.Array) -> jax.Array:
                start = (standing, standing, hs[0, 0], jnp.asarray(False))
                return jax.lax.scan(body, start, (qs[0], hs[0], vs[0]))[1][None]

            ways = over_rows(one_way, 2)(jnp.stack([q, q[::-1]]), jnp.stack([h, h[::-1]]),
                                         jnp.stack([valid, valid[::-1]]))  # fmt: skip
            fwd, bwd = ways[0], ways[1][::-1]
        elif _side_by_side():  # the two ways side by side (vmap): T steps

            def way(qs: jax.Array, hs: jax.Array, vs: jax.Array) -> jax.Array:
                start = (standing, standing, hs[0], jnp.asarray(False))
                return jax.lax.scan(body, start, (qs, hs, vs))[1]

            ways = jax.vmap(way)(jnp.stack([q, q[::-1]]), jnp.stack([h, h[::-1]]),
                                 jnp.stack([valid, valid[::-1]]))  # fmt: skip
            fwd, bwd = ways[0], ways[1][::-1]
        else:  # one scan over the motion and then the motion reversed, the state reset between
            reset = jnp.arange(2 * n_t) == n_t

            def body2(
                carry: Carry, xs: tuple[jax.Array, jax.Array, jax.Array, jax.Array]
            ) -> tuple[Carry, jax.Array]:
                *xs3, r = xs
                y, q_prev, h_prev, started = carry
                return body((y, q_prev, h_prev, started & ~r), tuple(xs3))  # type: ignore[arg-type]

            both = (jnp.concatenate([q, q[::-1]]), jnp.concatenate([h, h[::-1]]),
                    jnp.concatenate([valid, valid[::-1]]), reset)  # fmt: skip
            _, out2 = jax.lax.scan(body2, init, both)
            fwd, bwd = out2[:n_t], out2[n_t:][::-1]
        return self._join_ways(fwd, bwd, q, valid, h, names, cfg)

    def _join_ways(
        self,
        fwd: jax.Array,
        bwd: jax.Array,
        q: jax.Array,
        valid: jax.Array,
        h: jax.Array,
        names: tuple[str, ...],
        cfg: TrackConfig,
    ) -> jax.Array:
        """``track``'s two outputs ``(T, n_driven)`` joined: each chain takes one of them at
        each frame (``2^C`` combinations; for more than ``JOIN_CHAINS`` chains, all chains the
        same one), by a Viterbi path that minimises the sum over valid
        frames of the combined pose's own IK objective without its regulariser (the rows'
        squared direction residual against the person's directions ``h``, or the answers'
        without them, plus the collision term over every pair: two chains taken from
        different passes may touch) and changes a chain's source between consecutive valid
        frames only where that chain's step is within the pass's bound on each of its
        joints."""
        n_t = len(q)
        standing = jnp.asarray(self.robot.standing)
        didx = self.robot.driven_index
        data = jax.tree.map(jnp.asarray, self.problems.data)
        n_c = int(self.problems.data.row_mask.shape[0])
        member_np = self._members()  # (C, n)
        # each driven joint follows its first chain (a joint of no chain: the forward pass)
        owner = np.where(member_np.any(0), member_np.argmax(0), -1)
        if n_c <= JOIN_CHAINS:
            bits = (np.arange(2**n_c)[:, None] >> np.arange(n_c)[None]) & 1  # (S, C)
        else:  # whole poses only: 2^C combinations would cost too much a frame
            bits = np.repeat(np.arange(2)[:, None], n_c, axis=1)
        src = jnp.asarray(np.where(owner[None] >= 0, bits[:, np.maximum(owner, 0)], 0) == 1)
        # switch[s, s', j]: joint j changes pass between combination s' and s
        switch = src[:, None, :] != src[None, :, :]  # (S, S, n)
        mask = jnp.asarray(self.problems.data.row_mask)
        collide = self.config.collision > 0 and bool(self.problems.has_pairs.any())

        def cost(y: jax.Array, tgt: jax.Array, wt: jax.Array) -> jax.Array:  # one pose -> ()
            p = self.problems.fk.points(standing.at[didx].set(y))
            du = _row_directions(p, data) - tgt
            c = jnp.sum(wt * jnp.sum(du * du, axis=-1))
            if collide:
                pen = jax.vmap(lambda ch: self._collision_terms(p, None, ch)[0])(data)
                c = c + jnp.sum(pen * pen)
            return c

        if h.shape[-1] == 0:
            dirs = jax.vmap(lambda y: _row_directions(
                self.problems.fk.points(standing.at[didx].set(y)), data))(q)  # fmt: skip
            tgt, wt = dirs, jnp.broadcast_to(jnp.where(mask, data.weights, 0.0), dirs.shape[:-1])
        else:
            tgt, wt = jax.vmap(lambda x: self._targets(x, names))(h)

        def frame_costs(t: jax.Array) -> tuple[jax.Array, jax.Array]:  # (S,), (S, n)
            poses = jnp.where(src, bwd[t][None], fwd[t][None])
            return jax.vmap(cost, in_axes=(0, None, None))(poses, tgt[t], wt[t]), poses

        inf = jnp.float32(jnp.inf)
        tol = np.float32(1e-4)
        Carry = tuple[jax.Array, jax.Array, jax.Array, jax.Array, jax.Array]

        def forward(carry: Carry, xs: tuple[jax.Array, ...]) -> tuple[Carry, jax.Array]:
            v, y_last, d_last, w_last, started = carry  # (S,), (S, n), (C, R, 3), (C, R)
            t, d_t, w_t, ok = xs
            c_t, y_t = frame_costs(t)
            f_t, b_t = y_t[0], y_t[-1]  # all forward, all backward
            f_last, b_last = y_last[0], y_last[-1]
            turn = _worst_angle(jnp.sum(d_last * d_t, axis=-1), (w_last > 0) & (w_t > 0))
            bound = self._joint_bounds(_step_radius(turn, cfg))  # (n,)
            step = jnp.abs(y_t[:, None, :] - y_last[None, :, :])  # (S, S', n)
            # a change of pass no larger than either pass's own step there (plus the slack):
            # where the two outputs have (nearly) met, not halfway across a branch change
            own = jnp.maximum(jnp.abs(f_t - f_last), jnp.abs(b_t - b_last))  # (n,)
            cap = jnp.minimum(bound, own + np.float32(cfg.switch_slack))
            allowed = ~jnp.any(switch & (step > (cap + tol)[None, None]), axis=-1)  # (S, S')
            cand = jnp.where(allowed, v[None, :], inf)
            stay = jnp.arange(len(v))
            best = jnp.where(started, jnp.argmin(cand, axis=-1), stay)
            v_new = c_t + jnp.where(started, jnp.min(cand, axis=-1), 0.0)
            nxt = (jnp.where(ok, v_new, v), jnp.where(ok, y_t, y_last), jnp.where(ok, d_t, d_last),
                   jnp.where(ok, w_t, w_last), started | ok)  # fmt: skip
            return nxt, jnp.where(ok, best, stay)

        n_s = len(bits)
        init = (jnp.zeros((n_s,), jnp.float32), jnp.zeros((n_s, fwd.shape[-1]), jnp.float32),
                tgt[0], wt[0], jnp.asarray(False))  # fmt: skip
        (v_end, *_), back = jax.lax.scan(forward, init, (jnp.arange(n_t), tgt, wt, valid))

        def backward(s: jax.Array, b_t: jax.Array) -> tuple[jax.Array, jax.Array]:
            return b_t[s], s

        _, path = jax.lax.scan(backward, jnp.argmin(v_end), back, reverse=True)  # (T,)
        return jnp.where(src[path], bwd, fwd)

    @full_precision
    def step_bounds(
        self,
        valid: jax.typing.ArrayLike,
        d: jax.typing.ArrayLike,
        bones: str | tuple[str, ...] = "full",
        config: TrackConfig | None = None,
    ) -> jax.Array:
        """How far each driven joint may move into each frame by ``track``'s own rule, for the
        stages after it (``Robot.bound_steps``): ``max(r_0, g * turn)`` of the joint's chain,
        ``turn`` the largest angle a row's human direction turned since the previous frame.

        Args:
          valid: ``(T,)`` bool.
          d: ``(T, 3 * n_bones)`` the person's descriptors (``bones`` layout).
          bones: the descriptor's bones.
          config: ``TrackConfig()`` by default (``r_0``, ``g``).

        Returns:
          ``(T, n_driven)`` float32 rad: the bound of the step from frame ``t - 1`` to ``t``;
          ``inf`` where either frame is not valid, at ``t = 0`` and for a joint of no chain.
          Traceable.
        """
        cfg = TrackConfig() if config is None else config
        valid = jnp.asarray(valid, bool)
        d = jnp.asarray(d, jnp.float32)
        names = resolve_bones(bones)
        targets = jax.vmap(lambda x: self._targets(x, names))
        a, wa = targets(d[:-1])
        b, wb = targets(d[1:])
        turn = _worst_angle(jnp.sum(a * b, axis=-1), (wa > 0) & (wb > 0))  # (T - 1, C)
        per_joint = self._joint_bounds(_step_radius(turn, cfg))
        both = valid[1:] & valid[:-1]
        per_joint = jnp.where(both[:, None], per_joint, jnp.inf)
        first = jnp.full((1, self.robot.n_driven), jnp.inf, jnp.float32)
        return jnp.concatenate([first, per_joint.astype(jnp.float32)])

    def _members(self) -> np.ndarray:
        """``(C, n_driven)`` bool: which driven joints each chain moves."""
        didx = np.asarray(self.robot.driven_index)
        return (np.asarray(self.problems.data.joints)[:, :, None] == didx[None, None, :]).any(1)

    def _joint_bounds(self, radius: jax.Array) -> jax.Array:
        """``(..., C)`` chains' step radii -> ``(..., n_driven)``: each driven joint's, the
        smallest of the chains that move it (``inf`` for a joint of no chain)."""
        members = self._members()
        member = jnp.broadcast_to(jnp.asarray(members), radius.shape[:-1] + members.shape)
        return jnp.min(jnp.where(member, radius[..., :, None], jnp.inf), axis=-2)

    def _directions(self, q_full: jax.Array) -> jax.Array:
        """``(C, R, 3)`` unit row directions of every chain at ``(n_joints,)`` ``q_full``
        (padded rows: ``(1, 1, 1) / sqrt(3)``)."""
        return _row_directions(self.problems.fk.points(q_full), self.problems.data)

    def track_step(
        self,
        y: jax.Array,
        q_prev: jax.Array,
        q_t: jax.Array,
        config: TrackConfig | None = None,
        human: tuple[jax.Array, jax.Array, tuple[str, ...]] | None = None,
    ) -> jax.Array:
        """One frame of ``track``: ``(n_driven,)`` last output ``y``, last valid answer
        ``q_prev`` and this frame's answer ``q_t`` -> ``(n_driven,)`` this frame's output;
        ``human``: ``(last valid descriptor, this frame's, their bones)`` for the limbs' turn
        (else the answers' directions). Traceable (one pose; vmap for many)."""
        cfg = TrackConfig() if config is None else config
        standing = jnp.asarray(self.robot.standing)
        didx = self.robot.driven_index
        if self.config.collision > 0 and self.problems.has_pairs.any():
            # the answer's pairs between chains (which its per-frame solve did not count: a
            # hand in the hip) cleared first, from the answer and from the last output; left
            # in, the pass below clears them each frame by a step of whichever chain comes
            # last, and a standing leg walks away from the hand (CMU 131_03: 18 deg in 0.25 s)
            # (a step from the answer itself, the first frame: from the cleared answer)
            same = jnp.all(y == q_t)
            q_t = self.separate(q_t, start=y, keep_rows=True)
            y = jnp.where(same, q_t, y)
        q_full = standing.at[didx].set(q_t)
        y_full = standing.at[didx].set(y)
        t = self._directions(q_full)  # (C, R, 3): every chain's targets at once
        mask = jnp.asarray(self.problems.data.row_mask)

        def off_targets(q: jax.Array) -> jax.Array:  # (C,) rad: q's rows against t's
            return _worst_angle(jnp.sum(self._directions(q) * t, axis=-1), mask)

        if human is None:
            turn = off_targets(standing.at[didx].set(q_prev))
        else:
            h_prev, h_t, names = human
            a, wa = self._targets(h_prev, names)
            b, wb = self._targets(h_t, names)
            turn = _worst_angle(jnp.sum(a * b, axis=-1), (wa > 0) & (wb > 0))
        radius = _step_radius(turn, cfg)
        sc = np.float32(math.sqrt(cfg.continuity))
        # the pull toward the answer, per chain: by how far the last output is off its rows
        half = np.float32(cfg.follow_error / 2)
        ramp = jnp.clip((off_targets(y_full) - half) / half, 0.0, 1.0)
        sp = jnp.sqrt(np.float32(cfg.follow) * ramp)
        data = jax.tree.map(jnp.asarray, self.problems.data)
        q_ext = self._extended(q_full)

        def chain(
            out: jax.Array, xs: tuple[_ChainData[jax.Array], jax.Array, jax.Array, jax.Array]
        ) -> tuple[jax.Array, None]:
            c, t_c, radius_c, sp_c = xs
            anchor, answer = out[c.joints], q_ext[c.joints]
            lo = jnp.maximum(c.lo, anchor - radius_c)
            hi = jnp.minimum(c.hi, anchor + radius_c)

            def res_jac(x: jax.Array) -> tuple[jax.Array, jax.Array]:
                r, jac = self._residual(x, out, t_c, c.weights, c)
                eye = jnp.eye(x.shape[-1], dtype=jnp.float32)
                return (
                    jnp.concatenate([r, sc * (x - anchor), sp_c * (x - answer)]),
                    jnp.concatenate([jac, sc * eye, sp_c * eye], axis=0),
                )

            def run(x0: jax.Array) -> tuple[jax.Array, jax.Array]:
                x, r, _ = _levenberg_marquardt(
                    res_jac, x0, lo, hi, cfg.iterations, self.config.damping
                )
                return x, jnp.sum(r * r)

            starts = jnp.stack([jnp.clip(anchor, lo, hi), jnp.clip(answer, lo, hi)])
            xs_, fs = jax.vmap(run)(starts)
            return out.at[c.joints].set(xs_[jnp.argmin(fs)]), None

        out, _ = jax.lax.scan(chain, self._extended(y_full), (data, t, radius, sp))
        res = out[didx]
        return jnp.where(jnp.isfinite(res), res, q_t)

    def solve(self, d: jax.typing.ArrayLike, bones: str | tuple[str, ...] = "upper") -> jax.Array:
        """``(..., 3 * n_bones)`` descriptors -> ``(..., n_driven)`` float32 angles, rad, within
        limits, finite (``solve_info`` without the diagnostics). Traceable."""
        return self.solve_info(d, bones)[0]


def _worst_angle(cos: jax.Array, use: jax.Array) -> jax.Array:
    """``(..., C, R)`` cosines between two sets of row directions -> ``(..., C)`` rad: each
    chain's largest angle over the rows ``use`` keeps (0 for a chain with none)."""
    return jnp.max(jnp.arccos(jnp.clip(jnp.where(use, cos, 1.0), -1.0, 1.0)), axis=-1)


def _step_radius(turn: jax.Array, cfg: TrackConfig) -> jax.Array:
    """How far a chain's joints may move in one frame (``track``'s trust region): ``max(r_0,
    g * turn)`` of the ``(..., C)`` limb turns, rad."""
    return jnp.maximum(np.float32(cfg.min_step), np.float32(cfg.step_gain) * turn)


def _row_directions(p: jax.Array, c: _ChainData[Any]) -> jax.Array:
    """``(..., R, 3)`` unit directions of the rows of chain ``c`` (or of every chain, stacked:
    ``(C, R, 3)``) at FK points ``p`` ``(P, 3)`` (padded rows: ``(1, 1, 1) / sqrt(3)``, as
    ``GenericIK._residual`` computes them)."""
    seg = p[c.row_points[..., 1]] - p[c.row_points[..., 0]]
    seg = jnp.where(jnp.asarray(c.row_mask)[..., None], seg, jnp.float32(1.0))
    return seg / jnp.sqrt(jnp.sum(seg * seg, axis=-1, keepdims=True))


def _levenberg_marquardt(
    res_jac: Callable[[jax.Array], tuple[jax.Array, jax.Array]],
    x0: jax.Array,
    lo: jax.Array,
    hi: jax.Array,
    iterations: int,
    damping: float,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Box-constrained Levenberg-Marquardt (the module doc) from ``x0``: ``(x, r, jac)`` at the
    best point found. One residual and Jacobian per iteration, at the trial point (kept only if
    it lowers ``|r|^2``); a joint at a bound whose gradient points outward is held."""
    State = tuple[jax.Array, jax.Array, jax.Array, jax.Array, jax.Array]

    def step(_: int, state: State) -> State:
        x, r, jac, f, mu = state
        g = jnp.matmul(jac.T, r, precision=_HIGHEST)
        a = jnp.matmul(jac.T, jac, precision=_HIGHEST)
        held = ((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0))
        free = ~held
        mask = free[:, None] & free[None, :]
        diag = jnp.diagonal(a)
        a_free = jnp.where(mask, a, 0.0) + jnp.diag(jnp.where(free, mu * (diag + 1e-6), 1.0))
        delta = _spd_solve(a_free, -jnp.where(free, g, 0.0))
        x_new = jnp.clip(x + delta, lo, hi)
        r_new, jac_new = res_jac(x_new)
        f_new = jnp.sum(r_new * r_new)
        better = f_new < f
        return (
            jnp.where(better, x_new, x),
            jnp.where(better, r_new, r),
            jnp.where(better, jac_new, jac),
            jnp.where(better, f_new, f),
            jnp.where(better, mu * 0.3, mu * 4.0),
        )

    r0, jac0 = res_jac(x0)
    f0 = jnp.sum(r0 * r0)
    init = (_varying_as(x0, f0), r0, jac0, f0, _varying_as(jnp.float32(damping), f0))
    x, r, jac, _, _ = jax.lax.fori_loop(0, iterations, step, init)
    return x, r, jac


def _varying_as(x: jax.typing.ArrayLike, ref: jax.Array) -> jax.Array:
    """``x`` itself (the same values), made to vary with the scalar ``ref`` under ``vmap``.

    For a loop's initial carry: ``vmap`` of a ``scan`` / ``fori_loop`` traces the body with the
    carries batched as the initial ones are, and traces it again when an unbatched carry (a
    constant start) comes out batched; nested, the traces multiply (a second run's retarget of
    the G1 spent seconds tracing its IK's loops). A carry that varies from the start is traced
    once. ``where(isnan(ref), x, x)`` is ``x`` whatever ``ref`` holds, and XLA folds it away."""
    x = jnp.asarray(x)
    return jnp.where(jnp.isnan(ref), x, x)


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The least rotation (3, 3) taking direction ``a`` onto direction ``b`` (Rodrigues)."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(a @ b)
    if c < -1 + 1e-9:  # opposite: a half turn about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return 2.0 * np.outer(axis, axis) - np.eye(3)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _spd_solve(a: jax.Array, b: jax.Array) -> jax.Array:
    """``a^-1 b`` for one small symmetric positive definite ``(n, n)`` matrix: an unrolled
    Cholesky factorisation and two triangular solves (elementwise code: no LAPACK call per
    pose, which costs more than the arithmetic at these sizes)."""
    n = a.shape[-1]
    low = [[jnp.zeros((), a.dtype)] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1):
            acc = a[i, j] - sum((low[i][k] * low[j][k] for k in range(j)), jnp.zeros((), a.dtype))
            if i == j:
                low[i][i] = jnp.sqrt(jnp.maximum(acc, 1e-30))
            else:
                low[i][j] = acc / low[j][j]
    y: list[jax.Array] = []
    for i in range(n):
        y.append(
            (b[i] - sum((low[i][k] * y[k] for k in range(i)), jnp.zeros((), a.dtype))) / low[i][i]
        )
    x: list[jax.Array] = [jnp.zeros((), a.dtype)] * n
    for i in reversed(range(n)):
        rest = sum((low[k][i] * x[k] for k in range(i + 1, n)), jnp.zeros((), a.dtype))
        x[i] = (y[i] - rest) / low[i][i]
    return jnp.stack(x)


def _body_joints(model: mujoco.MjModel, bid: int) -> set[str]:
    """Names of the joints that move body ``bid`` (its own and its ancestors')."""
    names: set[str] = set()
    while bid > 0:
        for j in range(model.body_jntadr[bid], model.body_jntadr[bid] + model.body_jntnum[bid]):
            names.add(str(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)))
        bid = int(model.body_parentid[bid])
    return names


def _moved_by(model: mujoco.MjModel, geom: str) -> set[str]:
    """Names of the joints that move geom ``geom``."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    if gid < 0:
        raise ConfigError(f"the MJCF has no geom named {geom!r}")
    return _body_joints(model, int(model.geom_bodyid[gid]))


_CAPSULE_KINDS = (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_SPHERE))


def mjcf_collision_pairs(model: mujoco.MjModel) -> tuple[tuple[str, str], ...]:
    """Every pair of named capsule / sphere geoms of ``model`` that MuJoCo's own contact filter
    lets collide: their ``contype`` / ``conaffinity`` bits meet, they sit on bodies not welded
    together, not a parent and its child (MuJoCo's parent filter, on welded bodies) and not a
    pair of the MJCF's ``<exclude>``. In geom order. Boxes, meshes and planes are left out (the
    collision term takes segments; a robot whose boxes matter gives capsules along them, and
    the term widens those by how far the box stands out of them: ``box_overhang``)."""
    excluded = {int(x) for x in model.exclude_signature}
    weld = model.body_weldid
    named = [
        g
        for g in range(model.ngeom)
        if int(model.geom_type[g]) in _CAPSULE_KINDS
        and mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
    ]
    out = []
    for k, i in enumerate(named):
        for j in named[k + 1 :]:
            bits = (model.geom_contype[i] & model.geom_conaffinity[j]) or (
                model.geom_contype[j] & model.geom_conaffinity[i]
            )
            bi, bj = int(model.geom_bodyid[i]), int(model.geom_bodyid[j])
            wi, wj = int(weld[bi]), int(weld[bj])
            if not bits or wi == wj:
                continue
            if ((bi << 16) + bj) in excluded or ((bj << 16) + bi) in excluded:
                continue
            pi, pj = int(weld[model.body_parentid[wi]]), int(weld[model.body_parentid[wj]])
            if (pi == wj and wj != 0) or (pj == wi and wi != 0):
                continue
            out.append(
                (
                    str(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, i)),
                    str(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, j)),
                )
            )
    return tuple(out)


def own_chains(chains: Sequence[Chain], chain: Chain) -> tuple[Chain, ...]:
    """The chains whose answers ``chain``'s per-frame solve may depend on: itself and the
    chains before it in ``chains`` whose bones it reads too (the waist's for a G1 leg). Its IK
    from its own descriptor columns (``Chain.ik``) solves these."""
    before = chains[: chains.index(chain)]
    return (*(c for c in before if set(c.bones) <= set(chain.bones)), chain)


def _other_chains_joints(robot: Robot, chains: Sequence[Chain], chain: Chain) -> set[str]:
    """The joints of the robot's chains outside ``own_chains(robot.chains, chain)`` (of
    ``chains`` where ``chain`` is not one of the robot's)."""
    pool = tuple(robot.chains) if chain in robot.chains else tuple(chains)
    own = {j for c in own_chains(pool, chain) for j in c.joints}
    return {j for c in pool for j in c.joints} - own


def _pair_moved_by(model: mujoco.MjModel, pair: tuple[str, str]) -> set[str]:
    """Names of the joints that move geom ``pair[0]`` relative to geom ``pair[1]``: those on
    the path between their bodies (a joint above both moves them together)."""
    return _moved_by(model, pair[0]) ^ _moved_by(model, pair[1])


def _rows_read(
    model: mujoco.MjModel, correspondence: Correspondence, chains: Sequence[Chain], every: bool
) -> tuple[tuple[BonePair, ...], ...]:
    """``chain_rows`` of each chain, checked: every chain reads a row, and every row is read by
    a chain (with ``every``: all of the correspondence's rows; else those of the chains'
    bones, when a caller solves some chains only). ConfigError naming the chain or row."""
    read = tuple(chain_rows(model, correspondence, c) for c in chains)
    for chain, rows in zip(chains, read, strict=True):
        if not rows:
            raise ConfigError(
                f"chain {chain.name!r}: its joints {chain.joints} change the direction of no "
                f"correspondence row of its bones {chain.bones} (seen from "
                f"{correspondence.base!r}); add a row or drop the chain"
            )
    offered = [
        r
        for r in correspondence.pairs
        if every or any(r in correspondence.rows(c.bones) for c in chains)
    ]
    unread = [r for r in offered if not any(r in rows for rows in read)]
    if unread:
        names = ", ".join(f"{_row_name(r)!r} ({r.start} -> {r.end})" for r in unread)
        raise ConfigError(
            f"correspondence rows read by no chain: {names}; no chain of "
            f"{[c.name for c in chains]} lists the row's bones with a joint that changes its "
            f"direction seen from {correspondence.base!r}: add the bones to a chain whose "
            "joints move the row, or drop the row"
        )
    return read


def _row_name(row: BonePair) -> str:
    return row.bone if row.minus is None else f"{row.bone} - {row.minus}"


def row_turned_by(model: mujoco.MjModel, row: BonePair, base: str) -> set[str]:
    """Names of the joints that change the direction of ``row``, seen in ``base``'s frame.

    A joint moves a point relative to the base when it lies on the path between the point's
    body and the base body: the symmetric difference of the two bodies' ancestor joints (a
    joint above both turns the point and the base together, as ``TreeFK.jacobian`` treats it).
    The row's direction changes with the joints that move either of its points so, less a
    joint that moves only one of them when that point lies on the joint's axis (a hinge turns
    such a point about itself; checked for points of the two bodies the axis is fixed in: the
    G1's hip pitch and the hip line's end at the hip pitch link's origin, its waist yaw and
    the spine row's start at the pelvis origin).

    Raises:
      ConfigError: an unknown base or point.
    """
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base)
    if bid < 0:
        raise ConfigError(f"the MJCF has no body named {base!r} (the correspondence's base)")
    above_base = _body_joints(model, bid)
    moved = []
    for name in (row.start, row.end):
        body, offset = _point(model, name)
        moved.append(
            {
                j
                for j in _body_joints(model, body) ^ above_base
                if not _on_axis(model, j, body, offset)
            }
        )
    return moved[0] | moved[1]


def _on_axis(model: mujoco.MjModel, joint: str, body: int, offset: np.ndarray) -> bool:
    """Whether hinge ``joint`` leaves the point ``offset`` of ``body`` where it is at every
    pose: the point lies on the joint's axis, in a frame the axis is fixed in (the joint's body
    when the point hangs from it, else that body's parent), and every joint between that frame
    and the point's body has the point on its axis too (so that its place in the frame does
    not change). Bodies of more than one joint count as moving the point."""
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
    jb = int(model.jnt_bodyid[j])
    if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or model.body_jntnum[jb] != 1:
        return False

    def rest(b: int) -> tuple[np.ndarray, np.ndarray]:  # body b's frame in its parent's
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, np.asarray(model.body_quat[b], np.float64))
        return np.asarray(model.body_pos[b], np.float64), rot.reshape(3, 3)

    def on_axis(k: int, p: np.ndarray) -> bool:  # p (body frame of joint k) on k's axis
        axis = np.asarray(model.jnt_axis[k], np.float64)
        rel = p - np.asarray(model.jnt_pos[k], np.float64)
        return bool(np.linalg.norm(np.cross(axis / np.linalg.norm(axis), rel)) < 1e-9)

    ancestors, b = [], body
    while b > 0:
        ancestors.append(b)
        b = int(model.body_parentid[b])
    frame = jb if jb in ancestors else int(model.body_parentid[jb])
    if frame not in ancestors:
        return False
    p, b = np.asarray(offset, np.float64), body
    while b != frame:  # up to the frame, through joints that keep the point in place
        first, n = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        hinge = n == 1 and model.jnt_type[first] == mujoco.mjtJoint.mjJNT_HINGE
        if n > 1 or (n == 1 and not (hinge and on_axis(first, p))):
            return False
        pos, rot = rest(b)
        p, b = pos + rot @ p, int(model.body_parentid[b])
    if frame == jb:
        return on_axis(j, p)
    pos, rot = rest(jb)  # the point in the joint's body frame at the joint's zero
    return on_axis(j, rot.T @ (p - pos))


def chain_rows(
    model: mujoco.MjModel, correspondence: Correspondence, chain: Chain
) -> tuple[BonePair, ...]:
    """The rows ``chain`` reads: those of its bones (``Correspondence.rows``) whose direction,
    seen from ``correspondence.base``, one of its joints changes (``row_turned_by``). A leg
    chain of the G1 lists the waist's bones (its IK runs after the waist's) but reads none of
    their rows; the waist reads the hip line, whose points hang from the hips, because its
    joints turn the base."""
    joints = set(chain.joints)
    return tuple(
        r
        for r in correspondence.rows(chain.bones)
        if joints & row_turned_by(model, r, correspondence.base)
    )


def _closest(
    p1: jax.Array, q1: jax.Array, p2: jax.Array, q2: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Parameters ``(s, t)`` in [0, 1] of the closest points ``p1 + s (q1 - p1)`` and ``p2 + t
    (q2 - p2)`` of two segments (``(..., 3)`` each; a point when its ends coincide): Ericson,
    *Real-Time Collision Detection*, 5.1.9."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = jnp.sum(d1 * d1, -1)
    e = jnp.sum(d2 * d2, -1)
    f = jnp.sum(d2 * r, -1)
    c = jnp.sum(d1 * r, -1)
    b = jnp.sum(d1 * d2, -1)
    eps = 1e-12
    denom = a * e - b * b
    s = jnp.where(
        denom > eps, jnp.clip((b * f - c * e) / jnp.where(denom > eps, denom, 1.0), 0, 1), 0.0
    )
    s = jnp.where(a > eps, s, 0.0)
    t = jnp.where(e > eps, (b * s + f) / jnp.where(e > eps, e, 1.0), 0.0)
    # t outside [0, 1]: clamp it and recompute s
    t_c = jnp.clip(t, 0.0, 1.0)
    s = jnp.where(
        (t != t_c) & (a > eps), jnp.clip((b * t_c - c) / jnp.where(a > eps, a, 1.0), 0.0, 1.0), s
    )
    return s, t_c


def segment_distance(p1: jax.Array, q1: jax.Array, p2: jax.Array, q2: jax.Array) -> jax.Array:
    """Distance between segments ``p1q1`` and ``p2q2`` (``(..., 3)`` each)."""
    s, t = _closest(p1, q1, p2, q2)
    diff = (p1 + (q1 - p1) * s[..., None]) - (p2 + (q2 - p2) * t[..., None])
    return jnp.sqrt(jnp.sum(diff * diff, -1))
