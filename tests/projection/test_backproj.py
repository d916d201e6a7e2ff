"""The fused back-projection kernel (``projection.ops.backproj_pallas``), in Pallas' interpreter.

The kernel serves CUDA GPUs only (``projection.least_deviations_rows``); the interpreter executes
the same kernel program on the CPU, so its logic (hidden units in power-of-two chunks, padded
banks, ragged row counts, the slot loop and its running minimum) is checked here against a
float64 evaluation of the same kernels, within the float32 error bound of that arithmetic
(``jaxproj.testing.back_deviation_bound``). Its Triton lowering, speed and answers on real data are
checked on a GPU by ``benchmarks/experiments/fused_backproj_ab.py``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj.projection import elm as kernels
from jaxproj.projection.ops import backproj_pallas as _backproj_pallas
from jaxproj.testing import back_deviation_bound


def _bank(rng, k, d_in, d_out, hidden):
    x = rng.normal(size=(k, d_in)).astype(np.float32)
    t = rng.normal(size=(k, d_out)).astype(np.float32)
    key = jax.random.PRNGKey(int(rng.integers(1 << 30)))
    return kernels.train_bank(jnp.asarray(x), jnp.asarray(t), key, k=min(4, k), hidden=hidden)


def _pad_bank(bank, k, d_in, d_out, hidden):
    """The bank inside bigger arrays (as stacked chains are), padding filled with garbage."""

    def pad(a, shape):
        big = np.full(shape, 7.0, np.float32)
        big[tuple(slice(0, s) for s in a.shape)] = np.asarray(a)
        return jnp.asarray(big)

    return kernels.ELMBank(
        w=pad(bank.w, (hidden + 5, d_in + 1)),
        inv_scale=pad(bank.inv_scale, (k,)),
        bias=pad(bank.bias, (k, hidden + 5)),
        out=pad(bank.out, (k, d_out + 2, hidden + 5)),
        offset=pad(bank.offset, (k, d_out + 2)),
        neighbours=bank.neighbours,
        n_kernels=k,
        hidden=hidden + 5,
        d_in=d_in + 1,
        d_out=d_out + 2,
        k=bank.k,
    )


@pytest.mark.parametrize(
    "k, d_in, d_out, hidden, rows, m, padded",
    [
        (60, 4, 6, 24, 37, 10, False),  # an arm chain's widths; 24 = 16 + 8; ragged rows
        (40, 2, 3, 192, 16, 10, True),  # the head chain's widths, 192 = 6 x 32, padded bank
        (30, 4, 6, 5, 5, 1, True),  # one slot, hidden 5 = 4 + 1, fewer rows than a program
        (25, 3, 2, 32, 50, 7, False),  # a power-of-two hidden layer, M not a power of two
    ],
)
def test_kernel_matches_float64(k, d_in, d_out, hidden, rows, m, padded):
    rng = np.random.default_rng(k + hidden + rows)
    bank = _bank(rng, k, d_in, d_out, hidden)
    r = rng.normal(size=(rows, d_in + 1)).astype(np.float32)  # a padding column is never read
    h = rng.normal(size=(rows, d_out + 1)).astype(np.float32)
    idx = rng.integers(0, k, size=(rows, m)).astype(np.int32)
    want, bound = back_deviation_bound(bank, r, h, idx, d_in, d_out, hidden)
    use = _pad_bank(bank, k + 3, d_in, d_out, hidden) if padded else bank
    got = _backproj_pallas.back_min(
        use, jnp.asarray(r), jnp.asarray(h), jnp.asarray(idx), d_in, d_out, hidden, True
    )
    assert got.shape == (rows,) and got.dtype == jnp.float32
    assert np.all(np.abs(np.asarray(got) - want) <= bound)  # this arithmetic's float32 error


def test_kernel_bad_rows_stay_in_bounds():
    """Indices outside the bank are clamped (nothing is read out of bounds) and a NaN row gives
    NaN for that row only."""
    rng = np.random.default_rng(3)
    bank = _bank(rng, 20, 4, 6, 24)
    r = rng.normal(size=(20, 4)).astype(np.float32)
    h = rng.normal(size=(20, 6)).astype(np.float32)
    idx = rng.integers(0, 20, size=(20, 4)).astype(np.int32)
    want, bound = back_deviation_bound(bank, r, h, idx, 4, 6, 24)
    r[3] = np.nan
    idx[3] = [-5, 10**6, 0, 19]
    got = np.asarray(
        _backproj_pallas.back_min(
            bank, jnp.asarray(r), jnp.asarray(h), jnp.asarray(idx), 4, 6, 24, True
        )
    )
    assert np.isnan(got[3])
    keep = np.arange(20) != 3
    assert np.all(np.abs(got[keep] - want[keep]) <= bound[keep])


def test_chunks_cover_hidden():
    for hidden in (1, 5, 24, 64, 96, 192, 255):
        chunks = _backproj_pallas._chunks(hidden)
        cols = [c for s, w in chunks for c in range(s, s + w)]
        assert cols == list(range(hidden))
        assert all(w & (w - 1) == 0 for _, w in chunks)


@pytest.mark.parametrize("fast", [True, False])
def test_fast_sigmoid_reaches_the_cuda_kernel(monkeypatch, fast):
    """``FAST_SIGMOID`` puts the two PTX approximations into the kernel lowered for CUDA (the
    lowering runs without a GPU; their speed and answers: ``backproj_variants_ab``), and only
    into it: the interpreter's tests above take ``jax.nn.sigmoid``."""
    monkeypatch.setattr(_backproj_pallas, "FAST_SIGMOID", fast)
    bank = _bank(np.random.default_rng(5), 20, 4, 6, 24)
    r, h = jnp.zeros((16, 4)), jnp.zeros((16, 6))
    idx = jnp.zeros((16, 4), jnp.int32)
    fn = jax.jit(lambda b, r, h, i: _backproj_pallas.back_min(b, r, h, i, 4, 6, 24))
    text = fn.trace(bank, r, h, idx).lower(lowering_platforms=("cuda",)).as_text()
    for op in ("ex2.approx.ftz.f32", "rcp.approx.ftz.f32"):
        assert (op in text) == fast
