"""Nearest-neighbour search over landmark sets.

Exact brute force, written for ONE query point (callers vmap). It is the single place the
projection engine asks "which landmarks are nearest", so a faster search (neighbour lists,
clustered search) can replace it without touching the projection code.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def sq_norms(points: jax.Array) -> jax.Array:
    """``(K, d) -> (K,)`` squared norms (precompute once per landmark set)."""
    return jnp.sum(points * points, axis=-1)


def nearest(
    points: jax.Array, points_sq: jax.Array, x: jax.Array, n: int
) -> tuple[jax.Array, jax.Array]:
    """The ``n`` landmarks nearest to one point, exact.

    Args:
      points: ``(K, d)`` landmark coordinates.
      points_sq: ``(K,)`` ``sq_norms(points)``.
      x: ``(..., d)`` query point(s); a leading batch is allowed (e.g. the L candidates).
      n: how many (static), ``n <= K``.

    Returns:
      ``(idx, d2)``: ``(..., n)`` int32 indices, nearest first (ties by lower index), and their
      squared Euclidean distances.
    """
    cross = jnp.einsum("...d,kd->...k", x, points)
    d2 = jnp.broadcast_to(points_sq, cross.shape) - 2.0 * cross
    d2 = d2 + jnp.sum(x * x, axis=-1, keepdims=True)
    neg, idx = jax.lax.top_k(-d2, n)
    return idx.astype(jnp.int32), jnp.maximum(-neg, 0.0)
