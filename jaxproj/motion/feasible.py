"""Robot-feasible trajectories: joint position limits, speed limits and an acceleration bound.

A projected (or IK) motion follows the person frame by frame, and a Kinect skeleton can move a
joint target by a large angle in one frame (tracking noise, an ill-defined elbow yaw, a lost
frame filled by holding the last pose). A robot cannot follow: its joints have speed limits
(``Robot.speed_limits``, rad/s; every function here takes ``robot=``, no default).
``make_feasible`` turns a motion into one the robot can play
while staying as close as it can to it:

* positions within ``[robot.lower, robot.upper]`` and the coupled ranges
  (``Robot.coupled_limits``: the default robot's HeadPitch within the head anti-collision envelope
  at its HeadYaw) on every frame (hard);
* speed ``|q_t - q_{t-1}| / dt_t <= speed_fraction * robot.speed_limits(speeds)`` per joint
  (hard). By default (``speeds="rated"``) the cap is the rated speed, the speed a joint keeps at
  its motor's nominal torque (``Robot.rated_speeds``; the default robot's: its maker's nominal
  speeds, 74-79 % of no-load, else 0.75 x no-load), times ``SPEED_FRACTIONS["rated"]`` (99 %:
  headroom for float32 round-off, so that no exported step exceeds the rated speed);
  ``speeds="no-load"`` caps at ``SPEED_FRACTIONS["no-load"]`` (90 %) of the no-load maxima
  (``Robot.velocity_limits``), the default before rated speeds (``jaxproj retarget --speeds
  no-load``);
* acceleration ``|v_t - v_{t-1}| / ((dt_t + dt_{t-1}) / 2) <= accel`` (``v_t`` the speed of
  step ``t``) per joint: the robot's own ``Robot.acceleration_limits`` where it gives them (e.g.
  each joint's peak torque over the inertia it moves, ``robots.mjcf.torque_accelerations``),
  else a rule of ours: the no-load speed reached from rest in ``ACCEL_TIME`` (0.1 s), per joint
  (``FeasibleConfig.accel`` sets one bound for every joint of any robot).
  The default robot's documentation gives no acceleration limit; its bound is ours (its
  ``acceleration_limits``: 80 rad/s^2 on every joint, full speed in ~0.1 s), so the speed limit
  is never reached by a jump. Chosen on the training subjects (MSR Action3D
  1,3,5,7,9, arm actions, relaxed projection, smoothed): median M_avg against the IK 3.42 deg at
  40 rad/s^2, 2.67 at 80, 2.51 at 150 and 2.49 with no bound (speed limits alone); 1.76 before
  the filter. Most of the cost is the speed limit itself: the default robot's arms are slower than a
  person's punch or wave. It holds on every step except one where a position limit stops a joint
  (the only place the filter must choose between the two; ``feasibility_report`` counts it).

The filter, per joint, is a forward ``lax.scan`` that starts at rest on the first frame and, each
frame, moves towards the target with the speed that still lets it stop at the target (and at the
joint limits) under the acceleration bound, clipped to the acceleration window and the speed
limit. Alone it lags a moving target; ``zero_phase`` (default) also runs it backwards in time
and averages the two: every constraint above but the coupled ranges is convex in the trajectory
(bounds on linear maps of ``q``), so the average of two feasible trajectories is feasible, and
the lag of one pass cancels the lead of the other. A coupled range is a bound that moves with
its leader: each pass moves the follower no faster towards a bound than lets it stop before the
tightest value that bound takes over the angles the leader can reach meanwhile (this step plus
a full braking time, at the leader's speed limit), and holds it inside the range at the
leader's angle of each step (the position limit wins over the speed and acceleration bounds,
as at a fixed limit). Since the default robot's head envelope is not convex, the average (and the
read-back below) is clipped to it once more (``base.clip_coupled``).

The elbow yaw, handled explicitly on the target before the scan step, for each ``(yaw, roll)`` pair
of ``Robot.elbow_pairs`` (the default robot's two elbows; a robot without pairs gets no such rule):

* nearly straight elbow (``|elbow roll| < straight_elbow[1]``): the yaw only turns the forearm
  about its own axis, so it is ill-defined; the target yaw is blended towards the yaw the filter
  already holds (weight ``smoothstep(|elbow roll|, *straight_elbow)``): the continuous branch.
* wrap-around: where the person's forearm yaw is near +-180 deg, in the gap of elbow yaw's range
  (+-119.5 deg), the IK clips to one end or the other and noise flips between them (a 239 deg
  jump for no gain: both ends are about equally far from the true yaw). A target at one end
  (within ``wrap_band`` of the limit) while the filter holds the other end keeps the held end
  until the target has stayed there ``wrap_patience`` seconds: flicker is ignored, a real move
  to the other end is followed (late by the patience, at the speed limit).

Irregular time steps (frames the tracker dropped: UTKinect's frame numbers jump): the filter runs
on a uniform grid (step: the motion's shortest step; at most ``4 T`` grid points), onto which
the targets are interpolated linearly, and its result is read back at the motion's own times
by linear interpolation. Times on the grid (UTKinect: frame numbers) read back exact grid
values; between two read-back frames the speed is an average of the grid's speeds and the
change of speed an average of its accelerations, so the limits hold at any timing.

The filter works on the full configuration (``robot.joint_names``); joints that do not move
are left exactly as they are. ``feasibility_report`` measures a motion against the limits
(before and after, in ``jaxproj.eval.evaluate``, the demo and ``jaxproj retarget``).

Size: over 500 lines: one filter (its config, the forward pass, the zero-phase pass, the coupled
ranges, the host wrapper and its report), whose parts share the time grid and the limits.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import cast

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import full_precision, jit
from jaxproj.errors import ConfigError
from jaxproj.io.motion_files import EXPORT_MARGIN
from jaxproj.robots import Robot, clip_coupled

ACCEL_TIME = 0.1
"""s: a robot without ``acceleration_limits`` gets ``velocity_limits / ACCEL_TIME`` per joint
(its no-load speed from rest in 0.1 s; the rule behind the default robot's bound, module doc)."""

SPEED_FRACTIONS: dict[str, float] = {"rated": 0.99, "no-load": 0.9}
"""``FeasibleConfig.speed_fraction`` when left out, per ``speeds``: 99 % of the rated speeds, 90 %
of the no-load ones (the cap before rated speeds). The 1 % below the rated speed is headroom for
float32 round-off: at 100 % the filter's steps reach 1.0000003 x rated on the bundled UTKinect
recordings (relative round-off ~1e-6 at 30 fps, ~1e-4 at 1 kHz), at 99 % none exceeds it."""

Arms = tuple[tuple[int, int], ...]
"""Per elbow, ``(yaw, roll)`` joint positions in the configuration (``_arms``; static)."""


def _arms(robot: Robot) -> Arms:
    """The configuration positions of ``robot.elbow_pairs``."""
    return tuple((robot.index(yaw), robot.index(roll)) for yaw, roll in robot.elbow_pairs)


@dataclass(frozen=True)
class FeasibleConfig:
    """Settings of ``make_feasible`` (validated when constructed; ``ConfigError`` otherwise).

    Attributes:
      speeds: the speed limits capped (``Robot.speed_limits``): ``"rated"`` (default, the
        speeds at the motors' nominal torque) or ``"no-load"`` (the theoretical maxima).
      speed_fraction: fraction of those speeds allowed, in (0, 1]; ``None``:
        ``SPEED_FRACTIONS[speeds]`` (the constructed config holds the number).
      accel: acceleration bound, rad/s^2, every joint; ``None`` (default): the robot's
        ``acceleration_limits``, or ``velocity_limits / ACCEL_TIME`` for a robot without them
        (``accel_limits``).
      straight_elbow: ``(lo, hi)`` rad of ``|elbow roll|``: below ``lo`` the elbow yaw target is
        the held yaw, above ``hi`` it is the input's, smoothstep in between.
      wrap_band: rad from an elbow yaw limit within which a target counts as "at that end".
      wrap_patience: seconds a target must stay at the opposite end before the filter follows
        it there (shorter visits keep the held end).
      zero_phase: average the forward pass with a backward (time-reversed) pass.
      limit_margin: rad inside each joint's ``[lower, upper]`` the filter keeps the motion
        (default ``motion_files.EXPORT_MARGIN``, 2e-4: the margin the robot files hold, so that
        writing them clips nothing and the filter's braking to a limit stays within ``accel``).
    """

    speeds: str = "rated"
    speed_fraction: float | None = None
    accel: float | None = None
    straight_elbow: tuple[float, float] = (math.radians(5.0), math.radians(20.0))
    wrap_band: float = math.radians(5.0)
    wrap_patience: float = 0.3
    zero_phase: bool = True
    limit_margin: float = EXPORT_MARGIN

    def __post_init__(self) -> None:
        if self.speeds not in SPEED_FRACTIONS:
            raise ConfigError(f"speeds={self.speeds!r} must be one of {tuple(SPEED_FRACTIONS)}")
        if self.speed_fraction is None:
            object.__setattr__(self, "speed_fraction", SPEED_FRACTIONS[self.speeds])
        if not 0.0 < float(cast(float, self.speed_fraction)) <= 1.0:
            raise ConfigError(f"speed_fraction={self.speed_fraction} must lie in (0, 1]")
        if self.accel is not None and not (np.isfinite(self.accel) and float(self.accel) > 0.0):
            raise ConfigError(f"accel={self.accel} must be a positive number of rad/s^2")
        lo, hi = (float(x) for x in self.straight_elbow)
        if not 0.0 <= lo < hi:
            raise ConfigError(f"straight_elbow={self.straight_elbow} must be 0 <= lo < hi (rad)")
        if not 0.0 <= float(self.wrap_band) < math.pi:
            raise ConfigError(f"wrap_band={self.wrap_band} must lie in [0, pi) rad")
        if not 0.0 <= float(self.limit_margin) < 0.1:
            raise ConfigError(f"limit_margin={self.limit_margin} must lie in [0, 0.1) rad")
        if not float(self.wrap_patience) >= 0.0:
            raise ConfigError(f"wrap_patience={self.wrap_patience} must be >= 0 s")

    def accel_limits(self, robot: Robot) -> np.ndarray:
        """``(n_joints,)`` float32 rad/s^2: the acceleration bound per joint of ``robot``
        (``accel`` on every joint, else ``robot.acceleration_limits``, else
        ``robot.velocity_limits / ACCEL_TIME``)."""
        if self.accel is not None:
            return np.full(robot.n_joints, self.accel, np.float32)
        if robot.acceleration_limits is not None:
            return np.asarray(robot.acceleration_limits, np.float32)
        return (robot.require_velocity_limits() / np.float32(ACCEL_TIME)).astype(np.float32)

    def params(self, robot: Robot) -> jax.Array:
        """``(5, n_joints)`` float32 rows of ``robot``: lower and upper (``limit_margin``
        inside), speed limit
        (``speed_fraction * robot.speed_limits(speeds)``), accel (``accel_limits``), and
        (first 4 columns) ``straight_elbow`` lo / hi, ``wrap_band``, ``wrap_patience``: the
        traced argument of the filter.

        Raises:
          ConfigError: the robot has no velocity limits, or fewer than 4 joints.
        """
        vmax = cast(float, self.speed_fraction) * robot.speed_limits(self.speeds)
        if robot.n_joints < 4:
            raise ConfigError(f"the feasibility filter needs >= 4 joints, {robot.name} has "
                              f"{robot.n_joints}")  # fmt: skip
        extra = np.zeros(robot.n_joints, np.float32)
        extra[:4] = (*self.straight_elbow, self.wrap_band, self.wrap_patience)
        return jnp.asarray(
            np.stack(
                [
                    robot.lower + np.float32(self.limit_margin),
                    robot.upper - np.float32(self.limit_margin),
                    vmax,
                    self.accel_limits(robot),
                    extra,
                ]
            ),
            jnp.float32,
        )


DEFAULT_FEASIBLE = FeasibleConfig()
"""The defaults: 99 % of the rated speeds, the robot's acceleration limits (80 rad/s^2 where it
has none), zero-phase."""


def _smoothstep(x: jax.Array, lo: jax.Array, hi: jax.Array) -> jax.Array:
    t = jnp.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _stop_speed(dist: jax.Array, accel: jax.Array, dt: jax.Array) -> jax.Array:
    """Largest speed ``v`` from which braking by ``u = accel * dt`` per step, in steps of ``dt``,
    covers at most ``dist`` (this step's move included): the moves are ``v, v - u, ..., v - n u``
    with ``n = floor(v / u)``, i.e. ``D(v) = dt ((n + 1) v - u n (n + 1) / 2)``, inverted exactly
    (``D`` is increasing and linear between multiples of ``u``)."""
    d = jnp.maximum(dist, 0.0)
    u = accel * dt
    n = jnp.floor(0.5 * (jnp.sqrt(1.0 + 8.0 * d / (dt * u)) - 1.0))
    return (d / dt + 0.5 * u * n * (n + 1.0)) / (n + 1.0)


def _elbow_targets(
    y: jax.Array, q: jax.Array, away: jax.Array, step: jax.Array, params: jax.Array, arms: Arms
) -> tuple[jax.Array, jax.Array]:
    """The elbow yaw rules of the module doc for the target ``y`` (n_joints,) given the held
    ``q`` (n_joints,) and ``away`` (len(arms),): seconds each arm's target has spent at the far
    end of the yaw range."""
    if not arms:
        return y, away
    lo_s, hi_s, band, patience = params[4, 0], params[4, 1], params[4, 2], params[4, 3]
    new_away = []
    for arm, (yaw_i, roll_i) in enumerate(arms):
        lim_lo, lim_hi = params[0, yaw_i], params[1, yaw_i]
        target, held = y[yaw_i], q[yaw_i]
        hi_t, lo_t = target > lim_hi - band, target < lim_lo + band
        hi_h, lo_h = held > lim_hi - band, held < lim_lo + band
        far = (hi_t & lo_h) | (lo_t & hi_h)
        t_far = jnp.where(far, away[arm] + step, 0.0)
        target = jnp.where(far & (t_far < patience), held, target)
        w = _smoothstep(jnp.abs(y[roll_i]), lo_s, hi_s)
        y = y.at[yaw_i].set(held + w * (target - held))
        new_away.append(t_far)
    return y, jnp.stack(new_away)


def _coupled_bounds(
    q: jax.Array, vmax: jax.Array, horizon: jax.Array, lo: jax.Array, hi: jax.Array, robot: Robot
) -> tuple[jax.Array, jax.Array]:
    """``(lo, hi)`` ``(n_joints,)`` with each follower of ``robot.coupled_limits`` narrowed to
    the tightest of its ranges over the angles its leader can reach from ``q`` ``(n_joints,)``
    at speeds up to ``vmax`` within the follower's ``horizon`` (s; both ``(n_joints,)``): a
    piecewise-linear bound is extreme at an end of that window or at a knot inside it."""
    for limit in robot.coupled_limits:
        j, k = robot.index(limit.joint), robot.index(limit.by)
        a, b = q[k] - vmax[k] * horizon[j], q[k] + vmax[k] * horizon[j]
        lo_a, hi_a = limit.bounds(a)
        lo_b, hi_b = limit.bounds(b)
        knots = jnp.asarray(limit.knots)
        inside = (knots >= a) & (knots <= b)
        env_lo = jnp.maximum(
            jnp.maximum(lo_a, lo_b), jnp.max(jnp.where(inside, limit.lower, -jnp.inf))
        )
        env_hi = jnp.minimum(
            jnp.minimum(hi_a, hi_b), jnp.min(jnp.where(inside, limit.upper, jnp.inf))
        )
        lo = lo.at[j].set(jnp.minimum(jnp.maximum(lo[j], env_lo), hi[j]))
        hi = hi.at[j].set(jnp.maximum(jnp.minimum(hi[j], env_hi), lo[j]))
    return lo, hi


def _forward(y: jax.Array, dt: jax.Array, params: jax.Array, arms: Arms, robot: Robot) -> jax.Array:
    """One forward pass of the filter over a ``(T, n_joints)`` motion with steps ``dt`` ``(T,)``,
    the elbow pairs ``arms`` and ``robot``'s coupled ranges."""
    lo, hi, vmax, amax = params[0], params[1], params[2], params[3]
    q0 = clip_coupled(robot, jnp.clip(y[0], lo, hi))

    def body(carry, inp):
        q, v, dt_prev, away = carry
        target, step = inp
        target, away = _elbow_targets(target, q, away, step, params, arms)
        target = clip_coupled(robot, jnp.clip(target, lo, hi))
        err = target - q
        # the speed that reaches the target this step, capped so that the joint can still stop
        # at the target and inside its limits under the acceleration bound
        cap = _stop_speed(jnp.abs(err), amax, step)
        want = jnp.sign(err) * jnp.minimum(jnp.abs(err) / step, cap)
        window = amax * 0.5 * (step + dt_prev)

        def move(lo_b: jax.Array, hi_b: jax.Array) -> jax.Array:
            w = jnp.clip(
                want, -_stop_speed(q - lo_b, amax, step), _stop_speed(hi_b - q, amax, step)
            )
            return jnp.clip(jnp.clip(w, v - window, v + window), -vmax, vmax)

        v_new = move(lo, hi)
        if robot.coupled_limits:
            # a follower brakes for the tightest of its ranges wherever its leader can go while
            # it brakes (leaders are never followers: their v_new is final)
            horizon = step + vmax / amax  # this step, then braking from full speed
            v_new = move(*_coupled_bounds(q + v_new * step, vmax, horizon, lo, hi, robot))
        # position limits are hard: a follower stays inside its range at its leader's new angle
        q_new = clip_coupled(robot, jnp.clip(q + v_new * step, lo, hi))
        v_new = (q_new - q) / step
        return (q_new, v_new, step, away), q_new

    init = (q0, jnp.zeros_like(q0), dt[1], jnp.zeros(len(arms), q0.dtype))
    _, rest = jax.lax.scan(body, init, (y[1:], dt[1:]))
    return jnp.concatenate([q0[None], rest], axis=0)


@full_precision
def feasible_motion(
    y: jax.Array,
    dt: jax.Array,
    length: jax.Array,
    params: jax.Array,
    *,
    zero_phase: bool,
    robot: Robot,
) -> jax.Array:
    """The traceable core of ``make_feasible`` for one padded motion (call it inside a jit).

    Args:
      y: ``(T, n_joints)`` target motion, padded to ``T`` frames.
      dt: ``(T,)`` seconds from the previous frame (entry 0 unused); padding entries any
        positive value.
      length: ``()`` int, the true length (>= 1); frames past it are returned as the input.
      params: ``FeasibleConfig.params(robot)``.
      zero_phase: run the backward pass too and average.
      robot: the robot (its elbow pairs; static).

    Returns:
      ``(T, n_joints)`` the feasible motion (frames past ``length``: the input).
    """
    arms = _arms(robot)
    t = jnp.arange(y.shape[0])
    live = t < length
    last = jnp.maximum(length - 1, 0)
    hold = jnp.minimum(t, last)
    dt = jnp.where(live & (t > 0), dt, dt[jnp.minimum(1, last)])
    dt = jnp.where(dt > 0, dt, 1.0)
    out = _forward(y[hold], dt, params, arms, robot)
    if zero_phase:
        rev = jnp.where(live, last - t, 0)  # frame s of the reversed motion is frame last - s
        dt_rev = jnp.where(live & (t > 0), dt[jnp.minimum(last - t + 1, last)], dt[1])
        back = _forward(y[rev], dt_rev, params, arms, robot)[rev]
        out = clip_coupled(robot, 0.5 * (out + back))  # a coupled range need not be convex
    return jnp.where(live[:, None], out, y)


def _feasible_batch(y, dt, lengths, params, *, zero_phase, robot):
    one = functools.partial(feasible_motion, zero_phase=zero_phase, robot=robot)
    return jax.vmap(one, in_axes=(0, 0, 0, None))(y, dt, lengths, params)


_feasible_batch = jit(_feasible_batch, static_argnames=("zero_phase", "robot"))


def _steps(times: np.ndarray) -> np.ndarray:
    """``(..., T)`` times -> ``(..., T)`` steps (entry 0: the first step, or 1 s for T = 1)."""
    dt = np.diff(times, axis=-1)
    first = dt[..., :1] if dt.shape[-1] else np.ones(times.shape[:-1] + (1,))
    return np.concatenate([first, dt], axis=-1)


def _grid(t: np.ndarray) -> tuple[float, int]:
    """Uniform grid of one motion's times ``t`` ``(n,)``: (step, number of points)."""
    if len(t) < 2:
        return 1.0, 1
    span = t[-1] - t[0]
    step = max(float(np.diff(t).min()), span / (4 * (len(t) - 1)))
    return step, int(np.ceil(span / step - 1e-9)) + 1


def _bucket(n: int) -> int:
    return max(16, 1 << (int(n) - 1).bit_length())


def make_feasible(
    angles: np.ndarray,
    times: np.ndarray,
    lengths: np.ndarray | None = None,
    config: FeasibleConfig = DEFAULT_FEASIBLE,
    *,
    robot: Robot,
) -> np.ndarray:
    """Make motions robot-feasible (see the module doc); one compiled call for a batch.

    Args:
      angles: ``(T, n_joints)`` or ``(B, T, n_joints)`` float radians, ``robot.joint_names``
        order, finite.
      times: ``(T,)`` or ``(B, T)`` seconds, strictly increasing over each motion's length.
      lengths: ``(B,)`` true lengths of a padded batch (``None``: all ``T``).
      config: the limits and options.
      robot: the robot (limits, speed limits, elbow pairs).

    Returns:
      float32 array of ``angles``' shape (entries past a motion's length: the input).

    Raises:
      ConfigError: shapes that do not match, non-finite values, times not increasing, a robot
        without velocity limits.
    """
    q = np.asarray(angles, np.float32)
    one = q.ndim == 2
    if one:
        q = q[None]
    t = np.asarray(times, np.float64)
    t = t[None] if t.ndim == 1 else t
    nj = robot.n_joints
    if q.ndim != 3 or q.shape[-1] != nj or q.shape[1] < 1:
        raise ConfigError(f"angles must be (T, {nj}) or (B, T, {nj}), got {np.shape(angles)}")
    if t.shape != q.shape[:2]:
        raise ConfigError(f"times {np.shape(times)} do not match angles {np.shape(angles)}")
    n = np.full(q.shape[0], q.shape[1]) if lengths is None else np.asarray(lengths, np.int64)
    if n.shape != (q.shape[0],) or (n < 1).any() or (n > q.shape[1]).any():
        raise ConfigError(f"lengths must be ({q.shape[0]},) in 1..{q.shape[1]}, got {n}")
    live = np.arange(q.shape[1])[None] < n[:, None]
    if not np.isfinite(q[live]).all() or not np.isfinite(t[live]).all():
        raise ConfigError("angles and times must be finite over each motion's length")
    dt = _steps(t)
    if (dt[:, 1:][live[:, 1:]] <= 0).any():
        raise ConfigError("times must increase strictly over each motion's length")
    grids = [_grid(t[b, : n[b]]) for b in range(len(n))]
    size = _bucket(max(g for _, g in grids))
    targets = np.zeros((len(n), size, q.shape[-1]), np.float32)
    steps = np.ones((len(n), size), np.float32)
    for b, (step, g) in enumerate(grids):
        tb, qb = t[b, : n[b]], q[b, : n[b]]
        tg = np.minimum(tb[0] + step * np.arange(g), tb[-1])
        for j in range(q.shape[-1]):
            targets[b, :g, j] = np.interp(tg, tb, qb[:, j])
        targets[b, g:] = targets[b, g - 1]
        steps[b] = step
    grid_out = np.asarray(
        _feasible_batch(
            targets,
            steps,
            np.array([g for _, g in grids], np.int32),
            config.params(robot),
            zero_phase=config.zero_phase,
            robot=robot,
        )  # fmt: skip
    )
    out = q.copy()
    for b, (step, g) in enumerate(grids):
        tb = t[b, : n[b]]
        x = np.clip((tb - tb[0]) / step, 0.0, g - 1)
        i0 = np.minimum(np.floor(x + 1e-9).astype(np.int64), g - 1)
        i1 = np.minimum(i0 + 1, g - 1)
        w = np.clip(x - i0, 0.0, 1.0)[:, None]
        on_grid = (w < 1e-6)[:, 0]
        mixed = (1.0 - w) * grid_out[b, i0] + w * grid_out[b, i1]
        read = np.where(on_grid[:, None], grid_out[b, i0], mixed)
        if robot.coupled_limits and not on_grid.all():  # between grid points: back in range
            read = np.asarray(clip_coupled(robot, read))
        out[b, : n[b]] = read
    return out[0] if one else out


def feasibility_report(
    angles: np.ndarray,
    times: np.ndarray,
    config: FeasibleConfig = DEFAULT_FEASIBLE,
    *,
    robot: Robot,
) -> dict:
    """How one motion stands against a robot's limits (JSON-ready numbers).

    Args:
      angles: ``(T, n_joints)`` radians; times: ``(T,)`` seconds.
      config: the acceleration bound and speed fraction the motion is judged against (the speed
        figures use the full no-load ``robot.velocity_limits``).
      robot: the robot.

    Returns:
      dict: ``frames``; ``speed_violation_frames`` (frames whose step from the previous frame
      exceeds ``velocity_limits`` on some joint); ``max_speed_ratio`` and ``worst_joint``
      (largest speed / limit); ``rated_speed_ratio`` and ``rated_worst_joint`` (the same
      against the rated speeds, ``robot.speed_limits("rated")``); ``max_step_deg`` and
      ``max_step_joint`` (largest frame-to-frame change); ``steps_over_30deg``;
      ``accel_violation_frames`` (acceleration above
      ``config.accel_limits(robot)`` by more than 1 % on some joint); ``max_accel`` (rad/s^2)
      and ``max_accel_ratio`` (the largest acceleration over its joint's bound);
      ``limit_violation_frames``
      (a joint outside ``[lower, upper]``, or a follower outside its coupled range at its
      leader's angle (``Robot.coupled_limits``), by more than 1e-6 rad).
    """
    q = np.asarray(angles, np.float64)
    t = np.asarray(times, np.float64)
    step = np.diff(q, axis=0)  # (T-1, n_joints)
    dt = np.diff(t)[:, None]
    speed = np.abs(step) / dt
    ratio = speed / robot.require_velocity_limits()
    rated = speed / robot.speed_limits("rated")
    out: dict = {"frames": int(len(q))}
    if len(step):
        wj = int(np.argmax(ratio.max(axis=0)))
        sj = int(np.argmax(np.abs(step).max(axis=0)))
        out.update(
            speed_violation_frames=int((ratio > 1.0 + 1e-6).any(axis=1).sum()),
            max_speed_ratio=float(ratio.max()),
            worst_joint=robot.joint_names[wj],
            rated_speed_ratio=float(rated.max()),
            rated_worst_joint=robot.joint_names[int(np.argmax(rated.max(axis=0)))],
            max_step_deg=float(np.degrees(np.abs(step).max())),
            max_step_joint=robot.joint_names[sj],
            steps_over_30deg=int((np.abs(step) > math.radians(30.0)).any(axis=1).sum()),
        )
    else:
        out.update(speed_violation_frames=0, max_speed_ratio=0.0, worst_joint="",
                   rated_speed_ratio=0.0, rated_worst_joint="",
                   max_step_deg=0.0, max_step_joint="", steps_over_30deg=0)  # fmt: skip
    if len(step) > 1:
        v = step / dt
        acc = np.abs(np.diff(v, axis=0)) / (0.5 * (dt[1:] + dt[:-1]))
        bound = config.accel_limits(robot).astype(np.float64)
        out["accel_violation_frames"] = int((acc > 1.01 * bound).any(axis=1).sum())
        out["max_accel"] = float(acc.max())
        out["max_accel_ratio"] = float((acc / bound).max())
    else:
        out["accel_violation_frames"], out["max_accel"], out["max_accel_ratio"] = 0, 0.0, 0.0
    outside = np.maximum(robot.lower - q, q - robot.upper)
    for limit in robot.coupled_limits:
        lead, j = q[:, robot.index(limit.by)], robot.index(limit.joint)
        env_lo = np.interp(lead, limit.knots, limit.lower)
        env_hi = np.interp(lead, limit.knots, limit.upper)
        outside[:, j] = np.maximum(outside[:, j], np.maximum(env_lo - q[:, j], q[:, j] - env_hi))
    out["limit_violation_frames"] = int((outside > 1e-6).any(axis=1).sum())
    return out
