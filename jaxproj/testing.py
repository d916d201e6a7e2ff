"""The test oracle of the projection engine: the paper's algorithm, per query, in float64 NumPy.

``Reference`` re-implements the relaxed and full objectives (``jaxproj.projection.relaxed``,
``jaxproj.projection.full``) independently: NumPy in float64, one query at a time, exact k
nearest neighbours from ``scipy.spatial.cKDTree``, the full objective's gradients written out
by hand (no autodiff, no optax). It reads the landmarks and kernel banks of a trained
``Projector`` as they are, so engine and oracle answer the same question; the tests
(``tests/test_testing.py``) and the benchmarks (``benchmarks/bench_projection.py``) check the
float32 JAX engine against it. It is also the benchmarks' speed baseline: the code a Python user
would write without JAX.

It needs scipy, which is a test extra (``pip install "jaxproj[test]"``), not a dependency of
the package: scipy is imported when a ``Reference`` is constructed, not when this module is.

Size: over 500 lines: one oracle (the relaxed and full objectives in float64, the near-tie judge)
and the float32 error bounds the tests compare within.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, StackedProjector
from jaxproj.projection.relaxed import SEARCH_RTOL, TIE_ATOL, TIE_RTOL
from jaxproj.projection.simplex_newton import DAMPING_START, DAMPINGS, QP_SWEEPS, WEIGHT_FLOOR


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def simplex_projection(x: np.ndarray) -> np.ndarray:
    """Euclidean projection of each row of ``x (..., d)`` onto the unit simplex (NumPy)."""
    d = x.shape[-1]
    u = -np.sort(-x, axis=-1)
    css = np.cumsum(u, axis=-1)
    ind = np.arange(1, d + 1)
    cond = 1.0 / ind + (u - css / ind) > 0
    k = np.count_nonzero(cond, axis=-1)[..., None]  # >= 1
    theta = (np.take_along_axis(css, k - 1, axis=-1) - 1.0) / k
    return np.maximum(x - theta, 0.0)


def _modified_cholesky_solve(a: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``a^{-1} rhs`` through a Cholesky factor whose negative pivots are taken by absolute
    value (``simplex_newton._cholesky_solve``'s rule), in float64."""
    p = a.shape[0]
    low = np.zeros_like(a)
    floor = 1e-12 * np.abs(np.diag(a)).max()
    for j in range(p):
        v = a[:, j] - low[:, :j] @ low[j, :j]
        d = np.sqrt(max(abs(v[j]), floor))
        low[j, j] = d
        low[j + 1 :, j] = v[j + 1 :] / d
    y = np.linalg.solve(low, rhs)  # triangular; a general solve is exact enough here
    return np.linalg.solve(low.T, y)


def _simplex_qp(b: np.ndarray, c: np.ndarray, x: np.ndarray, sweeps: int) -> np.ndarray:
    """``x^T B x / 2 + c.x`` lowered over the unit simplex by ``sweeps`` sweeps of the primal
    active-set method ``simplex_newton.simplex_qp`` runs, from the feasible ``x`` (float64)."""
    x = np.where(x > WEIGHT_FLOOR, x, 0.0)
    x = x / x.sum()
    free = x > 0
    for _ in range(sweeps):
        a = np.where(free[:, None] & free[None, :], b, 0.0) + np.diag(np.where(free, 0.0, 1.0))
        z = _modified_cholesky_solve(a, np.stack([np.where(free, -c, 0.0), free * 1.0], axis=1))
        nu = (z[:, 0].sum() - 1.0) / z[:, 1].sum()
        y = np.where(free, z[:, 0] - nu * z[:, 1], 0.0)
        if (y[free] >= 0).all():
            x = y
            lam = np.where(free, np.inf, b @ y + c + nu)
            i = int(np.argmin(lam))
            if lam[i] >= 0:
                return x
            free[i] = True
        else:
            dec = free & (y < x)
            ratio = np.full(len(x), np.inf)
            ratio[dec] = x[dec] / (x[dec] - y[dec])
            i = int(np.argmin(ratio))
            x = np.where(free, x + min(ratio[i], 1.0) * (y - x), 0.0)
            x[i] = 0.0
            free[i] = False
    return x


def near_set(
    tree: Any, pts: np.ndarray, x: np.ndarray, n: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """The ``n`` nearest of ``pts (K, d)`` (in the cKDTree ``tree``) to ``x (d,)`` under the
    search tie (``projection.relaxed.SEARCH_RTOL``): ``(sure, tied, need)``, the indices surely
    among them and, apart, those tied with the ``n``-th (itself included), ``need`` of which
    complete the set (none tied, ``need == 0``, when the ``n+1``-th is clear of the ``n``-th)."""
    k = min(n + 4, len(pts))
    d, idx = tree.query(x, k=k)
    d2, idx = np.asarray(d) ** 2, np.asarray(idx)
    band = SEARCH_RTOL * (x @ x + pts[idx[n - 1]] @ pts[idx[n - 1]])
    if k == n or d2[n] - d2[n - 1] > band:  # the set is fixed
        return idx[:n], idx[:0], 0
    sure = idx[d2 < d2[n - 1] - band]
    tied = idx[np.abs(d2 - d2[n - 1]) <= band]
    return sure, tied, n - len(sure)


F32_UNIT_ROUNDOFF = 2.0**-24
"""``u``: the largest relative error of one float32 rounding (round to nearest)."""

SIGMOID_ULPS = 4.0
"""Relative error of one float32 sigmoid, in units of ``u`` (``exp``, one add and one divide,
each correctly rounded or within an ulp)."""


def _gamma(n: int | np.ndarray) -> np.ndarray:
    """Higham's ``gamma_n = n u / (1 - n u)``: the relative error bound of a float32 sum of
    ``n`` terms in any order (``|fl(sum x) - sum x| <= gamma_{n-1} sum |x|``)."""
    nu = np.asarray(n, np.float64) * F32_UNIT_ROUNDOFF
    return nu / (1.0 - nu)


def kernel_output_bound(
    bank: Any, x: np.ndarray, idx: np.ndarray, d_in: int, d_out: int, hidden: int
) -> tuple[np.ndarray, np.ndarray]:
    """ELM kernels' outputs in float64, and a bound on the error of their float32 evaluation.

    ``kappa_k(x) = offset_k + B_k^T sigmoid(W x / rho_k + beta_k)`` (``projection.elm.predict``,
    or the fused Pallas kernels, in any summation order) for rows of float32 inputs. The bound
    is a first-order forward error analysis (Higham, *Accuracy and Stability of Numerical
    Algorithms*, ch. 3) of that arithmetic with the float64 magnitudes of the actual operands,
    so it grows where the computation is ill-conditioned (large output weights whose products
    cancel):

    * ``W x`` (``d_in`` terms): ``gamma_{d_in} sum_d |W_jd x_d|``; the scale and bias add
      ``u |W x / rho|`` and ``u |pre|``; the sigmoid passes ``q (1 - q)`` of that and adds
      ``SIGMOID_ULPS u q``;
    * ``y_o = offset_o + sum_j B_jo q_j`` (``hidden + 1`` terms): ``gamma_{hidden + 1}
      (|offset| + sum |B q|)`` plus ``sum_j |B_jo| dq_j``.

    Args:
      bank: an ``ELMBank`` (may be padded beyond the sizes below).
      x: ``(R, >= d_in)`` input points; idx: ``(R, M)`` kernels of each row.
      d_in, d_out, hidden: the kernels' real sizes.

    Returns:
      ``(y, err)``: ``(R, M, d_out)`` float64 outputs and bounds on their float32 error.
    """
    u = F32_UNIT_ROUNDOFF
    w = np.asarray(bank.w, np.float64)[:hidden, :d_in]
    x = np.asarray(x, np.float64)[:, :d_in]
    idx = np.asarray(idx)
    inv = np.asarray(bank.inv_scale, np.float64)[idx][..., None]  # (R, M, 1)
    bias = np.asarray(bank.bias, np.float64)[idx][..., :hidden]  # (R, M, H)
    out = np.asarray(bank.out, np.float64)[idx][..., :d_out, :hidden]  # (R, M, O, H)
    offset = np.asarray(bank.offset, np.float64)[idx][..., :d_out]  # (R, M, O)

    wx = x @ w.T  # (R, H)
    err_wx = _gamma(d_in) * (np.abs(x) @ np.abs(w).T)
    scaled = wx[:, None, :] * inv
    pre = scaled + bias
    err_pre = np.abs(inv) * err_wx[:, None, :] + u * (np.abs(scaled) + np.abs(pre))
    q = _sigmoid(pre)
    err_q = q * (1.0 - q) * err_pre + SIGMOID_ULPS * u * q
    y = offset + np.einsum("rmoh,rmh->rmo", out, q)
    mag = np.abs(offset) + np.einsum("rmoh,rmh->rmo", np.abs(out), q)
    err = _gamma(hidden + 1) * mag + np.einsum("rmoh,rmh->rmo", np.abs(out), err_q)
    return y, err


def back_deviation_bound(
    bank: Any, r: np.ndarray, h: np.ndarray, idx: np.ndarray, d_in: int, d_out: int, hidden: int
) -> tuple[np.ndarray, np.ndarray]:
    """The least squared back-projected deviation in float64, and a bound on its float32 error.

    What ``projection.relaxed.least_deviations_rows`` computes (by XLA's three passes or the
    fused Pallas kernel, in any summation order), for rows of float32 inputs: ``min_k
    ||kappa_k(r) - h||^2``. On top of ``kernel_output_bound``'s ``E_o`` for ``y = kappa_k(r)``:
    ``e_o = y_o - h_o`` adds ``u |e_o|``; ``sum_o e_o^2`` is off by ``sum_o (2 |e_o| E_o +
    E_o^2) + gamma_{d_out + 1} sum_o e_o^2``; the minimum over the row's kernels by at most the
    largest of their bounds. It grows where the deviation is a small difference of large
    coordinates.

    Args:
      bank: an ``ELMBank`` (backward kernels; may be padded beyond the sizes below).
      r: ``(R, >= d_in)`` robot points; h: ``(R, >= d_out)`` queries; idx: ``(R, M)`` kernels.
      d_in, d_out, hidden: the kernels' real sizes.

    Returns:
      ``(b, bound)``: ``(R,)`` float64 least squared deviations and ``(R,)`` bounds such that a
      float32 evaluation of ``b`` lies within ``bound`` of it.
    """
    y, err = kernel_output_bound(bank, r, idx, d_in, d_out, hidden)
    e = y - np.asarray(h, np.float64)[:, None, :d_out]
    err = err + F32_UNIT_ROUNDOFF * np.abs(e)
    b = np.sum(e * e, axis=-1)  # (R, M)
    bound = np.sum(2.0 * np.abs(e) * err + err * err, axis=-1) + _gamma(d_out + 1) * b
    return b.min(axis=1), bound.max(axis=1)


def sq_distance_bound(x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A bound on the float32 error of squared distances computed as ``|x|^2 - 2 x.p + |p|^2``
    (``projection.search``'s form, by any kernel and summation order): ``gamma_{d+2} (|x|^2 +
    2 sum_i |x_i p_i| + |p|^2)`` for ``x (..., d)`` and ``p (..., d)`` (broadcast), float64."""
    x, p = np.asarray(x, np.float64), np.asarray(p, np.float64)
    mag = np.sum(x * x, axis=-1) + 2.0 * np.sum(np.abs(x * p), axis=-1) + np.sum(p * p, axis=-1)
    return _gamma(x.shape[-1] + 2) * mag


class _Bank:
    def __init__(self, bank: Any) -> None:
        self.w = np.asarray(bank.w, np.float64)
        self.inv = np.asarray(bank.inv_scale, np.float64)
        self.bias = np.asarray(bank.bias, np.float64)
        self.out = np.swapaxes(np.asarray(bank.out, np.float64), -1, -2)  # (K, hidden, d_out)
        self.offset = np.asarray(bank.offset, np.float64)

    def predict(self, x: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Kernels ``idx (..., k)`` at points ``x (..., d_in)`` -> (predictions, features)."""
        wx = x @ self.w.T  # (..., hidden)
        q = _sigmoid(wx[..., None, :] * self.inv[idx][..., None] + self.bias[idx])
        return self.offset[idx] + np.einsum("...h,...ho->...o", q, self.out[idx]), q


class Reference:
    """The paper's projection, per query, in NumPy + ``scipy.spatial.cKDTree`` (float64).

    Uses the landmarks and kernel banks of a trained ``Projector`` as they are; it is both the
    speed baseline and the exact answer the engine is checked against.
    """

    def __init__(self, p: Projector) -> None:
        from scipy.spatial import cKDTree  # a test extra: imported only here

        self.human = np.asarray(p.human, np.float64)
        self.robot = np.asarray(p.robot, np.float64)
        self.lower = np.asarray(p.lower, np.float64)
        self.upper = np.asarray(p.upper, np.float64)
        self.forward = _Bank(p.forward)
        self.backward = _Bank(p.backward)
        self.tree_h = cKDTree(self.human)
        self.tree_r = cKDTree(self.robot)

    def _knn(self, tree: Any, x: np.ndarray, n: int) -> np.ndarray:
        _, idx = tree.query(x, k=n)
        return np.asarray(idx).reshape(*x.shape[:-1], n)

    def candidates(self, h: np.ndarray, n_l: int) -> np.ndarray:
        """``(m,) -> (L, n)``: forward-kernel candidates of the ``L`` nearest human landmarks."""
        idx = self._knn(self.tree_h, h, n_l)
        return self.forward.predict(h, idx)[0]

    def relaxed_choices(self, h: np.ndarray, n_l: int, n_m: int) -> tuple[np.ndarray, np.ndarray]:
        """The relaxed objective's choices for one query ``(m,)``: ``(L, n)`` candidates clipped
        to the joint limits and ``(L,)`` their least squared back-projected deviations."""
        h = np.asarray(h, np.float64)
        cand = self.candidates(h, n_l)  # (L, n)
        ridx = self._knn(self.tree_r, cand, n_m)  # (L, M)
        back, _ = self.backward.predict(cand[:, None, :], ridx[:, None, :])  # (L, 1, M, m)
        dev = np.sum((back[:, 0] - h) ** 2, axis=-1)  # (L, M)
        return np.clip(cand, self.lower, self.upper), dev.min(axis=1)

    def relaxed(self, h: np.ndarray, n_l: int, n_m: int) -> tuple[np.ndarray, float]:
        """Relaxed projection of one query ``(m,)`` -> (pose ``(n,)``, deviation)."""
        cand, best = self.relaxed_choices(h, n_l, n_m)
        j = int(np.argmin(best))
        return cand[j], float(np.sqrt(best[j]))

    def judge(self, h: np.ndarray, r: np.ndarray, n_l: int, n_m: int, tol: float) -> str:
        """Whether ``r (n,)`` is a correct relaxed answer for ``h (m,)`` under the near-tie rule
        (``projection.relaxed.TIE_RTOL``): ``"exact"``, within ``tol`` rad on every joint of
        the reference's pick (``relaxed``); ``"tie"``, of a candidate that some resolution of
        the search ties makes tie with the best (its least possible deviation within the
        deviation tie of the least deviation the engine can have found); ``"differs"``,
        neither."""
        h, r = np.asarray(h, np.float64), np.asarray(r, np.float64)
        pick, _ = self.relaxed(h, n_l, n_m)
        if np.max(np.abs(pick - r)) <= tol:
            return "exact"
        sure_h, tied_h, _ = near_set(self.tree_h, self.human, h, n_l)
        idx_h = np.concatenate([sure_h, tied_h])
        cand = self.forward.predict(h, idx_h)[0]  # (L', n)
        lo, hi = np.empty(len(idx_h)), np.empty(len(idx_h))
        for j, c in enumerate(cand):
            sure, tied, need = near_set(self.tree_r, self.robot, c, n_m)
            idx = np.concatenate([sure, tied])
            back = self.backward.predict(c[None, :], idx[None, :])[0][0]  # (M', m)
            dev = np.sqrt(np.sum((back - h) ** 2, axis=-1))
            lo[j] = dev.min()  # the engine used the tied kernel with the least deviation
            worst = np.sort(dev[len(sure) :])[::-1][:need]  # ... or the worst ones
            hi[j] = min(dev[: len(sure)].min(initial=np.inf), worst.min(initial=np.inf))
        best = hi[: len(sure_h)].min(initial=hi.max())  # the engine's least is at most this
        match = np.max(np.abs(np.clip(cand, self.lower, self.upper) - r), axis=1) <= tol
        tie = lo <= best + TIE_RTOL * best + TIE_ATOL
        return "tie" if np.any(match & tie) else "differs"

    def full(
        self,
        h: np.ndarray,
        n_l: int,
        n_m: int,
        cfg: FullConfig = FullConfig(),  # noqa: B008 - immutable
    ) -> tuple[np.ndarray, float]:
        """Full projection of one query (``projection.full.project_full_one``, in NumPy).

        The same problems (``full.problems``: the weighted or the ``min_k min_w`` reading, the
        proximal and ridge terms), each solved in float64 by ``cfg.solver``: ``"newton"``, the
        engine's steps run to convergence on every problem (``_solve_newton``;
        ``cfg.iterations``, ``screen`` and ``finalists`` are ignored), ``"adam"`` as the engine
        does (``cfg.iterations`` steps, best iterate). The derivatives are written out by hand
        (``_derivatives``: the value, the gradient and the Gauss-Newton Hessian the engine
        uses). With ``cfg.clusters`` only the problems with
        the smallest warm-start values are solved. Returns (pose ``(n,)``, objective value).
        """
        h = np.asarray(h, np.float64)
        cand = self.candidates(h, n_l)  # (L, n)
        ridx = self._knn(self.tree_r, cand, n_m)  # (L, M)
        probs = [p for j in range(n_l) for p in self._problems(cand[j], ridx[j], cfg)]
        f0 = np.array([self._value(h, pr, pr["w0"], cfg) for pr in probs])
        order = np.arange(len(probs))  # candidate ranks, for the near-tie rule
        if 0 < cfg.clusters < len(probs):
            order = np.argsort(f0, kind="stable")[: cfg.clusters]
            probs = [probs[i] for i in order]
        solve = self._solve_adam if cfg.solver == "adam" else self._solve_newton
        out = [solve(h, pr, cfg) for pr in probs]
        f = np.array([v for _, v in out])
        # ``FullConfig.tie_rtol``: the first in candidate order within the tie of the least
        tied = f <= f.min() + cfg.tie_rtol * abs(f.min())
        j = int(np.argmin(np.where(tied, order, len(order) + np.max(order))))
        return np.clip(out[j][0], self.lower, self.upper), float(out[j][1])

    def _problems(self, r_c: np.ndarray, idx: np.ndarray, cfg: FullConfig) -> list[dict]:
        """The simplex problems of one candidate (``full.problems``), as dicts."""
        rk = self.robot[idx]
        n_m = len(idx)
        if cfg.include_candidate:
            verts = np.concatenate([r_c[None], rk])
            w0 = np.zeros(n_m + 1)
            w0[0] = 1.0
        else:
            verts = rk
            w0 = 1.0 / (np.sum((rk - r_c) ** 2, axis=1) + 1e-8)
            w0 /= w0.sum()
        base = dict(verts=verts, w0=w0, anchor=r_c)
        if cfg.objective == "min":
            zero = np.zeros((1, len(w0)))
            return [base | dict(k=idx[i : i + 1], mix=zero, mix0=np.ones(1)) for i in range(n_m)]
        mix = np.eye(n_m)
        if cfg.include_candidate:
            mix = np.concatenate([np.full((n_m, 1), 1.0 / n_m), mix], axis=1)
        return [base | dict(k=idx, mix=mix, mix0=np.zeros(n_m))]

    def _kernels(self, pr: dict, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The problem's kernels at ``r``: predictions ``(K, m)`` and Jacobians ``(K, m, n)``."""
        b = self.backward
        k = pr["k"]
        s = b.inv[k][:, None]  # (K, 1)
        q = _sigmoid((b.w @ r)[None] * s + b.bias[k])  # (K, H)
        out = np.swapaxes(b.out[k], 1, 2)  # (K, m, H)
        pred = b.offset[k] + np.einsum("koh,kh->ko", out, q)
        d1 = q * (1 - q) * s  # d q / d (W r)
        return pred, np.einsum("koh,kh,hn->kon", out, d1, b.w)

    def _value(self, h: np.ndarray, pr: dict, w: np.ndarray, cfg: FullConfig) -> float:
        return self._derivatives(h, pr, w, cfg, order=0)[0]

    def _derivatives(
        self, h: np.ndarray, pr: dict, w: np.ndarray, cfg: FullConfig, order: int = 2
    ) -> tuple[float, np.ndarray, np.ndarray]:
        """``F(w)`` and (``order`` >= 1) its gradient, (2) its Gauss-Newton Hessian in the
        weights (the residuals' second derivatives left out, as the engine does)."""
        v = pr["verts"]
        r = v.T @ w
        pred, jac = self._kernels(pr, r)
        e = pred - h
        phi = np.sum(e * e, axis=1)
        u = pr["mix"] @ w + pr["mix0"]
        dr = r - pr["anchor"]
        f = float(u @ phi + 0.5 * cfg.proximal * dr @ dr + 0.5 * cfg.ridge * w @ w)
        if order == 0:
            return f, np.zeros(0), np.zeros(0)
        pg = 2 * np.einsum("kon,ko->kn", jac, e)  # (K, n) gradients of phi_k
        g_r = u @ pg + cfg.proximal * dr
        grad = pr["mix"].T @ phi + v @ g_r + cfg.ridge * w
        cross = pr["mix"].T @ pg @ v.T
        if order == 1:
            return f, grad, np.zeros(0)
        h_r = 2 * np.einsum("k,kon,kop->np", u, jac, jac) + cfg.proximal * np.eye(len(r))
        return f, grad, cross + cross.T + v @ h_r @ v.T + cfg.ridge * np.eye(len(w))

    def _solve_newton(self, h: np.ndarray, pr: dict, cfg: FullConfig) -> tuple[np.ndarray, float]:
        """The engine's projected Gauss-Newton (``simplex_newton``) in float64, every problem
        run to convergence: until the model promises less than ``1e-12 F``, the step moved
        no joint by ``1e-9`` rad and the Frank-Wolfe gap ``g.w - min(g)`` is at most
        ``cfg.gap_tol * F`` (the engine's first-order test; none for ``gap_tol = 0``), or no
        damping lowers ``F`` (float64 exhausted); at most 500 steps. Returns (r(w*), F(w*))."""
        w = pr["w0"].copy()
        f, g, hess = self._derivatives(h, pr, w, cfg)
        r = pr["verts"].T @ w
        damping = DAMPING_START
        for _ in range(500):
            scale = float(np.mean(np.diag(hess))) + 1e-12
            trials, values = [], []
            for mult in DAMPINGS:
                b = hess + damping * mult * scale * np.eye(len(w))
                t = _simplex_qp(b, g - b @ w, w, QP_SWEEPS)
                trials.append(t)
                ok = np.isfinite(t).all()
                values.append(self._value(h, pr, t, cfg) if ok else np.inf)
            dx = [t - w for t in trials if np.isfinite(t).all()]
            predicted = max([-(g @ d + 0.5 * d @ hess @ d) for d in dx], default=np.inf)
            i = int(np.argmin(values))
            step = 0.0
            if values[i] < f:
                w = trials[i]
                f, g, hess = self._derivatives(h, pr, w, cfg)
                r_new = pr["verts"].T @ w
                step = float(np.abs(r_new - r).max())
                r = r_new
                damping = max(damping * DAMPINGS[i] / 8.0, 1e-12)
            else:
                damping *= 4096.0
            kkt = cfg.gap_tol <= 0 or float(g @ w - g.min()) <= cfg.gap_tol * max(f, 1e-8)
            if (predicted <= 1e-12 * max(f, 1e-8) and step <= 1e-9 and kkt) or damping > 1e8:
                break
        return r, f

    def _solve_adam(self, h: np.ndarray, pr: dict, cfg: FullConfig) -> tuple[np.ndarray, float]:
        """Projected Adam as the engine runs it (optax defaults), best iterate kept."""
        w = pr["w0"].copy()
        best_w, best_f = w, self._value(h, pr, w, cfg)
        mu, nu = np.zeros_like(w), np.zeros_like(w)
        b1, b2, eps = 0.9, 0.999, 1e-8
        for t in range(1, cfg.iterations + 2):
            f, g, _ = self._derivatives(h, pr, w, cfg, order=1)
            if f < best_f:
                best_w, best_f = w, f
            if t > cfg.iterations:
                break
            mu = b1 * mu + (1 - b1) * g
            nu = b2 * nu + (1 - b2) * g * g
            step = (mu / (1 - b1**t)) / (np.sqrt(nu / (1 - b2**t)) + eps)
            w = simplex_projection(w - cfg.learning_rate * step)
        return pr["verts"].T @ best_w, best_f

    def project(
        self, h: np.ndarray, objective: str, n_l: int, n_m: int, full: FullConfig | None = None
    ) -> tuple[np.ndarray, float]:
        """One query ``h (m,)``, either objective -> (pose ``(n,)``, value).

        ``"relaxed"``: ``relaxed`` (value: the deviation); ``"full"``: ``full`` with ``full``
        (default ``FullConfig()``; value: the objective). Anything else is a ``ConfigError``.
        """
        if objective not in ("relaxed", "full"):
            raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
        if objective == "relaxed":
            return self.relaxed(h, n_l, n_m)
        return self.full(h, n_l, n_m, FullConfig() if full is None else full)


class StackedReference:
    """``Reference`` of every chain of a ``StackedProjector`` (or a ``Model``'s projector).

    Each chain is projected by its own float64 ``Reference`` on its own columns of the query;
    the answers fill the chain's joints, and the values combine as the engine's do
    (``projection.project_stacked_one``): relaxed ``sqrt(sum_c dev_c^2)``, full ``sum_c f_c``.
    """

    def __init__(self, sp: StackedProjector) -> None:
        self.layout = sp.layout
        self.chains = [Reference(sp.chain(c)) for c in range(sp.layout.n_chains)]

    def _chains(self, h: np.ndarray) -> list[tuple[Reference, np.ndarray, list[int]]]:
        """Per chain: its ``Reference``, its columns of the query ``h (m,)`` (float64) and
        the indices of its joints in the whole pose."""
        h = np.asarray(h, np.float64)
        lay = self.layout
        return [
            (ref, h[list(cols)], list(joints))
            for ref, cols, joints in zip(self.chains, lay.inputs, lay.outputs, strict=True)
        ]

    def judge(self, h: np.ndarray, r: np.ndarray, n_l: int, n_m: int, tol: float) -> str:
        """``Reference.judge`` per chain on its columns and joints: ``"differs"`` if any chain
        differs, else ``"tie"`` if any chain took a tied candidate, else ``"exact"``."""
        r = np.asarray(r, np.float64)
        verdicts = {ref.judge(x, r[joints], n_l, n_m, tol) for ref, x, joints in self._chains(h)}
        return next(v for v in ("differs", "tie", "exact") if v in verdicts)

    def project(
        self, h: np.ndarray, objective: str, n_l: int, n_m: int, full: FullConfig | None = None
    ) -> tuple[np.ndarray, float]:
        """One query ``(m,)``, either objective -> (pose ``(n,)``, value)."""
        out = np.zeros(self.layout.n)
        values = []
        for ref, x, joints in self._chains(h):
            r, v = ref.project(x, objective, n_l, n_m, full)
            out[list(joints)] = r
            values.append(v)
        vs = np.asarray(values)
        value = float(np.sqrt(np.sum(vs * vs))) if objective == "relaxed" else float(np.sum(vs))
        if len(values) == 1:
            value = float(values[0])
        return out, value
