"""Fused exact k-nearest-neighbour search on CUDA GPUs: one Pallas (Triton) kernel.

``search.nearest_rows`` calls it with ``impl="pallas"`` (the default on CUDA GPUs,
``jaxproj.projection.ops.Impl``); ``impl="xla"`` runs the XLA search (``search.nearest``). The
kernel does, per program (``ROWS`` query rows of one landmark set):

1. distances ``|x - p|^2`` (computed directly, coordinate by coordinate) to every landmark, a
   tile of ``TILE_BLOCKS * BLOCK`` landmarks at a time, reduced at once to the minimum of each
   block of ``BLOCK`` landmarks (written to a scratch output: the ``(rows, K)`` distance matrix is
   never stored); the block count is padded to a power of two (Triton's shapes), but only the
   tiles that hold a landmark are computed, the rest get ``EMPTY`` (a set of 10,618 landmarks
   pads to 16,384: 83 of 128 tiles computed);
2. the ``n`` blocks with the smallest minima, by ``n`` rounds of (minimum, mask);
3. the distances to the ``n * BLOCK`` landmarks of those blocks, recomputed with the same
   arithmetic, and their ``n`` smallest, nearest first, by ``n`` more rounds.

Exact for the same reason as the XLA two-stage search (``search`` module doc): the ``n`` nearest
lie in the ``n`` blocks with the smallest minima. Ties at exactly equal distances may resolve to
either landmark. The XLA search expands ``|x|^2 + |p|^2 - 2 x.p``, which rounds differently:
where two landmarks lie within float32 round-off of the ``n``-th distance the two searches may
keep different ones (the direct form is the more accurate; both are checked against the float64
reference in ``benchmarks/``). Measured on an H200 on the per-chain model's real candidate rows
(3 chains, 655,360 rows each, n = 10; ``benchmarks/experiments/fused_knn_ab.py``): 175 against
383 ns per pose for the XLA search, the same neighbour sets on 99.999 % of rows, and the relaxed
projection's answers identical on all 65,536 poses.
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import pallas as pl

ROWS = 16
"""Query rows per program (swept on an H100: 16 rows, 8-block tiles, 4 warps was fastest)."""

BLOCK = 16
"""Landmarks per block of the two-stage selection (doubled, with ``TILE_BLOCKS``, for a set
of more than ``MAX_BLOCKS * BLOCK`` landmarks)."""

MAX_BLOCKS = 512
"""Most blocks the selection scans: a larger set gets larger blocks. Swept on one H100
(2026-11-26, ``benchmarks/experiments/knn_sweep.py``, 655,360 rows, n = 10, ns per pose): the
NAO's right arm (10,617 landmarks: 1,024 blocks of 16) 351 with blocks of 16 in tiles of 8,
294 with blocks of 32 in tiles of 16; sets of up to 8,192 landmarks (the NAO's head and left
arm, a G1 leg) were fastest with blocks of 16 in tiles of 8 (41.8 / 192.6 / 163.3 against
98.6 / 212.1 / 187.5 with 32 / 16)."""

TILE_BLOCKS = 8
"""Blocks per tile of the distance pass."""

SLOTS = 16
"""Width of the selection registers: the largest ``n`` the kernel serves."""

WARPS = 4

SKIP_EMPTY_TILES = True
"""Compute only the distance tiles that hold a landmark (``False``: every tile of the
power-of-two padding, as before 2026-11-26; read when a search is traced, for A/B runs:
``benchmarks/experiments/split_ab.py --knn-ab``)."""

FAR = 1e18
"""Coordinate of padding landmarks (and of the blocks padding ``K`` up to a power of two): far
but finite, so their squared distances (~1e36) stay below the ``+inf`` that marks a landmark or
block already chosen, and a chosen one is never chosen again."""


EMPTY = 1e38
"""Block minimum written for the tiles that hold padding only (``nt`` onwards): above every
padding landmark's distance (at most ``d * FAR**2`` = 1.8e37 for ``d <= 18``), below ``+inf``;
such a block is chosen only after every block holding a landmark."""


def _pow2(v: int) -> int:
    p = 1
    while p < v:
        p *= 2
    return p


def _kernel(
    x_ref, p_ref, pf_ref, idx_ref, d_ref, bm_ref, *, n: int, d: int, nb: int, nt: int,
    block: int, tb: int, sync: bool,
):  # fmt: skip
    xs = [x_ref[:, j] for j in range(d)]  # (ROWS,) per coordinate

    def tile(t: jax.Array, carry: int) -> int:
        s = pl.multiple_of(t * tb, tb)
        d2 = jnp.zeros((ROWS, tb, block), jnp.float32)
        for j in range(d):
            diff = xs[j][:, None, None] - p_ref[j, pl.ds(s, tb), :][None]
            d2 = d2 + diff * diff
        bm_ref[:, pl.ds(s, tb)] = jnp.min(d2, axis=2)
        return carry

    def empty(t: jax.Array, carry: int) -> int:  # tiles of padding only: no distances
        s = pl.multiple_of(t * tb, tb)
        bm_ref[:, pl.ds(s, tb)] = jnp.full((ROWS, tb), EMPTY, jnp.float32)
        return carry

    jax.lax.fori_loop(0, nt, tile, 0)
    if nt < nb // tb:
        jax.lax.fori_loop(nt, nb // tb, empty, 0)
    if sync:  # the block minima were written by other threads of this program
        from jax.experimental.pallas import triton as plgpu

        plgpu.debug_barrier()
    bm = bm_ref[...]  # (ROWS, nb)
    cols = jax.lax.broadcasted_iota(jnp.int32, (ROWS, nb), 1)
    slots = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS), 1)
    blk = jnp.zeros((ROWS, SLOTS), jnp.int32)
    for r in range(n):  # a chosen block is masked with +inf, above every real or padding minimum
        m = jnp.min(bm, axis=1)
        pos = jnp.min(jnp.where(bm == m[:, None], cols, nb), axis=1)
        pos = jnp.minimum(pos, nb - 1)  # a NaN row matches no column: keep its loads in bounds
        blk = jnp.where(slots == r, pos[:, None], blk)
        bm = jnp.where(cols == pos[:, None], jnp.inf, bm)
    member = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS, block), 2)
    slot3 = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS, block), 1)
    pidx = blk[:, :, None] * block + member  # (ROWS, SLOTS, block) landmark indices
    d2 = jnp.zeros((ROWS, SLOTS, block), jnp.float32)
    for j in range(d):
        diff = xs[j][:, None, None] - pf_ref[j, pidx]
        d2 = d2 + diff * diff
    width = SLOTS * block
    d2 = jnp.where(slot3 < n, d2, jnp.inf).reshape(ROWS, width)
    pidx = pidx.reshape(ROWS, width)
    c2 = jax.lax.broadcasted_iota(jnp.int32, (ROWS, width), 1)
    out_v = jnp.full((ROWS, SLOTS), jnp.inf, jnp.float32)
    out_i = jnp.zeros((ROWS, SLOTS), jnp.int32)
    for r in range(n):
        m = jnp.min(d2, axis=1)
        pos = jnp.min(jnp.where(d2 == m[:, None], c2, width), axis=1)
        pos = jnp.minimum(pos, width - 1)
        sel = c2 == pos[:, None]
        i = jnp.sum(jnp.where(sel, pidx, 0), axis=1)
        out_v = jnp.where(slots == r, m[:, None], out_v)
        out_i = jnp.where(slots == r, i[:, None], out_i)
        d2 = jnp.where(sel, jnp.inf, d2)
    idx_ref[...] = out_i
    d_ref[...] = out_v


def knn(
    points: jax.Array | np.ndarray,
    valid: jax.Array,
    x: jax.Array,
    n: int,
    interpret: bool = False,
) -> tuple[jax.Array, jax.Array]:
    """Exact ``n`` nearest landmarks of every row, per landmark set (traceable).

    Args:
      points: ``(C, K, d)`` float32 landmark sets.
      valid: ``(C, K)`` bool, ``False`` for padding landmarks (never returned while ``n`` valid
        ones exist). Finite query rows must lie far below ``FAR``; a non-finite row gets
        indices inside the padded landmark array (its answer is meaningless, nothing is read
        out of bounds).
      x: ``(C, R, d)`` float32 query rows.
      n: how many (static), ``1 <= n <= SLOTS``.
      interpret: run the kernel in Pallas' interpreter (any platform; for tests).

    Returns:
      ``(idx, d2)``: ``(C, R, n)`` int32 indices, nearest first, and squared distances.
    """
    if not 1 <= n <= SLOTS:
        raise ValueError(f"n={n} must lie in [1, {SLOTS}]")
    c, k, d = points.shape
    r = x.shape[1]
    block, tb = BLOCK, TILE_BLOCKS
    while _pow2(-(-k // block)) > MAX_BLOCKS:  # the selection scans every block n times
        block, tb = 2 * block, 2 * tb
    nb = max(_pow2(-(-k // block)), tb, _pow2(n))  # at least n blocks to choose from
    kp = nb * block
    rp = -(-r // ROWS) * ROWS
    pts = jnp.where(valid[..., None], points.astype(jnp.float32), FAR)
    pt = jnp.full((c, d, kp), FAR, jnp.float32).at[:, :, :k].set(pts.transpose(0, 2, 1))
    xp = jnp.zeros((c, rp, d), jnp.float32).at[:, :r].set(x.astype(jnp.float32))
    nt = -(-k // (tb * block)) if SKIP_EMPTY_TILES else nb // tb
    kern = functools.partial(
        _kernel, n=n, d=d, nb=nb, nt=nt, block=block, tb=tb, sync=not interpret
    )
    params: dict[str, Any] = {}
    if not interpret:
        from jax.experimental.pallas import triton as plgpu

        params = dict(compiler_params=plgpu.CompilerParams(num_warps=WARPS))
    idx, d2, _ = pl.pallas_call(
        kern,
        grid=(c, rp // ROWS),
        in_specs=[
            pl.BlockSpec((None, ROWS, d), lambda ci, b: (ci, b, 0)),
            pl.BlockSpec((None, d, nb, block), lambda ci, b: (ci, 0, 0, 0)),
            pl.BlockSpec((None, d, kp), lambda ci, b: (ci, 0, 0)),
        ],
        out_specs=[
            pl.BlockSpec((None, ROWS, SLOTS), lambda ci, b: (ci, b, 0)),
            pl.BlockSpec((None, ROWS, SLOTS), lambda ci, b: (ci, b, 0)),
            pl.BlockSpec((None, ROWS, nb), lambda ci, b: (ci, b, 0)),
        ],
        out_shape=[
            jax.ShapeDtypeStruct((c, rp, SLOTS), jnp.int32),
            jax.ShapeDtypeStruct((c, rp, SLOTS), jnp.float32),
            jax.ShapeDtypeStruct((c, rp, nb), jnp.float32),
        ],
        interpret=interpret,
        **params,
    )(xp, pt.reshape(c, d, nb, block), pt)
    return idx[:, :r, :n], d2[:, :r, :n]
