import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.motion import smoothing
from jaxproj.motion.smoothing import PAPER_SMOOTHING, SmoothingParams, smooth, smooth_batch


def _reference(y: np.ndarray, alpha: float, gamma: float, eta: float) -> np.ndarray:
    """Plain NumPy loop of the documented update rule (float64)."""
    y = np.asarray(y, dtype=np.float64)
    out = np.empty_like(y)
    s = y[0].copy()
    b = np.zeros_like(s)
    out[0] = s
    for t in range(1, len(y)):
        cand = alpha * y[t] + (1 - alpha) * (s + b)
        new = cand if np.linalg.norm(cand - s) >= eta else s
        b = gamma * (new - s) + (1 - gamma) * b
        s = new
        out[t] = s
    return out


def _motion(rng: np.random.Generator, t: int, n: int = 10) -> np.ndarray:
    base = np.cumsum(rng.normal(scale=0.08, size=(t, n)), axis=0)
    return (base + rng.normal(scale=0.02, size=(t, n))).astype(np.float32)


@pytest.mark.parametrize(
    "params", [PAPER_SMOOTHING, SmoothingParams(0.5, 0.1, 0.0), SmoothingParams(0.9, 0.6, 0.05)]
)
def test_matches_numpy_loop(params):
    rng = np.random.default_rng(1)
    y = _motion(rng, 80)
    got = np.asarray(smooth(y, params))
    want = _reference(y, *dataclasses.astuple(params)[:3])
    np.testing.assert_allclose(got, want, atol=1e-5)
    # the dead band actually held some frames with the paper's eta, and not with eta=0
    held = np.all(np.diff(got, axis=0) == 0, axis=1).sum()
    assert (held > 0) == (params.eta > 0.1)


def test_padded_batch_equals_one_by_one():
    rng = np.random.default_rng(2)
    lengths = [5, 40, 1, 23]
    t_max = 40
    ys = [_motion(rng, t) for t in lengths]
    batch = np.zeros((len(ys), t_max, 10), np.float32)
    for i, y in enumerate(ys):
        batch[i, : len(y)] = y
        batch[i, len(y) :] = 99.0  # padding must not leak into anything
    out = np.asarray(smooth_batch(batch, np.array(lengths)))
    for i, y in enumerate(ys):
        np.testing.assert_allclose(
            out[i, : len(y)], _reference(y, *dataclasses.astuple(PAPER_SMOOTHING)[:3]), atol=1e-5
        )
        assert (out[i, len(y) :] == 99.0).all()


def test_constant_motion_is_a_fixed_point():
    y = np.tile(np.linspace(-1, 1, 10, dtype=np.float32), (30, 1))
    np.testing.assert_array_equal(np.asarray(smooth(y)), y)


def test_new_gains_do_not_recompile(count_compiles):
    rng = np.random.default_rng(3)
    y = _motion(rng, 30)[None]
    lengths = np.array([30])
    name = smoothing._smooth_batch.__name__
    smooth_batch(y, lengths, SmoothingParams(0.7, 0.2, 0.1))

    with count_compiles() as compiles:
        smooth_batch(y, lengths, SmoothingParams(0.6, 0.25, 0.12))
        smooth_batch(y + 1.0, lengths, SmoothingParams(0.8, 0.3, 0.0))
    assert compiles[name] == 0, compiles
    # the counter does see compilations: a new shape (7 joints, which no other test or motion
    # has) compiles once, then is reused
    y7 = np.stack([_motion(rng, 17, n=7) for _ in range(3)])
    with count_compiles() as compiles:
        smooth_batch(y7, np.array([17, 9, 1]), SmoothingParams(0.6, 0.25, 0.12))
        smooth_batch(y7 - 1.0, np.array([5, 17, 17]), SmoothingParams(0.8, 0.3, 0.0))
    assert compiles[name] == 1, compiles


def test_bad_gains_are_config_errors():
    y = np.zeros((3, 2), np.float32)
    with pytest.raises(ConfigError, match="alpha"):
        smooth(y, SmoothingParams(alpha=1.5))
    with pytest.raises(ConfigError, match="eta"):
        smooth(y, SmoothingParams(eta=-1.0))
    with pytest.raises(ConfigError, match="shape"):
        smooth(np.zeros((3,), np.float32))


def test_step_is_one_frame_of_smooth():
    # smooth scans smoothing.step; a Python loop of the same step (one jitted call per frame,
    # as jaxproj.motion.streaming runs it) gives the same motion. Separately compiled float32
    # programs may round differently: 1e-6 rad (a few ulp of angles up to ~2 rad; measured 1.2e-7).
    rng = np.random.default_rng(4)
    y = _motion(rng, 120)
    params = SmoothingParams(0.75, 0.3, 0.15)
    want = np.asarray(smooth(y, params))
    one = jax.jit(smoothing.step)
    s, b = jnp.asarray(y[0]), jnp.zeros(10, jnp.float32)
    got = [np.asarray(s)]
    for t in range(1, len(y)):
        s, b = one(s, b, jnp.asarray(y[t]), params.gains())
        got.append(np.asarray(s))
    got = np.stack(got)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    # same frames held by the dead band
    held_got = np.all(np.diff(got, axis=0) == 0, axis=1)
    held_want = np.all(np.diff(want, axis=0) == 0, axis=1)
    assert held_want.any() and np.array_equal(held_got, held_want)


def test_step_follows_the_documented_rule():
    s_prev = np.array([0.1, -0.2, 0.3], np.float32)
    b_prev = np.array([0.05, 0.0, -0.02], np.float32)
    y = np.array([0.4, -0.1, 0.2], np.float32)
    alpha, gamma, eta = 0.75, 0.3, 0.15
    gains = SmoothingParams(alpha, gamma, eta).gains()
    s, b = smoothing.step(jnp.asarray(s_prev), jnp.asarray(b_prev), jnp.asarray(y), gains)
    cand = alpha * y + (1 - alpha) * (s_prev + b_prev)
    assert np.linalg.norm(cand - s_prev) >= eta  # this frame moves
    np.testing.assert_allclose(np.asarray(s), cand, atol=1e-6)
    b_want = gamma * (cand - s_prev) + (1 - gamma) * b_prev
    np.testing.assert_allclose(np.asarray(b), b_want, atol=1e-6)
    # inside the dead band: the value holds and the trend decays (dead band before the trend)
    wide = SmoothingParams(alpha, gamma, 1.0).gains()
    s2, b2 = smoothing.step(jnp.asarray(s_prev), jnp.asarray(b_prev), jnp.asarray(s_prev), wide)
    np.testing.assert_array_equal(np.asarray(s2), s_prev)
    np.testing.assert_allclose(np.asarray(b2), (1 - gamma) * b_prev, atol=1e-7)


def test_default_gains_behave_the_same_at_15_and_30_fps() -> None:
    """Gains follow the time step (``SmoothingParams.gains(dt)``): the same continuous motion
    sampled at 15 and 30 fps smooths to nearly the same curve; per-frame gains do not."""

    def signal(t: np.ndarray) -> np.ndarray:
        base = np.stack([np.sin(2 * np.pi * 0.4 * t), 0.8 * (t > 1.75)], axis=1)  # off-grid step
        return (2.0 * base).astype(np.float32)

    t15 = np.arange(60) / 15.0
    t30 = np.arange(120) / 30.0
    y15 = np.asarray(smooth(signal(t15), PAPER_SMOOTHING, times=t15))
    y30 = np.asarray(smooth(signal(t30), PAPER_SMOOTHING, times=t30))
    timed = np.abs(y30[::2] - y15).max()
    per_frame = np.abs(np.asarray(smooth(signal(t30)))[::2] - y15).max()
    assert timed < 0.35 * per_frame, (timed, per_frame)
    assert timed < 0.15  # rad, on a 4 rad peak-to-peak signal with a 1.6 rad step
    # at the reference rate the time-step gains are the given gains
    np.testing.assert_allclose(
        np.asarray(PAPER_SMOOTHING.gains(np.full(5, 1 / 15)))[1:],
        np.tile(np.asarray(PAPER_SMOOTHING.gains()), (4, 1)),
        rtol=1e-6,
    )
    with pytest.raises(ConfigError, match="rate"):
        SmoothingParams(rate=0.0)
