"""A negative result kept runnable: the relaxed back-projection with one program per query
(issue 46, item 1), each of the query's distinct landmarks' kernels read once.

``backproj_pallas.back_min`` runs 16 candidate rows a program and gathers, for each row and
slot, that row's kernel: a query's 100 (candidate, landmark) pairs of a chain read 100 kernels'
weights, though they touch ~13 distinct landmarks (``grouped_cpu``). ``back_min_shared`` runs
one program per query: it walks the query's distinct kernel indices in increasing order (each
next one the least index above the last, one reduction over the ``(L, M)`` index tile), reads
each kernel's weights once and evaluates it on all ``L`` candidates (padded to a power of two),
keeping each candidate's least deviation over its own kernels. Its deviations are bit-identical
to ``back_min``'s on a GPU (the same arithmetic per pair; its weights are gathered as
``(rows, width)`` tiles of one address per column, so that Triton gives them the index tile's
layout: a broadcast row-vector load cost 36 layout conversions per kernel).

Measured on one H100 (2026-11-27, NAO default model, batch 65,536,
``python -m benchmarks.experiments.backproj_variants_ab --variants knn_8x8,default,shared``,
``results/backproj_variants_2026-11-27_h100.json``): the back-projection 107.2 -> 214.6 ns per
pose, the core 277.5 -> 384.1; 7.6x fewer weights read, 2x slower. Not used by the engine:
reading the weights is not what binds ``back_min``. ``backproj_variants_ab``'s ``shared``
variant runs it in the engine's place (``use``).
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import pallas as pl

from jaxproj.projection import relaxed
from jaxproj.projection.elm import ELMBank
from jaxproj.projection.ops import backproj_pallas

L = 10
"""Candidates per query of the engine's relaxed default (``use`` regroups its rows by it)."""

SHARED_WARPS = 4

_NONE = np.int32(2**31 - 1)
"""Kernel index of a slot that holds none (the padding of ``L`` and ``M`` to powers of two)."""


def _shared_kernel(
    r_ref,
    h_ref,
    idx_ref,
    w_ref,
    inv_ref,
    bias_ref,
    out_ref,
    off_ref,
    best_ref,
    *,
    d_in: int,
    d_out: int,
    rows: int,
    chunks: tuple[tuple[int, int], ...],
    fast: bool,
):
    rs = [r_ref[:, j] for j in range(d_in)]  # (rows,) per coordinate: the query's candidates
    hs = [h_ref[o] for o in range(d_out)]  # the query (scalars)
    wx = backproj_pallas._hidden_inputs(rs, w_ref, rows, chunks)
    tile = idx_ref[...]  # (rows, M): every candidate's kernels, _NONE where no slot

    def least(a: jax.Array) -> jax.Array:
        return jnp.min(jnp.min(a, axis=1), axis=0)

    def kernel(carry: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        u, best = carry  # u: the least kernel index not yet evaluated
        # u's weights gathered as (rows, width) tiles of one address per column (one layout
        # with the index tile; a row-vector load broadcast would be converted per sum)
        each = jnp.full((rows,), u, jnp.int32)
        dev = backproj_pallas._deviation(
            each, wx, hs, inv_ref, bias_ref, out_ref, off_ref, chunks, fast
        )
        member = jnp.min(jnp.where(tile == u, 0, 1), axis=1) == 0  # candidates with kernel u
        best = jnp.where(member, jnp.minimum(best, dev), best)
        return least(jnp.where(tile > u, tile, _NONE)), best

    start = (least(tile), jnp.full((rows,), jnp.inf, jnp.float32))
    _, best = jax.lax.while_loop(lambda c: c[0] < _NONE, kernel, start)
    best_ref[...] = best


def back_min_shared(
    bank: ELMBank,
    r: jax.Array,
    h: jax.Array,
    idx: jax.Array,
    d_in: int,
    d_out: int,
    hidden: int,
    interpret: bool = False,
) -> jax.Array:
    """``back_min`` for candidates grouped by query (traceable): one program per query evaluates
    each distinct kernel among its candidates' ``M`` once, on all ``L`` candidates, and keeps
    each candidate's least deviation over its own kernels. The same minima as ``back_min`` (sums
    in the same order per kernel); the weights are read once per (query, distinct kernel)
    instead of once per (candidate, kernel): a relaxed query's 100 pairs of a chain touch ~13
    distinct landmarks (``grouped_cpu``), for ``pow2(L) / L`` times the arithmetic per
    evaluation (the candidates padded to a power of two).

    Args:
      bank: one landmark set's backward kernels (as ``back_min``).
      r: ``(Q, L, >= d_in)`` each query's candidate robot points.
      h: ``(Q, >= d_out)`` the queries.
      idx: ``(Q, L, M)`` int kernel indices of each candidate (clamped into the bank).
      d_in, d_out, hidden: the kernels' real sizes (static).
      interpret: run in Pallas' interpreter (any platform; for tests).

    Returns:
      ``(Q, L)`` float32: ``min_k ||kappa^r_{idx[q, l, k]}(r[q, l]) - h[q]||^2``.
    """
    n_q, n_l, n_m = idx.shape
    pow2, fit = backproj_pallas._pow2, backproj_pallas.fit
    ip, op, lp = pow2(d_in), pow2(d_out), pow2(n_l)
    mp = max(pow2(n_m), backproj_pallas.CHUNK)  # the tile as wide as a chunk: one layout
    k_max = bank.inv_scale.shape[0] - 1
    weights, weight_specs = backproj_pallas.bank_inputs(bank, d_in, d_out, hidden)
    args = (
        fit(r.astype(jnp.float32), (n_q, lp, ip)),
        fit(h.astype(jnp.float32), (n_q, op)),
        fit(jnp.clip(idx.astype(jnp.int32), 0, k_max), (n_q, lp, mp), _NONE),
        *weights,
    )
    kern = functools.partial(
        _shared_kernel, d_in=d_in, d_out=d_out, rows=lp, chunks=backproj_pallas._chunks(hidden),
        fast=backproj_pallas.FAST_SIGMOID and not interpret,
    )  # fmt: skip
    params: dict[str, Any] = {}
    if not interpret:
        from jax.experimental.pallas import triton as plgpu

        params = dict(compiler_params=plgpu.CompilerParams(num_warps=SHARED_WARPS))
    best = pl.pallas_call(
        kern,
        grid=(n_q,),
        in_specs=[
            pl.BlockSpec((None, lp, ip), lambda b: (b, 0, 0)),
            pl.BlockSpec((None, op), lambda b: (b, 0)),
            pl.BlockSpec((None, lp, mp), lambda b: (b, 0, 0)),
            *weight_specs,
        ],
        out_specs=pl.BlockSpec((None, lp), lambda b: (b, 0)),
        out_shape=jax.ShapeDtypeStruct((n_q, lp), jnp.float32),
        interpret=interpret,
        name="back_min_shared",
        **params,
    )(*args)
    return best[:, :n_l]


def grouped_back_min(
    bank: ELMBank,
    r: jax.Array,
    h: jax.Array,
    idx: jax.Array,
    d_in: int,
    d_out: int,
    hidden: int,
    interpret: bool = False,
) -> jax.Array:
    """``back_min``'s signature (``(R, ...)`` rows, each query repeated over its ``L``
    consecutive candidates) on ``back_min_shared``."""
    q = r.shape[0] // L
    best = back_min_shared(
        bank, r.reshape(q, L, -1), h[::L], idx.reshape(q, L, -1), d_in, d_out, hidden, interpret
    )
    return best.reshape(-1)


def use() -> dict[tuple[object, str], object]:
    """The module flag that puts ``back_min_shared`` in the engine's place (a
    ``backproj_variants_ab.VARIANTS`` entry)."""
    return {(relaxed, "back_min"): grouped_back_min}
