"""Exact k-nearest-neighbour search: the XLA search and the fused Pallas kernel.

The kernel serves CUDA GPUs (``search.nearest_rows`` with ``impl="pallas"``, the default there);
here it runs in Pallas' interpreter,
which executes the same kernel program on the CPU, so its logic (block minima, both selections,
padding, ragged row counts) is checked without a GPU. Its Triton lowering and speed are checked
on a GPU by ``benchmarks/experiments/fused_knn_ab.py``.
"""

import functools
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.projection import search
from jaxproj.projection.ops import Impl, resolve_impl
from jaxproj.projection.ops import knn_pallas as _knn_pallas
from jaxproj.testing import sq_distance_bound


def _sets(rng, c, k, d, r, valid_k):
    pts = rng.normal(size=(c, k, d)).astype(np.float32)
    valid = np.zeros((c, k), bool)
    for i, v in enumerate(valid_k):
        valid[i, :v] = True
    x = rng.normal(size=(c, r, d)).astype(np.float32)
    return pts, valid, x


def _check_exact(pts, valid, x, idx, d2, n):
    """Every returned set is the n nearest valid landmarks, by float64 distances."""
    assert idx.shape == d2.shape == (*x.shape[:2], n)
    for c in range(pts.shape[0]):
        d = ((x[c, :, None, :].astype(np.float64) - pts[c][None].astype(np.float64)) ** 2).sum(-1)
        d[:, ~valid[c]] = np.inf
        assert valid[c][idx[c]].all(), "a padding landmark was returned"
        want = np.sort(d, axis=1)[:, :n]
        got = np.take_along_axis(d, idx[c], axis=1)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)  # the same distances, sorted
        bound = sq_distance_bound(x[c, :, None, :], pts[c][idx[c]])  # float32 error of |x-p|^2
        assert np.all(np.abs(d2[c] - got) <= bound)  # and reported as such
        assert (np.diff(d2[c], axis=1) >= 0).all(), "not nearest first"


@pytest.mark.parametrize(
    "k, d, r, n, valid_k",
    [
        (300, 4, 37, 10, (300, 120, 11)),  # ragged rows, padded sets, one barely >= n
        (1725, 4, 16, 10, (799, 1656, 1725)),  # the per-chain model's sizes
        (200, 6, 20, 16, (200, 200, 200)),  # the widest selection, a 6-D human search
        (64, 2, 5, 1, (64, 64, 64)),  # one neighbour, fewer landmarks than one tile
        (9000, 3, 16, 10, (9000, 8300, 20)),  # over MAX_BLOCKS blocks of 16: blocks of 32
    ],
)
def test_fused_kernel_is_exact(k, d, r, n, valid_k):
    pts, valid, x = _sets(np.random.default_rng(k + d + n), 3, k, d, r, valid_k)
    idx, d2 = _knn_pallas.knn(jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), n, True)
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), n)


def test_fused_kernel_on_clustered_landmarks_and_duplicates():
    """Landmarks in tight clusters (many blocks hold near-equal minima) and exact duplicates."""
    rng = np.random.default_rng(7)
    centres = rng.normal(size=(20, 4))
    pts = (centres[rng.integers(0, 20, 600)] + 1e-3 * rng.normal(size=(600, 4))).astype(np.float32)
    pts[300:320] = pts[0]  # 21 copies of one landmark
    x = np.concatenate([pts[:8] + 1e-4, centres[:8]]).astype(np.float32)
    pts, x = pts[None], x[None]
    valid = np.ones((1, 600), bool)
    idx, d2 = _knn_pallas.knn(jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True)
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), 10)


def test_fused_kernel_on_non_finite_rows_stays_in_bounds():
    """A NaN or infinite query row (e.g. a lost joint's descriptor in streaming) gets indices
    inside the kernel's padded landmark array, and the finite rows beside it their exact
    neighbours. (That its loads stay in bounds on a GPU follows from the clamp on the chosen
    block, which the interpreter's outputs cannot show: it clamps gathers itself.)"""
    pts, valid, x = _sets(np.random.default_rng(11), 2, 300, 4, 20, (300, 200))
    x[:, 3] = np.nan
    x[:, 7, 1] = np.inf
    x[:, 9, 0] = -np.inf
    idx, d2 = _knn_pallas.knn(jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True)
    idx, d2 = np.asarray(idx), np.asarray(d2)
    blocks = max(_knn_pallas._pow2(-(-300 // _knn_pallas.BLOCK)), _knn_pallas.TILE_BLOCKS)
    assert ((idx >= 0) & (idx < blocks * _knn_pallas.BLOCK)).all()
    good = np.setdiff1d(np.arange(20), [3, 7, 9])
    _check_exact(pts, valid, x[:, good], idx[:, good], d2[:, good], 10)


def test_fused_kernel_rejects_a_selection_wider_than_its_registers():
    pts = jnp.zeros((1, 64, 4))
    with pytest.raises(ValueError, match="n=17"):
        _knn_pallas.knn(pts, jnp.ones((1, 64), bool), jnp.zeros((1, 4, 4)), 17, True)


@pytest.mark.parametrize("rows", [32, 30])  # a whole number of program rows, and a short one
def test_kernels_pad_without_a_scatter(rows):
    """The k-NN kernels' inputs are padded by ``lax.pad`` (or not at all), never scattered into
    a filled array: under ``jax.shard_map`` on GPUs, a scatter covering its whole target left a
    zero-sized constant that crashed XLA's partitioner (``knn_pallas._row_pad``)."""
    rng = np.random.default_rng(0)
    pts = rng.standard_normal((1, 300, 4)).astype(np.float32)
    ok = np.ones((1, 300), bool)
    x = rng.standard_normal((1, rows, 4)).astype(np.float32)
    index = _knn_pallas.prune_index(pts, ok, 64, _knn_pallas.PRUNE_LB_TILE)  # as projectors keep
    full = functools.partial(_knn_pallas.knn_full, pts, ok)
    pruned = functools.partial(_knn_pallas.knn_pruned, pts, ok, index=index)
    for name, fn in (("knn_full", full), ("knn_pruned", pruned)):
        text = str(jax.make_jaxpr(lambda a, fn=fn: fn(a, 3, interpret=True))(x))
        calls = text.split("pallas_call")[0]  # the wrapper's operations before the first kernel
        assert "pallas_call" in text and "scatter" not in calls, name


@pytest.mark.parametrize("n", [10, 20])
def test_nearest_rows_off_gpu_is_the_xla_search(n):
    """On the CPU ``nearest_rows`` is ``nearest`` per set: the same neighbours in the same order,
    the distances to float32 round-off (one batched product over the sets instead of one per
    set); also above the kernel's widest selection, where every platform takes this search."""
    pts, valid, x = _sets(np.random.default_rng(3), 2, 400, 4, 30, (400, 150))
    sq = np.where(valid, (pts.astype(np.float32) ** 2).sum(-1), np.inf).astype(np.float32)
    idx, d2 = jax.jit(search.nearest_rows, static_argnames="n")(pts, sq, x, n=n)
    for c in range(2):
        i1, v1 = search.nearest(jnp.asarray(pts[c]), jnp.asarray(sq[c]), jnp.asarray(x[c]), n)
        np.testing.assert_array_equal(np.asarray(idx[c]), np.asarray(i1))
        np.testing.assert_allclose(np.asarray(d2[c]), np.asarray(v1), rtol=1e-5, atol=1e-6)
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), n)


def test_nearest_rows_with_impl_pallas_is_the_kernel():
    """``impl="pallas"`` selects the fused kernel (Pallas' interpreter off CUDA GPUs): bit for
    bit the kernel's answer; ``impl="xla"`` and ``"auto"`` (on the CPU) the XLA search."""
    pts, valid, x = _sets(np.random.default_rng(4), 2, 300, 4, 21, (300, 90))
    sq = np.where(valid, (pts.astype(np.float32) ** 2).sum(-1), np.inf).astype(np.float32)
    rows = jax.jit(search.nearest_rows, static_argnames=("n", "impl"))
    idx, d2 = rows(pts, sq, x, n=10, impl="pallas")
    want_i, want_d = _knn_pallas.knn(jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True)
    np.testing.assert_array_equal(np.asarray(idx), np.asarray(want_i))
    np.testing.assert_array_equal(np.asarray(d2), np.asarray(want_d))
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), 10)
    xla_i, _ = rows(pts, sq, x, n=10, impl="xla")
    auto_i, _ = rows(pts, sq, x, n=10)
    np.testing.assert_array_equal(np.asarray(auto_i), np.asarray(xla_i))


def test_impl_resolves_once_from_the_platform():
    """``"auto"`` is the Pallas kernels on CUDA GPUs and XLA elsewhere (here: the CPU); explicit
    values pass through; anything else is a ``ConfigError`` naming the choices."""
    want = Impl.PALLAS if jax.devices()[0].platform == "gpu" else Impl.XLA
    assert resolve_impl("auto") is resolve_impl(Impl.AUTO) is want
    assert resolve_impl("auto", jax.devices("cpu")) is Impl.XLA
    assert resolve_impl("xla") is Impl.XLA and resolve_impl("pallas") is Impl.PALLAS
    with pytest.raises(ConfigError, match="impl must be one of 'auto', 'xla', 'pallas'"):
        resolve_impl("triton")


@pytest.fixture
def prune_every_set(monkeypatch):
    """The pruned search on sets of any size (by default only from ``PRUNE_MIN_LANDMARKS``),
    visiting 8 blocks (these sets have 12-16: the default 16 would visit all, and every row
    would be certified)."""
    monkeypatch.setattr(_knn_pallas, "PRUNE_MIN_LANDMARKS", 0)
    monkeypatch.setattr(_knn_pallas, "PRUNE_VISIT", 8)


def test_kd_order_is_a_permutation_with_padding_last():
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(2, 300, 3)).astype(np.float32)
    valid = np.ones((2, 300), bool)
    valid[1, 250:] = False
    order = np.asarray(_knn_pallas.kd_order(jnp.asarray(pts), jnp.asarray(valid), 16))
    for c in range(2):
        assert sorted(order[c]) == list(range(300))
    assert valid[1][order[1]][-16:].sum() < 16  # padding gathers in the last blocks


def test_pruned_search_certifies_near_rows_and_fails_far_ones(prune_every_set):
    """Rows near the landmarks are certified and exact; a row at the centre of landmarks on a
    sphere (every landmark equally far, every block's box nearer) fails the certificate.
    ``knn(prune=True)`` answers both exactly: the fallback's full scan on the failing rows, and
    on every row when more fail than its capacity."""
    rng = np.random.default_rng(9)
    pts = rng.normal(size=(1, 1500, 4))
    pts = (pts / np.linalg.norm(pts, axis=2, keepdims=True)).astype(np.float32)
    x = (pts[:, rng.integers(0, 1500, 48)] + 0.01 * rng.normal(size=(1, 48, 4))).astype(np.float32)
    x[0, 5] = 0.0  # the centre
    valid = np.ones((1, 1500), bool)
    args = (jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True)
    idx, d2, ok = (np.asarray(a) for a in _knn_pallas.knn_pruned(*args))
    assert not ok[0, 5] and ok.mean() > 0.5
    _check_exact(pts, valid, x[:, ok[0]], idx[:, ok[0]], d2[:, ok[0]], 10)
    idx, d2 = _knn_pallas.knn(*args, prune=True)  # a few failing rows: the fallback on them
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), 10)
    far = 1e-3 * rng.normal(size=x.shape).astype(np.float32)  # every row near the centre
    idx, d2 = _knn_pallas.knn(args[0], args[1], jnp.asarray(far), 10, True, prune=True)
    _check_exact(pts, valid, far, np.asarray(idx), np.asarray(d2), 10)  # all fail: full scan


def test_pruned_search_fallback_capacities(prune_every_set, monkeypatch):
    """The fallback's full scan on a small capacity of rows, a larger one, or every row, by how
    many fail the certificate (here 16 / 32 of 48 rows: shares 3 and 2): exact in each case."""
    monkeypatch.setattr(_knn_pallas, "FALLBACK_SMALL_SHARE", 3)
    monkeypatch.setattr(_knn_pallas, "FALLBACK_SHARE", 2)
    rng = np.random.default_rng(4)
    pts = rng.normal(size=(1, 1500, 4))
    pts = (pts / np.linalg.norm(pts, axis=2, keepdims=True)).astype(np.float32)
    near = (pts[:, rng.integers(0, 1500, 48)] + 0.01 * rng.normal(size=(1, 48, 4))).astype(
        np.float32
    )
    centre = 1e-3 * rng.normal(size=near.shape).astype(np.float32)  # fail the certificate
    valid = jnp.ones((1, 1500), bool)
    search = jax.jit(lambda x: _knn_pallas.knn(jnp.asarray(pts), valid, x, 10, True, True))
    pruned = jax.jit(lambda x: _knn_pallas.knn_pruned(jnp.asarray(pts), valid, x, 10, True)[2])
    for failing in (3, 24, 48):  # the small capacity, the larger one, every row
        x = near.copy()
        x[:, :failing] = centre[:, :failing]
        assert int((~np.asarray(pruned(jnp.asarray(x)))).sum()) >= failing
        idx, d2 = search(jnp.asarray(x))
        _check_exact(pts, np.ones((1, 1500), bool), x, np.asarray(idx), np.asarray(d2), 10)


def test_pruned_search_with_padding_and_small_sets(prune_every_set):
    """Padded sets (one with barely ``n`` landmarks), ragged rows, duplicates: exact."""
    pts, valid, x = _sets(np.random.default_rng(13), 3, 700, 3, 37, (700, 300, 11))
    pts[0, 100:130] = pts[0, 0]
    x[0, :4] = pts[0, 0]
    idx, d2 = _knn_pallas.knn(jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True, True)
    _check_exact(pts, valid, x, np.asarray(idx), np.asarray(d2), 10)


def test_precomputed_prune_index_gives_the_same_answers(prune_every_set, monkeypatch):
    """The pruning index computed once beforehand (jitted ``prune_index``, as
    ``projector.with_search_index`` does) is the one the search computes in its trace, bit for
    bit, and the pruned search gives identical answers with it; an index for other settings
    (``PruneIndex.fits``) is not used: the search computes its own (traced only, not run)."""
    rng = np.random.default_rng(21)
    pts, valid, _ = _sets(rng, 2, 1600, 4, 1, (1600, 1100))
    pts = (pts / np.linalg.norm(pts, axis=2, keepdims=True)).astype(np.float32)  # on a sphere
    pts[0, 200:240] = pts[0, 3]  # duplicates: exact ties in the k-d sort keys and distances
    x = (pts[:, rng.integers(0, 1100, 16)] + 0.01 * rng.normal(size=(2, 16, 4))).astype(np.float32)
    x[:, 7] = 0.0  # the centre: fails the certificate
    args = (jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x))
    blk, lbt = _knn_pallas.PRUNE_BLOCK, _knn_pallas.PRUNE_LB_TILE
    index = _knn_pallas.prune_index
    pre = jax.jit(index, static_argnames=("block", "lbt"))(args[0], args[1], block=blk, lbt=lbt)
    assert pre.fits(2, 1600, 4) and not pre.fits(2, 1600, 3)
    order = jax.jit(lambda p, v: _knn_pallas.kd_order(p, v, blk))(args[0], args[1])
    np.testing.assert_array_equal(np.asarray(pre.order), np.asarray(order))
    pruned = jax.jit(lambda p, v, q, i: _knn_pallas.knn_pruned(p, v, q, 10, True, i))
    got = [np.asarray(a) for a in pruned(*args, pre)]
    want = [np.asarray(a) for a in pruned(*args, None)]
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    assert not got[2].all() and got[2].mean() > 0.5  # both the certified and the uncertified rows
    for c, ok in enumerate(got[2]):  # the certified rows: exact
        sel = (slice(c, c + 1), ok)
        _check_exact(pts[c : c + 1], valid[c : c + 1], x[sel], got[0][sel], got[1][sel], 10)
    traced = []
    monkeypatch.setattr(_knn_pallas, "prune_index", lambda *a: traced.append(1) or index(*a))
    jax.eval_shape(lambda: _knn_pallas.knn(*args, 10, True, True, pre))
    assert traced == []  # the index fits: used
    monkeypatch.setattr(_knn_pallas, "PRUNE_BLOCK", 64)  # other settings: computed anew
    assert not pre.fits(2, 1600, 4)
    jax.eval_shape(lambda: _knn_pallas.knn(*args, 10, True, True, pre))
    assert traced == [1]


def test_pruned_program_shape_follows_the_block():
    """``prune_shape``: the pruned pass runs ``PRUNE_SMALL_ROWS`` rows on ``PRUNE_SMALL_WARPS``
    warps a program on a set it covers whole, ``PRUNE_ROWS`` on ``PRUNE_WARPS`` otherwise, and
    that is what reaches the kernel lowered for CUDA (no GPU needed to lower it)."""
    kp = _knn_pallas
    small = (kp.PRUNE_SMALL_ROWS, kp.PRUNE_SMALL_WARPS)
    assert kp.prune_shape(kp.PRUNE_SMALL_BLOCK) == small
    assert kp.prune_shape(kp.PRUNE_BLOCK) == (kp.PRUNE_ROWS, kp.PRUNE_WARPS)
    for k, (rows, warps) in ((1000, small), (5000, (kp.PRUNE_ROWS, kp.PRUNE_WARPS))):
        pts = jnp.zeros((1, k, 3))
        fn = jax.jit(lambda p=pts: _knn_pallas.knn_pruned(p, p[..., 0] == 0, p[:, :8], 10))
        text = fn.trace().lower(lowering_platforms=("cuda",)).as_text()
        assert re.findall(r"num_warps = (\d+) : i32", text) == [str(warps)]
        assert re.findall(r"grid_y = (\d+) : i32", text) == [str(-(-8 // rows))]


def test_small_sets_prune_with_every_block_visited(monkeypatch):
    """By default a set of at most ``PRUNE_VISIT * PRUNE_SMALL_BLOCK`` landmarks takes the
    pruned kernel with blocks of ``PRUNE_SMALL_BLOCK``, which visits every block: every row is
    certified and exact, the one at the centre of a sphere of landmarks too (``PRUNE_VISIT = 8``
    above fails it); a set between that and ``PRUNE_MIN_LANDMARKS`` takes the full scan."""
    pb = _knn_pallas.prune_block
    cap = _knn_pallas.PRUNE_VISIT * _knn_pallas.PRUNE_SMALL_BLOCK
    assert pb(cap) == _knn_pallas.PRUNE_SMALL_BLOCK and pb(cap + 1) is None
    assert pb(_knn_pallas.PRUNE_MIN_LANDMARKS) == _knn_pallas.PRUNE_BLOCK
    rng = np.random.default_rng(17)
    pts = rng.normal(size=(2, 1000, 3))
    pts = (pts / np.linalg.norm(pts, axis=2, keepdims=True)).astype(np.float32)
    valid = np.ones((2, 1000), bool)
    valid[1, 300:] = False  # a padded set
    x = (pts[:, rng.integers(0, 300, 8)] + 0.01 * rng.normal(size=(2, 8, 3))).astype(np.float32)
    x[:, 5] = 0.0  # the centre: every landmark equally far
    args = (jnp.asarray(pts), jnp.asarray(valid), jnp.asarray(x), 10, True)
    idx, d2, ok = (np.asarray(a) for a in _knn_pallas.knn_pruned(*args))
    assert ok.all()
    _check_exact(pts, valid, x, idx, d2, 10)
    calls = []
    real = _knn_pallas.knn_pruned
    monkeypatch.setattr(_knn_pallas, "knn_pruned", lambda *a: calls.append(1) or real(*a))
    jax.eval_shape(lambda: _knn_pallas.knn(*args, prune=True))
    big = jnp.zeros((1, cap + 1, 3))
    jax.eval_shape(lambda: _knn_pallas.knn(big, big[..., 0] == 0, big[:, :8], 10, True, True))
    assert calls == [1]  # the set of 1,000 only
