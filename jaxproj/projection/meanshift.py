"""Mean-shift clustering (Comaniciu & Meer 2002) in JAX, and the search for a bandwidth.

Size: over 500 lines on purpose: one algorithm, whose jitted iteration, merge, host wrapper and
bandwidth search share the private data preparation (``_prepare`` / ``_run``).

Generic: points are ``(N, m)`` float32 arrays; nothing here knows about skeletons, robots or IK
(``landmarks.build_landmarks`` runs it on human descriptors and adds the IK robot poses).

Algorithm (``mean_shift``)
  Every point is a seed (or an explicit seed set). A seed at ``x`` moves to the kernel-weighted
  mean ``sum_j w(x, p_j) p_j / sum_j w(x, p_j)`` of the data, again and again, which climbs the
  kernel density estimate to a local maximum (a mode). Kernels, bandwidth ``h``:

  * ``"gaussian"`` (default): ``w = exp(-|x - p|^2 / (2 h^2))``, ``h`` is the standard deviation;
  * ``"flat"``: ``w = 1`` if ``|x - p| <= h`` else 0 (the modes of the Epanechnikov density;
    converges in finitely many steps).

  All seeds move in parallel inside one jitted ``lax.while_loop``. Each iteration compacts the
  seeds still moving to the front and treats them ``BLOCK`` (256) at a time, so memory stays at
  one ``(256, N)`` weight matrix (11.5 MB for N = 11k; the ``N x N`` matrix is never formed) and
  converged seeds cost nothing. For a block, the exponents ``-|x - p|^2 / (2 h^2)`` come out of one
  ``(256, m + 1) @ (m + 1, N)`` product of augmented vectors and the numerator and denominator out
  of a second product with ``[p, 1]``. Where every Gaussian weight of a row underflows (a seed
  > ~13 h from all data) the row is recomputed with exponents shifted by their maximum. A seed
  stops when its step is shorter than ``tol * h`` (``tol`` is relative to the bandwidth, default
  ``1e-3``) or after ``max_iter`` steps (``converged`` reports which). The data are centred on
  their mean first (smaller norms, less float32 cancellation); modes are moved back.

Merge rule
  Converged seeds are visited in order of decreasing kernel density at their position (ties: lower
  index first). The first unassigned seed founds a mode at its own position and takes every
  unassigned seed within ``merge_fraction * h`` (default ``0.5 h``) of it; repeat until all are
  assigned (greedy, not transitive, deterministic). Modes come out in that order (densest first);
  a point's label is the mode its own seed joined (with explicit seeds: its nearest mode). With the
  Gaussian kernel seeds of one mode end within ~``tol * h`` of each other, so the count barely
  depends on ``merge_fraction`` (1293 / 1293 / 1286 modes for 0.25 / 0.5 / 1.0 at h = 0.15 on the
  11,280 training descriptors of ``landmarks``, MSR Action3D subjects 1, 3, 5, 7, 9) or on ``tol``
  (1299 for ``tol = 3e-3``). The flat kernel leaves plateaus of nearby fixed points, so its count
  depends on the merge radius (1591 / 1342 / 1166 at h = 0.4): it is available, but the Gaussian
  is the default.

Choosing the count (``find_bandwidth``)
  Bisection on ``log h`` with log-log secant cuts (see its docstring), starting from a guess
  ``0.048 * rms_spread * (target / N) ** -0.4`` fitted to those data. The count fell monotonically
  on a 40-step grid of h in [0.12, 0.45]. No warm start across bandwidths: a seed's trajectory
  depends on ``h`` from its first step, and starting from other modes would make the result depend
  on the search path; instead the data are prepared once and every evaluation reuses the same
  compiled ``_iterate`` / ``_merge`` (``h``, ``tol``, ``max_iter`` are traced, shapes are fixed).

Measured times (mean shift and bandwidth search to 1644 / 961 / 86 modes): section "Mean shift /
landmark build times" of ``benchmarks/RESULTS.md``; rerun with ``benchmarks/bench_build.py``.

Jit: ``_iterate``, ``_merge`` and ``_step`` are the jitted implementations behind ``mean_shift``,
``find_bandwidth`` and ``mean_shift_step``; the public functions check their arguments in plain
Python (``ConfigError``) before anything is traced.
"""

from __future__ import annotations

import math
import warnings
from typing import Any, Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError

Kernel = Literal["gaussian", "flat"]
KERNELS: tuple[str, ...] = ("gaussian", "flat")

BLOCK = 256
"""Seeds per block: a block holds one ``(BLOCK, N)`` float32 weight matrix (11.5 MB at N = 11k)."""

MAX_ITER = 1000
"""Default cap on mean-shift steps per seed."""

TOL = 1e-3
"""Default stopping tolerance, relative to the bandwidth: a seed stops when its step < TOL * h."""

MERGE_FRACTION = 0.5
"""Default merge radius, relative to the bandwidth."""


class MeanShiftResult(NamedTuple):
    """Output of ``mean_shift``.

    Attributes:
      modes: ``(K, m)`` float32 modes, in decreasing order of kernel density.
      labels: ``(N,)`` int32, index into ``modes`` of the mode each point belongs to.
      counts: ``(K,)`` int64, number of points with each label (sums to N).
      log_density: ``(K,)`` float32, log of the (unnormalised) kernel density at each mode.
      bandwidth: the bandwidth ``h`` used.
      kernel: ``"gaussian"`` or ``"flat"``.
      iterations: mean-shift iterations run (the slowest seed's).
      converged: every seed's last shift was below ``tol * h`` (false: ``max_iter`` was hit).
      seed_steps: total single-seed mean-shift steps computed (the work done).
    """

    modes: np.ndarray
    labels: np.ndarray
    counts: np.ndarray
    log_density: np.ndarray
    bandwidth: float
    kernel: str
    iterations: int
    converged: bool
    seed_steps: int

    @property
    def n_modes(self) -> int:
        """``K``, the number of modes."""
        return int(self.modes.shape[0])


_PAD_EXPONENT = -1.0e30
"""Exponent given to padding rows of the data: their weight is exactly 0 for both kernels."""


def _augment(p: jax.Array, p_mask: jax.Array, h: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Data rows prepared for the fused kernel evaluation (see ``_shift_block``).

    Returns ``(pa, pv)``: ``pa`` ``(N, m + 1)`` = ``[p / h^2, -|p|^2 / (2 h^2)]`` (padding rows get
    ``_PAD_EXPONENT``) and ``pv`` ``(N, m + 1)`` = ``[p, mask]``.
    """
    inv = 0.5 / (h * h)
    p_sq = jnp.sum(p * p, axis=-1)
    last = jnp.where(p_mask > 0, -p_sq * inv, jnp.full_like(p_sq, _PAD_EXPONENT))
    pa = jnp.concatenate([p * (2.0 * inv), last[:, None]], axis=1)
    pv = jnp.concatenate([p, p_mask[:, None]], axis=1)
    return pa, pv


def _shift_block(
    x: jax.Array, on: jax.Array, pa: jax.Array, pv: jax.Array, h: jax.Array, kernel: str
) -> tuple[jax.Array, jax.Array]:
    """One mean-shift step for the queries ``x`` ``(B, m)`` (``on`` ``(B,)``: rows that matter).

    The exponent ``-|x - p|^2 / (2 h^2)`` of every (query, data) pair comes out of a single
    ``(B, m + 1) @ (m + 1, N)`` product, and ``sum_j w_ij [p_j, 1]`` (numerator and denominator)
    out of a second one, so no ``(B, N, m)`` difference tensor and no separate distance pass exist.

    Returns ``(x_new, log_density)``: ``(B, m)`` weighted means and ``(B,)`` log of the
    (unnormalised) kernel density ``sum_j w_ij`` at ``x``; ``-inf`` and ``x_new = x`` where no data
    point has a non-zero weight (flat kernel only: the Gaussian falls back to a shifted exponent).
    """
    inv = 0.5 / (h * h)
    m = x.shape[1]
    ones = jnp.ones((x.shape[0], 1), x.dtype)
    e = jnp.concatenate([x, ones], axis=1) @ pa.T - (jnp.sum(x * x, axis=-1) * inv)[:, None]
    if kernel == "gaussian":
        nd = jnp.exp(e) @ pv
        log_scale = jnp.zeros((x.shape[0],), x.dtype)

        def rescaled(_):
            # Far from every data point exp(e) underflows; shift each row by its largest exponent.
            top = jnp.max(e, axis=-1)
            return jnp.exp(e - top[:, None]) @ pv, top

        tiny = jnp.asarray(np.finfo(np.float32).tiny * 1e6, x.dtype)
        nd, log_scale = jax.lax.cond(
            jnp.any(on & (nd[:, m] < tiny)), rescaled, lambda _: (nd, log_scale), None
        )
    else:
        nd = jnp.where(e >= -0.5, jnp.ones_like(e), jnp.zeros_like(e)) @ pv
        log_scale = jnp.zeros((x.shape[0],), x.dtype)
    den = nd[:, m]
    ok = den > 0
    safe = jnp.where(ok, den, jnp.ones_like(den))
    x_new = jnp.where(ok[:, None], nd[:, :m] / safe[:, None], x)
    log_den = jnp.where(ok, jnp.log(safe) + log_scale, jnp.full_like(den, -jnp.inf))
    return x_new, log_den


@jit(static_argnames=("kernel", "block"))
def _iterate(
    seeds: jax.Array,
    active0: jax.Array,
    p: jax.Array,
    p_mask: jax.Array,
    h: jax.Array,
    tol: jax.Array,
    max_iter: jax.Array,
    *,
    kernel: str,
    block: int,
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array, jax.Array]:
    """Run mean shift from every active seed until all shifts < ``tol * h`` or ``max_iter``.

    Each iteration moves only the seeds still active: they are compacted to the front (stable
    order) and processed ``block`` at a time, so converged seeds cost nothing.
    Returns ``(x, log_density, still_active, iterations, seed_steps)``.
    """
    n_seeds, _ = seeds.shape
    pa, pv = _augment(p, p_mask, h)
    tol_abs = tol * h

    def iteration(state):
        x, log_den, active, it, work = state
        order = jnp.argsort(jnp.logical_not(active), stable=True).astype(jnp.int32)
        n_active = jnp.sum(active.astype(jnp.int32))
        n_blocks = (n_active + block - 1) // block

        def body(b, carry):
            x, log_den, still = carry
            sel = jax.lax.dynamic_slice(order, (b * block,), (block,))
            xb = x[sel]
            on = active[sel]
            xn, ld = _shift_block(xb, on, pa, pv, h, kernel)
            shift = jnp.sqrt(jnp.sum((xn - xb) ** 2, axis=-1))
            x = x.at[sel].set(jnp.where(on[:, None], xn, xb))
            log_den = log_den.at[sel].set(jnp.where(on, ld, log_den[sel]))
            still = still.at[sel].set(on & (shift >= tol_abs))
            return x, log_den, still

        still0 = jnp.zeros_like(active)
        x, log_den, still = jax.lax.fori_loop(0, n_blocks, body, (x, log_den, still0))
        return x, log_den, still, it + 1, work + n_active

    def cond(state):
        _, _, active, it, _ = state
        return jnp.any(active) & (it < max_iter)

    log_den0 = jnp.full((n_seeds,), -jnp.inf, dtype=seeds.dtype)
    zero = jnp.zeros((), jnp.int32)
    state = (seeds, log_den0, active0, zero, zero)
    return jax.lax.while_loop(cond, iteration, state)


@jit
def _merge(
    x: jax.Array, log_den: jax.Array, valid: jax.Array, r2: jax.Array
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Greedy merge of converged seeds (module docstring, "Merge rule").

    Args: ``x`` ``(S, m)`` converged seeds, ``log_den`` ``(S,)`` their log densities, ``valid``
    ``(S,)`` real (non-padding) seeds, ``r2`` squared merge radius.
    Returns ``(labels (S,) int32 (-1 for padding), reps (S,) int32 (founding seed of mode k in
    reps[k], k < K), K)``.
    """
    n = x.shape[0]
    neg = jnp.asarray(-jnp.inf, log_den.dtype)
    score = jnp.where(jnp.isfinite(log_den), log_den, jnp.finfo(log_den.dtype).min)

    def cond(state):
        labels, _, _ = state
        return jnp.any(valid & (labels < 0))

    def body(state):
        labels, reps, k = state
        free = valid & (labels < 0)
        i = jnp.argmax(jnp.where(free, score, neg)).astype(jnp.int32)
        d2 = jnp.sum((x - x[i][None, :]) ** 2, axis=-1)
        take = free & (d2 <= r2)
        take = take.at[i].set(True)
        labels = jnp.where(take, k, labels)
        reps = reps.at[k].set(i)
        return labels, reps, k + 1

    state = (jnp.full((n,), -1, jnp.int32), jnp.zeros((n,), jnp.int32), jnp.zeros((), jnp.int32))
    return jax.lax.while_loop(cond, body, state)


@jit(static_argnames=("kernel", "block"))
def _step(
    x: jax.Array,
    x_valid: jax.Array,
    p: jax.Array,
    p_mask: jax.Array,
    h: jax.Array,
    *,
    kernel: str,
    block: int,
) -> tuple[jax.Array, jax.Array]:
    """One mean-shift step of every row of ``x`` (padded to a multiple of ``block``)."""
    pa, pv = _augment(p, p_mask, h)
    xb = x.reshape(-1, block, x.shape[1])
    on = x_valid.reshape(-1, block)
    xn, ld = jax.lax.map(lambda a: _shift_block(a[0], a[1], pa, pv, h, kernel), (xb, on))
    return xn.reshape(x.shape), ld.reshape(-1)


# --- host-side helpers ----------------------------------------------------------------------------


def _pad_rows(a: np.ndarray, multiple: int) -> np.ndarray:
    """Zero-pad the rows of ``a`` up to a positive multiple of ``multiple``."""
    n = a.shape[0]
    n_pad = max(multiple, -(-n // multiple) * multiple)
    out = np.zeros((n_pad, *a.shape[1:]), dtype=a.dtype)
    out[:n] = a
    return out


def _check_kernel(kernel: str) -> None:
    if kernel not in KERNELS:
        raise ConfigError(f"kernel must be one of {KERNELS}, got {kernel!r}")


def _check_bandwidth(bandwidth: float) -> float:
    h = float(bandwidth)
    if not (h > 0.0 and math.isfinite(h)):
        raise ConfigError(f"bandwidth must be positive and finite, got {bandwidth!r}")
    return h


def _as_points(points: Any, what: str = "points", m: int | None = None) -> np.ndarray:
    a = np.asarray(points, dtype=np.float32)
    if a.ndim != 2 or a.shape[0] == 0 or a.shape[1] == 0:
        raise ConfigError(f"{what} must be a non-empty (N, m) array, got shape {a.shape}")
    if m is not None and a.shape[1] != m:
        raise ConfigError(f"{what} must have {m} columns like the points, got {a.shape[1]}")
    if not np.isfinite(a).all():
        raise ConfigError(f"{what} contain non-finite values")
    return a


class _Prepared(NamedTuple):
    """Points centred on their mean (smaller norms: less cancellation), padded, on device."""

    n: int
    m: int
    center: np.ndarray  # (m,) float32
    p: jax.Array  # (N_pad, m) float32, centred, zero padding rows
    p_mask: jax.Array  # (N_pad,) float32, 1 for real rows
    p_valid: jax.Array  # (N_pad,) bool


def _prepare(points: np.ndarray) -> _Prepared:
    n, m = points.shape
    center = points.mean(axis=0, dtype=np.float64).astype(np.float32)
    p = _pad_rows(points - center[None, :], BLOCK)
    valid = np.zeros(p.shape[0], bool)
    valid[:n] = True
    return _Prepared(
        n=n,
        m=m,
        center=center,
        p=jnp.asarray(p),
        p_mask=jnp.asarray(valid.astype(np.float32)),
        p_valid=jnp.asarray(valid),
    )


def _nearest(x: np.ndarray, modes: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """``(N,)`` index of the nearest row of ``modes`` for each row of ``x`` (chunked, NumPy)."""
    m_sq = np.sum(modes * modes, axis=1)
    out = np.empty(x.shape[0], np.int32)
    for lo in range(0, x.shape[0], chunk):
        xc = x[lo : lo + chunk]
        d2 = m_sq[None, :] - 2.0 * (xc @ modes.T)
        out[lo : lo + chunk] = np.argmin(d2, axis=1)
    return out


def _run(
    prep: _Prepared,
    h: float,
    *,
    kernel: str,
    max_iter: int,
    tol: float,
    merge_fraction: float,
    seeds: np.ndarray | None,
) -> MeanShiftResult:
    """Mean shift on prepared points: iterate (jit), merge (jit), assemble the result."""
    if seeds is None:
        s, s_valid = prep.p, prep.p_valid
    else:
        s_host = _pad_rows(seeds - prep.center[None, :], BLOCK)
        valid = np.zeros(s_host.shape[0], bool)
        valid[: seeds.shape[0]] = True
        s, s_valid = jnp.asarray(s_host), jnp.asarray(valid)
    x, log_den, still, it, work = _iterate(
        s,
        s_valid,
        prep.p,
        prep.p_mask,
        jnp.float32(h),
        jnp.float32(tol),
        jnp.int32(max_iter),
        kernel=kernel,
        block=BLOCK,
    )
    labels, reps, k = _merge(x, log_den, s_valid, jnp.float32((merge_fraction * h) ** 2))
    k = int(k)
    reps_np = np.asarray(reps)[:k]
    x_np = np.asarray(x)
    modes = (x_np[reps_np] + prep.center[None, :]).astype(np.float32)
    if seeds is None:
        point_labels = np.asarray(labels)[: prep.n].astype(np.int32)
    else:
        p_np = np.asarray(prep.p)[: prep.n]
        point_labels = _nearest(p_np, x_np[reps_np])
    return MeanShiftResult(
        modes=modes,
        labels=point_labels,
        counts=np.bincount(point_labels, minlength=k).astype(np.int64),
        log_density=np.asarray(log_den)[reps_np].astype(np.float32),
        bandwidth=float(h),
        kernel=kernel,
        iterations=int(it),
        converged=not bool(np.any(np.asarray(still))),
        seed_steps=int(work),
    )


# --- public API -----------------------------------------------------------------------------------


def check_options(
    kernel: str = "gaussian",
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    merge_fraction: float = MERGE_FRACTION,
    *,
    bandwidth: float | None = None,
) -> None:
    """Check mean-shift options in plain Python (nothing is traced).

    Args: as in ``mean_shift``; ``bandwidth`` is checked too unless ``None``.

    Raises:
      ConfigError: an unknown kernel, ``max_iter < 1``, ``tol`` not positive and finite,
        ``merge_fraction`` negative or not finite, or a bandwidth not positive and finite.
    """
    _check_kernel(kernel)
    if bandwidth is not None:
        _check_bandwidth(bandwidth)
    if int(max_iter) < 1:
        raise ConfigError(f"max_iter must be >= 1, got {max_iter}")
    if not (float(tol) > 0.0 and math.isfinite(float(tol))):
        raise ConfigError(f"tol must be positive and finite, got {tol}")
    if not (0.0 <= float(merge_fraction) and math.isfinite(float(merge_fraction))):
        raise ConfigError(f"merge_fraction must be >= 0 and finite, got {merge_fraction}")


def mean_shift(
    points: Any,
    bandwidth: float,
    *,
    kernel: Kernel = "gaussian",
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    merge_fraction: float = MERGE_FRACTION,
    seeds: Any = None,
) -> MeanShiftResult:
    """Mean-shift clustering (Comaniciu & Meer 2002) of ``points``.

    Every seed (by default every point) climbs the kernel density estimate by repeated
    mean-shift steps, all seeds in parallel (jit, ``BLOCK`` rows at a time), until its step is
    shorter than ``tol * bandwidth`` or ``max_iter`` steps were taken; then the converged seeds are
    merged greedily (module docstring) into modes.

    Args:
      points: ``(N, m)`` data, float32 (finite).
      bandwidth: kernel bandwidth ``h`` (Gaussian standard deviation / flat radius), in the units
        of ``points``.
      kernel: ``"gaussian"`` (``w = exp(-|x - p|^2 / (2 h^2))``, default) or ``"flat"``
        (``w = 1`` if ``|x - p| <= h`` else 0).
      max_iter: most mean-shift steps per seed.
      tol: a seed stops once its step is shorter than ``tol * bandwidth`` (relative).
      merge_fraction: converged seeds closer than ``merge_fraction * bandwidth`` to a denser
        mode's seed join that mode.
      seeds: optional ``(S, m)`` starting points; default (``None``) every point is a seed. With
        explicit seeds each point is labelled with its nearest mode.

    Returns:
      ``MeanShiftResult`` with ``modes (K, m)`` (decreasing density), ``labels (N,)``,
      ``counts (K,)`` and diagnostics. Deterministic: the same input gives the same output.

    Raises:
      ConfigError: bad shapes, non-finite values, or an option out of range.
    """
    check_options(kernel, max_iter, tol, merge_fraction)
    h = _check_bandwidth(bandwidth)
    pts = _as_points(points)
    s = None if seeds is None else _as_points(seeds, "seeds", pts.shape[1])
    return _run(
        _prepare(pts),
        h,
        kernel=kernel,
        max_iter=max_iter,
        tol=tol,
        merge_fraction=merge_fraction,
        seeds=s,
    )


def mean_shift_step(
    x: Any, points: Any, bandwidth: float, *, kernel: Kernel = "gaussian"
) -> np.ndarray:
    """One mean-shift step: the kernel-weighted mean of ``points`` around each row of ``x``.

    Args:
      x: ``(S, m)`` query positions.
      points: ``(N, m)`` data.
      bandwidth: ``h``, as in ``mean_shift``.
      kernel: ``"gaussian"`` or ``"flat"``.

    Returns:
      ``(S, m)`` float32 ``sum_j w(x, p_j) p_j / sum_j w(x, p_j)``; a row with no point inside
      the flat kernel stays where it is.
    """
    _check_kernel(kernel)
    h = _check_bandwidth(bandwidth)
    pts = _as_points(points)
    q = _as_points(x, "x", pts.shape[1])
    prep = _prepare(pts)
    xq = _pad_rows(q - prep.center[None, :], BLOCK)
    xq_valid = np.arange(xq.shape[0]) < q.shape[0]
    xn, _ = _step(
        jnp.asarray(xq),
        jnp.asarray(xq_valid),
        prep.p,
        prep.p_mask,
        jnp.float32(h),
        kernel=kernel,
        block=BLOCK,
    )
    return (np.asarray(xn)[: q.shape[0]] + prep.center[None, :]).astype(np.float32)


def _initial_bandwidth(points: np.ndarray, target: int) -> float:
    """Guess ``h`` for ``target`` modes: ``0.048 * rms_spread * (target / N) ** -0.4``.

    The constants fit the Gaussian count curve of the MSR Action3D upper-body descriptors
    (within ~10 % for 200..3000 modes of ~11k points); elsewhere it is only a starting point.
    """
    n = points.shape[0]
    spread = float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))
    spread = spread if spread > 0 else 1.0
    return 0.048 * spread * (target / n) ** -0.4


def find_bandwidth(
    points: Any,
    target: int,
    *,
    rel_tol: float = 0.05,
    kernel: Kernel = "gaussian",
    initial: float | None = None,
    max_evals: int = 30,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    merge_fraction: float = MERGE_FRACTION,
    history: list[tuple[float, int]] | None = None,
) -> tuple[float, MeanShiftResult]:
    """The bandwidth whose mean shift gives ``target`` modes (within ``rel_tol``).

    The mode count ``K(h)`` falls as ``h`` grows (not strictly: it may wobble by a few modes). The
    search works on ``log h``: from ``initial`` (default ``_initial_bandwidth``) it steps along
    the log-log slope (at most x4 per step) until the target is bracketed, then bisects the
    bracket, each cut taken at the log-log secant point when that lies in the inner 80 % of the
    bracket, else at the midpoint. It stops at the first ``h`` with
    ``|K - target| <= rel_tol * target``. Every evaluation is a full ``mean_shift`` run with the
    same compiled functions (the data are prepared once; shapes never change, so nothing
    recompiles between steps).

    Args:
      points: ``(N, m)`` data.
      target: wanted number of modes, ``1 <= target <= N``.
      rel_tol: accepted relative error of the count.
      kernel, max_iter, tol, merge_fraction: as in ``mean_shift``.
      initial: first bandwidth tried.
      max_evals: most mean-shift runs (``>= 1``); if none hits the window, the closest count is
        returned with a ``RuntimeWarning``.
      history: if given, each ``(bandwidth, count)`` evaluated is appended to it.

    Returns:
      ``(bandwidth, result)``: the bandwidth found and its ``MeanShiftResult``
      (``result.n_modes`` is the count reached). ``result`` equals
      ``mean_shift(points, bandwidth, ...)`` with the same options.

    Raises:
      ConfigError: target out of ``1..N``, bad ``rel_tol``, ``max_evals < 1`` or bad options.
    """
    check_options(kernel, max_iter, tol, merge_fraction)
    pts = _as_points(points)
    n = pts.shape[0]
    target = int(target)
    if not 1 <= target <= n:
        raise ConfigError(f"target must be in 1..{n} (the number of points), got {target}")
    if not (0.0 <= rel_tol < 1.0):
        raise ConfigError(f"rel_tol must be in [0, 1), got {rel_tol}")
    if int(max_evals) < 1:
        raise ConfigError(f"max_evals must be >= 1, got {max_evals}")
    h = _check_bandwidth(initial) if initial is not None else _initial_bandwidth(pts, target)
    prep = _prepare(pts)
    window = rel_tol * target
    lo: tuple[float, int] | None = None  # largest log h seen with K > target
    hi: tuple[float, int] | None = None  # smallest log h seen with K < target
    seen: list[tuple[float, int]] = []
    results: list[MeanShiftResult] = []
    max_step = math.log(4.0)
    u = math.log(h)
    for _ in range(int(max_evals)):
        res = _run(
            prep,
            math.exp(u),
            kernel=kernel,
            max_iter=max_iter,
            tol=tol,
            merge_fraction=merge_fraction,
            seeds=None,
        )
        k = res.n_modes
        if history is not None:
            history.append((res.bandwidth, k))
        results.append(res)
        if abs(k - target) <= window:
            return res.bandwidth, res
        seen.append((u, k))
        if k > target and (lo is None or u > lo[0]):
            lo = (u, k)
        if k < target and (hi is None or u < hi[0]):
            hi = (u, k)
        nxt = _next_log_bandwidth(lo, hi, seen, target, max_step)
        if nxt is None:
            break
        u = nxt
    best = min(results, key=lambda r: abs(r.n_modes - target))  # the first of equally close
    warnings.warn(
        f"find_bandwidth: no bandwidth gives {target} +- {window:.0f} modes; closest is "
        f"{best.n_modes} modes at h = {best.bandwidth:.6g}",
        RuntimeWarning,
        stacklevel=2,
    )
    return best.bandwidth, best


def _next_log_bandwidth(
    lo: tuple[float, int] | None,
    hi: tuple[float, int] | None,
    seen: list[tuple[float, int]],
    target: int,
    max_step: float,
) -> float | None:
    """Next ``log h`` to try (see ``find_bandwidth``), or ``None`` when the bracket is spent."""
    v_t = math.log(target)
    if lo is not None and hi is not None:
        width = hi[0] - lo[0]
        if width < 1e-5:
            return None
        v_lo, v_hi = math.log(lo[1]), math.log(max(hi[1], 1))
        mid = lo[0] + 0.5 * width
        if v_lo > v_hi:
            u = lo[0] + (v_t - v_lo) * width / (v_hi - v_lo)
            if lo[0] + 0.1 * width <= u <= hi[0] - 0.1 * width:
                return u
        return mid
    # Not bracketed yet: extrapolate along the log-log slope of the last two points.
    u_last, k_last = seen[-1]
    slope = -2.5
    if len(seen) >= 2:
        u_prev, k_prev = seen[-2]
        if u_last != u_prev:
            slope = (math.log(k_last) - math.log(k_prev)) / (u_last - u_prev)
    slope = min(max(slope, -8.0), -0.5)
    step = (v_t - math.log(k_last)) / slope
    sign = 1.0 if k_last > target else -1.0
    step = sign * min(max(abs(step), math.log(1.25)), max_step)
    return u_last + step
