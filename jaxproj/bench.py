"""Speed benchmarks of the engine: ``jaxproj bench`` and ``benchmarks/bench_projection.py``.

What is measured (every timing waits for the device with ``block_until_ready``; compilation is
timed apart):

* **projection** records, one per ``(objective, L, M, N, batch)``: the engine's jitted
  ``engine.project_chunk`` on a fixed batch of held-out queries. ``compile_s`` is the
  ``lower(...).compile()`` time of exactly that executable; the executable is then called once
  (warm-up, its answer is checked, see below) and again ``repeats`` times; ``us_per_projection``
  is the median call time divided by the batch, ``throughput`` its inverse (projections/s).
* the **reference** (``reference_us_per_projection``, ``speedup``): a faithful per-query NumPy +
  ``scipy.spatial.cKDTree`` implementation of the paper's algorithm (``Reference``) on the SAME
  trained landmarks and kernels, in float64 -- the baseline a Python user would write. It is
  timed per query over ``ref_queries`` queries in the same run, and it is the "exact mode" every
  projection record is checked against before timing: ``max_abs_diff_deg`` is the largest
  ``|engine - reference|`` over the driven joints of the first ``n_checked`` queries (at least
  ``n_check`` = 64: a smaller batch is run again on the next queries; up to ``ref_queries``), in
  degrees, with ``n_disagree`` queries beyond the tolerance (0.1 deg relaxed, 1 deg full).
* **build** records, one per landmark count: descriptors -> landmarks (mean shift with the
  bandwidth search) -> both ELM kernel banks, timed on a second build so that compilation is
  excluded (``compile_s`` = first build minus second); ``banks_s`` times the two kernel banks
  alone (``engine.build_from_landmarks``).
* the **streaming** record: latency of one frame, a ``(20, 3)`` host array of joint positions ->
  descriptor -> relaxed projection (batch 1) -> one double-exponential smoothing step -> a host
  array of 10 angles (one jitted call, host <-> device transfers included); median and p99.
* **rollout** records: MJX rollout (``jaxproj.rollout.simulate``) NAO physics steps per second
  per batch size, through ``bench`` of ``benchmarks/bench_rollout.py`` (found next to the package
  in a checkout; a ``jaxproj.rollout.benchmark`` function is preferred when one exists), with
  motion 0 checked against CPU MuJoCo; marked ``skipped`` when neither is available.

Landmark sets: N = 86, 961, 1644 are real models, ``engine.build(train, BuildConfig(landmarks=N))``
on the valid upper-body descriptors of MSR Action3D subjects 1, 3, 5, 7, 9 (the count reached by
the bandwidth search is ``n_landmarks``, e.g. 1635 for 1644). There are only ~11k training frames,
so N = 8192 has no mean-shift counterpart: it is a deterministic subsample (seed 0) of 8192
distinct training descriptors with their IK poses, trained with ``engine.build_from_landmarks``.
Queries: the valid descriptors of subjects 2, 4, 6, 8, 10 (all actions) in a fixed random order,
tiled to the batch size.

The JSON written by ``--json`` is a list of records; each has ``kind`` (``header``, ``build``,
``projection``, ``streaming``, ``rollout``, ``target``). Projection records carry ``objective, L,
M, N, batch, device, us_per_projection, throughput, compile_s, reference_us_per_projection,
max_abs_diff_deg, speedup`` (plus ``n_landmarks, repeats, n_checked``...). The header holds the
machine, the versions and the date. A configuration that would not fit in memory (XLA's own
estimate of the compiled executable, checked before running it) or would take too long is kept as
a record with ``skipped`` saying why.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import importlib
import importlib.util
import json
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj import datasets, engine, ik
from jaxproj.exceptions import ConfigError
from jaxproj.projection import FullConfig, Projector, project_relaxed_one
from jaxproj.skeleton import descriptor
from jaxproj.smoothing import PAPER_SMOOTHING, SmoothingParams

TRAIN_SUBJECTS = (1, 3, 5, 7, 9)
TEST_SUBJECTS = (2, 4, 6, 8, 10)
SYNTHETIC_N = 8192
"""Landmark count built by subsampling training frames (no mean-shift counterpart)."""

RELAXED_TOL_DEG = 0.1
"""Engine vs reference: the relaxed answers must agree to this (degrees)."""
FULL_TOL_DEG = 1.0
"""Engine vs reference, full objective: stated tolerance (degrees). 30 Adam steps in float32
against float64 can drift apart where the objective is flat; disagreement is reported, not
fatal."""


@dataclass(frozen=True)
class Plan:
    """What one benchmark run measures."""

    landmarks: tuple[int, ...]
    batches: tuple[int, ...]
    configs: tuple[tuple[str, int, int], ...]  # (objective, L, M)
    min_repeats: int
    max_repeats: int
    min_time_s: float
    ref_queries: dict[str, int]
    n_check: int
    stream_frames: int
    max_call_s: float
    memory_fraction: float = 0.5
    subsample_all: bool = False
    """Build every N by subsampling training frames (fast; for tests), not by mean shift."""


def make_plan(
    quick: bool,
    device: str,
    *,
    landmarks: Sequence[int] | None = None,
    batches: Sequence[int] | None = None,
    configs: Sequence[tuple[str, int, int]] | None = None,
    repeats: int | None = None,
    ref_queries: int | None = None,
    n_check: int = 64,
    stream_frames: int | None = None,
) -> Plan:
    """The default plan for ``quick`` / full mode on ``device``, with optional overrides."""
    if quick:
        plan = Plan(
            landmarks=(86, 1644),
            batches=(1, 256, 4096),
            configs=(("relaxed", 10, 10), ("full", 10, 10), ("relaxed", 50, 50)),
            min_repeats=3,
            max_repeats=100,
            min_time_s=0.3,
            ref_queries={"relaxed": 200, "full": 64},
            n_check=n_check,
            stream_frames=600,
            max_call_s=60.0,
        )
    else:
        plan = Plan(
            landmarks=(86, 961, 1644, SYNTHETIC_N),
            batches=(1, 256, 4096),
            configs=(
                ("relaxed", 10, 10),
                ("relaxed", 50, 50),
                ("full", 10, 10),
                ("full", 50, 50),
            ),
            min_repeats=5,
            max_repeats=300,
            min_time_s=1.0,
            ref_queries={"relaxed": 500, "full": 64},
            n_check=n_check,
            stream_frames=2000,
            max_call_s=300.0,
        )
    if device == "gpu":
        # a GPU's memory is the process's own: let a run take most of what is free
        plan = dataclasses.replace(plan, batches=(*plan.batches, 65536), memory_fraction=0.85)
    over: dict[str, Any] = {}
    if landmarks is not None:
        over["landmarks"] = tuple(landmarks)
    if batches is not None:
        over["batches"] = tuple(batches)
    if configs is not None:
        over["configs"] = tuple(configs)
    if repeats is not None:
        over["min_repeats"] = repeats
        over["max_repeats"] = max(repeats, 3 * repeats)
    if ref_queries is not None:
        over["ref_queries"] = {"relaxed": ref_queries, "full": ref_queries}
    if stream_frames is not None:
        over["stream_frames"] = stream_frames
    return dataclasses.replace(plan, **over)


# ----------------------------------------------------------------------------------- data


def descriptors(subjects: Sequence[int]) -> np.ndarray:
    """``(N, 15)`` upper-body descriptors of the valid frames of the bundled data's subjects."""
    seqs = datasets.msr_action3d(subjects=list(subjects))
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    return np.asarray(d)[np.asarray(ok)]


def queries(test: np.ndarray, batch: int) -> np.ndarray:
    """``(batch, m)``: ``test`` (already in a fixed random order) tiled to ``batch`` rows."""
    reps = -(-batch // len(test))
    return np.ascontiguousarray(np.tile(test, (reps, 1))[:batch])


def shuffled(d: np.ndarray, seed: int = 0) -> np.ndarray:
    """Rows of ``d`` in a fixed random order."""
    return d[np.random.default_rng(seed).permutation(len(d))]


def subsample_projector(train: np.ndarray, n: int, config: engine.BuildConfig) -> Projector:
    """A projector on ``n`` distinct training descriptors (seed 0) and their IK poses."""
    uniq = np.unique(train, axis=0)
    if n > len(uniq):
        raise ConfigError(f"N={n} exceeds the {len(uniq)} distinct training descriptors")
    idx = np.sort(np.random.default_rng(0).choice(len(uniq), n, replace=False))
    human = uniq[idx].astype(np.float32)
    robot_poses = np.asarray(ik.solve_driven(human), np.float32)
    return engine.build_from_landmarks(human, robot_poses, config)


def build_models(
    train: np.ndarray,
    landmarks: Sequence[int],
    device: jax.Device,
    log: Callable[[str], None],
    subsample_all: bool = False,
) -> tuple[dict[int, Projector], list[dict]]:
    """Build one projector per landmark count; also return their build records."""
    models: dict[int, Projector] = {}
    records = []
    for n in landmarks:
        sub = subsample_all or n == SYNTHETIC_N
        cfg = engine.BuildConfig() if sub else engine.BuildConfig(landmarks=n)
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            if sub:
                p = subsample_projector(train, n, cfg)
            else:
                p = engine.build(train, cfg).projector
            jax.block_until_ready(p)
            times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        jax.block_until_ready(
            engine.build_from_landmarks(np.asarray(p.human), np.asarray(p.robot), cfg)
        )
        banks_s = time.perf_counter() - t0
        models[n] = jax.device_put(p, device)
        rec = _record(
            "build",
            objective="build",
            N=n,
            device=device.platform,
            compile_s=max(times[0] - times[1], 0.0),
            n_landmarks=p.n_landmarks,
            build_s=times[1],
            first_build_s=times[0],
            banks_s=banks_s,
            landmarks_source="subsample" if sub else "mean_shift",
        )
        records.append(rec)
        log(
            f"build N={n}: K={p.n_landmarks}, {times[1]:.2f} s (first {times[0]:.2f} s), "
            f"banks {banks_s:.2f} s"
        )
    return models, records


# ------------------------------------------------------------------------------ reference


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
    def __init__(self, bank: Any):
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

    def __init__(self, p: Projector):
        from scipy.spatial import cKDTree

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
        """
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
        """One query, either objective."""
        if objective == "relaxed":
            return self.relaxed(h, n_l, n_m)
        return self.full(h, n_l, n_m, FullConfig() if full is None else full)


def time_reference(
    ref: Reference, h: np.ndarray, objective: str, n_l: int, n_m: int, full: FullConfig
) -> tuple[np.ndarray, float]:
    """Answers ``(Q, n)`` for queries ``h (Q, m)`` and the median-free mean us per query.

    The first query is run once untimed (warm-up); then every query once, timed as a whole.
    """
    ref.project(h[0], objective, n_l, n_m, full)
    t0 = time.perf_counter()
    out = [ref.project(q, objective, n_l, n_m, full)[0] for q in h]
    us = (time.perf_counter() - t0) / len(h) * 1e6
    return np.asarray(out), us


# ------------------------------------------------------------------------------ streaming


def _smooth_step(
    y: jax.Array, s_prev: jax.Array, b_prev: jax.Array, started: jax.Array, params: SmoothingParams
) -> tuple[jax.Array, jax.Array]:
    """One step of ``smoothing``'s double exponential smoother; the first frame starts it."""
    alpha, gamma, eta = (jnp.asarray(v, y.dtype) for v in params)
    cand = alpha * y + (1 - alpha) * (s_prev + b_prev)
    moved = jnp.sqrt(jnp.sum((cand - s_prev) ** 2)) >= eta
    s_t = jnp.where(moved, cand, s_prev)
    b_t = gamma * (s_t - s_prev) + (1 - gamma) * b_prev
    return jnp.where(started, s_t, y), jnp.where(started, b_t, jnp.zeros_like(b_t))


def _stream_step(
    p: Projector,
    positions: jax.Array,
    state: tuple[jax.Array, jax.Array, jax.Array],
    params: SmoothingParams,
    n_l: int,
    n_m: int,
) -> tuple[jax.Array, tuple[jax.Array, jax.Array, jax.Array]]:
    d, ok = descriptor(positions)
    r, _ = project_relaxed_one(p, d, n_l, n_m)
    s_prev, b_prev, started = state
    s_t, b_t = _smooth_step(r, s_prev, b_prev, started, params)
    # a frame without a valid descriptor holds the smoother's state (and output)
    s_t = jnp.where(ok, s_t, s_prev)
    b_t = jnp.where(ok, b_t, b_prev)
    return s_t, (s_t, b_t, started | ok)


stream_step = jax.jit(_stream_step, static_argnums=(4, 5))
"""Jitted ``(projector, (20, 3) positions, state, params, L, M) -> ((n,) angles, state)``: one
streamed frame (descriptor, relaxed projection, one smoothing step)."""


def stream_init(p: Projector) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Initial smoother state (nothing seen yet)."""
    z = jnp.zeros((p.robot.shape[1],), jnp.float32)
    return z, z, jnp.asarray(False)


def bench_streaming(
    p: Projector,
    positions: np.ndarray,
    device: jax.Device,
    n_frames: int,
    n_l: int = 10,
    n_m: int = 10,
    params: SmoothingParams = PAPER_SMOOTHING,
    warmup: int = 50,
) -> dict:
    """Per-frame latency of ``stream_step`` over ``positions (T, 20, 3)`` (cycled)."""
    frames = np.asarray(positions, np.float32)
    state = jax.device_put(stream_init(p), device)
    t0 = time.perf_counter()
    compiled = stream_step.lower(p, frames[0], state, params.gains(), n_l, n_m).compile()
    compile_s = time.perf_counter() - t0
    lat = []
    for i in range(warmup + n_frames):
        t0 = time.perf_counter()
        out, state = compiled(p, frames[i % len(frames)], state, params.gains())
        a = np.asarray(out)
        dt = time.perf_counter() - t0
        if i >= warmup:
            lat.append(dt)
    if not np.isfinite(a).all():
        raise RuntimeError("streaming produced non-finite angles")
    lat_us = np.asarray(lat) * 1e6
    med = float(np.median(lat_us))
    return _record(
        "streaming",
        objective="streaming",
        L=n_l,
        M=n_m,
        N=None,
        batch=1,
        device=device.platform,
        us_per_projection=med,
        throughput=1e6 / med,
        compile_s=compile_s,
        median_us=med,
        p99_us=float(np.percentile(lat_us, 99)),
        mean_us=float(lat_us.mean()),
        frames=n_frames,
    )


# ----------------------------------------------------------------------------- projection


def _record(kind: str, **kw: Any) -> dict:
    base = dict(
        kind=kind,
        objective=None,
        L=None,
        M=None,
        N=None,
        batch=None,
        device=None,
        us_per_projection=None,
        throughput=None,
        compile_s=None,
    )
    base.update(kw)
    return base


def _available_bytes(device: jax.Device) -> int | None:
    if device.platform == "cpu":
        try:
            with open("/proc/meminfo") as fh:
                for line in fh:
                    if line.startswith("MemAvailable:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            pass
        try:
            return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return None
    try:
        stats = device.memory_stats() or {}
    except Exception:  # noqa: BLE001 - backends differ in what they expose
        return None
    limit = stats.get("bytes_limit")
    return None if limit is None else int(limit) - int(stats.get("bytes_in_use", 0))


def _total_memory() -> int:
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0


def _needed_bytes(compiled: Any) -> int | None:
    try:
        ma = compiled.memory_analysis()
        return int(ma.temp_size_in_bytes + ma.argument_size_in_bytes + ma.output_size_in_bytes)
    except Exception:  # noqa: BLE001 - not every backend reports it
        return None


def time_calls(fn: Callable[[], Any], plan: Plan) -> tuple[float, int]:
    """Median seconds per ``fn()`` (blocked): at least ``min_repeats`` calls, more (up to
    ``max_repeats``) while the total stays under ``min_time_s``."""
    ts: list[float] = []
    total = 0.0
    while len(ts) < plan.min_repeats or (total < plan.min_time_s and len(ts) < plan.max_repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        dt = time.perf_counter() - t0
        ts.append(dt)
        total += dt
    return float(np.median(ts)), len(ts)


def bench_projection(
    p: Projector,
    h_all: np.ndarray,
    objective: str,
    n_l: int,
    n_m: int,
    batch: int,
    device: jax.Device,
    plan: Plan,
    ref_answers: np.ndarray,
    full: FullConfig | None = None,
    estimate_us: float | None = None,
) -> dict:
    """One projection record (see the module doc); ``ref_answers`` are the reference's poses
    for the first rows of ``h_all``."""
    rec = _record(
        "projection",
        objective=objective,
        L=n_l,
        M=n_m,
        batch=batch,
        device=device.platform,
        n_landmarks=p.n_landmarks,
    )
    if estimate_us is not None and estimate_us * batch * 1e-6 > plan.max_call_s:
        rec["skipped"] = (
            f"estimated {estimate_us * batch * 1e-6:.0f} s per call (from a smaller batch) "
            f"exceeds the {plan.max_call_s:.0f} s budget"
        )
        return rec
    full = FullConfig() if full is None else full
    h = jax.device_put(queries(h_all, batch), device)
    t0 = time.perf_counter()
    compiled = engine.project_chunk.lower(p, h, objective, n_l, n_m, full).compile()
    rec["compile_s"] = time.perf_counter() - t0
    need, avail = _needed_bytes(compiled), _available_bytes(device)
    rec["memory_bytes"] = need
    if need is not None and avail is not None and need > plan.memory_fraction * avail:
        rec["skipped"] = (
            f"needs {need / 2**30:.1f} GiB (XLA estimate), more than "
            f"{plan.memory_fraction:.0%} of the {avail / 2**30:.1f} GiB available"
        )
        return rec
    t0 = time.perf_counter()
    r, v = jax.block_until_ready(compiled(p, h))
    rec["first_call_s"] = time.perf_counter() - t0
    r, v = np.asarray(r), np.asarray(v)
    # a batch smaller than the check is run again on the next queries until it is covered
    start = batch
    while len(r) < min(plan.n_check, len(ref_answers)):
        more = jax.device_put(queries(np.roll(h_all, -start, axis=0), batch), device)
        r2, v2 = compiled(p, more)
        r, v = np.concatenate([r, np.asarray(r2)]), np.concatenate([v, np.asarray(v2)])
        start += batch
    if not (np.isfinite(r).all() and np.isfinite(v).all()):
        raise RuntimeError(f"non-finite engine output for {objective} L={n_l} M={n_m}")
    n = min(len(r), len(ref_answers), max(plan.n_check, batch))
    diff = np.degrees(np.abs(r[:n] - ref_answers[:n]))
    per_query = diff.max(axis=1)
    tol = RELAXED_TOL_DEG if objective == "relaxed" else FULL_TOL_DEG
    rec.update(
        n_checked=int(n),
        max_abs_diff_deg=float(per_query.max()),
        median_abs_diff_deg=float(np.median(per_query)),
        n_disagree=int(np.sum(per_query > tol)),
        tolerance_deg=tol,
        agrees=bool(per_query.max() <= tol),
    )
    sec, reps = time_calls(lambda: compiled(p, h), plan)
    rec.update(
        us_per_projection=sec / batch * 1e6,
        throughput=batch / sec,
        repeats=reps,
        call_s=sec,
    )
    return rec


# -------------------------------------------------------------------------------- rollout


def _rollout_bench_module() -> Any:
    """``jaxproj.rollout.benchmark``'s module if it has one, else ``benchmarks/bench_rollout.py``
    of the checkout this package runs from; ``None`` when neither exists."""
    mod = importlib.import_module("jaxproj.rollout")  # ImportError when MJX is missing
    if callable(getattr(mod, "benchmark", None)):
        return mod
    script = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_rollout.py"
    if not script.is_file():
        return None
    spec = importlib.util.spec_from_file_location("_jaxproj_bench_rollout", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def bench_rollout(quick: bool, device: jax.Device, frames: int = 30) -> list[dict]:
    """MJX rollout steps/s (``benchmarks/bench_rollout.py``'s ``bench``: synthetic arm motions,
    15 frames/s, 33 physics steps per frame), one record per batch size; motion 0 is checked
    against CPU MuJoCo ``mj_step`` (``mjx_vs_cpu_max_dq_rad``)."""
    rec = _record("rollout", objective="rollout", device=device.platform)
    try:
        mod = _rollout_bench_module()
    except ImportError as e:
        return [rec | {"skipped": f"rollout module not available ({e})"}]
    if mod is None:
        return [rec | {"skipped": "rollout module not available (no rollout benchmark found)"}]
    if device.platform == "cpu":
        batches = (64,) if quick else (64, 256)
    else:
        batches = (4096,) if quick else (1024, 4096, 16384)
    out = []
    try:
        if hasattr(mod, "benchmark"):
            res = mod.benchmark(quick=quick, device=device)
            return [rec | (dict(res) if isinstance(res, dict) else {"steps_per_s": float(res)})]
        from jaxproj import robot

        substeps = round((1.0 / 15.0) / robot.load_model("fixed").opt.timestep)
        ref = mod.motions(1, frames, 0)[0]
        cpu_q, cpu_ncon, _ = mod.cpu_rollout(ref, substeps)
        with jax.default_device(device):
            for b in batches:
                r = mod.bench(b, frames, 0, 1 if quick else 3, substeps)
                dq = float(np.abs(np.asarray(r.pop("qpos0")) - cpu_q).max())
                out.append(
                    rec
                    | dict(
                        batch=b,
                        throughput=r["steps_per_s"],
                        compile_s=r["compile_s"],
                        steps_per_s=r["steps_per_s"],
                        run_s=r["run_s"],
                        steps=r["steps"],
                        frames=frames,
                        substeps=substeps,
                        finite=r["finite"],
                        mjx_vs_cpu_max_dq_rad=dq,
                        cpu_contacts=int(cpu_ncon),
                    )
                )
    except Exception as e:  # noqa: BLE001 - report, do not lose the projection numbers
        return out + [rec | {"skipped": f"rollout benchmark failed: {type(e).__name__}: {e}"}]
    return out


# -------------------------------------------------------------------------------- targets


def _find(records: list[dict], **kw: Any) -> list[dict]:
    return [
        r for r in records if all(r.get(k) == v for k, v in kw.items()) and r.get("skipped") is None
    ]


def target_checks(records: list[dict], device: str) -> list[dict]:
    """The issue's speed targets that apply to ``device``, checked against ``records``."""
    out = []

    def check(name: str, recs: list[dict], key: str, op: str, threshold: float) -> None:
        vals = [r[key] for r in recs if r.get(key) is not None]
        if not vals:
            out.append(_target(name, None, op, threshold, None))
            return
        value = min(vals) if op == "<=" else max(vals)
        met = value <= threshold if op == "<=" else value >= threshold
        out.append(_target(name, value, op, threshold, met))

    proj = dict(kind="projection", N=1644)

    def full_name(name: str, recs: list[dict]) -> str:
        """Say so when the full records are of the pruned (approximate) full objective."""
        pruned = sorted(
            {(r["full_config"]["clusters"], r["full_config"]["iterations"])
             for r in recs if 0 < r["full_config"]["clusters"] < r["L"]}
        )  # fmt: skip
        if not pruned:
            return name
        c, it = pruned[0]
        return f"{name} [pruned full objective, clusters={c}, {it} steps: an approximation]"

    if device == "cpu":
        r10 = _find(records, objective="relaxed", L=10, M=10, batch=4096, **proj)
        f10 = _find(records, objective="full", L=10, M=10, batch=4096, **proj)
        check("relaxed L=M=10, N~1644, batch 4096: us/projection",
              r10, "us_per_projection", "<=", 10.0)  # fmt: skip
        check("relaxed L=M=10, N~1644, batch 4096: speedup vs reference",
              r10, "speedup", ">=", 50.0)  # fmt: skip
        check(full_name("full L=M=10, N~1644, batch 4096: us/projection", f10),
              f10, "us_per_projection", "<=", 100.0)  # fmt: skip
        check("streaming latency median (us)",
              _find(records, kind="streaming"), "median_us", "<=", 200.0)  # fmt: skip
    else:
        r10 = _find(records, objective="relaxed", L=10, M=10, **proj)
        r50 = _find(records, objective="relaxed", L=50, M=50, **proj)
        f10 = _find(records, objective="full", L=10, M=10, **proj)
        check("relaxed L=M=10, N~1644: projections/s", r10, "throughput", ">=", 20e6)
        check("relaxed L=M=50, N~1644: projections/s", r50, "throughput", ">=", 2e6)
        check(full_name("full L=M=10, N~1644: projections/s", f10), f10, "throughput", ">=", 1e6)
        check("MJX rollout: NAO steps/s (batched)",
              _find(records, kind="rollout"), "steps_per_s", ">=", 1e6)  # fmt: skip
    return out


def _target(name: str, value: float | None, op: str, threshold: float, met: bool | None) -> dict:
    if value is None or met is None:
        factor = None
    elif op == "<=":
        factor = value / threshold
    else:
        factor = threshold / value if value > 0 else float("inf")
    return dict(
        kind="target", target=name, value=value, op=op, threshold=threshold, met=met,
        off_by_factor=None if met or factor is None else factor,
    )  # fmt: skip


# ----------------------------------------------------------------------------------- run


def header(device: jax.Device) -> dict:
    """Machine, versions and date."""
    import jaxlib

    versions = {
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "numpy": np.__version__,
    }
    for mod in ("scipy", "optax", "mujoco"):
        try:
            versions[mod] = importlib.import_module(mod).__version__
        except ImportError:
            versions[mod] = None
    from jaxproj import __version__

    versions["jaxproj"] = __version__
    cpu_model = platform.processor() or None
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu_model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return dict(
        kind="header",
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        platform=platform.platform(),
        machine=platform.machine(),
        cpu_model=cpu_model,
        cpu_count=os.cpu_count(),
        cpu_usable=usable,
        memory_gib=round(_total_memory() / 2**30, 1),
        memory_available_gib=round((_available_bytes(jax.devices("cpu")[0]) or 0) / 2**30, 1),
        device=device.platform,
        device_kind=getattr(device, "device_kind", str(device)),
        device_count=len(jax.devices(device.platform)),
        versions=versions,
        argv=sys.argv,
    )


def get_device(device: str) -> jax.Device:
    """The first JAX device of ``"cpu"`` / ``"gpu"``; ``ConfigError`` when there is none."""
    if device not in ("cpu", "gpu"):
        raise ConfigError(f"--device must be cpu or gpu, got {device!r}")
    try:
        devs = jax.devices(device)
    except RuntimeError as e:
        raise ConfigError(
            f"--device {device}: no {device.upper()} visible to JAX ({e}); "
            "install jax[cuda12] and check nvidia-smi, or use --device cpu"
        ) from None
    if not devs:
        raise ConfigError(f"--device {device}: no {device.upper()} visible to JAX")
    return devs[0]


def run(
    quick: bool,
    device: str,
    *,
    plan: Plan | None = None,
    streaming: bool = True,
    rollout: bool = True,
    log: Callable[[str], None] | None = None,
    full: FullConfig | None = None,
    **plan_overrides: Any,
) -> list[dict]:
    """Run the benchmark suite; returns the records (header first, target checks last).

    ``full`` sets the full objective's solver (default ``FullConfig()``, the exact full
    objective); the reference runs the same configuration, and every full record carries it.
    """
    dev = get_device(device)
    plan = plan or make_plan(quick, device, **plan_overrides)
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    records = [header(dev)]
    log(f"bench on {records[0]['device_kind']} ({records[0]['cpu_usable']} usable CPU cores)")
    train = descriptors(TRAIN_SUBJECTS)
    test = shuffled(descriptors(TEST_SUBJECTS))
    models, builds = build_models(train, plan.landmarks, dev, log, plan.subsample_all)
    records += builds
    full = FullConfig() if full is None else full
    for n in plan.landmarks:
        p = models[n]
        ref = Reference(p)
        for objective, n_l, n_m in plan.configs:
            if max(n_l, n_m) > p.n_landmarks:
                continue
            nq = max(plan.ref_queries[objective], plan.n_check)
            ans, ref_us = time_reference(ref, test[:nq], objective, n_l, n_m, full)
            log(f"reference {objective} L={n_l} M={n_m} N={n}: {ref_us:.0f} us/query")
            estimate = None
            for batch in sorted(plan.batches):
                rec = bench_projection(
                    p, test, objective, n_l, n_m, batch, dev, plan, ans, full, estimate
                )
                rec.update(N=n, reference_us_per_projection=ref_us, reference_queries=nq)
                if objective == "full":
                    rec["full_config"] = dataclasses.asdict(full)
                if rec.get("us_per_projection"):
                    rec["speedup"] = ref_us / rec["us_per_projection"]
                    estimate = rec["us_per_projection"]
                else:
                    rec.setdefault("speedup", None)
                    rec.setdefault("max_abs_diff_deg", None)
                records.append(rec)
                log(_row(rec))
    if streaming:
        n_stream = 1644 if 1644 in models else max(models)
        seqs = datasets.msr_action3d(subjects=list(TEST_SUBJECTS))
        pos = np.concatenate([s.positions[s.valid] for s in seqs[:20]])
        rec = bench_streaming(models[n_stream], pos, dev, plan.stream_frames)
        rec["N"] = n_stream
        rec["n_landmarks"] = models[n_stream].n_landmarks
        records.append(rec)
        log(f"streaming N={n_stream}: median {rec['median_us']:.0f} us, p99 {rec['p99_us']:.0f} us")
    if rollout:
        for rec in bench_rollout(quick, dev):
            records.append(rec)
            if rec.get("steps_per_s"):
                log(f"rollout batch {rec['batch']}: {rec['steps_per_s']:.4g} steps/s")
    records += target_checks(records, device)
    return records


# ---------------------------------------------------------------------------------- output


def _fmt(v: Any, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def _row(r: dict) -> str:
    if r.get("skipped"):
        tail = f"skipped: {r['skipped']}"
    else:
        tail = (
            f"{_fmt(r.get('us_per_projection'), '10.2f')} {_fmt(r.get('throughput'), '12.4g')} "
            f"{_fmt(r.get('compile_s'), '8.2f')} "
            f"{_fmt(r.get('reference_us_per_projection'), '9.1f')} "
            f"{_fmt(r.get('speedup'), '8.2f')} {_fmt(r.get('max_abs_diff_deg'), '9.2g')}"
        )
    return f"{r['objective']:8s} {r['L']:>3} {r['M']:>3} {r['N']:>5} {r['batch']:>6}  " + tail


def format_table(records: list[dict]) -> str:
    """A readable table of the records and the target checks."""
    lines = []
    head = records[0] if records and records[0].get("kind") == "header" else None
    if head:
        v = head["versions"]
        lines.append(
            f"# {head['date']}  {head['device_kind']}  ({head['cpu_model']}, "
            f"{head['cpu_usable']} cores)  jax {v['jax']}  numpy {v['numpy']}"
        )
    builds = [r for r in records if r["kind"] == "build"]
    if builds:
        lines.append("\nkernel-bank build (second build; compile excluded)")
        lines.append(f"{'N':>5} {'K':>5} {'build_s':>8} {'banks_s':>8} {'compile_s':>9}  source")
        for r in builds:
            lines.append(
                f"{r['N']:>5} {r['n_landmarks']:>5} {r['build_s']:8.2f} {r['banks_s']:8.3f} "
                f"{r['compile_s']:9.2f}  {r['landmarks_source']}"
            )
    proj = [r for r in records if r["kind"] == "projection"]
    if proj:
        lines.append("\nprojection (median over repeats; reference = NumPy + cKDTree per query)")
        lines.append(
            f"{'obj':8s} {'L':>3} {'M':>3} {'N':>5} {'batch':>6}  {'us/proj':>10} "
            f"{'proj/s':>12} {'compile':>8} {'ref_us':>9} {'speedup':>8} {'maxdiff°':>9}"
        )
        lines += [_row(r) for r in proj]
    for r in records:
        if r["kind"] == "streaming":
            lines.append(
                f"\nstreaming (pose -> descriptor -> relaxed L={r['L']} M={r['M']} N={r['N']} -> "
                f"smoothing step, host round trip): median {r['median_us']:.1f} us, "
                f"p99 {r['p99_us']:.1f} us over {r['frames']} frames"
            )
        if r["kind"] == "rollout":
            if r.get("skipped"):
                lines.append(f"\nMJX rollout: skipped ({r['skipped']})")
            else:
                lines.append(
                    f"\nMJX rollout (batch {r.get('batch')}): "
                    f"{_fmt(r.get('steps_per_s'), '.4g')} NAO steps/s, compile "
                    f"{_fmt(r.get('compile_s'), '.1f')} s, motion 0 vs CPU MuJoCo max |dq| "
                    f"{_fmt(r.get('mjx_vs_cpu_max_dq_rad'), '.1e')} rad"
                )
    targets = [r for r in records if r["kind"] == "target"]
    if targets:
        lines.append("\ntargets")
        for t in targets:
            status = {True: "met", False: "NOT MET", None: "not measured"}[t["met"]]
            extra = f" (off by {t['off_by_factor']:.1f}x)" if t.get("off_by_factor") else ""
            lines.append(
                f"  {t['target']}: {_fmt(t['value'], '.4g')} {t['op']} {t['threshold']:g} "
                f"-> {status}{extra}"
            )
    return "\n".join(lines)


def _ints(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected integers like 86,1644, got {text!r}") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``jaxproj bench`` (also used by ``benchmarks/bench_projection.py``)."""
    parser.add_argument("--quick", action="store_true", help="a subset that runs in minutes")
    parser.add_argument("--device", default="cpu", choices=("cpu", "gpu"))
    parser.add_argument("--json", default=None, metavar="OUT", help="write the records here")
    parser.add_argument("--landmarks", type=_ints, default=None, help="override N, e.g. 86,1644")
    parser.add_argument("--batches", type=_ints, default=None, help="override batch sizes")
    parser.add_argument("--repeats", type=int, default=None, help="minimum timed calls")
    parser.add_argument("--ref-queries", type=int, default=None, help="reference queries")
    parser.add_argument("--no-streaming", action="store_true", help="skip streaming latency")
    parser.add_argument("--no-rollout", action="store_true", help="skip the MJX rollout")
    parser.add_argument(
        "--full-clusters",
        type=int,
        default=0,
        help="full objective: optimise only this many best-starting clusters (0: all, exact)",
    )
    parser.add_argument(
        "--full-iterations", type=int, default=None, help="full objective: projected-gradient steps"
    )


def _full_config(clusters: int, iterations: int | None) -> FullConfig:
    cfg = FullConfig(clusters=clusters)
    if iterations is not None:
        cfg = dataclasses.replace(cfg, iterations=iterations)
    return cfg


def main(args: argparse.Namespace) -> int:
    """Run ``jaxproj bench``: print the table, write ``--json``; returns the exit status."""
    records = run(
        args.quick,
        args.device,
        streaming=not args.no_streaming,
        rollout=not args.no_rollout,
        landmarks=args.landmarks,
        batches=args.batches,
        repeats=args.repeats,
        ref_queries=args.ref_queries,
        full=_full_config(args.full_clusters, args.full_iterations),
    )
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(records, indent=1) + "\n")
    print(format_table(records))
    return 0
