"""Nearest-neighbour search over landmark sets.

Exact brute force, written for ONE query point (callers vmap). It is the single place the
projection engine asks "which landmarks are nearest", so a faster search can replace it without
touching the projection code.

Selection is two-stage and still exact: the ``K`` distances are cut into blocks of ``BLOCK``,
the ``n`` blocks with the smallest minima are kept, and ``top_k`` runs over those ``n * BLOCK``
distances only. The ``n`` nearest always lie in those blocks (a block holding one of them has a
minimum no larger than the ``n``-th distance, and at most ``n - 1`` other blocks can have a
smaller minimum). ``lax.top_k`` sorts whole rows; a min-reduction over blocks is far cheaper
(measured on an H200: robot search 1.10 -> 0.3 us per query at K = 1635, batch 65536).

Both selections of the two-stage search (``n <= SELECT_MAX``) pick the ``n`` smallest by ``n``
rounds of "take the row's minimum, mask it" on GPUs and TPUs, and with ``lax.top_k`` on CPUs
(``lax.platform_dependent`` decides when the function is lowered). On an H200 the rounds of
fused reductions beat XLA's ``TopK`` kernel (one arm chain's robot search, 10 rows of 1,656
landmarks per query, batch 65,536: 151 -> 90 ns per query, the same neighbour sets); on the CPU
the rounds were 3x slower than ``TopK`` (``benchmarks/RESULTS.md``).

``nearest_rows`` searches many rows of several landmark sets at once: with ``impl="pallas"``
(the default on CUDA GPUs, ``jaxproj.projection.ops.Impl``) the fused Pallas kernel of
``jaxproj.projection.ops.knn_pallas`` (distances, block minima and both selections in one
kernel, no ``(rows, K)`` matrix in memory), with ``impl="xla"`` ``nearest`` per set.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.projection.ops import Impl, ImplLike, pallas_interpret, resolve_impl
from jaxproj.projection.ops import knn_pallas as _knn_pallas

BLOCK = 16
"""Landmarks per block of the two-stage exact selection."""

SELECT_MAX = 16
"""Largest ``n`` selected by repeated minima on accelerators (more rounds cost more than
``TopK``, which also stops being a partial selection above 16: XLA sorts such rows)."""


def sq_norms(points: jax.Array) -> jax.Array:
    """``(K, d) -> (K,)`` squared norms (precompute once per landmark set)."""
    return jnp.sum(points * points, axis=-1)


def nearest(
    points: jax.Array | np.ndarray, points_sq: jax.Array | np.ndarray, x: jax.Array, n: int
) -> tuple[jax.Array, jax.Array]:
    """The ``n`` landmarks nearest to one point, exact.

    Args:
      points: ``(K, d)`` landmark coordinates.
      points_sq: ``(K,)`` ``sq_norms(points)``.
      x: ``(..., d)`` query point(s); a leading batch is allowed (e.g. the L candidates).
      n: how many (static), ``n <= K``.

    Returns:
      ``(idx, d2)``: ``(..., n)`` int32 indices, nearest first, and their squared Euclidean
      distances. Exactly tied distances may be ordered differently from a full sort.
    """
    cross = jnp.einsum("...d,kd->...k", x, points)
    d2 = jnp.broadcast_to(points_sq, cross.shape) - 2.0 * cross
    d2 = d2 + jnp.sum(x * x, axis=-1, keepdims=True)
    k = d2.shape[-1]
    if k < 4 * n * BLOCK:  # small sets: one top_k is as cheap
        neg, idx = jax.lax.top_k(-d2, n)
        return idx.astype(jnp.int32), jnp.maximum(-neg, 0.0)
    pad = (-k) % BLOCK
    if pad:
        inf = jnp.full((*d2.shape[:-1], pad), jnp.inf, d2.dtype)
        d2 = jnp.concatenate([d2, inf], axis=-1)
    blocks = d2.reshape(*d2.shape[:-1], -1, BLOCK)  # (..., K / BLOCK, BLOCK)
    best_blocks, _ = smallest(jnp.min(blocks, axis=-1), n)  # (..., n)
    cand = jnp.take_along_axis(blocks, best_blocks[..., None], axis=-2)  # (..., n, BLOCK)
    cand = cand.reshape(*cand.shape[:-2], n * BLOCK)
    pos, val = smallest(cand, n)
    block_of = jnp.take_along_axis(best_blocks, pos // BLOCK, axis=-1)
    idx = block_of * BLOCK + pos % BLOCK
    return idx.astype(jnp.int32), jnp.maximum(val, 0.0)


def nearest_rows(
    points: jax.Array | np.ndarray,
    points_sq: jax.Array | np.ndarray,
    x: jax.Array,
    n: int,
    impl: ImplLike = Impl.AUTO,
    prune: bool = False,
    index: _knn_pallas.PruneIndex | None = None,
) -> tuple[jax.Array, jax.Array]:
    """The ``n`` nearest landmarks of many rows, per landmark set, exact.

    Args:
      points: ``(C, K, d)`` landmark sets.
      points_sq: ``(C, K)`` ``sq_norms(points)``; ``+inf`` marks padding landmarks (never
        returned while ``n`` others exist).
      x: ``(C, R, d)`` query rows of each set.
      n: how many (static), ``n <= K``.
      impl: ``"xla"``: ``nearest`` per set; ``"pallas"``: the fused kernel (for
        ``n <= knn_pallas.SLOTS``; XLA above); ``"auto"`` (default): ``ops.resolve_impl``'s choice
        for the default backend (static).
      prune: with the fused kernel, its pruned exact search first (``knn_pallas.knn``; static):
        for rows near the landmarks.
      index: with ``prune``, the sets' ``knn_pallas.prune_index`` computed beforehand (once per
        projector: ``projector.with_search_index``), else computed in the trace; the same
        answers either way.

    Returns:
      ``(idx, d2)``: ``(C, R, n)`` int32 indices, nearest first, and squared distances. The
      fused kernel computes ``|x - p|^2`` directly; the XLA search (``nearest``) expands it, so
      the two may differ where distances tie to float32 round-off
      (``jaxproj.projection.ops.knn_pallas``).
    """

    def xla(
        points: jax.Array | np.ndarray, points_sq: jax.Array | np.ndarray, x: jax.Array
    ) -> tuple[jax.Array, jax.Array]:
        return jax.vmap(lambda p, s, q: nearest(p, s, q, n))(points, points_sq, x)

    if n > _knn_pallas.SLOTS or resolve_impl(impl) is Impl.XLA:
        return xla(points, points_sq, x)
    valid = jnp.isfinite(points_sq)
    return _knn_pallas.knn(
        points, valid, x, n, interpret=pallas_interpret(), prune=prune, index=index
    )


def smallest(values: jax.Array, n: int) -> tuple[jax.Array, jax.Array]:
    """The ``n`` smallest entries of each row, smallest first (exact).

    Args:
      values: ``(..., R)`` rows.
      n: how many (static), ``n <= R``.

    Returns:
      ``(pos, val)``: ``(..., n)`` int32 positions in the row and their values. Exactly tied
      values may come in either order. ``lax.top_k`` on CPUs; repeated minima on other
      platforms for ``n <= SELECT_MAX`` (see the module doc).
    """

    def by_top_k(v: jax.Array) -> tuple[jax.Array, jax.Array]:
        neg, pos = jax.lax.top_k(-v, n)
        return pos.astype(jnp.int32), -neg

    if n > SELECT_MAX:
        return by_top_k(values)
    return jax.lax.platform_dependent(values, cpu=by_top_k, default=_repeated_min(n))


def _repeated_min(n: int):
    """``n`` rounds of (argmin of the row, then mask that entry with ``+inf``)."""

    def select(v: jax.Array) -> tuple[jax.Array, jax.Array]:
        cols = jax.lax.broadcasted_iota(jnp.int32, v.shape, v.ndim - 1)
        pos, val = [], []
        for _ in range(n):
            i = jnp.argmin(v, axis=-1).astype(jnp.int32)
            pos.append(i)
            val.append(jnp.take_along_axis(v, i[..., None], axis=-1)[..., 0])
            v = jnp.where(cols == i[..., None], jnp.inf, v)
        return jnp.stack(pos, axis=-1), jnp.stack(val, axis=-1)

    return select
