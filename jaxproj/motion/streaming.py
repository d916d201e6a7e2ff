"""Streaming: one pose at a time, live from a sensor, with an optax-style ``init`` / ``update``.

Each frame runs one frame of the motion pipeline (``jaxproj.motion.pipeline.frame``, the same
stages as ``retarget``) in one jitted call::

    (20, 3) joint positions -> descriptor (pipeline.frame_descriptors)
      -> relaxed projection (pipeline.map_frames: projection.api.project_batch on a batch of
         one; L and M nearest landmarks)
      -> the robot's continuity pass, one frame (Robot.continuous_step: a robot's track_step,
         where it has one, re-chooses the pose near the last output, as retarget's
         GenericIK.track; none for the default robot)
      -> one step of the double exponential smoother (smoothing.step, the same function the
         whole-motion smoother scans) -> clipped to the joint limits -> (n,) driven angles

Usage::

    state = streaming.init(model)
    for positions in sensor:                      # (20, 3) metres, Kinect SDK joint order
        angles, state = streaming.update(model, state, positions)   # (n_driven,) rad

``update`` is pure: the state (``StreamState``) holds everything carried between frames. A frame
whose descriptor is invalid (lost tracking, a degenerate bone or body frame, non-finite values)
leaves the state untouched and repeats the previous output. The first valid frame starts the
smoother (``s = y``, zero trend), exactly as ``smoothing.smooth`` starts a motion; before it the
output is the standing posture's driven joints (``Robot.standing_driven`` of the model's robot,
``Model.robot``; a bare projector streams for ``robot=``, default the default robot).
The output is never NaN. On a recording whose frames are all valid, streaming it frame by frame
gives ``clip(smooth(project(descriptors)))`` of the whole recording
(``tests/motion/test_streaming.py`` states the tolerance).

The jitted function compiles once per (model shapes, ``L``, ``M``, descriptor options); new
smoothing gains or new frames do not recompile (the gains are traced).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import N_JOINTS, resolve_bones
from jaxproj.motion import pipeline
from jaxproj.motion.pipeline import AnyProjector
from jaxproj.motion.smoothing import PAPER_SMOOTHING, SmoothingParams
from jaxproj.projection.api import Model, check_neighbours
from jaxproj.projection.confidence import DEVIATION_SCALE, rescale
from jaxproj.projection.projector import Projector, StackedProjector
from jaxproj.robots import Robot, get


class StreamState(NamedTuple):
    """What ``update`` carries from one frame to the next (a pytree of device arrays).

    Attributes:
      level: ``(n,)`` float32, the smoother's value ``s`` (unclipped; the output is its clip).
        The standing posture's driven joints until the first valid frame.
      trend: ``(n,)`` float32, the smoother's trend ``b``.
      started: ``()`` bool, whether a valid frame has been seen.
      confidence: ``()`` float32, the last frame's confidence (``projection.confidence``; 0 for
        an invalid frame and before any frame); the only field an invalid frame changes.
      tracked: ``(n,)`` float32, the continuity pass's last output (``Robot.continuous_step``;
        for a robot without one, the last valid projection).
      answer: ``(n,)`` float32, the last valid frame's projection.
      descriptor: ``(m,)`` float32, the last valid frame's descriptor (how far the person's
        limbs turned since: the pass's bound).
    """

    level: jax.Array
    trend: jax.Array
    started: jax.Array
    confidence: jax.Array
    tracked: jax.Array
    answer: jax.Array
    descriptor: jax.Array


def _widths(p: AnyProjector) -> tuple[int, int]:
    """``(m, n)``: descriptor width and driven joints of a projector."""
    if isinstance(p, StackedProjector):
        return p.layout.m, p.layout.n
    return p.human.shape[1], p.robot.shape[1]


def _robot(model: Model | AnyProjector, robot: Robot | str | None) -> Robot:
    """The robot streamed for: a model's own (``robot`` must agree), else ``robot`` (default)."""
    spec = get(robot)
    if isinstance(model, Model):
        if robot is not None and spec is not model.robot:
            raise ConfigError(f"robot {spec.name!r} differs from the model's robot "
                              f"{model.robot.name!r}: leave robot=None with a model")  # fmt: skip
        return model.robot
    return spec


def _projector(model: Model | AnyProjector) -> tuple[AnyProjector, str | tuple[str, ...], bool]:
    """The projector and the descriptor options it was built for (a bare ``Projector``: the
    default upper-body bones, direct imitation)."""
    if isinstance(model, Model):
        bones = model.config.bones
        return (
            model.projector,
            bones if isinstance(bones, str) else tuple(bones),
            model.config.mirror,
        )
    if isinstance(model, Projector | StackedProjector):
        return model, "upper", False
    raise ConfigError(f"model must be an engine.Model or a projection.Projector, got {type(model)}")


def init(model: Model | AnyProjector, *, robot: Robot | str | None = None) -> StreamState:
    """The state before any frame: nothing seen, output at the standing posture.

    Args:
      model: an ``engine.Model`` or a bare ``projection.Projector``.
      robot: for a bare projector, its robot (``None``: the default robot); a model streams
        for its own robot (``Model.robot``).

    Returns:
      ``StreamState`` with ``(n,)`` level (the standing posture's driven joints), ``(n,)``
      zero trend, ``started = False`` and confidence 0.
    """
    p, _, _ = _projector(model)
    spec = _robot(model, robot)
    m, n = _widths(p)
    if n != spec.n_driven:
        raise ConfigError(f"model drives {n} joints, {spec.name} has {spec.n_driven} driven joints")
    standing = jnp.asarray(pipeline.standing_driven(spec))
    return StreamState(
        level=standing,
        trend=jnp.zeros((n,), jnp.float32),
        started=jnp.zeros((), jnp.bool_),
        confidence=jnp.zeros((), jnp.float32),
        tracked=standing,
        answer=standing,
        descriptor=jnp.zeros((m,), jnp.float32),
    )


def _update(
    p: AnyProjector,
    state: StreamState,
    positions: jax.Array,
    gains: jax.Array,
    *,
    n_l: int,
    n_m: int,
    bones: str | tuple[str, ...],
    mirror: bool,
    robot: Robot,
) -> tuple[jax.Array, StreamState]:
    carried = (state.tracked, state.answer, state.descriptor)
    angles, conf, (level, trend, started), carried = pipeline.frame(
        p, state.level, state.trend, state.started, positions, gains, carried,
        n_l=n_l, n_m=n_m, bones=bones, mirror=mirror, robot=robot,
    )  # fmt: skip
    return angles, StreamState(level, trend, started, conf, *carried)


_update_jit = jit(_update, static_argnames=("n_l", "n_m", "bones", "mirror", "robot"))


def update(
    model: Model | AnyProjector,
    state: StreamState,
    positions: np.ndarray | jax.Array,
    *,
    n_l: int = 10,
    n_m: int = 10,
    smoothing: SmoothingParams = PAPER_SMOOTHING,
    robot: Robot | str | None = None,
) -> tuple[jax.Array, StreamState]:
    """One frame: joint positions -> smoothed driven-joint angles, and the next state.

    Options are checked here, in Python, before the jitted step runs (``ConfigError``).

    Args:
      model: an ``engine.Model`` (its ``config.bones`` / ``config.mirror`` set the descriptor)
        or a bare ``projection.Projector`` (upper-body bones, direct imitation).
      state: from ``init`` or the previous ``update``.
      positions: ``(20, 3)`` joint positions of one frame, Kinect SDK order (any finite
        values; NaN / lost joints make the frame invalid).
      n_l, n_m: ``L`` human and ``M`` robot neighbours of the relaxed projection (static:
        each new pair compiles once).
      smoothing: smoother gains (traced: new gains do not recompile).
      robot: as in ``init``.

    Returns:
      ``(angles, state)``: ``(n,)`` float32 driven-joint angles (rad, the robot's
      ``driven_joints`` order, within its joint limits, never NaN) and the next ``StreamState``
      (its ``confidence``: this frame's).
    """
    p, bones, mirror = _projector(model)
    spec = _robot(model, robot)
    if isinstance(n_l, bool) or isinstance(n_m, bool):
        raise ConfigError("n_l and n_m must be integers")
    if not isinstance(n_l, int | np.integer) or not isinstance(n_m, int | np.integer):
        raise ConfigError(f"n_l and n_m must be integers, got {n_l!r}, {n_m!r}")
    check_neighbours(p, int(n_l), int(n_m))
    if not isinstance(smoothing, SmoothingParams):
        raise ConfigError(f"smoothing must be a SmoothingParams, got {type(smoothing).__name__}")
    if not isinstance(state, StreamState):
        raise ConfigError(f"state must be a StreamState from streaming.init, got {type(state)}")
    m, n = _widths(p)
    if (
        state.level.shape != (n,)
        or state.trend.shape != (n,)
        or state.started.shape != ()
        or state.confidence.shape != ()
        or state.tracked.shape != (n,)
        or state.answer.shape != (n,)
        or state.descriptor.shape != (m,)
    ):
        raise ConfigError(
            f"state does not fit this model: level {state.level.shape}, trend "
            f"{state.trend.shape}, started {state.started.shape}, tracked "
            f"{state.tracked.shape}, answer {state.answer.shape}, descriptor "
            f"{state.descriptor.shape} (expected ({n},), ({n},), (), ({n},), ({n},), ({m},))"
        )
    if len(resolve_bones(bones)) * 3 != m:
        raise ConfigError(
            f"descriptor bones {bones!r} do not match the model's {m}-wide "
            "landmarks; pass the engine.Model it was built with"
        )
    if not isinstance(positions, jax.Array):
        positions = np.asarray(positions, np.float32)  # host array: the jitted call copies it
    elif positions.dtype != jnp.float32:
        positions = positions.astype(jnp.float32)
    if positions.shape != (N_JOINTS, 3):
        raise ConfigError(f"positions must be one frame ({N_JOINTS}, 3), got {positions.shape}")
    gains = np.asarray((smoothing.alpha, smoothing.gamma, smoothing.eta), np.float32)
    angles, new = _update_jit(
        p, state, positions, gains, n_l=int(n_l), n_m=int(n_m), bones=bones, mirror=mirror,
        robot=spec,
    )  # fmt: skip
    if isinstance(model, Model) and model.deviation_scale is not None:  # the model's own scale
        conf = rescale(new.confidence, spec.deviation_scale or DEVIATION_SCALE,
                       model.deviation_scale)  # fmt: skip
        new = new._replace(confidence=conf)
    return angles, new
