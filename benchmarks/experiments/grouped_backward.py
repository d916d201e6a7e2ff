"""Experiment (negative result, 2026-11-23): grouped back-projection as a Pallas Triton kernel.

    python -m benchmarks.experiments.grouped_backward MODEL.npz      # needs a CUDA GPU

The relaxed projection evaluates 100 backward kernels per query and chain (L candidates x M robot
landmarks), but the candidates of one query lie close together and share most robot landmarks
(per-chain model at N = 1644, 2,048 held-out queries: median 10 / 14 / 15 distinct kernels of
100 for head / left arm / right arm, p99 16 / 32 / 39). This kernel runs one program per query
and chain: it walks the query's 100 kernel ids, skips ids seen before, loads each distinct
kernel's weights once and evaluates it at all 10 candidates, keeping per candidate the least
deviation over its own M landmarks. Prints its agreement with XLA's per-(j, k) path (the
engine's) and both timings at batch 65,536 for 1-8 warps. H200 result: XLA 395 ns per pose,
the kernel 905 ns at best (2 warps): one program per query walks its ids serially and is bound
by the latency of each step's dependent loads and reductions, not by the weight traffic it
saves. Not used by the library.
"""

import functools
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import pallas as pl
from jax.experimental.pallas import triton as plgpu

from jaxproj._internal.jit import jit
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.elm import predict
from jaxproj.projection.projector import back_deviation
from jaxproj.projection.search import nearest_rows

L = M = 10
HP, OP, KP = 256, 8, 2048


def _kernel(
    cand_ref,
    ridx_ref,
    flat_ref,
    hq_ref,
    w_ref,
    inv_ref,
    bias_ref,
    out_ref,
    off_ref,
    best_ref,
    *,
    n_in,
):
    wx = jnp.zeros((16, HP), jnp.float32)
    for j in range(n_in):
        wx = wx + cand_ref[:, j][:, None] * w_ref[j, :][None, :]
    ids_all = flat_ref[...]  # (128,)
    pos = jax.lax.broadcasted_iota(jnp.int32, (128,), 0)
    ridx = ridx_ref[...]  # (16, 16)
    hq = [hq_ref[o] for o in range(OP)]

    def step(i, best):
        kid = flat_ref[i]
        dup = jnp.max(jnp.where((ids_all == kid) & (pos < i), 1, 0)) > 0
        skip = dup | (kid < 0)

        def work(best):
            inv = inv_ref[kid]
            b = bias_ref[kid, :]
            pre = wx * inv + b[None, :]
            q = 1.0 / (1.0 + jnp.exp(-pre))
            dev = jnp.zeros((16,), jnp.float32)
            for o in range(OP):
                y = off_ref[kid, o] + jnp.sum(q * out_ref[kid, o, :][None, :], axis=1)
                dev = dev + (y - hq[o]) ** 2
            member = jnp.max(jnp.where(ridx == kid, 1, 0), axis=1) > 0
            return jnp.where(member, jnp.minimum(best, dev), best)

        return jax.lax.cond(skip, lambda b: b, work, best)

    best = jax.lax.fori_loop(0, L * M, step, jnp.full((16,), jnp.inf, jnp.float32))
    best_ref[...] = best


def grouped(cand, ridx, flat, hq, bank_w, inv, bias, out, off, nw=4):
    c, s = cand.shape[:2]
    n_in = cand.shape[3]
    kern = functools.partial(_kernel, n_in=n_in)
    return pl.pallas_call(
        kern,
        grid=(c, s),
        in_specs=[
            pl.BlockSpec((None, None, 16, n_in), lambda ci, si: (ci, si, 0, 0)),
            pl.BlockSpec((None, None, 16, 16), lambda ci, si: (ci, si, 0, 0)),
            pl.BlockSpec((None, None, 128), lambda ci, si: (ci, si, 0)),
            pl.BlockSpec((None, None, OP), lambda ci, si: (ci, si, 0)),
            pl.BlockSpec((None, n_in, HP), lambda ci, si: (ci, 0, 0)),
            pl.BlockSpec((None, KP), lambda ci, si: (ci, 0)),
            pl.BlockSpec((None, KP, HP), lambda ci, si: (ci, 0, 0)),
            pl.BlockSpec((None, KP, OP, HP), lambda ci, si: (ci, 0, 0, 0)),
            pl.BlockSpec((None, KP, OP), lambda ci, si: (ci, 0, 0)),
        ],
        out_specs=pl.BlockSpec((None, None, 16), lambda ci, si: (ci, si, 0)),
        out_shape=jax.ShapeDtypeStruct((c, s, 16), jnp.float32),
        compiler_params=plgpu.CompilerParams(num_warps=nw),
    )(cand, ridx, flat, hq, bank_w, inv, bias, out, off)


def main(path, S=65536):
    model = engine.load(path)
    sp = model.projector
    st, lay = sp.stack, sp.layout
    test = datasets.valid_descriptors(
        datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    ).astype(np.float32)
    test = test[np.random.default_rng(0).permutation(len(test))]
    h = jnp.asarray(np.tile(test, (S // len(test) + 1, 1))[:S])
    x = jnp.concatenate([h, jnp.zeros((S, 1))], 1)[:, lay.input_index()]  # (S, C, m)

    @jit
    def prep(st, x):
        hidx, _ = nearest_rows(st.human, st.human_sq, x.transpose(1, 0, 2), L)
        cand = jax.vmap(jax.vmap(lambda p, q, i: predict(p.forward, q, i)), in_axes=(None, 0, 0))(
            st, x, hidx.transpose(1, 0, 2)
        )
        c, n = cand.shape[1], cand.shape[3]
        rows = cand.transpose(1, 0, 2, 3).reshape(c, S * L, n)
        ridx, _ = nearest_rows(st.robot, st.robot_sq, rows, M)
        return cand, ridx.reshape(c, S, L, M).transpose(1, 0, 2, 3)

    cand, ridx = prep(st, x)  # (S, C, L, n), (S, C, L, M)

    @jit
    def xla_bwd(st, x, cand, ridx):
        def one(p, q, cd, ri):
            dev = jax.vmap(back_deviation, in_axes=(None, 0, None, 0))(p, cd, q, ri)
            return jnp.min(dev, axis=1)  # (L,)

        return jax.vmap(jax.vmap(one), in_axes=(None, 0, 0, 0))(st, x, cand, ridx)  # (S, C, L)

    # padded inputs for the kernel (prepared once, outside the timing)
    C = lay.n_chains
    bw = st.backward

    def pad(a, shape):
        return jnp.pad(a, [(0, t - s_) for s_, t in zip(a.shape, shape, strict=True)])

    inv = pad(bw.inv_scale, (C, KP))
    bias = pad(bw.bias, (C, KP, HP))
    out = pad(bw.out, (C, KP, OP, HP))
    off = pad(bw.offset, (C, KP, OP))
    wT = pad(bw.w.transpose(0, 2, 1), (C, bw.w.shape[2], HP))  # (C, n_in, HP)
    cand_k = pad(cand.transpose(1, 0, 2, 3), (C, S, 16, cand.shape[3]))
    rk = jnp.full((C, S, 16, 16), -1, jnp.int32).at[:, :, :L, :M].set(ridx.transpose(1, 0, 2, 3))
    flat = (
        jnp.full((C, S, 128), -1, jnp.int32)
        .at[:, :, : L * M]
        .set(ridx.transpose(1, 0, 2, 3).reshape(C, S, L * M))
    )
    hq = pad(x.transpose(1, 0, 2), (C, S, OP))
    g = jax.jit(grouped)

    def t(f, *a):
        jax.block_until_ready(f(*a))
        ts = []
        for _ in range(5):
            t0 = time.perf_counter()
            jax.block_until_ready(f(*a))
            ts.append(time.perf_counter() - t0)
        return np.median(ts) / S * 1e9

    ref = np.asarray(xla_bwd(st, x, cand, ridx))  # (S, C, L)
    got = np.asarray(g(cand_k, rk, flat, hq, wT, inv, bias, out, off))[:, :, :L].transpose(1, 0, 2)
    rel = np.abs(got - ref) / np.maximum(ref, 1e-6)
    print(
        "grouped vs XLA min-deviation: max rel diff",
        rel.max(),
        "argmin equal",
        np.mean(got.argmin(-1) == ref.argmin(-1)),
        flush=True,
    )
    print(f"XLA back-projection {t(xla_bwd, st, x, cand, ridx):.1f} ns/pose", flush=True)
    for nw in (1, 2, 4, 8):
        gg = jax.jit(functools.partial(grouped, nw=nw))
        print(
            f"grouped Pallas warps={nw}: "
            f"{t(gg, cand_k, rk, flat, hq, wT, inv, bias, out, off):.1f} ns/pose",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1])
