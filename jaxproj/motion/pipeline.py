"""The one motion pipeline: skeleton positions -> playable robot joint angles.

Stages, each a small pure (traceable) function written for ONE motion (``(T, 20, 3)``
positions, ``(T,)`` valid, ``(T,)`` times) or ONE frame::

    frame_descriptors   (T, 20, 3) positions -> (T, m) descriptors, (T,) valid
    glitch_frames       (T,) frames where a bone the robot reads jumps out and back in one
                        frame (a tracker's glitch): ``motion`` marks them invalid (offline only)
    lost_frames         (T,) frames where a bone the robot reads is less than half or more than
                        twice its median length (a limb the tracker lost): ``motion`` marks
                        them invalid (offline only)
    level               the neck's neutral tilt moved to the reference (``skeleton.level_neck``;
                        ``retarget``: each recording's own median tilt, see ``level``)
    map_frames          (T, m) -> (T, n) driven angles: analytic IK or a projector
    fill_invalid        invalid frames hold the last valid frame, leading ones back-fill
    smooth              the zero-lag offline smoother (``offline.rts_motion``: invalid frames'
                        values skipped, gaps bridged) or the paper's causal double exponential
                        smoother (``smoothing.smooth_motion``, on the filled motion); then
                        ``Robot.bound_steps``: no step past the continuity pass's own bound
                        (the smoother's overshoot cannot bring back a flip)
    clip_to_limits      (T, n) -> within the robot's limits (``Robot.lower`` / ``upper``) and
                        its coupled ranges (``Robot.coupled_limits``: a head envelope),
                        and out of self-collision where the robot says how (``Robot.separate``;
                        ``Robot.playable`` does all three; over a motion
                        ``Robot.playable_motion``: each frame's separation also searched from
                        the previous frame's answer)
    stand_if_lost       a motion with no valid frame -> the robot's standing posture
    feasible            ``feasible.make_feasible`` on the full configuration (host side: it
                        resamples irregular times on a grid before its own jitted filter)
    playable_full       after the filter, ``Robot.playable_motion`` once more, last
                        (``retarget``): the filter moves joints, and a contact it brings back
                        is pushed apart (what is written is free of self-contact; the
                        separation's small moves can exceed the filter's bounds on a few
                        frames, which ``retarget``'s report counts)

``finish`` composes track -> fill -> smooth -> clip -> stand for one motion (``track``:
``Robot.continuous``, the robot's continuity pass over the per-frame answers, where it has one; the
clip to the limits and coupled ranges runs on every path through ``finish`` and ``frame``, smoothed
or not: no output of retarget, evaluate or streaming leaves them), ``motion`` composes the whole
pipeline for one motion (descriptor -> map -> finish -> all ``n_joints``), ``frame`` is one frame
of the same stages with the smoother's ``step`` (causal). No function here is jitted: the callers
jit at their entry points and add the batch axis (``jax.vmap``) where they call it. Every stage
that needs the robot (limits, posture, IK) takes ``robot`` (a ``Robot``, a static argument of the
callers' jits; no default: the callers pass the model's or the caller's robot), so ``n`` is its
``n_driven``.

The callers, and the options that keep each one's answers as they were measured:

* ``jaxproj.motion.retarget`` jits ``motion`` on a recording padded to a length bucket. Every
  frame is mapped (invalid ones too; their answers are then replaced by ``fill_invalid``). The
  smoother is optional (``smooth=``); the clip runs with or without it (the smoother's trend
  term can overshoot the limits; the mappings answer within them but, for a projection, not
  always within the coupled ranges). ``standing="last"``: a
  motion with no valid frame becomes the standing posture after the smoother and the clip, so
  it is exactly the standing posture. ``feasible`` runs afterwards on the host, optional.
* ``jaxproj.eval.evaluate`` maps only the valid frames of all its motions at once
  (``projection.api.project`` or a baseline: the answers it scores per frame), scatters them
  into padded motions and runs ``finish`` vmapped over them. ``standing="first"``: a motion
  with no valid frame is set to the standing posture BEFORE the smoother (as evaluate has
  always done it; with a dead band ``eta > 0`` the smoother holds a constant motion exactly, so
  the two orders differ only for ``eta = 0``). Smoothing is optional as in retarget;
  ``feasible`` is reported beside the scores (``evaluate.feasibility_block``), not scored as
  the summary.
* ``jaxproj.motion.streaming`` runs ``frame``: one frame, causal. It cannot look ahead, so
  invalid frames differ from ``fill_invalid``'s rule: an invalid frame leaves the smoother's
  state untouched (the output repeats; ``retarget`` instead feeds the held pose to the
  smoother, whose trend goes on), and before the first valid frame the output is the standing
  posture (``retarget`` back-fills the first valid frame). The smoother is always on and the
  output always clipped; no feasibility filter (it needs the whole motion).

Size: over 500 lines: the stages and the three ways they are put together (``motion``, one
motion; ``motions``, many packed into one program; ``frame``, streaming), which share the
stages' code and must stay in step.
"""

from __future__ import annotations

from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import full_precision
from jaxproj.errors import ConfigError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import (
    MIRROR_BONE,
    NECK_TILT_REFERENCE,
    descriptor,
    level_body,
    level_neck,
    recording_neck_tilt,
    resolve_bones,
    world_up,
)
from jaxproj.motion.smoothing import smooth_any
from jaxproj.motion.smoothing import step as smoothing_step
from jaxproj.projection.api import project_batch
from jaxproj.projection.confidence import confidence
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, StackedProjector
from jaxproj.robots import Robot

Standing = Literal["first", "last"]
"""When ``finish`` puts a motion with no valid frame at the standing posture: ``"first"``
before the smoother (evaluate), ``"last"`` after the smoother and the clip (retarget)."""

AnyProjector = Projector | StackedProjector


def frame_descriptors(
    positions: jax.Array,
    valid: jax.Array | None,
    *,
    bones: str | tuple[str, ...],
    mirror: bool,
) -> tuple[jax.Array, jax.Array]:
    """Descriptors of one motion (or one frame) and their validity.

    Args:
      positions: ``(T, 20, 3)`` (or ``(20, 3)``) joint positions, Kinect SDK order.
      valid: ``(T,)`` (or ``()``) bool from the reader, combined with the descriptor's own
        check; ``None``: the descriptor's check alone.
      bones, mirror: descriptor options (``skeleton.descriptor``).

    Returns:
      ``(d, ok)``: ``(T, m)`` descriptors and ``(T,)`` bool.
    """
    d, ok = descriptor(positions, bones=bones, mirror=mirror)
    if valid is not None:
        ok = ok & valid
    return d, ok


GLITCH_DEG = 60.0
"""``glitch_frames``' threshold: a bone that turns more than this into a run of one or two frames
and more than this out of it, while the frames on either side differ by less than half as much."""


def glitch_frames(
    d: jax.Array, ok: jax.Array, *, bones: str | tuple[str, ...], read: tuple[str, ...]
) -> jax.Array:
    """The frames of one motion where a tracker glitched for one or two frames: some bone of
    ``read`` turns by more than ``GLITCH_DEG`` into the run and by more than that out of it,
    while its directions in the frames on either side of the run are less than half the smaller
    turn apart (it went out and came back). A limb does not do that: on UTKinect-Action3D (7.5
    fps after resampling) a forearm turns 131 deg into one frame and 168 deg out of it, and the
    robot's shoulder, following it, swings 238 deg and back; another forearm turns 128 deg into
    two frames and 145 deg out of them (UTKinect person 9, e02, frames 894-895 at 7.5 fps), and
    a 29-joint robot's shoulder yaw, following it, swings 205 deg. Only runs whose neighbours
    are valid are judged; the first and last frames never are.

    Args:
      d: ``(T, 3 * n_bones)`` descriptors of ``bones``; ok: ``(T,)`` their validity.
      bones: the descriptor's bones.
      read: the bones to judge (the robot's, ``Robot.ik_bones``); bones the descriptor lacks
        are skipped.

    Returns:
      ``(T,)`` bool, true at a glitch frame.
    """
    names = resolve_bones(bones)
    idx = [names.index(b) for b in read if b in names]
    t = d.shape[0]
    if not idx or t < 3:
        return jnp.zeros(ok.shape, bool)
    v = d.reshape(t, -1, 3)[:, np.asarray(idx)]
    n = jnp.sqrt(jnp.sum(v * v, axis=-1, keepdims=True))
    u = v / jnp.where(n > 1e-6, n, 1.0)
    bound = np.float32(np.radians(GLITCH_DEG))

    def angle(a: jax.Array, b: jax.Array) -> jax.Array:
        return jnp.arccos(jnp.clip(jnp.sum(a * b, axis=-1), -1.0, 1.0))

    def runs(k: int) -> jax.Array:
        """``(T,)``: frames in a glitch run of ``k`` frames (from frame ``i`` to ``i + k - 1``,
        neighbours ``i - 1`` and ``i + k``)."""
        before, first, last, after = u[: t - k - 1], u[1 : t - k], u[k : t - 1], u[k + 1 :]
        smaller = jnp.minimum(angle(first, before), angle(after, last))
        jump = (smaller > bound) & (angle(after, before) < smaller / 2)
        valid = ok[: t - k - 1] & ok[k + 1 :]
        for j in range(k):
            valid = valid & ok[1 + j : t - k + j]
        start = jnp.any(jump, axis=-1) & valid  # (t - k - 1,): a run starts at frame 1 + i
        marked = jnp.zeros((t,), bool)
        for j in range(k):
            marked = marked.at[1 + j : t - k + j].set(marked[1 + j : t - k + j] | start)
        return marked

    return runs(1) | runs(2) if t >= 4 else runs(1)


LOST_RATIO = 2.0
"""``lost_frames``' threshold: a bone more than this many times its median length, or less than
its inverse, is one the tracker lost."""
LOST_MIN_FRAMES = 30
"""``lost_frames`` judges a motion of at least this many valid frames only: the median of fewer
says little of a bone's length (of a few frames, most of them garbage, it is the garbage's)."""


def lost_frames(
    positions: jax.Array, ok: jax.Array, *, read: tuple[str, ...], mirror: bool = False
) -> jax.Array:
    """The frames of one motion where the tracker lost a limb: some bone of ``read`` is shorter
    than ``1 / LOST_RATIO`` or longer than ``LOST_RATIO`` times its median length over the
    motion's ``ok`` frames (at least ``LOST_MIN_FRAMES`` of them; a shorter motion is not
    judged). A person's bones keep their length; a Kinect that loses a leg
    while the person sits down reports its thigh at 0.28-0.38 and its shin at 0.43-0.61 of
    their median lengths for two seconds (UTKinect person 9, e02, frames 277-291 at 7.5 fps),
    and a robot's hip, following it, swings 87 deg in one step. On the bundled data it marks 1
    of 22,365 valid MSR Action3D frames and 115 of 3,227 UTKinect-Action3D ones (3.6 %; the
    G1's bones; bone-frames: the pelvis's two halves 79, the legs 59, the arms 3), none of
    the CMU clips'.

    Args:
      positions: ``(T, 20, 3)`` Kinect v1 joints; ok: ``(T,)`` their validity.
      read: the robot's bones (``Robot.ik_bones``); bones the skeleton lacks are skipped.
      mirror: the descriptor's ``mirror``: the person's bones of the other side drive them.

    Returns:
      ``(T,)`` bool, true at a lost frame (never where ``ok`` is false).
    """
    s = skeletons.get(skeletons.DEFAULT)
    names = tuple(MIRROR_BONE[b] if mirror else b for b in read if b in s.bones)
    if not names:
        return jnp.zeros(ok.shape, bool)
    start, end = np.array(s.bone_joints(names)).T
    length = jnp.linalg.norm(positions[:, end] - positions[:, start], axis=-1)  # (T, k)
    median = jnp.nanmedian(jnp.where(ok[:, None], length, jnp.nan), axis=0)
    ratio = length / jnp.maximum(median, 1e-9)[None]
    lost = (ratio < 1.0 / LOST_RATIO) | (ratio > LOST_RATIO)
    enough = jnp.sum(ok) >= LOST_MIN_FRAMES
    return jnp.any(lost, axis=-1) & ok & enough


NeckLevel = Literal["recording", "given", "off"]
"""How ``level`` finds a motion's neutral neck tilt (see there)."""


def level(
    d: jax.Array,
    ok: jax.Array,
    neck: NeckLevel,
    neck_neutral: jax.typing.ArrayLike = NECK_TILT_REFERENCE,
    *,
    bones: str | tuple[str, ...],
    up: jax.Array | None = None,
    legs: bool = True,
) -> jax.Array:
    """One motion's descriptors levelled: for descriptors with legs the body frame and the
    spine against the motion's own medians and the feet against the floor (``up``, the
    capture's up axis per frame: ``skeleton.level_body``; with ``neck`` ``"recording"`` or
    ``"given"``), and the neck (``skeleton.level_neck``): its neutral
    tilt moved to ``skeleton.NECK_TILT_REFERENCE``, before the IK or the projection reads it
    (both then see the same levelled descriptor, so they stay consistent, and the IK stays a
    pure function of one descriptor).

    Args:
      d: ``(T, m)`` descriptors; ok: ``(T,)`` bool, their validity.
      neck: ``"recording"``: the neutral is the median neck tilt of the valid frames
        (``skeleton.recording_neck_tilt``); ``"given"``: ``neck_neutral`` (rad); ``"off"``:
        ``d`` unchanged (the fixed reference, as before levelling existed).
      bones: the descriptor's bones (no neck bone: ``d`` unchanged).
      up: ``(T, 3)`` the capture's up axis in each frame's body frame (``skeleton.world_up``),
        or ``None``: the feet against the body's medians.
      legs: ``level_body``'s first step (every bone turned so the median shin hangs straight
        down); off for a whole-body motion.
    """
    if neck == "off":
        return d
    d = level_body(d, ok, bones, up=up, legs=legs)
    if "neck" not in resolve_bones(bones):
        return d
    if neck == "recording":
        neck_neutral = recording_neck_tilt(d, ok, bones)
    elif neck != "given":
        raise ConfigError(f"neck must be 'recording', 'given' or 'off', got {neck!r}")
    return level_neck(d, neck_neutral, bones)


def map_frames(
    p: AnyProjector | None,
    d: jax.Array,
    *,
    method: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
    bones: str | tuple[str, ...],
    robot: Robot,
    shards: int = 1,
) -> tuple[jax.Array, jax.Array]:
    """Per-frame mapping: ``(T, m)`` descriptors -> ``(T, n)`` driven angles (rad) and ``(T,)``
    confidence (``projection.confidence``).

    ``method="ik"``: the robot's analytic IK (``Robot.solve_ik_traced``; ``p`` unused;
    ``bones`` picks its bones; its frames split over ``shards`` CPU devices, the same answers),
    confidence 1; ``"relaxed"`` / ``"full"``:
    ``projection.api.project_batch`` of ``p`` with ``L = n_l``, ``M = n_m``, confidence from
    the objective's value. Both answer within the joint limits.
    """
    if method == "ik":
        q = robot.solve_ik_traced(d, bones, shards)
        return q, jnp.ones(q.shape[:-1], jnp.float32)
    if p is None:
        raise ConfigError(f"method {method!r} needs a projector")
    q, value = project_batch(p, d, objective=method, n_l=n_l, n_m=n_m, full=full)
    return q, confidence(value, robot.deviation_scale)


def fill_invalid(q: jax.Array, valid: jax.Array) -> jax.Array:
    """Fill invalid frames of one motion: hold the last valid frame, back-fill leading ones.

    Args:
      q: ``(T, n)`` per-frame values (anything at invalid frames, NaN included).
      valid: ``(T,)`` bool.

    Returns:
      ``(T, n)``: valid frames unchanged; an invalid frame takes the last valid frame before
      it, or the first valid frame if there is none before it. If no frame is valid the input
      is returned with non-finite entries zeroed (``stand_if_lost`` substitutes a posture).
    """
    t = jnp.arange(q.shape[0])
    last = jax.lax.cummax(jnp.where(valid, t, -1), axis=0)
    first = jnp.argmax(valid)
    src = jnp.where(last >= 0, last, first)
    out = q[src]
    return jnp.where(jnp.isfinite(out), out, 0.0)


def clip_to_limits(q: jax.Array, robot: Robot) -> jax.Array:
    """``(..., n_driven)`` driven angles clipped to ``robot``'s limits (float32 limits), then
    each follower of ``robot.coupled_limits`` to its range at its leader (``Robot.clip_driven``:
    e.g. the default robot's HeadPitch to the head anti-collision envelope at its HeadYaw), and
    moved out of self-collision by ``robot.separate`` where it has one (its collision pairs pushed
    apart; ``Robot.playable``)."""
    return robot.playable(q)


def stand_if_lost(q: jax.Array, valid: jax.Array, robot: Robot) -> jax.Array:
    """``(T, n_driven)`` -> the standing posture's driven joints on every frame if no frame of
    ``valid`` ``(T,)`` is true, else ``q`` unchanged."""
    return jnp.where(jnp.any(valid), q, jnp.asarray(standing_driven(robot), q.dtype))


def finish(
    q: jax.Array,
    valid: jax.Array,
    length: jax.Array,
    gains: jax.Array | None,
    *,
    standing: Standing,
    robot: Robot,
    smoother: str = "paper",
    d: jax.Array | None = None,
    bones: str | tuple[str, ...] = "full",
    shards: int = 1,
) -> tuple[jax.Array, jax.Array]:
    """The stages after the mapping for one motion: the robot's continuity pass
    (``Robot.continuous``) -> fill -> smooth (and ``Robot.bound_steps``) -> clip, and the
    standing posture for a motion
    with no valid frame (``standing``: before or after the smoother).

    Args:
      q: ``(T, n)`` per-frame driven angles of a motion padded to ``T`` frames.
      valid: ``(T,)`` bool (padding frames false).
      length: ``()`` int, the true length (the smoother leaves later frames as they are).
      gains: ``(3,)`` or ``(T, 3)`` smoother gains (``smoothing.frame_gains``); ``None``: no
        smoothing (the clip still runs: the mappings answer within the joint limits, not
        always within the coupled ranges, e.g. a projection's answer and the head envelope).
      standing: ``"first"`` (evaluate) or ``"last"`` (retarget); see the module doc.
      robot: the robot (its limits and standing posture).
      smoother: the ``kind`` of the settings ``gains`` came from: ``"paper"`` or ``"offline"``.
      d, bones: the person's ``(T, m)`` descriptors (of ``bones``) for the continuity pass (how
        far each limb turned), or ``None`` (the answers' own directions).
      shards: CPU devices the continuity pass may spread over (the same answers).

    Returns:
      ``(filled, out)``, each ``(T, n)``: the filled motion (standing posture included with
      ``"first"``) and the playable one (filled when ``gains`` is ``None``).
    """
    q = robot.continuous(q, valid, d, bones, shards)
    q = fill_invalid(q, valid)
    if standing == "first":
        q = stand_if_lost(q, valid, robot)
    filled = q
    if gains is not None:
        q = smooth_any(q, valid, length, gains, smoother)
        q = robot.bound_steps(q, valid, d, bones)  # no overshoot past the continuity bound
    q = robot.playable_motion(q)  # clip_to_limits over the motion, in time order
    if standing == "last":
        q = stand_if_lost(q, valid, robot)
    return filled, q


@full_precision
def motion(
    p: AnyProjector | None,
    positions: jax.Array,
    valid: jax.Array,
    length: jax.Array,
    gains: jax.Array,
    *,
    method: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
    bones: str | tuple[str, ...],
    mirror: bool,
    smoother: str | None,
    robot: Robot,
    neck: NeckLevel = "off",
    neck_neutral: jax.typing.ArrayLike = NECK_TILT_REFERENCE,
    shards: int = 1,
    level_legs: bool = True,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The whole pipeline for one padded motion (``retarget``'s compiled call).

    Args:
      p: the projector (``None`` for ``method="ik"``).
      positions: ``(T, 20, 3)`` joint positions, padded to ``T`` frames.
      valid: ``(T,)`` bool from the reader (padding false).
      length: ``()`` int, the true length.
      gains: ``(3,)`` or ``(T, 3)`` smoother gains (unused without ``smoother``).
      method, n_l, n_m, full, bones: ``map_frames``.
      mirror: descriptor option.
      smoother: the smoother's ``kind`` (``"offline"`` or ``"paper"``; with the clip), or
        ``None``: neither.
      robot: the robot (its IK, limits, posture and joints).
      neck, neck_neutral: the neck's neutral tilt (``level``): ``"recording"``, the median of
        the motion's valid frames; ``"given"``, ``neck_neutral`` (rad); ``"off"``, none.
      shards: CPU devices the IK's frames are split over (``map_frames``; the same answers).
      level_legs: ``level``'s ``legs``.

    Returns:
      ``((T, n_joints) angles, (T,) valid, (T,) confidence)``: ``robot.joint_names`` order,
      the rest of the body at the standing posture; validity after the descriptor's own check;
      ``projection.confidence`` of each frame (0 where invalid, 1 for the IK).
    """
    d, ok = _before_mapping(positions, valid, bones, mirror, robot, neck, neck_neutral,
                            level_legs)  # fmt: skip
    q, conf = map_frames(p, d, method=method, n_l=n_l, n_m=n_m, full=full, bones=bones,
                         robot=robot, shards=shards)  # fmt: skip
    q = _after_mapping(q, ok, length, gains, d, bones, smoother, robot, shards)
    return q, ok, jnp.where(ok, conf, 0.0)


def _before_mapping(
    positions: jax.Array,
    valid: jax.Array,
    bones: str | tuple[str, ...],
    mirror: bool,
    robot: Robot,
    neck: NeckLevel,
    neck_neutral: jax.typing.ArrayLike,
    level_legs: bool,
) -> tuple[jax.Array, jax.Array]:
    """``motion``'s stages before the mapping: ``(T, m)`` levelled descriptors, ``(T,)`` valid."""
    d, ok = frame_descriptors(positions, valid, bones=bones, mirror=mirror)
    ok = ok & ~glitch_frames(d, ok, bones=bones, read=robot.ik_bones)
    ok = ok & ~lost_frames(positions, ok, read=robot.ik_bones, mirror=mirror)
    d = level(d, ok, neck, neck_neutral, bones=bones, up=world_up(positions), legs=level_legs)
    return d, ok


def _after_mapping(
    q: jax.Array,
    ok: jax.Array,
    length: jax.Array,
    gains: jax.Array,
    d: jax.Array,
    bones: str | tuple[str, ...],
    smoother: str | None,
    robot: Robot,
    shards: int,
) -> jax.Array:
    """``motion``'s stages after the mapping: ``(T, n_joints)`` playable angles."""
    _, q = finish(q, ok, length, gains if smoother else None, standing="last", robot=robot,
                  smoother=smoother or "paper", d=d, bones=bones, shards=shards)  # fmt: skip
    return robot.driven_to_full(q)


def motions(
    p: AnyProjector | None,
    positions: jax.Array,
    valid: jax.Array,
    length: jax.Array,
    gains: jax.Array,
    *,
    method: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
    bones: str | tuple[str, ...],
    mirror: bool,
    smoother: str | None,
    robot: Robot,
    neck: NeckLevel = "off",
    neck_neutral: jax.typing.ArrayLike = NECK_TILT_REFERENCE,
    shards: int = 1,
    level_legs: bool = True,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``motion`` for ``B`` motions padded to one length, in one program: the stages before
    and after the mapping per motion (``jax.vmap``), the per-frame mapping once over all ``B *
    T`` frames (the projection's kernels or the robot's IK see one batch, as for one long
    motion). Each motion's answer is the one ``motion`` gives it alone, up to the float
    rounding of a differently shaped batch (``retarget.retarget_many``).

    Args:
      positions: ``(B, T, 20, 3)``; valid: ``(B, T)``; length: ``(B,)`` int; gains: ``(B, 3)``
        or ``(B, T, 3)``; the rest as ``motion`` (one value for every motion). ``shards``
        splits the mapping's frames over CPU devices (``map_frames``); the per-motion stages
        run on one.

    Returns:
      ``((B, T, n_joints) angles, (B, T) valid, (B, T) confidence)``.
    """
    b, t = valid.shape
    d, ok = jax.vmap(
        lambda x, v: _before_mapping(x, v, bones, mirror, robot, neck, neck_neutral, level_legs)
    )(positions, valid)
    q, conf = map_frames(p, d.reshape(b * t, -1), method=method, n_l=n_l, n_m=n_m, full=full,
                         bones=bones, robot=robot, shards=shards)  # fmt: skip
    q = q.reshape(b, t, -1)
    angles = jax.vmap(
        lambda qi, oi, li, gi, di: _after_mapping(qi, oi, li, gi, di, bones, smoother, robot, 1)
    )(q, ok, length, gains, d)
    return angles, ok, jnp.where(ok, conf.reshape(b, t), 0.0)


Carried = tuple[jax.Array, jax.Array, jax.Array]
"""``(tracked, answer, descriptor)``: what the continuity pass carries between frames: the
last ``(n,)`` output of ``Robot.continuous_step``, the last valid ``(n,)`` projection and the
last valid ``(m,)`` descriptor (``streaming.StreamState``)."""


@full_precision
def frame(
    p: AnyProjector,
    level: jax.Array,
    trend: jax.Array,
    started: jax.Array,
    positions: jax.Array,
    gains: jax.Array,
    carried: Carried,
    *,
    n_l: int,
    n_m: int,
    bones: str | tuple[str, ...],
    mirror: bool,
    robot: Robot,
) -> tuple[jax.Array, jax.Array, tuple[jax.Array, jax.Array, jax.Array], Carried]:
    """One frame of the pipeline, causal (``streaming.update``'s compiled call).

    Descriptor -> relaxed projection (a batch of one) -> the robot's continuity pass, one frame
    (``Robot.continuous_step``, as ``Robot.continuous`` runs it over a motion in ``finish``;
    the projection as it is for a robot without one) -> one smoother ``step`` -> clip. The
    first valid frame starts the smoother (``s = y``, zero trend) as ``smooth_motion`` starts
    a motion; an invalid frame leaves the state as it was (see the module doc).

    Args:
      p: the projector.
      level, trend: ``(n,)`` the smoother's ``s`` (unclipped) and ``b``.
      started: ``()`` bool, whether a valid frame has been seen.
      positions: ``(20, 3)`` joint positions of this frame.
      gains: ``(3,)`` smoother gains.
      carried: the continuity pass's state (``Carried``).
      n_l, n_m: ``L`` and ``M`` of the relaxed projection.
      bones, mirror: descriptor options.
      robot: the robot (its joint limits, its continuity pass).

    Returns:
      ``(angles, confidence, (level, trend, started), carried)``: ``(n,)`` clipped driven
      angles, this frame's ``()`` confidence (0 if invalid) and the next state.
    """
    d, ok = frame_descriptors(positions, None, bones=bones, mirror=mirror)  # (m,), ()
    full = FullConfig()  # unused by the relaxed projection
    r, conf = map_frames(p, d[None], method="relaxed", n_l=n_l, n_m=n_m, full=full, bones=bones,
                         robot=robot)  # fmt: skip
    answer = r[0]
    tracked, last_answer, last_d = carried
    # as GenericIK.track: the first valid frame is a step from its own answer
    tracked = jnp.where(started, tracked, answer)
    last_answer = jnp.where(started, last_answer, answer)
    last_d = jnp.where(started, last_d, d)
    step = robot.continuous_step(tracked, last_answer, answer, last_d, d, bones)
    r = jnp.where(ok, step, answer)
    carried = (
        jnp.where(ok, r, tracked),
        jnp.where(ok, answer, last_answer),
        jnp.where(ok, d, last_d),
    )
    s_t, b_t = smoothing_step(level, trend, r, gains)
    # the first valid frame starts the smoother, as smooth_motion starts a motion
    s_t = jnp.where(started, s_t, r)
    b_t = jnp.where(started, b_t, jnp.zeros_like(b_t))
    # an invalid frame leaves the state (and so the output) as it was
    new_level = jnp.where(ok, s_t, level)
    new_trend = jnp.where(ok, b_t, trend)
    new_started = started | ok
    out = clip_to_limits(new_level, robot)
    return out, jnp.where(ok, conf[0], 0.0), (new_level, new_trend, new_started), carried


def playable_full(angles: jax.Array, robot: Robot) -> jax.Array:
    """One motion's ``(T, n_joints)`` configurations -> the same with the driven joints made
    playable (``Robot.playable_motion``: clipped, and out of self-collision where the robot has
    ``separate``, frame by frame in time order), the others as given: the last stage of
    ``retarget`` after the feasibility filter, which moves joints and so could bring a contact
    back."""
    q = jnp.asarray(angles, jnp.float32)
    idx = robot.driven_index
    return q.at[:, idx].set(robot.playable_motion(q[:, idx]))


def playable_many(angles: jax.Array, robot: Robot) -> jax.Array:
    """``playable_full`` of each of ``(B, T, n_joints)`` motions (each in its own time order), in
    one program: ``retarget_many``'s last stage for a packed call's motions at once."""
    return jax.vmap(lambda q: playable_full(q, robot))(angles)


def standing_driven(robot: Robot) -> np.ndarray:
    """``(n_driven,)`` float32: the standing posture's driven joints (the output before any
    valid frame, and of a motion without one)."""
    return robot.standing_driven.astype(np.float32)
