"""Fused back-projection of the relaxed objective on CUDA GPUs: one Pallas (Triton) kernel.

For every candidate row ``r`` (a robot point, with its query ``h`` and its ``M`` nearest robot
landmarks ``k_1..k_M``) the relaxed projection needs ``min_k ||kappa^r_k(r) - h||^2`` over the
row's backward kernels (``projector.back_deviation``, then a minimum). In XLA that is three
passes: the hidden layer ``sigmoid(W r / rho_k + beta_k)`` of every (row, kernel) pair is
written to memory as a ``(rows, M, hidden)`` tensor (one fusion), read back and contracted with
the gathered output weights (a second), then squared and reduced (a third). This kernel does it
per program of ``ROWS`` rows without the intermediate: ``W r`` once per row, then per slot
``k``: the slot's kernel weights gathered (``1 / rho``, ``beta``, ``B^T``, offset), the sigmoid,
the contraction over ``hidden`` (in chunks of ``CHUNK`` and powers of two, so any ``hidden``
works), the squared deviation and a running minimum. Only the ``(rows,)`` minimum is written.

The arithmetic is XLA's (``exp`` is libdevice's ``expf``), summed in another order: a deviation
differs from XLA's by float32 round-off, so where two candidates' deviations tie to round-off
(the head chain's deviations are ~1e-8, and XLA's own error against float64 is ~1e-3 of that)
the two may pick different candidates. Both are checked against the float64 reference in
``benchmarks/experiments/fused_backproj_ab.py``.
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import pallas as pl

from jaxproj.projection.elm import ELMBank

ROWS = 16
"""Candidate rows per program."""

WARPS = 4

CHUNK = 32
"""Hidden units per step of the contraction. Swept on an H200 (per-chain model, batch 65,536;
chunks of 16 / 32 / 64 or 128 + 64, 8-32 rows, 2-16 warps, the slot loop rolled or unrolled):
32-wide chunks, 16 rows, 4 warps, rolled: 103 ns per pose, against 148 for 128 + 64 chunks."""


FAST_SIGMOID = True
"""The hidden layer's sigmoid as ``1 / (1 + 2^(-z log2 e))`` by two PTX approximations,
``ex2.approx.ftz.f32`` and ``rcp.approx.ftz.f32`` (four instructions), instead of libdevice's
``expf`` and a full division (``False``; read when the kernel is traced; the interpreter always
takes ``jax.nn.sigmoid``). Measured on one H200 (2026-11-27, default model, batch 65,536,
``python -m benchmarks.experiments.backproj_variants_ab``, ``backproj_variants_h200.json``):
the back-projection 108.2 -> 97.8 ns per pose, the whole relaxed projection 300.0 -> 285.9; 99.6 %
of answers bit-identical, the first 500 judged against the float64 reference 498 exact and 2
near-ties (499 and 1 before). Summing each slot's products over the chunks before one
cross-thread reduction (instead of one per chunk) was no faster (114.6 alone, 93.0 with the
fast sigmoid): not kept. Its floor is reading the weights (counted, not profiled): each (row,
kernel) pair gathers ``hidden * (d_out + 1)`` floats (5.4 KB for an arm), 1.6 MB per pose over
the three chains, ~54 ns per pose at the L1's 128 bytes per cycle and SM."""

LOG2E = np.float32(1.4426950408889634)


def _asm(op: str, x: jax.Array) -> jax.Array:
    """One PTX instruction ``op`` (``"ex2.approx.ftz.f32"``) applied elementwise to float32."""
    from jax.experimental.pallas import triton as plgpu

    [y] = plgpu.elementwise_inline_asm(
        f"{op} $0, $1;", args=[x], constraints="=f,f", pack=1,
        result_shape_dtypes=[jax.ShapeDtypeStruct(x.shape, x.dtype)],
    )  # fmt: skip
    return y


def _sigmoid(z: jax.Array, fast: bool) -> jax.Array:
    """``sigmoid(z)``: XLA's arithmetic, or with ``fast`` the two approximations above (an
    overflowing ``2^t`` gives ``rcp(inf) = 0``, the right limit)."""
    if not fast:
        return jax.nn.sigmoid(z)
    e = _asm("ex2.approx.ftz.f32", z * -LOG2E)
    return _asm("rcp.approx.ftz.f32", e + 1.0)


def _pow2(v: int) -> int:
    p = 1
    while p < v:
        p *= 2
    return p


def _chunks(hidden: int) -> tuple[tuple[int, int], ...]:
    """``hidden`` as ``(start, width)`` chunks: ``CHUNK`` wide, then the rest in powers of two
    (192 = 3 x 64; 100 = 64 + 32 + 4)."""
    out = [(start, CHUNK) for start in range(0, hidden - hidden % CHUNK, CHUNK)]
    start = len(out) * CHUNK
    for bit in reversed(range(CHUNK.bit_length())):
        width = 1 << bit
        if hidden - start >= width:
            out.append((start, width))
            start += width
    return tuple(out)


def _hidden_inputs(
    rs: list[jax.Array], w_ref: Any, rows: int, chunks: tuple[tuple[int, int], ...]
) -> list[jax.Array]:
    """``W r`` of the program's rows (``rs``: ``d_in`` coordinates, ``(rows,)`` each), per chunk
    of hidden units: ``(rows, width)`` each."""
    wx = []
    for start, width in chunks:
        acc = jnp.zeros((rows, width), jnp.float32)
        for j, rj in enumerate(rs):
            acc = acc + rj[:, None] * w_ref[j, pl.ds(start, width)][None, :]
        wx.append(acc)
    return wx


def _deviation(
    idx: jax.Array,
    wx: list[jax.Array],
    hs: list[Any],
    inv_ref: Any,
    bias_ref: Any,
    out_ref: Any,
    off_ref: Any,
    chunks: tuple[tuple[int, int], ...],
    fast: bool,
) -> jax.Array:
    """``||kappa^r_{idx_i}(r_i) - h_i||^2`` of every row ``i`` (``idx``: ``(rows,)`` kernel
    indices, gathered as ``(rows, width)`` tiles; ``hs``: the ``d_out`` query coordinates)."""
    rows = idx.shape[0]
    inv = inv_ref[idx]
    y = [off_ref[idx, o] for o in range(len(hs))]
    at = idx[:, None]
    for c, (start, width) in enumerate(chunks):
        cols = start + jax.lax.broadcasted_iota(jnp.int32, (rows, width), 1)
        q = _sigmoid(wx[c] * inv[:, None] + bias_ref[at, cols], fast)
        for o in range(len(hs)):
            y[o] = y[o] + jnp.sum(q * out_ref[at, o, cols], axis=1)
    dev = (y[0] - hs[0]) ** 2
    for o in range(1, len(hs)):
        dev = dev + (y[o] - hs[o]) ** 2
    return dev


def _kernel(
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
    m: int,
    chunks: tuple[tuple[int, int], ...],
    fast: bool,
):
    rs = [r_ref[:, j] for j in range(d_in)]  # (ROWS,) per coordinate
    hs = [h_ref[:, o] for o in range(d_out)]
    wx = _hidden_inputs(rs, w_ref, ROWS, chunks)

    def slot(k: jax.Array, best: jax.Array) -> jax.Array:
        idx = idx_ref[:, k]  # (ROWS,) this slot's kernel of every row
        dev = _deviation(idx, wx, hs, inv_ref, bias_ref, out_ref, off_ref, chunks, fast)
        return jnp.minimum(best, dev)

    best_ref[...] = jax.lax.fori_loop(0, m, slot, jnp.full((ROWS,), jnp.inf, jnp.float32))


def fit(a: jax.Array | np.ndarray, shape: tuple[int, ...], fill: Any = 0) -> jax.Array:
    """``a`` cut to at most ``shape`` and padded with ``fill`` to exactly ``shape``."""
    a = a[tuple(slice(0, min(s, t)) for s, t in zip(a.shape, shape, strict=True))]
    pad = [(0, t - s) for s, t in zip(a.shape, shape, strict=True)]
    return jnp.pad(a, pad, constant_values=fill)


def bank_inputs(
    bank: ELMBank, d_in: int, d_out: int, hidden: int
) -> tuple[tuple[jax.Array, ...], list[Any]]:
    """The kernels' weights as the fused kernels read them (``W^T``, ``1 / rho``, ``beta``,
    ``B^T``, offset; each padded to powers of two) and their whole-array block specs."""
    kp, hp = _pow2(bank.inv_scale.shape[0]), _pow2(hidden)
    ip, op = _pow2(d_in), _pow2(d_out)
    args = (
        fit(bank.w[:hidden, :d_in].T, (ip, hp)),
        fit(bank.inv_scale, (kp,)),
        fit(bank.bias, (kp, hp)),
        fit(bank.out, (kp, op, hp)),
        fit(bank.offset, (kp, op)),
    )
    specs = [pl.BlockSpec(a.shape, lambda *_, n=a.ndim: (0,) * n) for a in args]
    return args, specs


def back_min(
    bank: ELMBank,
    r: jax.Array,
    h: jax.Array,
    idx: jax.Array,
    d_in: int,
    d_out: int,
    hidden: int,
    interpret: bool = False,
) -> jax.Array:
    """``min_k ||kappa^r_{idx[i, k]}(r_i) - h_i||^2`` of every row, fused (traceable).

    Args:
      bank: one landmark set's backward kernels (may be padded beyond the sizes below; the
        padding is never read).
      r: ``(R, >= d_in)`` candidate robot points (only the first ``d_in`` columns are read).
      h: ``(R, >= d_out)`` each row's query (first ``d_out`` columns).
      idx: ``(R, M)`` int kernel indices of each row; clamped into the bank (a NaN candidate's
        indices are meaningless, and nothing is read out of bounds).
      d_in, d_out, hidden: the kernels' real sizes (static).
      interpret: run the kernel in Pallas' interpreter (any platform; for tests).

    Returns:
      ``(R,)`` float32: the least squared back-projected deviation of each row.
    """
    n_rows, m = idx.shape
    ip, op, mp = _pow2(d_in), _pow2(d_out), _pow2(m)
    rp = -(-n_rows // ROWS) * ROWS
    k_max = bank.inv_scale.shape[0] - 1
    weights, weight_specs = bank_inputs(bank, d_in, d_out, hidden)
    args = (
        fit(r.astype(jnp.float32), (rp, ip)),
        fit(h.astype(jnp.float32), (rp, op)),
        fit(jnp.clip(idx.astype(jnp.int32), 0, k_max), (rp, mp)),
        *weights,
    )
    kern = functools.partial(
        _kernel, d_in=d_in, d_out=d_out, m=m, chunks=_chunks(hidden),
        fast=FAST_SIGMOID and not interpret,
    )  # fmt: skip
    params: dict[str, Any] = {}
    if not interpret:
        from jax.experimental.pallas import triton as plgpu

        params = dict(compiler_params=plgpu.CompilerParams(num_warps=WARPS))
    best = pl.pallas_call(
        kern,
        grid=(rp // ROWS,),
        in_specs=[
            pl.BlockSpec((ROWS, ip), lambda b: (b, 0)),
            pl.BlockSpec((ROWS, op), lambda b: (b, 0)),
            pl.BlockSpec((ROWS, mp), lambda b: (b, 0)),
            *weight_specs,
        ],
        out_specs=pl.BlockSpec((ROWS,), lambda b: (b,)),
        out_shape=jax.ShapeDtypeStruct((rp,), jnp.float32),
        interpret=interpret,
        name="back_min",
        **params,
    )(*args)
    return best[:n_rows]
