"""Padded sizes for host arrays (``jaxproj._internal.buckets``) and the public functions that use
them: one compile per bucket, not per length, and the same answers as the unpadded function
(to the float32 rounding that already depends on the batch's shape)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj._internal.buckets import (
    LINEAR_FROM,
    MIN_ROWS,
    bucket,
    fine_bucket,
    packed_calls,
    pad_rows,
)
from jaxproj.errors import ConfigError
from jaxproj.human import skeleton
from jaxproj.io import datasets
from jaxproj.projection import elm
from jaxproj.robots.nao_h25 import ik


@pytest.mark.parametrize(
    ("n", "want"),
    [(0, MIN_ROWS), (1, MIN_ROWS), (64, 64), (65, 128), (1000, 1024), (LINEAR_FROM, LINEAR_FROM),
     (LINEAR_FROM + 1, 2 * LINEAR_FROM), (5 * LINEAR_FROM - 3, 5 * LINEAR_FROM)],
)  # fmt: skip
def test_bucket(n, want):
    assert bucket(n) == want
    assert bucket(n, minimum=256) == max(want, 256)


@pytest.mark.parametrize(
    ("n", "want"),
    [(0, 64), (64, 64), (65, 80), (81, 96), (97, 112), (113, 128), (1018, 1024), (1025, 1280),
     (1157, 1280), (1283, 1536), (1537, 1792), (1793, 2048)],
)  # fmt: skip
def test_fine_bucket_pads_at_most_a_quarter(n, want):
    assert fine_bucket(n) == want
    assert fine_bucket(n, minimum=4) == want or n <= 64
    assert all(fine_bucket(m) - m <= m // 4 for m in range(64, 5000))


def test_pad_rows_keeps_the_rows_and_fills_the_rest():
    a = np.arange(6, dtype=np.float32).reshape(3, 2)
    b = pad_rows(a, 5, 7.0)
    assert b.shape == (5, 2) and b.dtype == a.dtype
    np.testing.assert_array_equal(b[:3], a)
    assert (b[3:] == 7.0).all()
    assert pad_rows(a, 2) is a


@pytest.fixture(scope="module")
def recordings() -> list[np.ndarray]:
    """Three real recordings of different lengths in one bucket (33..64 frames)."""
    seqs = datasets.msr_action3d(subjects=[1], actions=[1, 2, 3, 4, 5, 6])
    out = [s.positions for s in seqs if 33 <= len(s.positions) <= 64][:3]
    assert len({len(p) for p in out}) >= 2
    return out


def test_packed_calls_stack_motions_of_one_padded_length():
    """Every motion in exactly one call; a call's motions of one padded length (powers of two
    where coarse, quarter-octaves otherwise), at most ``frames // rows`` of them, its stack a
    power of two."""
    lengths = [60, 56, 50, 90, 300, 10, 64, 65] + [100] * 9
    for coarse in (True, False):
        calls = packed_calls(lengths, coarse=coarse, frames=1024)
        seen = sorted(i for _, members, _ in calls for i in members)
        assert seen == list(range(len(lengths)))
        sizes = bucket if coarse else fine_bucket
        for rows, members, count in calls:
            assert all(sizes(lengths[i]) == rows for i in members)
            assert len(members) <= max(1, 1024 // rows) and count >= len(members)
            assert count & (count - 1) == 0 and count >= len(members)
    # coarse: 64 rows for five, then 128 for eleven, 1024 // 128 = 8 a call; 512 for one
    got = [(r, len(m), c) for r, m, c in packed_calls(lengths, coarse=True, frames=1024)]
    assert got == [(64, 5, 8), (128, 8, 8), (128, 3, 8), (512, 1, 1)]  # one stack size a length
    fine = [(r, len(m), c) for r, m, c in packed_calls(lengths, coarse=False, frames=1024)]
    assert (112, 9, 16) in fine and (96, 1, 1) in fine  # quarter-octave rows: 100s, the 90


def test_descriptor_of_host_recordings_compiles_once_per_bucket(recordings, count_compiles):
    skeleton.descriptor(recordings[0])  # the bucket's program
    with count_compiles() as n:
        got = [skeleton.descriptor(p) for p in recordings]
    assert sum(n.values()) == 0, n  # other lengths, same bucket: nothing compiles
    index = tuple(skeleton.BONE_NAMES.index(b) for b in skeleton.UPPER_BODY)
    for p, (d, ok) in zip(recordings, got, strict=True):
        assert isinstance(d, jax.Array) and d.shape == (len(p), 15) and ok.shape == (len(p),)
        d0, ok0 = skeleton._descriptor(jnp.asarray(p, jnp.float32), index, False)  # unpadded
        np.testing.assert_array_equal(np.asarray(ok), np.asarray(ok0))
        np.testing.assert_allclose(np.asarray(d), np.asarray(d0), rtol=0, atol=1e-6)
    # one pose and a (S, T, 20, 3) batch keep their leading shape
    d1, ok1 = skeleton.descriptor(recordings[0][0])
    assert d1.shape == (15,) and ok1.shape == ()
    np.testing.assert_array_equal(np.asarray(d1), np.asarray(got[0][0][0]))
    stack = np.stack([recordings[0][:30], recordings[1][:30]])
    d2, _ = skeleton.descriptor(stack, "full")
    assert d2.shape == (2, 30, 57)
    with pytest.raises(ConfigError, match=r"\(\.\.\., 20, 3\)"):
        skeleton.descriptor(np.zeros((5, 19, 3)))


def test_ik_of_host_descriptors_compiles_once_per_bucket(recordings, count_compiles):
    ds = [np.asarray(skeleton.descriptor(p)[0]) for p in recordings]
    ik.solve_driven(ds[0])
    with count_compiles() as n:
        got = [np.asarray(ik.solve_driven(d)) for d in ds]
    assert sum(n.values()) == 0, n
    for d, q in zip(ds, got, strict=True):
        assert q.shape == (len(d), 10)
        np.testing.assert_allclose(q, np.asarray(ik.solve_driven(jnp.asarray(d))), atol=1e-6)
    assert np.asarray(ik.solve_driven(ds[0][0])).shape == (10,)


def test_elm_training_compiles_once_per_bucket_and_pads_no_neighbour(count_compiles):
    rng = np.random.default_rng(0)
    key = jax.random.key(1)
    x = rng.normal(size=(500, 4)).astype(np.float32)
    t = rng.normal(size=(500, 6)).astype(np.float32)
    elm.train_bank(x[:300], t[:300], key)  # the 512-row bucket's program
    with count_compiles() as n:
        banks = [elm.train_bank(x[:m], t[:m], key) for m in (290, 300, 400)]
    assert n["_train_bank"] == 0, n
    for m, bank in zip((290, 300, 400), banks, strict=True):
        assert bank.n_kernels == m and bank.out.shape == (m, 6, 32)
        nbr = np.asarray(bank.neighbours)
        assert nbr.shape == (m, 16) and nbr.max() < m  # never a padding row
        np.testing.assert_array_equal(nbr, np.asarray(elm.knn_indices(x[:m], 16)))
