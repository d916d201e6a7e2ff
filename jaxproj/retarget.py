"""Whole-motion retargeting: skeleton positions -> NAO joint trajectories.

The per-frame mapping (analytic IK here; the projection engine adds learned methods) runs on the
valid frames; invalid frames (lost tracking, non-finite values) are kept and filled by a
documented rule, so a motion never dies halfway and never contains NaN:

* an invalid frame holds the last valid frame's angles;
* leading invalid frames take the first valid frame's angles;
* a motion with no valid frame at all takes ``robot.STANDING_POSTURE`` throughout.

Smoothing (``jaxproj.smoothing``) then runs over the driven joints of the filled motion, and
the result is clipped to the joint limits (the smoother's trend term can overshoot them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj import ik, robot
from jaxproj.skeleton import descriptor
from jaxproj.smoothing import PAPER_SMOOTHING, SmoothingParams, smooth


@dataclass(frozen=True)
class RetargetResult:
    """A retargeted motion.

    Attributes:
      angles: ``(T, 26)`` float32 radians in ``robot.JOINT_NAMES`` order.
      valid: ``(T,)`` bool, false where the input frame was invalid (its angles were filled).
    """

    angles: np.ndarray
    valid: np.ndarray


@jax.jit
def fill_invalid(q: jax.Array, valid: jax.Array) -> jax.Array:
    """Fill invalid frames of one motion: hold the last valid frame, back-fill leading ones.

    Args:
      q: ``(T, n)`` per-frame values (anything at invalid frames, NaN included).
      valid: ``(T,)`` bool.

    Returns:
      ``(T, n)``: valid frames unchanged; see the module doc for the rest. If no frame is
      valid the input is returned with non-finite entries zeroed (callers substitute a posture).
    """
    t = jnp.arange(q.shape[0])
    last = jax.lax.cummax(jnp.where(valid, t, -1), axis=0)
    first = jnp.argmax(valid)
    src = jnp.where(last >= 0, last, first)
    out = q[src]
    return jnp.where(jnp.isfinite(out), out, 0.0)


def retarget_positions(
    positions: np.ndarray,
    valid: np.ndarray | None = None,
    *,
    mapping: Callable[[jax.Array], jax.Array] | None = None,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    smoothing: SmoothingParams | None = PAPER_SMOOTHING,
) -> RetargetResult:
    """Retarget one motion.

    Args:
      positions: ``(T, 20, 3)`` joint positions, Kinect SDK order.
      valid: optional ``(T,)`` bool from the reader; combined with the descriptor's own check.
      mapping: ``(N, 3 * n_bones)`` descriptors -> ``(N, 10)`` driven angles; default the
        analytic IK (``ik.solve_driven``).
      bones, mirror: descriptor options (``skeleton.descriptor``).
      smoothing: smoother gains, or ``None`` for no smoothing.

    Returns:
      ``RetargetResult`` with ``(T, 26)`` angles and ``(T,)`` validity.
    """
    positions = np.asarray(positions, dtype=np.float32)
    if positions.ndim != 3 or positions.shape[1:] != (20, 3) or positions.shape[0] < 1:
        raise ValueError(f"positions must be (T >= 1, 20, 3), got {positions.shape}")
    d, ok = descriptor(positions, bones=bones, mirror=mirror)
    ok = np.asarray(ok)
    if valid is not None:
        ok = ok & np.asarray(valid, dtype=bool)
    if not ok.any():
        angles = np.broadcast_to(robot.STANDING_POSTURE, (positions.shape[0], robot.N_JOINTS))
        return RetargetResult(np.array(angles, dtype=np.float32), ok)
    if mapping is None:
        q = ik.solve_driven(d, bones)
    else:
        q = mapping(d)
    q = fill_invalid(q, jnp.asarray(ok))
    if smoothing is not None:
        # The trend term can overshoot; the robot never gets an angle outside its limits.
        q = smooth(q, smoothing)
        lo = jnp.broadcast_to(robot.LOWER[robot.DRIVEN_INDEX], q.shape)
        hi = jnp.broadcast_to(robot.UPPER[robot.DRIVEN_INDEX], q.shape)
        q = jnp.clip(q, lo, hi)
    angles = np.asarray(ik.driven_to_full(q), dtype=np.float32)
    return RetargetResult(angles, ok)
