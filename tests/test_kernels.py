import jax
import numpy as np
import pytest

from jaxproj.exceptions import ConfigError
from jaxproj.kernels import knn_indices, predict, train_bank
from jaxproj.search import nearest, sq_norms


def _data(n=120, d_in=6, d_out=4, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, d_in)).astype(np.float32)
    a = rng.normal(size=(d_in, d_out))
    y = np.tanh(x @ a).astype(np.float32)
    return x, y


def _sigmoid(z):
    return 1.0 / (1.0 + np.exp(-z))


def test_knn_matches_numpy_and_puts_self_first():
    x, _ = _data(n=700)  # more rows than one block
    got = np.asarray(knn_indices(x, 9))
    d2 = ((x[:, None].astype(np.float64) - x[None]) ** 2).sum(-1)
    want = np.argsort(d2, axis=1, kind="stable")[:, :9]
    assert (got[:, 0] == np.arange(len(x))).all()
    np.testing.assert_array_equal(np.sort(got, axis=1), np.sort(want, axis=1))


def test_nearest_matches_numpy():
    x, _ = _data(n=300)
    q = np.random.default_rng(1).normal(size=(5, 6)).astype(np.float32)
    idx, d2 = nearest(x, sq_norms(x), q, 7)
    ref = ((q[:, None].astype(np.float64) - x[None]) ** 2).sum(-1)
    np.testing.assert_array_equal(np.asarray(idx), np.argsort(ref, axis=1)[:, :7])
    np.testing.assert_allclose(np.asarray(d2), np.sort(ref, axis=1)[:, :7], rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("anchor", [False, True])
def test_bank_equals_a_numpy_elm_per_kernel(anchor):
    x, y = _data()
    k, hidden, lam = 12, 24, 1e-3
    bank = train_bank(x, y, jax.random.PRNGKey(3), k=k, hidden=hidden, lam=lam, anchor=anchor)
    w = np.asarray(bank.w, np.float64)
    b_shared = None
    for i in (0, 17, 119):
        nbr = np.asarray(bank.neighbours[i])
        xi, ti = x[nbr].astype(np.float64), y[nbr].astype(np.float64)
        rho = np.max(np.linalg.norm(xi - xi[0], axis=1))
        # recover the shared bias b from beta_i = b - W c_i / rho_i
        b = np.asarray(bank.bias[i], np.float64) + w @ xi[0] / rho
        if b_shared is None:
            b_shared = b
        np.testing.assert_allclose(b, b_shared, atol=1e-4)
        h = _sigmoid((xi - xi[0]) @ w.T / rho + b)
        q0 = h[0].copy()
        if anchor:
            h = h - q0
        beta = h.T @ np.linalg.solve(lam * np.eye(k) + h @ h.T, ti - ti[0])
        q = np.random.default_rng(i).normal(size=6)
        feat = _sigmoid((q - xi[0]) @ w.T / rho + b)
        want = ti[0] + ((feat - q0) if anchor else feat) @ beta
        got = np.asarray(predict(bank, q.astype(np.float32), np.array(i)))
        np.testing.assert_allclose(got, want, atol=2e-4)


def test_each_kernel_interpolates_its_training_pairs():
    x, y = _data()
    bank = train_bank(x, y, jax.random.PRNGKey(0), k=10, hidden=40, lam=1e-6)
    for i in range(0, 120, 7):
        nbr = np.asarray(bank.neighbours[i])
        got = np.stack([np.asarray(predict(bank, x[j], np.array(i))) for j in nbr])
        np.testing.assert_allclose(got, y[nbr], atol=2e-2)
        # the kernel's own landmark is reproduced closely (identity property)
        np.testing.assert_allclose(got[0], y[i], atol=2e-3)


def test_anchored_kernels_are_exact_at_their_landmark_even_when_smooth():
    x, y = _data()
    # heavy regularisation and a small input scale: the kernels no longer interpolate...
    kw = dict(k=30, hidden=60, lam=1e-1, input_scale=0.3)
    plain = train_bank(x, y, jax.random.PRNGKey(0), anchor=False, **kw)
    anchored = train_bank(x, y, jax.random.PRNGKey(0), anchor=True, **kw)
    idx = np.arange(len(x))
    own_plain = np.stack([np.asarray(predict(plain, x[i], np.array(i))) for i in idx])
    own_anchor = np.stack([np.asarray(predict(anchored, x[i], np.array(i))) for i in idx])
    assert np.abs(own_plain - y).max() > 1e-2
    # ...but the anchored ones still reproduce their own landmark
    np.testing.assert_allclose(own_anchor, y, atol=1e-5)


def test_training_is_deterministic_and_key_dependent():
    x, y = _data()
    a = train_bank(x, y, jax.random.PRNGKey(0), k=8, hidden=16)
    b = train_bank(x, y, jax.random.PRNGKey(0), k=8, hidden=16)
    c = train_bank(x, y, jax.random.PRNGKey(1), k=8, hidden=16)
    np.testing.assert_array_equal(np.asarray(a.out), np.asarray(b.out))
    assert not np.allclose(np.asarray(a.out), np.asarray(c.out))


@pytest.mark.parametrize(
    ("kw", "word"),
    [(dict(k=1), "k=1"), (dict(k=20, hidden=10), "hidden"), (dict(lam=0.0), "lam")],
)
def test_bad_settings_are_config_errors(kw, word):
    x, y = _data()
    with pytest.raises(ConfigError, match=word):
        train_bank(x, y, jax.random.PRNGKey(0), **kw)


@pytest.mark.parametrize(("k", "n"), [(2000, 10), (1637, 50), (8192, 3)])
def test_two_stage_nearest_is_exact_on_large_sets(k, n):
    rng = np.random.default_rng(k)
    pts = rng.normal(size=(k, 10)).astype(np.float32)
    q = rng.normal(size=(40, 10)).astype(np.float32)
    idx, d2 = nearest(pts, sq_norms(pts), q, n)
    ref = ((q[:, None].astype(np.float64) - pts[None]) ** 2).sum(-1)
    np.testing.assert_array_equal(np.asarray(idx), np.argsort(ref, axis=1)[:, :n])
    np.testing.assert_allclose(np.asarray(d2), np.sort(ref, axis=1)[:, :n], rtol=1e-4, atol=1e-4)


def test_an_ill_conditioned_ridge_system_is_a_config_error_never_nan():
    """A tiny ridge leaves lam I + H H^T numerically indefinite in float32 (its Cholesky gives
    NaN): training refuses with a message that says what to change, instead of a NaN bank."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(200, 3)).astype(np.float32)
    t = rng.normal(size=(200, 2)).astype(np.float32)
    key = jax.random.PRNGKey(0)
    with pytest.raises(ConfigError, match="non-finite weights.*raise lam"):
        train_bank(x, t, key, k=32, hidden=64, lam=1e-8, input_scale=1.0)
    bank = train_bank(x, t, key, k=32, hidden=64, lam=1e-3, input_scale=1.0)
    assert np.isfinite(np.asarray(bank.out)).all()
