import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.projection import search
from jaxproj.projection.elm import knn_indices, predict, train_bank
from jaxproj.projection.search import nearest, sq_norms
from jaxproj.testing import sq_distance_bound


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
    bound = sq_distance_bound(q[:, None], x[np.asarray(idx)])  # float32 error of |q-p|^2
    assert np.all(np.abs(np.asarray(d2) - np.sort(ref, axis=1)[:, :7]) <= bound)


U32 = float(np.finfo(np.float32).eps) / 2
"""Unit round-off of float32 (2^-24): one rounding moves a value by at most this, relatively."""


def _elm_float32_error_bound(
    w: np.ndarray,
    b: np.ndarray,
    rho: float,
    xi: np.ndarray,
    ti: np.ndarray,
    q: np.ndarray,
    lam: float,
    anchor: bool,
) -> tuple[np.ndarray, np.ndarray, float]:
    """A kernel's prediction at ``q`` in float64, and how far a float32 evaluation can be from it.

    The kernel (see ``jaxproj.projection.elm``) predicts ``f = t_0 + a^T B``, ``B = H^T c``,
    ``c = G^-1 (T - t_0)``, ``G = lam I + H H^T``, with ``a`` the query's hidden features (minus
    the landmark's, anchored). The ill-conditioned step is the solve: here ``cond(G)`` is 2e3-1e4
    (anchored) and 2e4-7e4 (plain sigmoid features, whose Gram matrix has one large eigenvalue,
    ~k * hidden / 4, against lam ~ 1e-3), and ``c`` is large along G's weakest eigenvector. To
    first order, rounding errors ``dG`` (from forming ``H H^T``, dot products of length ``hidden``,
    and from the Cholesky solve, backward error ``|dG| <= gamma_{3k+1} |R^T| |R|``, Higham,
    Accuracy and Stability, Thm 10.4) move the prediction by ``|z^T dG c|`` with ``z = G^-1 H a``:
    ``cond(G)`` enters through ``z`` and ``c``, both ~1/lambda_min(G) along that eigenvector. So::

        |f32 - f64| <= u * ( sqrt(hidden) |z|^T |H| |H|^T |c| + sqrt(3k+1) |z|^T |R^T||R| |c|
                           + sqrt(k) |a|^T |H|^T |c|                           # B = H^T c
                           + sqrt(hidden+1) (|t_0| + (|feat| + |q_0|) . |B|)     # t_0 + a . B
                           + (sqrt(d_in)+2) sum_l s'_l (|W_l|(|q|+|c_0|)/rho + |b_l|) |B_l| )

    per output (the ``|q_0|`` term only when anchored), the last line being the rounding of the
    pre-activations ``(W x) / rho + beta``
    through the sigmoid's slope ``s'``. The worst-case constant of a length-n sum is ``n u``
    (Higham Thm 3.5); rounding errors of random sign grow like ``sqrt(n) u`` instead
    (Wilkinson's rule, made rigorous with high probability by Higham & Mary, SIAM J. Sci.
    Comput. 41, 2019, and Ipsen & Zhou, 2020), which is what is used. The absolute-value sums
    over the k^2 entries of ``dG`` take no credit for cancellations between them, which is where
    the margin lies: over all 120 kernels of this test, the float32 answers of 28 different
    summation orders and vector paths (XLA_FLAGS=--xla_cpu_max_isa=AVX or SSE4_2 (no FMA: the
    old fixed atol=2e-4 failed there, 6.6e-4, as on another CPU), --xla_cpu_enable_fast_math=true,
    vmap batches of 1/8/40/120 kernels, 20 random permutations of the hidden units and training
    points, NumPy/LAPACK float32) stayed within 0.08 of it, with errors up to 2.5e-3 (plain) and
    1.4e-4 (anchored). It still catches real mistakes: training with lam off by 30% exceeds it on
    119 of the 120 kernels (by up to 8x plain, 140x anchored).

    Returns:
      ``(f, bound, cond(G))``: ``(d_out,)`` float64 prediction and error bound, and ``cond(G)``.
    """
    k, hidden, d_in = len(xi), len(b), len(q)
    c0 = xi[0]
    h = _sigmoid((xi - c0) @ w.T / rho + b)  # (k, hidden)
    q0 = h[0].copy()
    if anchor:
        h = h - q0
    gram = lam * np.eye(k) + h @ h.T
    coef = np.linalg.solve(gram, ti - ti[0])  # (k, d_out)
    beta = h.T @ coef  # (hidden, d_out)
    feat = _sigmoid((q - c0) @ w.T / rho + b)
    a = feat - q0 if anchor else feat
    f = ti[0] + a @ beta
    z = np.linalg.solve(gram, h @ a)
    r = np.linalg.cholesky(gram).T
    ah, ac, ab = np.abs(h), np.abs(coef), np.abs(beta)
    solve = np.abs(z) @ (np.sqrt(hidden) * ah @ ah.T + np.sqrt(3 * k + 1) * np.abs(r.T) @ np.abs(r))
    slope = feat * (1.0 - feat) * (np.abs(w) @ (np.abs(q) + np.abs(c0)) / rho + np.abs(b))
    bound = U32 * (
        solve @ ac
        + np.sqrt(k) * (np.abs(a) @ ah.T) @ ac
        + np.sqrt(hidden + 1) * (np.abs(ti[0]) + (feat + (q0 if anchor else 0.0)) @ ab)
        + (np.sqrt(d_in) + 2.0) * slope @ ab
    )
    return f, bound, float(np.linalg.cond(gram))


@pytest.mark.parametrize("anchor", [False, True])
def test_bank_equals_a_numpy_elm_per_kernel(anchor):
    x, y = _data()
    k, hidden, lam = 12, 24, 1e-3
    bank = train_bank(x, y, jax.random.PRNGKey(3), k=k, hidden=hidden, lam=lam, anchor=anchor)
    w = np.asarray(bank.w, np.float64)
    b_shared = None
    for i in range(len(x)):  # every kernel, each at its own random query point
        nbr = np.asarray(bank.neighbours[i])
        xi, ti = x[nbr].astype(np.float64), y[nbr].astype(np.float64)
        rho = np.max(np.linalg.norm(xi - xi[0], axis=1))
        # recover the shared bias b from beta_i = b - W c_i / rho_i. In float32, W c_i (length
        # d_in: d_in u |W||c_i|), rho_i (a norm: 5 u), 1 / rho_i, their product and the
        # difference are rounded, so each recovered b is within (worst case, first order)
        # u (|b| + (2 d_in + 2) |W||c_i| / rho_i) of the true one; measured: within 0.2 of it
        b = np.asarray(bank.bias[i], np.float64) + w @ xi[0] / rho
        b_err = U32 * (np.abs(b) + (2 * x.shape[1] + 2) * (np.abs(w) @ np.abs(xi[0])) / rho)
        if b_shared is None:
            b_shared, b_err_0 = b, b_err
        assert (np.abs(b - b_shared) <= b_err + b_err_0).all(), f"kernel {i}: bias differs"
        q = np.random.default_rng(i).normal(size=6)
        want, bound, cond = _elm_float32_error_bound(w, b, rho, xi, ti, q, lam, anchor)
        got = np.asarray(predict(bank, q.astype(np.float32), np.array(i)), np.float64)
        err = np.abs(got - want)
        assert (err <= bound).all(), (
            f"kernel {i}: |error| {err} > bound {bound}, cond(G) {cond:.3g}"
        )


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
    bound = sq_distance_bound(q[:, None], pts[np.asarray(idx)])  # float32 error of |q-p|^2
    assert np.all(np.abs(np.asarray(d2) - np.sort(ref, axis=1)[:, :n]) <= bound)


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


@pytest.mark.parametrize("n", [1, 3, 10, 16])
def test_repeated_minima_select_exactly_what_top_k_selects(n):
    """The accelerator selection (``search._repeated_min``, the default off CPUs) against
    ``lax.top_k``: the same values and positions, nearest first, with ties, infinities (padded
    landmarks) and rows shorter than a block."""
    rng = np.random.default_rng(n)
    v = rng.integers(0, 40, size=(64, 37)).astype(np.float32)  # many exact ties
    v[:, -5:] = np.inf
    pos, val = search._repeated_min(n)(jnp.asarray(v))
    neg, ref_pos = jax.lax.top_k(-jnp.asarray(v), n)
    np.testing.assert_array_equal(np.asarray(val), -np.asarray(neg))
    np.testing.assert_array_equal(np.take_along_axis(v, np.asarray(pos), 1), np.asarray(val))
    assert all(len(set(row)) == n for row in np.asarray(pos).tolist())  # n distinct entries
    # without ties the positions are top_k's too
    u = rng.permutation(64 * 37).reshape(64, 37).astype(np.float32)
    np.testing.assert_array_equal(
        np.asarray(search._repeated_min(n)(jnp.asarray(u))[0]),
        np.asarray(jax.lax.top_k(-jnp.asarray(u), n)[1]),
    )


@pytest.mark.parametrize(("k", "n"), [(2000, 10), (1656, 16)])
def test_two_stage_nearest_with_the_accelerator_selection_is_exact(k, n, monkeypatch):
    """``nearest`` as it runs on GPUs (both stages by repeated minima), forced on the CPU."""
    monkeypatch.setattr(search, "smallest", lambda v, m: search._repeated_min(m)(v))
    rng = np.random.default_rng(k)
    pts = rng.normal(size=(k, 4)).astype(np.float32)
    q = rng.normal(size=(40, 4)).astype(np.float32)
    idx, d2 = nearest(pts, sq_norms(pts), q, n)
    ref = ((q[:, None].astype(np.float64) - pts[None]) ** 2).sum(-1)
    np.testing.assert_array_equal(np.asarray(idx), np.argsort(ref, axis=1)[:, :n])
    bound = sq_distance_bound(q[:, None], pts[np.asarray(idx)])  # float32 error of |q-p|^2
    assert np.all(np.abs(np.asarray(d2) - np.sort(ref, axis=1)[:, :n]) <= bound)
