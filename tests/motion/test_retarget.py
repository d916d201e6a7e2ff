"""Whole-motion retargeting (jaxproj.motion.retarget): one compiled call per motion, equal to the
stage-by-stage pipeline it replaces."""

import numpy as np
import pytest
from fuzzing import no_tracing

from jaxproj.errors import ConfigError, InputError, NoValidFrameError
from jaxproj.human.skeleton import NECK_TILT_REFERENCE, descriptor
from jaxproj.io import datasets
from jaxproj.motion import smoothing
from jaxproj.motion.retarget import retarget
from jaxproj.projection import api as engine
from jaxproj.projection.confidence import LOW_CONFIDENCE
from jaxproj.robots.nao_h25 import ik, robot

FUSED_TOL_RAD = 2e-5
"""The descriptor computed inside the compiled whole-motion call differs from the eager one by a
few float32 ulp (XLA fuses its arithmetic: measured 3e-7); through the kernels that moves a
relaxed projection by up to ~1.5e-5 rad (measured), never the chosen candidate."""


@pytest.fixture(scope="module")
def model():
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3], actions=[1, 2, 5]))
    human = d[np.random.default_rng(0).choice(len(d), 300, replace=False)]
    cfg = engine.BuildConfig(landmarks=None, bandwidth=1.0, k=16, hidden=32, input_scale=1.0)
    return engine.from_landmarks(human, np.asarray(ik.solve_driven(human)), cfg)


@pytest.fixture(scope="module")
def motion():
    seq = next(s for s in datasets.msr_action3d(subjects=[2], actions=[13]) if (~s.valid).any())
    return seq.positions, seq.valid


def _stagewise(model, positions, valid, smooth):
    """The pipeline stage by stage: eager descriptor, the neck levelled to the recording's
    median tilt (NumPy), engine.project, fill, smooth, clip (limits, then the head envelope)."""
    d, ok = descriptor(positions)
    ok = np.asarray(ok) & valid
    d = np.array(d, np.float64)
    tilt = np.arctan2(d[:, 0], d[:, 2])
    delta = NECK_TILT_REFERENCE - np.median(tilt[ok])
    x, z = d[:, 0].copy(), d[:, 2].copy()
    d[:, 0], d[:, 2] = np.cos(delta) * x + np.sin(delta) * z, np.cos(delta) * z - np.sin(delta) * x
    d = d.astype(np.float32)
    if model is None:
        q = np.asarray(ik.solve_driven(d))
    else:
        q, _ = engine.project(model, np.asarray(d), "relaxed")
    idx = np.flatnonzero(ok)
    src = np.searchsorted(idx, np.arange(len(ok)), side="right") - 1
    q = q[idx[np.maximum(src, 0)]]  # hold the last valid frame, back-fill leading ones
    if smooth:
        q = np.asarray(smoothing.smooth(q))
    q = np.clip(q, robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX])
    env = (robot.HEAD_ENVELOPE_PITCH_MIN, robot.HEAD_ENVELOPE_PITCH_MAX)
    q[:, 1] = np.clip(q[:, 1], *(np.interp(q[:, 0], robot.HEAD_ENVELOPE_YAW, b) for b in env))
    return np.asarray(ik.driven_to_full(q)), ok


@pytest.mark.parametrize("method", ["ik", "relaxed"])
@pytest.mark.parametrize("smooth", [False, True])
def test_one_call_equals_the_stagewise_pipeline(model, motion, method, smooth):
    positions, valid = motion
    res = retarget(
        positions,
        valid,
        model=None if method == "ik" else model,
        smoothing=smoothing.PAPER_SMOOTHING if smooth else None,
    )
    want, ok = _stagewise(None if method == "ik" else model, positions, valid, smooth)
    np.testing.assert_array_equal(res.valid, ok)
    assert res.angles.shape == (len(valid), robot.N_JOINTS) and res.angles.dtype == np.float32
    # the IK is well conditioned: the fused descriptor's few ulp stay a few ulp
    tol = 1e-6 if method == "ik" else FUSED_TOL_RAD
    np.testing.assert_allclose(res.angles, want, rtol=0, atol=tol)
    assert (res.angles >= robot.LOWER).all() and (res.angles <= robot.UPPER).all()


def test_motions_of_similar_length_share_one_compilation(model, motion, count_compiles):
    positions, valid = motion
    retarget(positions[:40], valid[:40], model=model)  # compiles the 64-frame bucket
    with count_compiles() as n:
        retarget(positions[:50], valid[:50], model=model)
        retarget(positions[:33], valid[:33], model=model)
    assert n["motion"] == 0
    with count_compiles() as n:  # a longer motion takes the next bucket: the counter works
        retarget(np.resize(positions, (100, 20, 3)), np.ones(100, bool), model=model)
    assert n["motion"] == 1


def test_no_valid_frame_is_a_typed_error_saying_why(model, motion):
    """A motion with no valid frame is refused (``NoValidFrameError``, an ``InputError``), with
    the count of frames that failed each check; where the values alone rule every frame out,
    before anything is traced."""
    positions, _ = motion
    t = 7
    lost = np.zeros((t, 20, 3), np.float32)  # all-zero: a collapsed skeleton, found in the jit
    with pytest.raises(NoValidFrameError) as e:
        retarget(lost, model=model)
    assert isinstance(e.value, InputError) and e.value.n_frames == t
    assert str(e.value).startswith(f"positions: no valid frame among {t}: {t} with a degenerate")
    tiny = positions[:t] * 1e-5  # a unit error: every bone shorter than 1 mm
    with pytest.raises(NoValidFrameError, match=f"{t} with a degenerate skeleton.*units"):
        retarget(tiny)
    mixed = positions[:t].copy()
    mixed[:3] = np.nan
    marked = np.zeros(t, bool)
    with no_tracing() as traced, pytest.raises(NoValidFrameError) as e:
        retarget(mixed, marked, model=model)
    assert traced == []
    assert str(e.value) == (
        f"positions: no valid frame among {t}: 3 with non-finite coordinates (NaN / inf), "
        f"{t - 3} marked invalid (lost tracking or non-finite values)"
    )
    # one valid frame is enough: the others take its pose
    one = retarget(np.concatenate([lost, positions[:1]]), smoothing=None)
    np.testing.assert_array_equal(one.valid, [False] * t + [True])
    assert one.valid_share == 1 / (t + 1)
    np.testing.assert_array_equal(one.angles, np.tile(one.angles[-1], (t + 1, 1)))


def test_bad_arguments_are_config_errors(model, motion):
    positions, valid = motion
    with pytest.raises(ConfigError, match="positions"):
        retarget(positions[:, :19])
    with pytest.raises(ConfigError, match="valid"):
        retarget(positions, valid[:-1])
    with pytest.raises(ConfigError, match="needs a projector model"):
        retarget(positions, method="relaxed")
    with pytest.raises(ConfigError, match="method"):
        retarget(positions, model=model, method="nearest")
    with pytest.raises(ConfigError, match="L=0"):
        retarget(positions, model=model, n_l=0)


def test_confidence_and_the_default_offline_smoother(model, motion):
    positions, valid = motion
    # defaults: offline smoother (the neck not levelled here, to project the same descriptors)
    res = retarget(positions, valid, model=model, neck_neutral=None)
    _, v = engine.project(model, np.asarray(descriptor(positions)[0])[res.valid], "relaxed")
    np.testing.assert_allclose(res.confidence[res.valid], np.exp(-v / 0.174), rtol=1e-5)
    assert (res.confidence[~res.valid] == 0).all() and (~res.valid).any()
    low = res.confidence < LOW_CONFIDENCE
    assert res.low_confidence_share == np.mean(low)  # invalid frames (confidence 0) included
    assert res.low_confidence_valid_share == np.mean(low[res.valid])  # what the CLI reports
    assert res.low_confidence_valid_share < res.low_confidence_share  # the invalid ones count
    assert res.valid_share == np.mean(res.valid) < 1.0
    ik_res = retarget(positions, valid)
    np.testing.assert_array_equal(ik_res.confidence, res.valid.astype(np.float32))
    # the default is the offline smoother: the stage-wise pipeline with smoothing.smooth of it
    # on the projection, invalid frames skipped
    d, ok = descriptor(positions)
    ok = np.asarray(ok) & valid
    q, _ = engine.project(model, np.asarray(d), "relaxed")
    q = np.asarray(smoothing.smooth(q, smoothing.OFFLINE_SMOOTHING, valid=ok))
    q = np.clip(q, robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX])
    env = (robot.HEAD_ENVELOPE_PITCH_MIN, robot.HEAD_ENVELOPE_PITCH_MAX)
    q[:, 1] = np.clip(q[:, 1], *(np.interp(q[:, 0], robot.HEAD_ENVELOPE_YAW, b) for b in env))
    first, last = np.flatnonzero(ok)[[0, -1]]
    inner = slice(first, last + 1)
    np.testing.assert_allclose(res.angles[inner][:, robot.DRIVEN_INDEX], q[inner], atol=1e-4)
