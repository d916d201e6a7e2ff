"""A per-frame confidence from what the projection already computes.

The relaxed objective's value is the least back-projection deviation: how far the chosen
candidate, sent back through the backward kernels of its nearest robot landmarks, lands from the
query (descriptor units: differences of bone unit vectors; per-chain deviations combine as the
root of their sum of squares). A query near the landmarks gets a candidate that back-projects
onto itself; one far from them (a pose, a body or a camera set-up the landmarks never saw) does
not. The confidence maps it to ``[0, 1]``::

    confidence = exp(-deviation / DEVIATION_SCALE)

``DEVIATION_SCALE`` is the 90th percentile of the deviation on training people projected by
models that never saw them (leave one training subject out, the default model's settings:
``benchmarks/tune_smoother.py``'s projections; docs/guide/smoothing.md). So
``confidence < LOW_CONFIDENCE = exp(-1)`` flags the frames less trusted than nine in ten frames
of a person the model did not see; on those training people the flagged tenth holds 68 % of the
frames with M_max > 30 deg (17 % of it errs that much against 2.6 % of all frames).

That scale is the default robot's default model's. A robot whose default model deviates on
another scale (more chains and bones, e.g. five chains over 19 bones) gives its own
(``Robot.deviation_scale``, measured the same way on training people its model did not see),
which ``retarget``, ``evaluate`` and ``streaming`` pass as ``scale``.

Any other model (fewer landmarks, other training people) deviates on its own scale: a
100-landmark model of two people deviates more on every frame, and against the default model's
scale it would flag nearly every frame of anyone. So ``build`` calibrates each model
(``Model.deviation_scale``): the p90 of the relaxed deviation of ``CALIBRATION_FRAMES`` evenly
spaced frames of its own training set, times ``HELD_OUT_RATIO``, the ratio of the held-out p90
to that in-sample p90 measured on the default robot's default model (so that model keeps exactly
``DEVIATION_SCALE``). The confidence of a model then means the same for every model: frames less
trusted than nine in ten of a person that model did not see. ``Model.confidence_scale`` is the
scale used: the model's own, else (a model file written before models were calibrated) its
robot's ``deviation_scale``, else ``DEVIATION_SCALE``; ``rescale`` moves a confidence from one
scale to another.

The full objective's value (``f(w*)``) is a weighted deviation of the same units and is read the
same way; the analytic IK answers with confidence 1; an invalid frame (filled, not projected)
has confidence 0.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

DEVIATION_SCALE = 0.174
"""Descriptor units: the leave-one-subject-out p90 of the relaxed deviation (training people,
default model, L = M = 10; measured 0.1743)."""

CALIBRATION_FRAMES = 1024
"""Training frames (evenly spaced) a build projects to calibrate its model's scale."""

HELD_OUT_RATIO = 2.834
"""``DEVIATION_SCALE`` over the p90 of the relaxed deviation of the default robot's default model on
its own ``CALIBRATION_FRAMES`` training frames (measured 0.06139, 2-core VM, 2026-11-27): how much
more a person the model did not see deviates than the people it was built from."""

LOW_CONFIDENCE = math.exp(-1.0)
"""Frames with a lower confidence are reported as low-confidence (``retarget``, ``evaluate``)."""


def confidence(value: jax.Array, scale: float | None = None) -> jax.Array:
    """``(...,)`` projection values (``project``'s second output) -> ``(...,)`` float32
    confidence in ``[0, 1]`` (module doc); non-finite values give 0. ``scale``: the deviation
    scale (``None``: ``DEVIATION_SCALE``, the default robot's default model's; another robot's
    default model deviates on another scale: ``Robot.deviation_scale``)."""
    v = jnp.asarray(value, jnp.float32)
    c = jnp.exp(-jnp.maximum(v, 0.0) / np.float32(DEVIATION_SCALE if scale is None else scale))
    return jnp.where(jnp.isfinite(v), c, 0.0)


def rescale(conf: jax.Array, from_scale: float, to_scale: float) -> jax.Array:
    """``(...,)`` confidences on ``from_scale`` -> the same frames' on ``to_scale``:
    ``exp(-v / to) = exp(-v / from) ** (from / to)`` (0 stays 0, 1 stays 1)."""
    c = jnp.asarray(conf, jnp.float32)
    return jnp.power(c, np.float32(from_scale / to_scale))
