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
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, StackedProjector


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

    def relaxed(self, h: np.ndarray, n_l: int, n_m: int) -> tuple[np.ndarray, float]:
        """Relaxed projection of one query ``(m,)`` -> (pose ``(n,)``, deviation)."""
        h = np.asarray(h, np.float64)
        cand = self.candidates(h, n_l)  # (L, n)
        ridx = self._knn(self.tree_r, cand, n_m)  # (L, M)
        back, _ = self.backward.predict(cand[:, None, :], ridx[:, None, :])  # (L, 1, M, m)
        dev = np.sum((back[:, 0] - h) ** 2, axis=-1)  # (L, M)
        best = dev.min(axis=1)
        j = int(np.argmin(best))
        return np.clip(cand[j], self.lower, self.upper), float(np.sqrt(best[j]))

    def full(
        self,
        h: np.ndarray,
        n_l: int,
        n_m: int,
        cfg: FullConfig = FullConfig(),  # noqa: B008 - immutable
    ) -> tuple[np.ndarray, float]:
        """Full projection of one query (``projection.project_full_one``, in NumPy).

        The same projected gradient: Adam (optax defaults b1 0.9, b2 0.999, eps 1e-8) on the
        simplex weights of each candidate's cluster, ``cfg.iterations`` steps, best iterate
        kept; gradients written out by hand. With ``cfg.clusters`` only the clusters with the
        smallest warm-start values are optimised. Returns (pose ``(n,)``, objective value).
        Only ``solver="adam"`` is re-implemented (``ConfigError`` otherwise): the Newton solver
        is checked against its own long solves and against Adam's objective values
        (``tests/projection/test_projection.py``, ``benchmarks/experiments/full_newton.py``).
        """
        if cfg.solver != "adam":
            raise ConfigError(
                f"the float64 reference re-implements solver='adam' only, not {cfg.solver!r}"
            )
        h = np.asarray(h, np.float64)
        cand = self.candidates(h, n_l)  # (L, n)
        ridx = self._knn(self.tree_r, cand, n_m)  # (L, M)
        if 0 < cfg.clusters < n_l:
            start = self._full(h, cand, ridx, dataclasses.replace(cfg, iterations=0))[2]
            keep = np.argsort(start, kind="stable")[: cfg.clusters]
            cand, ridx = cand[keep], ridx[keep]
        r, f, _ = self._full(h, cand, ridx, cfg)
        j = int(np.argmin(f))
        return np.clip(r[j], self.lower, self.upper), float(f[j])

    def _full(
        self, h: np.ndarray, cand: np.ndarray, ridx: np.ndarray, cfg: FullConfig
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every cluster's (r(w*) ``(L, n)``, f(w*) ``(L,)``, f(w0) ``(L,)``)."""
        bank = self.backward
        rk = self.robot[ridx]  # (L, M, n)
        if cfg.include_candidate:
            verts = np.concatenate([cand[:, None], rk], axis=1)  # (L, M + 1, n)
            w = np.zeros(verts.shape[:2])
            w[:, 0] = 1.0
        else:
            verts = rk
            w = 1.0 / (np.sum((rk - cand[:, None]) ** 2, axis=-1) + 1e-8)
            w = w / w.sum(axis=1, keepdims=True)
        s = bank.inv[ridx][..., None]  # (L, M, 1)
        beta, out, off = bank.bias[ridx], bank.out[ridx], bank.offset[ridx]

        def value_grad(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            r = np.einsum("lk,lkn->ln", w, verts)
            q = _sigmoid((r @ bank.w.T)[:, None, :] * s + beta)  # (L, M, hidden)
            e = off + np.einsum("lmh,lmho->lmo", q, out) - h  # (L, M, m)
            dev = np.sum(e * e, axis=-1)  # (L, M)
            # d dev_k / d r = 2 * s_k * W^T (q_k (1 - q_k) * (B_k e_k))
            gz = 2.0 * np.einsum("lmho,lmo->lmh", out, e) * q * (1.0 - q) * s
            if cfg.objective == "min":
                k = np.argmin(dev, axis=1)
                val = dev[np.arange(len(k)), k]
                g_r = gz[np.arange(len(k)), k] @ bank.w
                g = np.einsum("ln,lkn->lk", g_r, verts)
                return val, g
            if cfg.include_candidate:
                tot = w[:, 1:].sum(axis=1, keepdims=True)
                norm = np.maximum(tot, 1e-12)
                wk = w[:, 1:] / norm
                val = np.sum(wk * dev, axis=1)
                g_direct = np.zeros_like(w)
                g_direct[:, 1:] = np.where(tot > 1e-12, (dev - val[:, None]) / norm, dev / norm)
            else:
                wk = w
                val = np.sum(wk * dev, axis=1)
                g_direct = dev
            g_r = np.einsum("lm,lmh->lh", wk, gz) @ bank.w  # (L, n)
            return val, g_direct + np.einsum("ln,lkn->lk", g_r, verts)

        f0, _ = value_grad(w)
        best_w, best_f = w.copy(), f0.copy()
        mu, nu = np.zeros_like(w), np.zeros_like(w)
        b1, b2, eps, lr = 0.9, 0.999, 1e-8, cfg.learning_rate
        for t in range(1, cfg.iterations + 1):
            val, g = value_grad(w)
            better = val < best_f
            best_w = np.where(better[:, None], w, best_w)
            best_f = np.where(better, val, best_f)
            mu = b1 * mu + (1 - b1) * g
            nu = b2 * nu + (1 - b2) * g * g
            step = (mu / (1 - b1**t)) / (np.sqrt(nu / (1 - b2**t)) + eps)
            w = simplex_projection(w - lr * step)
        val, _ = value_grad(w)
        better = val < best_f
        best_w = np.where(better[:, None], w, best_w)
        best_f = np.where(better, val, best_f)
        r = np.einsum("lk,lkn->ln", best_w, verts)
        return r, best_f, f0

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

    def project(
        self, h: np.ndarray, objective: str, n_l: int, n_m: int, full: FullConfig | None = None
    ) -> tuple[np.ndarray, float]:
        """One query ``(m,)``, either objective -> (pose ``(n,)``, value)."""
        h = np.asarray(h, np.float64)
        out = np.zeros(self.layout.n)
        values = []
        for ref, cols, joints in zip(
            self.chains, self.layout.inputs, self.layout.outputs, strict=True
        ):
            r, v = ref.project(h[list(cols)], objective, n_l, n_m, full)
            out[list(joints)] = r
            values.append(v)
        vs = np.asarray(values)
        value = float(np.sqrt(np.sum(vs * vs))) if objective == "relaxed" else float(np.sum(vs))
        if len(values) == 1:
            value = float(values[0])
        return out, value
