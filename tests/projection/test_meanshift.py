"""Mean shift: synthetic blobs, NumPy reference, merge rule, determinism, compile reuse, errors."""

from __future__ import annotations

import contextlib

import jax
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.io import datasets
from jaxproj.projection import meanshift

# --- helpers --------------------------------------------------------------------------------------


def _blobs(n_blobs: int = 4, per_blob: int = 60, dim: int = 15, sigma: float = 0.1, seed: int = 0):
    """Well-separated Gaussian blobs: ``(points, true_labels, centres)``."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(size=(n_blobs, dim)) * 2.0  # pairwise distances ~ 8 >> sigma
    true = np.repeat(np.arange(n_blobs), per_blob)
    points = centres[true] + sigma * rng.normal(size=(true.size, dim))
    perm = rng.permutation(true.size)
    return points[perm].astype(np.float32), true[perm], centres.astype(np.float32)


def _reference_mean_shift(points, h, kernel, tol, merge_fraction, max_iter=500):
    """Plain NumPy (float64) mean shift with the same stopping and greedy merge rules."""
    p = np.asarray(points, np.float64)
    x = p.copy()
    log_den = np.full(len(p), -np.inf)
    active = np.ones(len(p), bool)
    for _ in range(max_iter):
        if not active.any():
            break
        idx = np.nonzero(active)[0]
        d2 = np.sum((x[idx, None, :] - p[None, :, :]) ** 2, axis=-1)
        if kernel == "gaussian":
            w = np.exp(-d2 / (2 * h * h))
        else:
            w = (d2 <= h * h).astype(np.float64)
        den = w.sum(axis=1)
        new = (w @ p) / den[:, None]
        shift = np.linalg.norm(new - x[idx], axis=1)
        x[idx] = new
        log_den[idx] = np.log(den)
        active[idx] = shift >= tol * h
    # greedy merge: densest unassigned converged seed absorbs all unassigned ones within r
    labels = np.full(len(p), -1)
    modes, order = [], np.argsort(-log_den, kind="stable")
    for i in order:
        if labels[i] >= 0:
            continue
        free = labels < 0
        close = free & (np.sum((x - x[i]) ** 2, axis=1) <= (merge_fraction * h) ** 2)
        labels[close] = len(modes)
        modes.append(x[i])
    return np.array(modes), labels


def _train_points(subjects, actions=None):
    return datasets.valid_descriptors(datasets.msr_action3d(subjects=subjects, actions=actions))


# --- mean shift ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("kernel", "h"), [("gaussian", 0.3), ("flat", 1.0)])
def test_blobs_give_one_mode_per_blob_at_its_centre(kernel, h):
    points, true, centres = _blobs()
    res = meanshift.mean_shift(points, h, kernel=kernel)
    assert res.converged
    assert res.n_modes == 4
    assert res.modes.shape == (4, 15) and res.modes.dtype == np.float32
    assert res.labels.shape == (points.shape[0],)
    assert res.counts.sum() == points.shape[0]
    # each mode sits near one blob centre (the blob's sample mean is within ~sigma/sqrt(60))
    dist = np.linalg.norm(res.modes[:, None, :] - centres[None, :, :], axis=-1)
    match = dist.argmin(axis=1)
    assert sorted(match) == [0, 1, 2, 3]
    assert dist.min(axis=1).max() < 0.1
    # labels agree with the generating blobs, exactly
    np.testing.assert_array_equal(match[res.labels], true)
    np.testing.assert_array_equal(res.counts, np.full(4, 60))


@pytest.mark.parametrize("kernel", ["gaussian", "flat"])
def test_modes_are_fixed_points(kernel):
    points = _train_points([1], actions=[1, 2, 5])
    h, tol = (0.2, 1e-3) if kernel == "gaussian" else (0.5, 1e-3)
    res = meanshift.mean_shift(points, h, kernel=kernel, tol=tol)
    assert res.converged and res.n_modes > 3
    moved = np.linalg.norm(
        meanshift.mean_shift_step(res.modes, points, h, kernel=kernel) - res.modes, axis=1
    )
    assert moved.max() < 2 * tol * h + 1e-5
    # ... while a data point is not a fixed point
    far = np.linalg.norm(meanshift.mean_shift_step(points, points, h) - points, axis=1)
    assert far.max() > 10 * tol * h


def test_modes_are_density_maxima():
    """Moving a Gaussian mode in any direction lowers the kernel density estimate."""
    points = _train_points([1], actions=[1])
    h = 0.2
    res = meanshift.mean_shift(points, h)

    def density(x):
        d2 = np.sum((x[:, None, :] - points[None, :, :].astype(np.float64)) ** 2, axis=-1)
        return np.exp(-d2 / (2 * h * h)).sum(axis=1)

    rng = np.random.default_rng(1)
    for mode in res.modes[:10].astype(np.float64):
        probes = mode + 0.1 * h * rng.normal(size=(32, mode.size))
        assert density(probes).max() < density(mode[None])[0]


@pytest.mark.parametrize(("kernel", "h"), [("gaussian", 0.2), ("flat", 0.5)])
def test_matches_numpy_reference(kernel, h):
    points = _train_points([2], actions=[1, 3])[:300]
    res = meanshift.mean_shift(points, h, kernel=kernel)
    ref_modes, ref_labels = _reference_mean_shift(points, h, kernel, tol=1e-3, merge_fraction=0.5)
    assert res.n_modes == len(ref_modes) > 5
    dist = np.linalg.norm(res.modes[:, None, :] - ref_modes[None, :, :], axis=-1)
    match = dist.argmin(axis=1)
    assert len(set(match.tolist())) == res.n_modes  # one-to-one
    assert dist.min(axis=1).max() < 0.02 * h
    np.testing.assert_array_equal(match[res.labels], ref_labels)


def test_explicit_seeds_label_points_by_nearest_mode():
    points, true, centres = _blobs(seed=3)
    seeds = points[::10]
    res = meanshift.mean_shift(points, 0.3, seeds=seeds)
    assert res.n_modes == 4
    dist = np.linalg.norm(res.modes[:, None, :] - centres[None, :, :], axis=-1)
    np.testing.assert_array_equal(dist.argmin(axis=1)[res.labels], true)


def test_merge_rule_is_greedy_by_density():
    """Flat kernel, h = 1: isolated points are their own converged seeds, 1.2 h apart on a line."""
    line = np.zeros((3, 15), np.float32)
    line[:, 0] = [0.0, 1.2, 2.4]
    assert meanshift.mean_shift(line, 1.0, kernel="flat").n_modes == 3  # no merge below 1.2 h
    # merge radius 1.5 h, equal densities: index order; seed 0 absorbs seed 1 but not seed 2
    res = meanshift.mean_shift(line, 1.0, kernel="flat", merge_fraction=1.5)
    assert res.n_modes == 2
    np.testing.assert_array_equal(res.labels, [0, 0, 1])
    # a duplicated middle point is the densest: it absorbs both neighbours
    dense = np.concatenate([line, line[1:2]])
    res = meanshift.mean_shift(dense, 1.0, kernel="flat", merge_fraction=1.5)
    assert res.n_modes == 1
    np.testing.assert_array_equal(res.counts, [4])
    np.testing.assert_allclose(res.modes[0], line[1], atol=1e-6)


def test_gaussian_step_far_from_the_data_does_not_underflow():
    """exp(-d^2 / 2h^2) underflows for every point: the step falls back to shifted exponents."""
    pts = np.zeros((2, 15), np.float32)
    pts[1, 0] = 3.0  # 6 h apart: two modes
    far = np.zeros((1, 15), np.float32)
    far[0, 0] = 25.0  # exponents -1250 and -968: both 0 in float32
    np.testing.assert_allclose(meanshift.mean_shift_step(far, pts, 0.5), pts[1:], atol=1e-6)
    res = meanshift.mean_shift(pts, 0.5, seeds=far)
    assert res.n_modes == 1 and np.isfinite(res.log_density).all()
    np.testing.assert_allclose(res.modes, pts[1:], atol=1e-6)


def test_find_bandwidth_warns_when_the_window_is_missed():
    points, _, _ = _blobs()
    history: list[tuple[float, int]] = []
    with pytest.warns(RuntimeWarning, match="closest"):
        h, res = meanshift.find_bandwidth(
            points, 7, rel_tol=0.0, initial=0.3, max_evals=2, history=history
        )
    assert len(history) == 2
    assert res.n_modes == min((k for _, k in history), key=lambda k: abs(k - 7))


def test_deterministic():
    points = _train_points([1], actions=[1, 2])
    first = meanshift.mean_shift(points, 0.15)
    second = meanshift.mean_shift(points.copy(), 0.15)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


# --- compile reuse --------------------------------------------------------------------------------

_TRACE = "/jax/core/compile/jaxpr_trace_duration"
_COMPILE = "/jax/core/compile/backend_compile_duration"


@contextlib.contextmanager
def _recorded_compiles():
    """Record ``(event, function name)`` of every JAX trace and backend compile in the block.

    Uses the public ``jax.monitoring`` duration events that JAX emits for each trace of a jitted
    function and each XLA compilation (keyword ``fun_name``); no private jit attribute.
    """
    seen: list[tuple[str, str]] = []

    def listener(event: str, duration: float, **kwargs) -> None:
        if event in (_TRACE, _COMPILE):
            seen.append((event, str(kwargs.get("fun_name", ""))))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield seen
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def _of(seen, name):
    return [event for event, fun in seen if name in fun]


def test_bisection_reuses_the_compiled_functions():
    points = _train_points([1, 3], actions=[1, 2, 3, 4])
    meanshift.mean_shift(points, 0.2)  # compile for this shape
    history: list[tuple[float, int]] = []
    with _recorded_compiles() as seen:
        h, res = meanshift.find_bandwidth(points, 60, initial=1.5, history=history)
    assert len(history) >= 3  # a bad start: several mean-shift runs
    assert _of(seen, "_iterate") == [] and _of(seen, "_merge") == [], seen
    assert abs(res.n_modes - 60) <= 3
    assert history[-1] == (h, res.n_modes)
    # the recorder does see a recompilation: another shape traces and compiles both again
    with _recorded_compiles() as seen:
        meanshift.mean_shift(points[:, :13], 0.2)  # 13 columns: a shape no other test uses
    assert _TRACE in _of(seen, "_iterate") and _COMPILE in _of(seen, "_iterate"), seen
    assert _TRACE in _of(seen, "_merge"), seen


# --- errors ---------------------------------------------------------------------------------------


def test_bad_arguments_raise_config_error():
    points, _, _ = _blobs()
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.0)
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.3, kernel="epanechnikov")
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.3, max_iter=0)
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.3, tol=float("nan"))
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.3, merge_fraction=-0.1)
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points[:, :0], 0.3)
    with pytest.raises(ConfigError):
        meanshift.mean_shift(points, 0.3, seeds=points[:, :3])
    bad = points.copy()
    bad[0, 0] = np.inf
    with pytest.raises(ConfigError):
        meanshift.mean_shift(bad, 0.3)
    with pytest.raises(ConfigError):
        meanshift.mean_shift_step(points[:2], points, -1.0)
    with pytest.raises(ConfigError):
        meanshift.find_bandwidth(points, points.shape[0] + 1)
    with pytest.raises(ConfigError):
        meanshift.find_bandwidth(points, 0)
    with pytest.raises(ConfigError):
        meanshift.find_bandwidth(points, 4, rel_tol=1.0)
    with pytest.raises(ConfigError, match="max_evals"):
        meanshift.find_bandwidth(points, 4, max_evals=0)
    with pytest.raises(ConfigError, match="bandwidth"):
        meanshift.check_options(bandwidth=float("inf"))
    meanshift.check_options("flat", 1, 1e-3, 0.0, bandwidth=0.5)  # valid: no error
