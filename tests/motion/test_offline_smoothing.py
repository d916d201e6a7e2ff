"""The zero-lag offline smoother (jaxproj.motion.offline): against a float64 matrix Kalman / RTS
written out here, no lag on a shifted sine, tracking gaps, irregular steps, padding."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.motion import smoothing
from jaxproj.motion.offline import OFFLINE_SMOOTHING, OfflineSmoothing
from jaxproj.motion.smoothing import PAPER_SMOOTHING, smooth, smooth_batch


def _reference(y: np.ndarray, valid: np.ndarray, times: np.ndarray, a: float, r: float):
    """Kalman filter + RTS smoother with 2 x 2 matrices, float64, one joint column at a time;
    the same prior as the engine (first valid value, 1 rad and 10 rad/s wide)."""
    out = np.empty(y.shape, np.float64)
    q = a * a
    first, last = np.flatnonzero(valid)[[0, -1]]
    for j in range(y.shape[1]):
        xs, ps, xp, pp, fs = [], [], [], [], []
        x = np.array([y[first, j], 0.0])
        p = np.diag([1.0, 100.0])
        for t in range(len(y)):
            if t > 0:
                dt = times[t] - times[t - 1]
                f = np.array([[1.0, dt], [0.0, 1.0]])
                qm = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
                x, p = f @ x, f @ p @ f.T + qm
                xp.append(x.copy())
                pp.append(p.copy())
                fs.append(f)
            if valid[t]:
                s = p[0, 0] + r * r
                k = p[:, 0] / s
                x = x + k * (y[t, j] - x[0])
                p = p - np.outer(k, p[0, :])
            xs.append(x.copy())
            ps.append(p.copy())
        sm = xs[-1]
        col = [sm[0]]
        for t in range(len(y) - 2, -1, -1):
            g = ps[t] @ fs[t].T @ np.linalg.inv(pp[t])
            sm = xs[t] + g @ (sm - xp[t])
            col.append(sm[0])
        col = np.array(col[::-1])
        out[:, j] = col[np.clip(np.arange(len(y)), first, last)]
    return out


def _noisy_sine(times: np.ndarray, shift: float = 0.0, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    clean = 0.6 * np.sin(2 * np.pi * 0.5 * (times - shift))[:, None] * np.array([1.0, -0.5])
    return (clean + rng.normal(scale=0.01, size=clean.shape)).astype(np.float32)


def test_matches_float64_reference_with_gaps_and_irregular_steps():
    rng = np.random.default_rng(3)
    times = np.cumsum(rng.uniform(1 / 30, 1 / 8, 60))
    y = _noisy_sine(times)
    valid = np.ones(60, bool)
    valid[[0, 1, 17, 18, 19, 40, 59]] = False
    y[~valid] = 5.0  # the values of invalid frames must not be read
    params = OfflineSmoothing(accel_std=30.0, noise_std=0.02)
    got = np.asarray(smooth(y, params, times=times, valid=valid))
    want = _reference(y, valid, times, 30.0, 0.02)
    np.testing.assert_allclose(got, want, atol=2e-4)
    assert np.abs(got).max() < 1.0  # the 5.0 never leaked


def test_no_lag_on_a_shifted_sine():
    # the paper's causal smoother lags a sine; the offline one does not: the best alignment
    # of the smoothed and the clean sine is a shift of zero frames (cross-correlation)
    times = np.arange(150) / 15.0
    clean = 0.6 * np.sin(2 * np.pi * 0.5 * times)
    y = _noisy_sine(times, seed=1)[:, :1]

    def lag_frames(out: np.ndarray) -> int:
        inner = slice(20, 130)
        shifts = range(-6, 7)
        err = [np.mean((np.roll(out[:, 0], -k)[inner] - clean[inner]) ** 2) for k in shifts]
        return list(shifts)[int(np.argmin(err))]

    off = np.asarray(smooth(y, OFFLINE_SMOOTHING, times=times))
    paper = np.asarray(smooth(y, PAPER_SMOOTHING, times=times))
    assert lag_frames(off) == 0
    assert lag_frames(paper) >= 1
    # and it removes noise: closer to the clean sine than the measurement
    assert np.sqrt(np.mean((off[:, 0] - clean) ** 2)) < np.sqrt(np.mean((y[:, 0] - clean) ** 2))
    # shifting the input by whole frames shifts the output the same (away from the ends)
    y2 = _noisy_sine(times, shift=3 / 15.0, seed=1)[:, :1]
    y2[3:] = y[:-3]
    off2 = np.asarray(smooth(y2, OFFLINE_SMOOTHING, times=times))
    np.testing.assert_allclose(off2[40:140], off[37:137], atol=1e-3)


def test_irregular_steps_follow_time_not_frames():
    # the same motion sampled at 15 and at 30 fps smooths to the same curve at the shared times
    t15, t30 = np.arange(60) / 15.0, np.arange(120) / 30.0
    f = lambda t: (0.5 * np.sin(2 * np.pi * 0.4 * t))[:, None].astype(np.float32)  # noqa: E731
    a = np.asarray(smooth(f(t15), OFFLINE_SMOOTHING, times=t15))
    b = np.asarray(smooth(f(t30), OFFLINE_SMOOTHING, times=t30))
    np.testing.assert_allclose(a[5:-5], b[10:-10:2], atol=0.01)


def test_gap_is_bridged_not_held():
    # a linear ramp with a 10-frame tracking gap: the smoother interpolates across it
    times = np.arange(40) / 15.0
    y = (0.5 * times)[:, None].astype(np.float32)
    valid = np.ones(40, bool)
    valid[15:25] = False
    y[~valid] = y[14]  # what fill_invalid would hand over: the held frame
    out = np.asarray(smooth(y, OFFLINE_SMOOTHING, times=times, valid=valid))
    np.testing.assert_allclose(out[15:25, 0], 0.5 * times[15:25], atol=2e-3)


def test_a_long_gap_is_a_straight_line_between_its_ends():
    """A joint moving fast into a 3 s gap (more than ``BRIDGE_S``) and still after it: the
    model's cubic would carry the speed into the gap and overshoot; the bridge is the straight
    line between the smoothed values around it, within their range."""
    times = np.arange(60) / 10.0
    y = np.where(times < 2.0, 1.5 * times, 3.0)[:, None].astype(np.float32)
    valid = np.ones(60, bool)
    valid[20:50] = False  # frames 19 and 50 around it, 3.1 s apart
    y[~valid] = y[19]
    out = np.asarray(smooth(y, OFFLINE_SMOOTHING, times=times, valid=valid))[:, 0]
    w = (times[20:50] - times[19]) / (times[50] - times[19])
    np.testing.assert_allclose(out[20:50], out[19] * (1 - w) + out[50] * w, atol=1e-5)
    assert out[20:50].min() >= min(out[19], out[50]) - 1e-6
    assert out[20:50].max() <= max(out[19], out[50]) + 1e-6
    # the model alone (the float64 reference above) leaves that range by far: what it replaced
    cubic = _reference(y, valid, times, OFFLINE_SMOOTHING.accel_std, OFFLINE_SMOOTHING.noise_std)
    assert cubic[20:50, 0].max() > max(out[19], out[50]) + 0.2


def test_padded_batch_equals_one_by_one_and_keeps_padding():
    rng = np.random.default_rng(2)
    lengths = [5, 40, 1, 23]
    batch = np.full((4, 40, 3), 99.0, np.float32)
    valid = np.zeros((4, 40), bool)
    for i, n in enumerate(lengths):
        batch[i, :n] = np.cumsum(rng.normal(scale=0.05, size=(n, 3)), axis=0)
        valid[i, :n] = rng.uniform(size=n) > 0.2
        valid[i, 0] = True
    out = np.asarray(smooth_batch(batch, lengths, OFFLINE_SMOOTHING, valid=valid))
    for i, n in enumerate(lengths):
        one = np.asarray(smooth(batch[i, :n], OFFLINE_SMOOTHING, valid=valid[i, :n]))
        np.testing.assert_allclose(out[i, :n], one, atol=1e-5)
        assert np.all(out[i, n:] == 99.0)
    np.testing.assert_array_equal(out[2, 0], batch[2, 0])  # one frame: itself


def test_no_valid_frame_returns_input_and_bad_settings_fail():
    y = np.ones((6, 2), np.float32)
    out = np.asarray(smooth(y, OFFLINE_SMOOTHING, valid=np.zeros(6, bool)))
    np.testing.assert_array_equal(out, y)
    for bad in (dict(accel_std=0.0), dict(noise_std=-1.0), dict(rate=float("nan"))):
        with pytest.raises(ConfigError, match="must be positive"):
            OfflineSmoothing(**bad)
    with pytest.raises(ConfigError, match="SmoothingParams or an OfflineSmoothing"):
        smooth(y, (0.75, 0.3, 0.15))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="valid must be"):
        smooth(y, OFFLINE_SMOOTHING, valid=np.ones(5, bool))
    assert smoothing.frame_gains(OFFLINE_SMOOTHING, None, 6).shape == (3,)
