"""Zero-lag offline smoothing: a Rauch-Tung-Striebel (RTS) smoother of a constant-velocity model.

The paper's double exponential smoother (``jaxproj.motion.smoothing``) is causal: built for live
teleoperation, it can only lag. When the whole recording is known (``retarget``, ``evaluate``, the
demo), a forward-backward smoother has no lag: each joint angle ``y_t`` (rad) is read as a noisy
measurement of a state ``x = (angle, angular velocity)`` that moves with white-noise
acceleration::

    x_t = F(dt_t) x_{t-1} + w_t,   F(dt) = [[1, dt], [0, 1]],
    w_t ~ N(0, q [[dt^3/3, dt^2/2], [dt^2/2, dt]]),    q = accel_std ** 2   ((rad/s^2)^2 s)
    y_t = x_t[0] + v_t,            v_t ~ N(0, noise_std ** 2)

A Kalman filter runs forward (``lax.scan``), the RTS recursion backward (``lax.scan`` in
reverse), each joint on its own (a 2 x 2 covariance per joint, written out). What the model
gives for free:

* **irregular time steps**: ``F`` and the process noise follow each frame's own ``dt`` (the
  recording's ``times``);
* **invalid frames**: the filter skips their measurement update, so a tracking gap is bridged by
  the model (a cubic-like interpolation between the valid frames around it) instead of a held
  pose; a gap longer than ``BRIDGE_S`` (1 s) by a straight line between the smoothed values
  around it (the model's cubic overshoots there); before the first valid frame and after the
  last one the output holds that frame's smoothed value (nothing to interpolate between);
* **no lag**: the smoothed estimate uses the past and the future alike; on a motion that is a
  shifted copy of another, the output is the shifted output (a test checks a sine).

Only the ratio ``accel_std / noise_std`` shapes the output (the mean of the RTS smoother is
invariant to scaling both); ``noise_std`` fixes the units. Defaults: chosen on training people
(``benchmarks/tune_smoother.py``; docs/guide/smoothing.md): the lowest error against the IK on
leave-one-subject-out projections of the training subjects with a jerk at most the paper
smoother's.

The traced argument is an array like the paper smoother's gains: ``(3,)`` ``(dt, accel_std,
noise_std)`` for frames ``dt`` apart, or ``(T, 3)`` with each frame's own ``dt``
(``OfflineSmoothing.gains``; ``jaxproj.motion.smoothing.frame_gains`` builds both).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import full_precision
from jaxproj.errors import ConfigError


@dataclass(frozen=True)
class OfflineSmoothing:
    """Settings of the zero-lag RTS smoother (module doc), validated when constructed.

    Attributes:
      accel_std: ``sqrt(q)``, the white-noise acceleration's spectral density, rad/s^2 per
        sqrt(Hz): larger follows faster motion (less smoothing).
      noise_std: the measurement noise of a frame's angle, rad.
      rate: frames per second assumed when a motion comes without ``times``.
    """

    accel_std: float = 7.0
    noise_std: float = 0.02
    rate: float = 15.0
    kind: ClassVar[str] = "offline"

    def __post_init__(self) -> None:
        for name in ("accel_std", "noise_std", "rate"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0.0):
                raise ConfigError(f"offline smoothing {name}={v} must be positive and finite")

    def gains(self, dt: np.ndarray | None = None) -> jax.Array:
        """The traced argument of the smoother.

        Args:
          dt: optional ``(T,)`` seconds from the previous frame to each frame (entry 0 is not
            used: the first frame starts the filter).

        Returns:
          ``(3,)`` float32 ``(1 / rate, accel_std, noise_std)`` without ``dt``; with it,
          ``(T, 3)`` float32 rows ``(dt_t, accel_std, noise_std)``.
        """
        if dt is None:
            return jnp.asarray((1.0 / self.rate, self.accel_std, self.noise_std), jnp.float32)
        dt = check_steps(dt)
        a, r = np.full_like(dt, self.accel_std), np.full_like(dt, self.noise_std)
        rows = np.stack([np.maximum(dt, 0.0), a, r], axis=-1)
        return jnp.asarray(rows, jnp.float32)


def check_steps(dt: np.ndarray) -> np.ndarray:
    """``(T,)`` seconds from each frame's predecessor (entry 0 unused) as float64, or
    ``ConfigError`` unless finite and positive after the first frame (both smoothers'
    ``gains``)."""
    dt = np.asarray(dt, np.float64)
    if dt.ndim != 1 or not np.isfinite(dt).all() or (dt[1:] <= 0).any():
        raise ConfigError("dt must be (T,) finite seconds, positive after the first frame")
    return dt


OFFLINE_SMOOTHING = OfflineSmoothing()
"""The default smoother of the offline tools (``retarget``, ``evaluate``, the demo)."""


BRIDGE_S = 1.0
"""s: a gap of invalid frames whose valid neighbours are more than this apart is bridged by a
straight line between their smoothed values, not by the model. Across a long gap the constant
velocity model carries the velocity at the gap's ends into a cubic that overshoots (roughly
the end velocity times a quarter of the gap): over the 8.9 s of frames 52-118 of UTKinect
person 9, e02 at 7.5 fps (a leg the tracker lost, ``pipeline.lost_frames``) it swung the G1's
left hip pitch from -30 to -128 deg and put the foot in the head."""


def _bridge_long_gaps(out: jax.Array, meas: jax.Array, time: jax.Array) -> jax.Array:
    """``(T, n)`` ``out`` with each run of frames without a measurement between two measured
    frames more than ``BRIDGE_S`` apart (``time``: ``(T,)`` s) replaced by the straight line
    between those two frames' values."""
    n_t = out.shape[0]
    t_idx = jnp.arange(n_t)
    before = jax.lax.cummax(jnp.where(meas, t_idx, -1), axis=0)
    after = jax.lax.cummin(jnp.where(meas, t_idx, n_t), axis=0, reverse=True)
    inside = ~meas & (before >= 0) & (after < n_t)
    a, b = jnp.clip(before, 0, n_t - 1), jnp.clip(after, 0, n_t - 1)
    span = time[b] - time[a]
    long = inside & (span > BRIDGE_S)
    w = jnp.where(long, (time - time[a]) / jnp.where(long, span, 1.0), 0.0)[:, None]
    line = out[a] * (1.0 - w) + out[b] * w
    return jnp.where(long[:, None], line, out)


@full_precision
def rts_motion(y: jax.Array, valid: jax.Array, length: jax.Array, gains: jax.Array) -> jax.Array:
    """The RTS smoother of one padded motion (traceable; call it inside a jitted function).

    Args:
      y: ``(T, n)`` a motion padded to ``T`` frames (any finite values at invalid frames).
      valid: ``(T,)`` bool: frames whose measurement is used (padding must be false or past
        ``length``).
      length: ``()`` int, the true length; later frames are returned as the input.
      gains: ``(3,)`` or ``(T, 3)`` ``OfflineSmoothing.gains`` (row ``t``: the step into frame
        ``t``).

    Returns:
      ``(T, n)`` the smoothed motion, ``y``'s dtype. A motion with no valid frame is returned
      as the input.
    """
    n_t = y.shape[0]
    g = jnp.broadcast_to(gains.astype(jnp.float32), (n_t, 3))
    dt, q, r = g[:, 0], g[:, 1] ** 2, g[:, 2] ** 2
    t_idx = jnp.arange(n_t)
    live = t_idx < length
    meas = valid & live
    yf = y.astype(jnp.float32)
    zeros = jnp.zeros(y.shape[1], jnp.float32)

    def predict(state, dt_t, q_t):
        x0, x1, p00, p01, p11 = state
        return (
            x0 + dt_t * x1,
            x1,
            p00 + 2.0 * dt_t * p01 + dt_t * dt_t * p11 + q_t * dt_t**3 / 3.0,
            p01 + dt_t * p11 + q_t * dt_t**2 / 2.0,
            p11 + q_t * dt_t,
        )

    def correct(state, y_t, r_t, ok):
        x0, x1, p00, p01, p11 = state
        s = p00 + r_t
        k0, k1 = p00 / s, p01 / s
        innov = y_t - x0
        new = (x0 + k0 * innov, x1 + k1 * innov, p00 * r_t / s, p01 * r_t / s, p11 - k1 * p01)
        return tuple(jnp.where(ok, a, b) for a, b in zip(new, state, strict=True))

    # the first valid frame's value as the prior mean (the caller filled invalid frames from it),
    # a wide prior: 1 rad on the angle, 10 rad/s on the velocity
    first = jnp.argmax(meas)
    prior = (yf[first], zeros, zeros + 1.0, zeros, zeros + 100.0)
    filt0 = correct(prior, yf[0], r[0], meas[0])

    def forward(state, inp):
        y_t, dt_t, q_t, r_t, ok = inp
        pred = predict(state, dt_t, q_t)
        filt = correct(pred, y_t, r_t, ok)
        return filt, (filt, pred)

    _, (filt_rest, pred_rest) = jax.lax.scan(
        forward, filt0, (yf[1:], dt[1:], q[1:], r[1:], meas[1:])
    )
    filt = tuple(jnp.concatenate([a[None], b]) for a, b in zip(filt0, filt_rest, strict=True))

    def backward(xs_next, inp):
        # xs_next: (2, n) smoothed state of frame t+1; inp: frame t's filtered state and the
        # prediction of frame t+1 from it
        f, p, dt_n, restart = inp
        x0, x1, p00, p01, p11 = f
        px0, px1, pp00, pp01, pp11 = p
        a00, a01 = p00 + dt_n * p01, p01  # (P_f F^T), rows (0, 1)
        a10, a11 = p01 + dt_n * p11, p11
        det = pp00 * pp11 - pp01 * pp01
        g00, g01 = (a00 * pp11 - a01 * pp01) / det, (a01 * pp00 - a00 * pp01) / det
        g10, g11 = (a10 * pp11 - a11 * pp01) / det, (a11 * pp00 - a10 * pp01) / det
        d0, d1 = xs_next[0] - px0, xs_next[1] - px1
        xs = jnp.stack([x0 + g00 * d0 + g01 * d1, x1 + g10 * d0 + g11 * d1])
        xs = jnp.where(restart, jnp.stack([x0, x1]), xs)  # frame t is the motion's last
        return xs, xs[0]

    f_t = tuple(a[:-1] for a in filt)  # frames 0 .. T-2
    restart = t_idx[:-1] + 1 >= length
    last = jnp.stack([filt[0][-1], filt[1][-1]])
    _, rest = jax.lax.scan(backward, last, (f_t, pred_rest, dt[1:], restart), reverse=True)
    out = jnp.concatenate([rest, filt[0][-1:]])
    # before the first valid frame and after the last one: hold that frame's smoothed value
    last_valid = n_t - 1 - jnp.argmax(meas[::-1])
    src = jnp.clip(t_idx, first, last_valid)
    out = out[src]
    out = _bridge_long_gaps(out, meas, jnp.cumsum(dt))
    keep = live & jnp.any(meas)
    return jnp.where(keep[:, None], out, yf).astype(y.dtype)
