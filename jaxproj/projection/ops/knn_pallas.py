"""Fused exact k-nearest-neighbour search on CUDA GPUs: Pallas (Triton) kernels.

Size: over 500 lines on purpose: one exact search in two kernels, the full scan and the pruned
pass (``knn_pruned``) whose uncertified rows fall back to it, sharing its constants, its
selection code and the dispatch (``knn``).

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
from collections.abc import Callable
from dataclasses import dataclass, field
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
default robot's right arm (10,617 landmarks: 1,024 blocks of 16) 351 with blocks of 16 in tiles
of 8, 294 with blocks of 32 in tiles of 16; sets of up to 8,192 landmarks (the default robot's
head and left arm, a leg of another bundled robot) were fastest with blocks of 16 in tiles of 8
(41.8 / 192.6 / 163.3 against 98.6 / 212.1 / 187.5 with 32 / 16)."""

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


def _row_pad(a: jax.Array, size: int, fill: float, axis: int = 1) -> jax.Array:
    """``a`` padded with ``fill`` to ``size`` along ``axis`` (``lax.pad``; ``a`` itself where it
    is that size). Not ``jnp.full(...).at[...].set(a)``: on several GPUs under ``jax.shard_map``,
    where that scatter covers the whole array XLA removes it and its zero-sized index constant,
    captured into the ``shard_map`` body, is left unused there; the partitioner (Shardy) then
    segfaults while compiling (jax 0.11.2, 2 H200s, 2026-11-30: the ``zero_padx`` case of
    ``benchmarks/experiments/pallas_shard_map.py``)."""
    if a.shape[axis] == size:
        return a
    widths = [(0, 0)] * a.ndim
    widths[axis] = (0, size - a.shape[axis])
    return jnp.pad(a, widths, constant_values=fill)


def _gathered_d2(xs: list[jax.Array], pf_ref: Any, pidx: jax.Array) -> jax.Array:
    """``|x - p|^2`` of each row ``x`` (``xs``: ``d`` coordinates, ``(ROWS,)`` each) to the
    landmarks ``pidx`` (``(ROWS, S, B)`` indices into ``pf_ref``, ``(d, K)``), coordinate by
    coordinate in one fixed order (both kernels' selections, so that they round alike)."""
    d2 = jnp.zeros(pidx.shape, jnp.float32)
    for j, xj in enumerate(xs):
        diff = xj[:, None, None] - pf_ref[j, pidx]
        d2 = d2 + diff * diff
    return d2


def _tiles(
    ref: Any, width: int, nt: int, total: int, compute: Callable[[Any], jax.Array], fill: Any
) -> None:
    """``ref[:, tile] = compute(start)`` for the first ``nt`` of ``total`` tiles of ``width``
    columns, ``fill`` for the rest (tiles of padding only: nothing computed)."""

    def tile(t: jax.Array, carry: int) -> int:
        s = pl.multiple_of(t * width, width)
        ref[:, pl.ds(s, width)] = compute(s)
        return carry

    def empty(t: jax.Array, carry: int) -> int:
        s = pl.multiple_of(t * width, width)
        ref[:, pl.ds(s, width)] = jnp.full((ref.shape[0], width), fill, ref.dtype)
        return carry

    jax.lax.fori_loop(0, nt, tile, 0)
    if nt < total:
        jax.lax.fori_loop(nt, total, empty, 0)


def _barrier(sync: bool) -> None:
    """With ``sync`` (compiled, not interpreted): wait until every thread of the program has
    written its part of the scratch memory the next step reads."""
    if sync:
        from jax.experimental.pallas import triton as plgpu

        plgpu.debug_barrier()


def _params(interpret: bool, warps: int) -> dict[str, Any]:
    """``pallas_call``'s compiler parameters: ``warps`` per program on a GPU."""
    if interpret:
        return {}
    from jax.experimental.pallas import triton as plgpu

    return dict(compiler_params=plgpu.CompilerParams(num_warps=warps))


def _kernel(
    x_ref, p_ref, pf_ref, idx_ref, d_ref, bm_ref, *, n: int, d: int, nb: int, nt: int,
    block: int, tb: int, sync: bool,
):  # fmt: skip
    xs = [x_ref[:, j] for j in range(d)]  # (ROWS,) per coordinate

    def minima(s: Any) -> jax.Array:  # the block minima of one tile of landmarks
        d2 = jnp.zeros((ROWS, tb, block), jnp.float32)
        for j in range(d):
            diff = xs[j][:, None, None] - p_ref[j, pl.ds(s, tb), :][None]
            d2 = d2 + diff * diff
        return jnp.min(d2, axis=2)

    _tiles(bm_ref, tb, nt, nb // tb, minima, EMPTY)
    _barrier(sync)  # the block minima were written by other threads of this program
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
    d2 = _gathered_d2(xs, pf_ref, pidx)
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


def knn_full(
    points: jax.Array | np.ndarray,
    valid: jax.Array,
    x: jax.Array,
    n: int,
    interpret: bool = False,
) -> tuple[jax.Array, jax.Array]:
    """Exact ``n`` nearest landmarks of every row, per landmark set, by a full scan (traceable).

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
    pt = _row_pad(pts.transpose(0, 2, 1), kp, FAR, axis=2)
    xp = _row_pad(x.astype(jnp.float32), rp, 0.0)
    nt = -(-k // (tb * block)) if SKIP_EMPTY_TILES else nb // tb
    kern = functools.partial(
        _kernel, n=n, d=d, nb=nb, nt=nt, block=block, tb=tb, sync=not interpret
    )
    params = _params(interpret, WARPS)
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
        name="knn_full",
        **params,
    )(xp, pt.reshape(c, d, nb, block), pt)
    return idx[:, :r, :n], d2[:, :r, :n]


# --- the pruned search -------------------------------------------------------------------------

PRUNE = True
"""``knn`` runs the pruned search (``knn_pruned``) first and the full scan only for the rows
its certificate fails (``False``: the full scan for every row; read when a search is traced,
for A/B runs)."""

PRUNE_VISIT = 16
"""Blocks of the spatial order whose landmarks the pruned search measures per row. 8 until
2026-11-26, when the pruned pass measured one block at a time (``PRUNE_TILED``): then 16
certified 99.98-100 % of the default robot's arm rows against 92-93 % (one H100, ``python -m
benchmarks.experiments.knn_prune_ab --chains left_arm,right_arm --blocks 64,128 --visits 8,16
--shares 8,16``, ``knn_prune_arms_h100.json``; ns per pose with the fallback, left / right arm:
77.4 / 97.2 with 8 blocks, 61.8 / 95.4 with 16, the right arm's rest the fallback's capacity:
``FALLBACK_SMALL_SHARE``); blocks of 64 certified fewer (83 % with 8, 99.4-99.8 % with 16)."""

PRUNE_BLOCK = 128
"""Landmarks per block of the spatial order (a power of two, at least ``BLOCK``). With
``PRUNE_VISIT``, swept on one H100 on the default robot's default model's real robot-search rows
(``benchmarks/experiments/knn_prune_ab.py``, ``knn_prune_ab_h100.json``): 128 x 8 was fastest
on both arms (certified 92-93 % of rows); fewer visited landmarks certify too few rows, more
cost more in the pruned pass than they save in the fallback."""

PRUNE_MIN_LANDMARKS = 4096
"""Sets from this size prune with blocks of ``PRUNE_BLOCK``; smaller ones take the full scan,
except those the pruned kernel covers whole (``PRUNE_SMALL_BLOCK``). On the default robot's head
(1,010 landmarks) pruning with blocks of 128 was no faster (40-85 against 41 ns per pose on one
H100, before ``PRUNE_TILED``). Lowered to 2,048 another bundled robot's five chains all prune
(1,022 -> 821 ns per pose, one H100), but that run judged 1 of 300 checked poses outside the
near-tie rule, unexplained: not changed."""

PRUNE_SMALL_BLOCK = 64
"""Landmarks per block for a set of at most ``PRUNE_VISIT * PRUNE_SMALL_BLOCK`` landmarks
(1,024: the default robot's head; that other robot's default chains, ~4,000 each, are not
affected): the pruned
kernel then visits every block, so every row is certified (no fallback runs) and its answers
are the full scan's; it serves as a faster full scan (``PRUNE_SMALL_ROWS`` rows a program, against
the full scan's 16). The head's robot search 41 -> 33 ns per pose (one H100, 2026-11-26,
``knn_prune_head_h100.json``, then 8 rows on 8 warps); in the engine, the head's robot search
44.4 -> 37.2 ns (``stage_split_2026-11-27_h100.json``, another H100, 2026-11-27), 24.7 with 2
rows on 1 warp (``prune_shape``; a third H100, the same day). Sets between this and
``PRUNE_MIN_LANDMARKS`` take the full scan."""


def prune_block(k: int) -> int | None:
    """Landmarks per block of the pruned search on sets of ``k`` landmarks, ``None`` where the
    full scan serves them (``PRUNE_MIN_LANDMARKS``, ``PRUNE_SMALL_BLOCK``)."""
    if k >= PRUNE_MIN_LANDMARKS:
        return PRUNE_BLOCK
    if k <= PRUNE_VISIT * PRUNE_SMALL_BLOCK:
        return PRUNE_SMALL_BLOCK
    return None


PRUNE_LB_TILE = 32
"""Blocks per tile of the pruned search's lower-bound pass."""

PRUNE_ROWS = 4
"""Query rows per program of the pruned pass with blocks of ``PRUNE_BLOCK`` (the full scan's are
``ROWS``; 8 until 2026-11-27). Swept with ``PRUNE_WARPS`` on one H100 (2026-11-27, the pruned pass
alone on the default robot's default model's real robot-search rows of 8,192 held-out poses tiled to
655,360, ns per pose; rows x warps): right arm 54.1 (8 x 8), 62.6 (8 x 4), **52.0 (4 x 4)**,
60.5 (4 x 2), 50.9 (2 x 2), 53.8 (2 x 1), 57.6 (1 x 1), 60.5 (16 x 8); left arm 50.4 (8 x 8),
**46.9 (4 x 4)**, 64.3 (4 x 2), 49.9 (2 x 2), 47.8 (2 x 1), 55.3 (1 x 1); the same certified
rows and answers in every shape. The compiled kernel of 8 x 8 synchronises the program 138 times
(Triton spreads a row's selection over several warps), but fewer barriers were not faster by
themselves (1 warp: 5 barriers, 57.6 / 55.3)."""

PRUNE_WARPS = 4
"""Warps per program of the pruned pass with blocks of ``PRUNE_BLOCK`` (8 until 2026-11-27)."""

PRUNE_SMALL_ROWS = 2
"""Query rows per program of the pruned pass on a set it covers whole (blocks of
``PRUNE_SMALL_BLOCK``: the default robot's head). Same sweep as ``PRUNE_ROWS``, the head's
1,010 robot landmarks: 38.4 (8 x 8), 35.6 (4 x 4), 35.9 (2 x 2), **27.6 (2 x 1)**, 41.8 (1 x 1)."""

PRUNE_SMALL_WARPS = 1
"""Warps per program of the pruned pass on a set it covers whole (``PRUNE_SMALL_ROWS``)."""


def prune_shape(block: int) -> tuple[int, int]:
    """``(rows, warps)`` per program of the pruned pass with blocks of ``block`` landmarks."""
    if block == PRUNE_SMALL_BLOCK and block != PRUNE_BLOCK:
        return PRUNE_SMALL_ROWS, PRUNE_SMALL_WARPS
    return PRUNE_ROWS, PRUNE_WARPS


PRUNE_SUB = BLOCK
"""Landmarks per sub-block inside a visited block (the pruned pass's two-stage selection)."""

PRUNE_TILED = True
"""The pruned pass measures its visited blocks one at a time (``(rows, PRUNE_BLOCK)``
distances live at once) instead of all together (``(rows, PRUNE_VISIT * PRUNE_BLOCK)``; read
when a search is traced, for A/B runs). With ``PRUNE_ROWS`` and ``PRUNE_WARPS``, swept on one
H100 on the default robot's default model's real robot-search rows (2026-11-26, blocks of 128, 8
visited, ``python -m benchmarks.experiments.knn_prune_ab --chains left_arm,right_arm --blocks 128
--visits 8 --rows 8,16,32 --warps 4,8 --tiled 0,1``, ``knn_prune_grid_h100.json``), ns per
pose with the fallback: left arm 133.9 -> 75.4, right arm 156.2 -> 96.3 (16 rows, 4 warps, all
together -> 8 rows, 8 warps, one block at a time; the pruned pass alone 108 -> 51 and 120 ->
60), the same certified rows and answers. All together, each thread held the distances of
``16 * 1,024`` landmarks over 128 threads."""

FALLBACK_SHARE = 16
"""The full scan for the rows that fail the certificate runs on a fixed capacity of rows per
set (static shapes): ``rows / FALLBACK_SMALL_SHARE`` where that many suffice, else ``rows /
FALLBACK_SHARE``; more failing rows than that: on all."""

FALLBACK_SMALL_SHARE = 128
"""The smaller capacity of the fallback (``FALLBACK_SHARE``): with 16 blocks visited, 0-0.02 %
of the default robot's default model's robot-search rows failed the certificate (one H100,
2026-11-26, ``knn_prune_arms_h100.json``), where a capacity of a sixteenth of the rows cost the
right arm 25 ns per pose."""

_KEY_MAX = np.int32(2**31 - 1)


def kd_order(points: jax.Array, valid: jax.Array, block: int) -> jax.Array:
    """``(C, K)`` permutations putting each set's landmarks in a balanced k-d order: split at a
    multiple of ``block`` landmarks along the widest axis, recursively, until one block each
    (traceable; ``ceil(log2(K / block))`` sorts). Padding (``valid`` false) sorts to the end of
    the part it is in."""
    c, k, _ = points.shape
    segs = [(0, k)]
    levels = []
    while any(b - a > block for a, b in segs):
        ids = np.empty(k, np.int32)
        nxt = []
        for i, (a, b) in enumerate(segs):
            ids[a:b] = i
            nblk = -(-(b - a) // block)
            if nblk > 1:
                m = a + block * (-(-nblk // 2))
                nxt += [(a, m), (m, b)]
            else:
                nxt.append((a, b))
        levels.append((ids, len(segs)))
        segs = nxt

    def one(p: jax.Array, v: jax.Array) -> jax.Array:
        perm = jnp.arange(k, dtype=jnp.int32)
        for ids, ns in levels:
            q, w = p[perm], v[perm]
            seg = jnp.asarray(ids)
            lo = jax.ops.segment_min(jnp.where(w[:, None], q, jnp.inf), seg, ns)
            hi = jax.ops.segment_max(jnp.where(w[:, None], q, -jnp.inf), seg, ns)
            axis = jnp.argmax(hi - lo, axis=1)[seg]  # each landmark's part's widest axis
            key = jnp.where(w, jnp.take_along_axis(q, axis[:, None], axis=1)[:, 0], jnp.inf)
            _, _, perm = jax.lax.sort((seg, key, perm), num_keys=2)
        return perm

    return jax.vmap(one)(points, valid)


def _pruned_kernel(
    x_ref, lo_ref, hi_ref, pf_ref, idx_ref, d_ref, ok_ref, key_ref, bm_ref, *, n: int, d: int,
    nb: int, nt: int, block: int, sub: int, lbt: int, visit: int, sync: bool, rows: int,
    tiled: bool,
):  # fmt: skip
    ROWS = rows  # noqa: N806 - this kernel's rows per program (``prune_shape``)
    xs = [x_ref[:, j] for j in range(d)]  # (ROWS,) per coordinate
    low = nb - 1  # the key's low bits: the block's column

    def keys(s: Any) -> jax.Array:  # the blocks' lower bounds, with their columns
        lb = jnp.zeros((ROWS, lbt), jnp.float32)
        for j in range(d):
            xj = xs[j][:, None]
            g = jnp.maximum(jnp.maximum(lo_ref[j, pl.ds(s, lbt)][None] - xj,
                                        xj - hi_ref[j, pl.ds(s, lbt)][None]), 0.0)  # fmt: skip
            lb = lb + g * g
        cols = s + jax.lax.broadcasted_iota(jnp.int32, (ROWS, lbt), 1)
        bits = jax.lax.bitcast_convert_type(lb, jnp.int32)  # >= 0: ordered as the floats
        return (bits & ~low) | cols  # rounded down: still a lower bound

    _tiles(key_ref, lbt, nt, nb // lbt, keys, _KEY_MAX)
    _barrier(sync)
    key = key_ref[...]  # (ROWS, nb): unique per row (the column is in the low bits)
    per = block // sub  # sub-blocks per visited block
    ns = visit * per
    scol = jax.lax.broadcasted_iota(jnp.int32, (ROWS, ns), 1)
    gid = jnp.zeros((ROWS, ns), jnp.int32)  # the sub-blocks of the visited blocks
    visited = []
    for r in range(visit):
        m = jnp.min(key, axis=1)
        visited.append(m & low)
        gid = jnp.where(scol // per == r, (m & low)[:, None] * per + scol % per, gid)
        key = jnp.where(key == m[:, None], _KEY_MAX, key)
    nxt = jnp.min(key, axis=1)  # the least lower bound of the blocks not visited
    bound = jax.lax.bitcast_convert_type(nxt & ~low, jnp.float32)
    # inside the visited blocks: the full search's two stages (sub-block minima, then the n
    # nearest inside the n sub-blocks with the smallest minima)
    if tiled:  # one visited block at a time: (ROWS, block) distances live at once, not all
        sb = jax.lax.broadcasted_iota(jnp.int32, (ROWS, per, sub), 1)
        member = jax.lax.broadcasted_iota(jnp.int32, (ROWS, per, sub), 2)
        for r, b in enumerate(visited):
            d2 = _gathered_d2(xs, pf_ref, b[:, None, None] * block + sb * sub + member)
            bm_ref[:, pl.ds(r * per, per)] = jnp.min(d2, axis=2)
        _barrier(sync)
        bm = bm_ref[...]  # (ROWS, ns)
    else:
        member = jax.lax.broadcasted_iota(jnp.int32, (ROWS, ns, sub), 2)
        d2 = _gathered_d2(xs, pf_ref, gid[:, :, None] * sub + member)
        bm = jnp.min(d2, axis=2)  # (ROWS, ns)
    slots = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS), 1)
    big = nb * per
    chosen = jnp.zeros((ROWS, SLOTS), jnp.int32)
    for r in range(n):
        m = jnp.min(bm, axis=1)
        g = jnp.min(jnp.where(bm == m[:, None], gid, big), axis=1)
        g = jnp.minimum(g, big - 1)  # a NaN row matches nothing: stay in bounds
        chosen = jnp.where(slots == r, g[:, None], chosen)
        bm = jnp.where(gid == g[:, None], jnp.inf, bm)
    member = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS, sub), 2)
    slot3 = jax.lax.broadcasted_iota(jnp.int32, (ROWS, SLOTS, sub), 1)
    pidx = chosen[:, :, None] * sub + member
    d2 = _gathered_d2(xs, pf_ref, pidx)
    width = SLOTS * sub
    d2 = jnp.where(slot3 < n, d2, jnp.inf).reshape(ROWS, width)
    pidx = pidx.reshape(ROWS, width)
    kp = nb * block
    out_v = jnp.full((ROWS, SLOTS), jnp.inf, jnp.float32)
    out_i = jnp.zeros((ROWS, SLOTS), jnp.int32)
    m = jnp.zeros((ROWS,), jnp.float32)
    for r in range(n):
        m = jnp.min(d2, axis=1)
        i = jnp.min(jnp.where(d2 == m[:, None], pidx, kp), axis=1)
        i = jnp.minimum(i, kp - 1)
        out_v = jnp.where(slots == r, m[:, None], out_v)
        out_i = jnp.where(slots == r, i[:, None], out_i)
        d2 = jnp.where(pidx == i[:, None], jnp.inf, d2)
    # the certificate: no block left unvisited can hold a landmark nearer than the n-th
    ok = (nxt == _KEY_MAX) | (m <= bound)
    idx_ref[...] = out_i
    d_ref[...] = out_v
    ok_ref[...] = jnp.where(ok[:, None], 1, 0) + jnp.zeros((ROWS, SLOTS), jnp.int32)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class PruneIndex:
    """What the pruned search needs of landmark sets that depends on the sets alone: their k-d
    order, the blocks' bounding boxes and the landmarks in that order, as the kernel reads them
    (``prune_index``; a pytree). Computed once per projector (``projector.with_search_index``)
    instead of in every traced call (1.09 / 1.40 ms a call on the default robot's arms, one H100).

    Attributes:
      order: ``(C, K)`` int32, ``kd_order``'s permutations.
      lo, hi: ``(C, d, nb)`` float32 per block and coordinate the least and greatest landmark
        coordinate (``FAR`` for a block of padding).
      pt: ``(C, d, nb * block)`` float32 the landmarks in the k-d order, ``FAR`` for padding.
      block: landmarks per block (``prune_block`` of the sets' size; static).
      lbt: blocks per tile of the lower-bound pass (``PRUNE_LB_TILE``; static).
    """

    order: jax.Array
    lo: jax.Array
    hi: jax.Array
    pt: jax.Array
    block: int = field(metadata=dict(static=True))
    lbt: int = field(metadata=dict(static=True))

    def fits(self, c: int, k: int, d: int) -> bool:
        """Whether this is an index of ``c`` sets of ``k`` landmarks of ``d`` coordinates for
        today's ``prune_block(k)`` and ``PRUNE_LB_TILE`` (static shapes only: that it was computed
        from the same landmarks is the caller's promise)."""
        nb = max(_pow2(-(-k // self.block)), self.lbt)
        return (
            self.block == prune_block(k)
            and self.lbt == PRUNE_LB_TILE
            and tuple(self.order.shape) == (c, k)
            and tuple(self.lo.shape) == tuple(self.hi.shape) == (c, d, nb)
            and tuple(self.pt.shape) == (c, d, nb * self.block)
        )


def prune_index(
    points: jax.Array | np.ndarray, valid: jax.Array | np.ndarray, block: int, lbt: int
) -> PruneIndex:
    """The ``PruneIndex`` of ``(C, K, d)`` landmark sets (``valid`` ``(C, K)``; traceable,
    ``block`` and ``lbt`` static). ``knn_pruned`` computes it in its trace when it is not given:
    the same operations, so the same arrays bit for bit."""
    c, k, d = points.shape
    nb = max(_pow2(-(-k // block)), lbt)
    kp = nb * block
    valid = jnp.asarray(valid)
    points = jnp.asarray(points, jnp.float32)
    order = kd_order(points, valid, block)  # (C, K)
    pts = jnp.where(valid[..., None], points, FAR)
    srt = jnp.take_along_axis(pts, order[..., None], axis=1)  # (C, K, d)
    ok_pt = jnp.take_along_axis(valid, order, axis=1)
    pad = jnp.full((c, kp - k, d), FAR, jnp.float32)
    blocks = jnp.concatenate([srt, pad], axis=1).reshape(c, nb, block, d)
    okb = jnp.concatenate([ok_pt, jnp.zeros((c, kp - k), bool)], axis=1).reshape(c, nb, block)
    lo = jnp.min(jnp.where(okb[..., None], blocks, jnp.inf), axis=2)  # (C, nb, d)
    hi = jnp.max(jnp.where(okb[..., None], blocks, -jnp.inf), axis=2)
    none = ~okb.any(axis=2)[..., None]
    lo, hi = jnp.where(none, FAR, lo), jnp.where(none, FAR, hi)  # a block of padding: far
    pt = blocks.reshape(c, kp, d).transpose(0, 2, 1)
    return PruneIndex(order, lo.transpose(0, 2, 1), hi.transpose(0, 2, 1), pt, block, lbt)


def knn_pruned(
    points: jax.Array | np.ndarray,
    valid: jax.Array,
    x: jax.Array,
    n: int,
    interpret: bool = False,
    index: PruneIndex | None = None,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """The pruned search alone: ``(idx, d2, ok)``, ``ok`` (``(C, R)`` bool) where the answer is
    certified exact (``knn``'s arguments; ``idx`` in the landmarks' own order). Not certified
    rows hold some landmarks, not necessarily the nearest. ``index``: these sets'
    ``prune_index``, computed beforehand (used where it ``fits``; otherwise, or ``None``,
    computed here, in the trace)."""
    if not 1 <= n <= SLOTS:
        raise ValueError(f"n={n} must lie in [1, {SLOTS}]")
    c, k, d = points.shape
    r = x.shape[1]
    block = prune_block(k) or PRUNE_BLOCK
    lbt, sub = PRUNE_LB_TILE, min(PRUNE_SUB, block)
    rows, warps = prune_shape(block)
    nblk = -(-k // block)
    nb = max(_pow2(nblk), lbt)
    visit = max(min(PRUNE_VISIT, _pow2(nblk)), _pow2(-(-n // (block // sub))))
    kp = nb * block
    rp = -(-r // rows) * rows
    if index is None or not index.fits(c, k, d):
        index = prune_index(points, valid, block, lbt)
    order = index.order
    xp = _row_pad(x.astype(jnp.float32), rp, 0.0)
    nt = -(-nblk // lbt)
    ns = visit * (block // sub)
    kern = functools.partial(_pruned_kernel, n=n, d=d, nb=nb, nt=nt, block=block, sub=sub,
                             lbt=lbt, visit=visit, sync=not interpret, rows=rows,
                             tiled=PRUNE_TILED)  # fmt: skip
    params = _params(interpret, warps)
    row = pl.BlockSpec((None, rows, SLOTS), lambda ci, b: (ci, b, 0))
    idx, d2, ok, _, _ = pl.pallas_call(
        kern,
        grid=(c, rp // rows),
        in_specs=[
            pl.BlockSpec((None, rows, d), lambda ci, b: (ci, b, 0)),
            pl.BlockSpec((None, d, nb), lambda ci, b: (ci, 0, 0)),
            pl.BlockSpec((None, d, nb), lambda ci, b: (ci, 0, 0)),
            pl.BlockSpec((None, d, kp), lambda ci, b: (ci, 0, 0)),
        ],
        out_specs=[
            row,
            row,
            row,
            pl.BlockSpec((None, rows, nb), lambda ci, b: (ci, b, 0)),
            pl.BlockSpec((None, rows, ns if PRUNE_TILED else 1), lambda ci, b: (ci, b, 0)),
        ],
        out_shape=[
            jax.ShapeDtypeStruct((c, rp, SLOTS), jnp.int32),
            jax.ShapeDtypeStruct((c, rp, SLOTS), jnp.float32),
            jax.ShapeDtypeStruct((c, rp, SLOTS), jnp.int32),
            jax.ShapeDtypeStruct((c, rp, nb), jnp.int32),
            jax.ShapeDtypeStruct((c, rp, ns if PRUNE_TILED else 1), jnp.float32),
        ],
        interpret=interpret,
        name="knn_pruned",
        **params,
    )(xp, index.lo, index.hi, index.pt)
    pos = jnp.minimum(idx[:, :r, :n], k - 1)  # a position of padding is no landmark's
    own = jnp.take_along_axis(order, pos.reshape(c, -1), axis=1).reshape(pos.shape)
    return own, d2[:, :r, :n], ok[:, :r, 0] == 1


def knn(
    points: jax.Array | np.ndarray,
    valid: jax.Array,
    x: jax.Array,
    n: int,
    interpret: bool = False,
    prune: bool = False,
    index: PruneIndex | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Exact ``n`` nearest landmarks of every row, per landmark set (traceable).

    With ``prune`` (and ``PRUNE``, and a set size that ``prune_block`` prunes) the pruned search
    (``knn_pruned``) answers every row its certificate holds for, and the full scan
    (``knn_full``) the others: on a capacity of ``rows / FALLBACK_SMALL_SHARE`` or ``rows /
    FALLBACK_SHARE`` rows per set (the smaller where it holds them all), on every row where more
    fail. Otherwise the full scan. The same arguments and answers as
    ``knn_full`` (ties at exactly equal distances may resolve to either landmark). Pruning pays
    where the rows lie near the landmarks (the relaxed projection's robot search: candidates
    predicted from the robot landmarks' kernels), not for rows far from them (all fail).
    ``index``: the sets' ``prune_index`` computed beforehand (``knn_pruned``), the same answers.
    """
    if not (prune and PRUNE and prune_block(points.shape[1]) is not None):
        return knn_full(points, valid, x, n, interpret)
    idx, d2, ok = knn_pruned(points, valid, x, n, interpret, index)
    c, r = ok.shape
    bad = ~ok
    worst = jnp.max(jnp.sum(bad, axis=1))

    def some(cap: int) -> Callable[[], tuple[jax.Array, jax.Array]]:
        def run() -> tuple[jax.Array, jax.Array]:
            (rows,) = jax.vmap(lambda b: jnp.nonzero(b, size=cap, fill_value=r))(bad)
            take = jnp.minimum(rows, r - 1)
            xs = jnp.take_along_axis(x, take[..., None], axis=1)
            i2, v2 = knn_full(points, valid, xs, n, interpret)
            put = jax.vmap(lambda a, rw, b: a.at[rw].set(b, mode="drop"))
            return put(idx, rows, i2), put(d2, rows, v2)

        return run

    def every() -> tuple[jax.Array, jax.Array]:
        return knn_full(points, valid, x, n, interpret)

    caps = sorted({min(-(-max(r // share, 1) // ROWS) * ROWS, r)
                   for share in (FALLBACK_SHARE, FALLBACK_SMALL_SHARE)})  # fmt: skip
    branch = every
    for cap in reversed(caps):  # the smallest capacity that holds every failing row
        branch = functools.partial(jax.lax.cond, worst <= cap, some(cap), branch)
    return jax.lax.cond(worst == 0, lambda: (idx, d2), branch)
