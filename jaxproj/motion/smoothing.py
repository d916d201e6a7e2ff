"""Double exponential smoothing of a projected motion (paper section II-D, after LaViola 2003).

For a motion ``y_0 .. y_{T-1}`` (each a vector of joint angles, rad), with ``s_0 = y_0`` and
``b_0 = 0``, every later frame does::

    s~_t = alpha * y_t + (1 - alpha) * (s_{t-1} + b_{t-1})
    s_t  = s_{t-1}  if ||s~_t - s_{t-1}||_2 < eta  else  s~_t        (dead band)
    b_t  = gamma * (s_t - s_{t-1}) + (1 - gamma) * b_{t-1}

The paper lists the dead band after the trend update; we apply it before, so that a held frame
also decays the trend (``b_t = (1 - gamma) b_{t-1}``) instead of feeding a step that never
happened into it. ``eta`` is in the units of ``y`` (radians; the norm runs over all the joints
given, usually ``robot.DRIVEN_JOINTS``). Defaults are the paper's: alpha 0.75, gamma 0.3,
eta 0.15.

Frame rate. The update is per frame, so fixed gains smooth a 30 fps recording over half the time
of a 15 fps one. The gains are therefore stated at a reference rate (``SmoothingParams.rate``,
15 frames/s: the paper's gains on the MSR Action3D rate we validate them on) and converted to
each frame's own time step ``dt`` (``SmoothingParams.gains(dt)``) so that the filter has the same
time constants at any rate:

    alpha(dt) = 1 - (1 - alpha) ** (dt * rate)      (the same decay per second)
    gamma(dt) = 1 - (1 - gamma) ** (dt * rate)
    eta(dt)   = eta * dt * rate                     (a dead band on speed, rad/s * s)

At ``dt = 1 / rate`` these are the given gains. ``jaxproj.motion.retarget`` uses the recording's own
time axis (irregular steps included: each frame gets its own gains); ``gains()`` with no ``dt``
returns the gains as given, per frame, as before.

``smooth`` handles one motion (``lax.scan`` over time); ``smooth_batch`` vmaps it over a padded
batch ``(B, T, n)`` with lengths: frames past a motion's length leave its state untouched and
are returned as the input. ``step`` is one frame of the update: the scan's body, and what
``jaxproj.motion.streaming`` runs once per frame, so the two cannot drift apart.
``frame_gains`` turns times of one padded motion or a padded batch into the gains of each frame
(``jaxproj.motion.retarget``, ``smooth``, ``smooth_batch`` and ``jaxproj.eval.evaluate``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from jaxproj._internal.jit import full_precision, jit
from jaxproj.errors import ConfigError
from jaxproj.motion.offline import OFFLINE_SMOOTHING, OfflineSmoothing, check_steps, rts_motion


@dataclass(frozen=True)
class SmoothingParams:
    """Smoother gains, validated when constructed (``ConfigError`` unless ``0 <= alpha, gamma <=
    1`` and ``eta >= 0``). They enter the jitted smoother as traced values: changing them does
    not recompile."""

    alpha: float = 0.75
    gamma: float = 0.3
    eta: float = 0.15
    rate: float = 15.0
    """Frames per second at which ``alpha``, ``gamma``, ``eta`` are per-frame values."""
    kind: ClassVar[str] = "paper"
    """The pipeline's name of this smoother (``jaxproj.motion.offline.OfflineSmoothing``:
    ``"offline"``)."""

    def __post_init__(self) -> None:
        for name in ("alpha", "gamma"):
            v = float(getattr(self, name))
            if not 0.0 <= v <= 1.0:
                raise ConfigError(f"smoothing {name}={v} must lie in [0, 1]")
        if not float(self.eta) >= 0.0:
            raise ConfigError(f"smoothing eta={self.eta} must be >= 0")
        if not (np.isfinite(self.rate) and float(self.rate) > 0.0):
            raise ConfigError(f"smoothing rate={self.rate} must be a positive frame rate")

    def gains(self, dt: np.ndarray | None = None) -> jax.Array:
        """The traced argument of the smoother.

        Args:
          dt: optional ``(T,)`` seconds from the previous frame to each frame (entry 0 is not
            used: the first frame starts the smoother).

        Returns:
          ``(3,)`` float32 ``(alpha, gamma, eta)`` as given (per frame at ``rate``) without
          ``dt``; with it, ``(T, 3)`` float32 gains of each frame for its own time step (see the
          module doc).
        """
        if dt is None:
            return jnp.asarray((self.alpha, self.gamma, self.eta), jnp.float32)
        dt = check_steps(dt)
        n = np.maximum(dt, 0.0) * float(self.rate)
        per = np.stack(
            [
                1.0 - (1.0 - float(self.alpha)) ** n,
                1.0 - (1.0 - float(self.gamma)) ** n,
                float(self.eta) * n,
            ],
            axis=-1,
        )
        # a step of ~1e37 s or more would overflow float32's dead band: cap it there (a dead
        # band that large holds the frame either way)
        per = np.minimum(per, np.finfo(np.float32).max)
        return jnp.asarray(per, jnp.float32)


PAPER_SMOOTHING = SmoothingParams()
"""The paper's gains: alpha 0.75, gamma 0.3, eta 0.15."""

__all__ = ["OFFLINE_SMOOTHING", "PAPER_SMOOTHING", "OfflineSmoothing", "SmoothingParams",
           "Smoothing", "frame_gains", "smooth", "smooth_any", "smooth_batch", "smooth_motion",
           "smoother_kind", "step"]  # fmt: skip


def step(
    s_prev: jax.Array, b_prev: jax.Array, y: jax.Array, gains: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """One frame of the smoother (the update rule of the module doc, dead band before trend).

    ``smooth`` / ``smooth_batch`` scan this over time and ``jaxproj.motion.streaming`` calls it once
    per frame: both run exactly the same operations.

    Args:
      s_prev: ``(n,)`` previous smoothed value ``s_{t-1}``.
      b_prev: ``(n,)`` previous trend ``b_{t-1}``.
      y: ``(n,)`` this frame's input ``y_t``.
      gains: ``(3,)`` ``(alpha, gamma, eta)`` (``SmoothingParams.gains()``), cast to ``y``'s
        dtype.

    Returns:
      ``(s_t, b_t)``, each ``(n,)``. The first frame of a motion is not a step: it starts the
      smoother with ``s_0 = y_0``, ``b_0 = 0``.
    """
    alpha, gamma, eta = (gains[i].astype(y.dtype) for i in range(3))
    cand = alpha * y + (1 - alpha) * (s_prev + b_prev)
    moved = jnp.sqrt(jnp.sum((cand - s_prev) ** 2)) >= eta
    s_t = jnp.where(moved, cand, s_prev)
    b_t = gamma * (s_t - s_prev) + (1 - gamma) * b_prev
    return s_t, b_t


@full_precision
def smooth_motion(y: jax.Array, length: jax.Array, gains: jax.Array) -> jax.Array:
    """The traceable core of ``smooth`` (call it inside a jitted function).

    Args:
      y: ``(T, n)`` a motion padded to ``T`` frames.
      length: ``()`` int, its true length; later frames are returned as the input.
      gains: ``(3,)`` ``SmoothingParams.gains()`` (every frame), or ``(T, 3)``
        ``SmoothingParams.gains(dt)`` (frame ``t`` uses row ``t``).

    Returns:
      ``(T, n)`` the smoothed motion.
    """

    def scan_step(carry, inp):
        s_prev, b_prev = carry
        y_t, t, g_t = inp
        s_t, b_t = step(s_prev, b_prev, y_t, g_t)
        live = t < length
        s_t = jnp.where(live, s_t, s_prev)
        b_t = jnp.where(live, b_t, b_prev)
        return (s_t, b_t), jnp.where(live, s_t, y_t)

    s0 = y[0]
    ts = jnp.arange(1, y.shape[0])
    per_frame = jnp.broadcast_to(gains, (y.shape[0], 3))[1:]
    _, rest = jax.lax.scan(scan_step, (s0, jnp.zeros_like(s0)), (y[1:], ts, per_frame))
    return jnp.concatenate([s0[None], rest], axis=0)


def smooth_any(
    y: jax.Array, valid: jax.Array, length: jax.Array, gains: jax.Array, kind: str
) -> jax.Array:
    """``smooth_motion`` (``kind="paper"``, which does not read ``valid``: fill invalid frames
    first) or ``offline.rts_motion`` (``"offline"``) of one padded ``(T, n)`` motion."""
    if kind == "paper":
        return smooth_motion(y, length, gains)
    if kind == "offline":
        return rts_motion(y, valid, length, gains)
    raise ConfigError(f"unknown smoother kind {kind!r}: 'paper' or 'offline'")


def _smooth_batch(
    y: jax.Array, valid: jax.Array, lengths: jax.Array, gains: jax.Array, kind: str
) -> jax.Array:
    per_motion = 0 if gains.ndim == 3 else None  # (B, T, 3) gains of each motion's frames
    one = functools.partial(smooth_any, kind=kind)
    return jax.vmap(one, in_axes=(0, 0, 0, per_motion))(y, valid, lengths, gains)


_smooth_batch = jit(_smooth_batch, static_argnames=("kind",))

Smoothing = SmoothingParams | OfflineSmoothing
"""Either smoother's settings: the paper's causal one or the zero-lag offline one."""


def smooth(
    y: jax.Array,
    params: Smoothing = PAPER_SMOOTHING,
    times: np.ndarray | None = None,
    valid: np.ndarray | None = None,
) -> jax.Array:
    """Smooth one motion.

    Args:
      y: ``(T, n)`` joint angles over time (T >= 1).
      params: the paper's smoother (``SmoothingParams``, default, its gains) or the offline
        one (``offline.OfflineSmoothing``).
      times: optional ``(T,)`` seconds of the frames: the gains follow each frame's time step
        (``params.gains(dt)``); ``None``: frames ``1 / params.rate`` apart.
      valid: optional ``(T,)`` bool, frames to use (the offline smoother skips the others'
        values; the paper's reads every frame: fill invalid frames before); ``None``: all.

    Returns:
      ``(T, n)`` smoothed motion, same dtype.
    """
    y = jnp.asarray(y)
    if y.ndim != 2 or y.shape[0] < 1:
        raise ConfigError(f"smooth expects a (T, n) motion with T >= 1, got shape {y.shape}")
    if times is not None and np.shape(times) != (y.shape[0],):
        raise ConfigError(f"times must be ({y.shape[0]},) seconds, got shape {np.shape(times)}")
    kind = smoother_kind(params)
    gains = frame_gains(params, times, y.shape[0])
    ok = np.ones(y.shape[0], bool) if valid is None else np.asarray(valid, bool)
    if ok.shape != (y.shape[0],):
        raise ConfigError(f"valid must be ({y.shape[0]},) bool, got shape {ok.shape}")
    lengths = jnp.asarray([y.shape[0]], jnp.int32)
    return _smooth_batch(y[None], jnp.asarray(ok[None]), lengths, gains, kind=kind)[0]


def smooth_batch(
    y: jax.Array,
    lengths: ArrayLike,
    params: Smoothing = PAPER_SMOOTHING,
    times: np.ndarray | None = None,
    valid: np.ndarray | None = None,
) -> jax.Array:
    """Smooth a padded batch of motions in one call.

    Args:
      y: ``(B, T, n)`` motions padded to a common ``T``.
      lengths: ``(B,)`` int, the true length of each motion (1..T).
      params: either smoother's settings (``smooth``).
      times: optional ``(B, T)`` seconds of each motion's frames (increasing over its length;
        padding entries are not used): gains per frame time step; ``None``: frames
        ``1 / params.rate`` apart.
      valid: optional ``(B, T)`` bool (``smooth``); ``None``: all frames.

    Returns:
      ``(B, T, n)``; entries past a motion's length are the input, unchanged.
    """
    y = jnp.asarray(y)
    if y.ndim != 3:
        raise ConfigError(f"smooth_batch expects (B, T, n) motions, got shape {y.shape}")
    lengths = np.asarray(lengths, np.int64)
    if times is not None and np.shape(times) != y.shape[:2]:
        raise ConfigError(f"times must be {y.shape[:2]} seconds, got shape {np.shape(times)}")
    kind = smoother_kind(params)
    gains = frame_gains(params, times, lengths)
    ok = np.ones(y.shape[:2], bool) if valid is None else np.asarray(valid, bool)
    if ok.shape != y.shape[:2]:
        raise ConfigError(f"valid must be {y.shape[:2]} bool, got shape {ok.shape}")
    return _smooth_batch(y, jnp.asarray(ok), jnp.asarray(lengths, jnp.int32), gains, kind=kind)


def smoother_kind(params: object) -> str:
    """``params.kind`` of either smoother's settings, or ``ConfigError`` for anything else."""
    if not isinstance(params, SmoothingParams | OfflineSmoothing):
        got = type(params).__name__
        raise ConfigError(f"smoothing must be a SmoothingParams or an OfflineSmoothing, got {got}")
    return params.kind


def frame_gains(
    params: Smoothing, times: np.ndarray | None, lengths: np.ndarray | jax.Array | int
) -> jax.Array:
    """The smoother's gains for padded motions (the ``gains`` of ``smooth_motion``).

    Args:
      params: gains.
      times: ``(T,)`` seconds of one motion's frames or ``(B, T)`` of a batch's (increasing
        over each length; padding entries are not used); ``None``: frames ``1 / params.rate``
        apart.
      lengths: ``()`` (one motion) or ``(B,)`` true lengths.

    Returns:
      ``(3,)`` ``params.gains()`` without ``times``; else ``(T, 3)`` or ``(B, T, 3)`` gains of
      each frame for its own time step (padding frames: ``1 / params.rate``, not smoothed).
    """
    if times is None:
        return params.gains()
    t = np.asarray(times, np.float64)
    dt = np.diff(t, axis=-1, prepend=t[..., :1])
    live = np.arange(t.shape[-1]) < np.asarray(lengths)[..., None]
    dt = np.where(live, dt, 1.0 / params.rate)  # padding frames are not smoothed
    if dt.ndim == 1:
        return params.gains(dt)
    return jnp.stack([params.gains(row) for row in dt])
