"""Streaming (``jaxproj.motion.streaming``): one pose at a time equals the whole-recording pipeline.

The model is small and real: 200 distinct descriptors of subjects 1 and 3 with their IK poses
and both kernel banks (``engine.build_from_landmarks``); recordings are subject 2's.
"""

import jax
import numpy as np
import pytest
from helpers import clip_driven_np, small_projector

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.motion import pipeline, streaming
from jaxproj.motion.smoothing import PAPER_SMOOTHING, SmoothingParams, smooth
from jaxproj.projection import api as engine
from jaxproj.robots.generic_ik import TrackConfig
from jaxproj.robots.nao_h25 import robot

STANDING = robot.STANDING_POSTURE[robot.DRIVEN_INDEX]


@pytest.fixture(scope="module")
def projector():
    return small_projector()


@pytest.fixture(scope="module")
def recordings():
    """Three real recordings of subject 2 whose frames are all valid, ``(T, 20, 3)`` each."""
    out = []
    for seq in datasets.msr_action3d(subjects=[2]):
        _, ok = descriptor(seq.positions)
        if np.asarray(ok).all() and len(seq.positions) >= 40:
            out.append(np.asarray(seq.positions, np.float32))
        if len(out) == 3:
            return out
    raise AssertionError("expected three fully valid recordings of subject 2")


def _stream(model, positions, **kw):
    """Angles ``(T, n)`` and every state of a recording streamed frame by frame."""
    state = streaming.init(model)
    angles, states = [], []
    for frame in positions:
        a, state = streaming.update(model, state, frame, **kw)
        angles.append(np.asarray(a))
        states.append(jax.tree.map(np.asarray, state))
    return np.stack(angles), states


def test_streaming_equals_the_whole_recording_pipeline(projector, recordings):
    one_frame = jax.jit(lambda x: descriptor(x)[0])
    for pos in recordings[:2]:
        angles, states = _stream(projector, pos)
        level = np.stack([s.level for s in states])
        assert all(s.started for s in states)

        # the whole recording at once: descriptors of the batch, projected in one batch,
        # smooth, clip. float32 results depend on array shapes (one frame or a batch of T in
        # the descriptor's einsum: ~1 ulp; engine.project's own batch sizes 1 and 256 differ
        # by up to ~8e-6 rad after the kernels), so 2e-5 rad (1e-3 deg)
        d, _ = descriptor(pos)
        r, _ = engine.project(projector, np.asarray(d), "relaxed", batch_size=64)
        s = np.asarray(smooth(r))
        np.testing.assert_allclose(level, s, rtol=0, atol=2e-5)
        np.testing.assert_allclose(angles, clip_driven_np(s), rtol=0, atol=2e-5)

        # the same pipeline with the shapes streaming sees (descriptors one frame at a time,
        # projections in batches of 1): only the smoother's scan vs its single step remain,
        # separately compiled float32 programs (a few ulp: 1e-6 rad; measured 1.2e-7)
        d1 = np.stack([np.asarray(one_frame(x)) for x in pos])
        r1, _ = engine.project(projector, d1, "relaxed", batch_size=1)
        np.testing.assert_allclose(level, np.asarray(smooth(r1)), rtol=0, atol=1e-6)
        # the first frame starts the smoother at the projection itself, exactly (the output:
        # its clip to the limits and the head envelope)
        np.testing.assert_array_equal(level[0], r1[0])
        np.testing.assert_allclose(angles[0], clip_driven_np(r1[0]), rtol=0, atol=8 * 2.0**-24)
        np.testing.assert_array_equal(states[0].trend, np.zeros(10, np.float32))
        # the smoother is on: the output is not the raw projection
        assert np.abs(angles - r1).max() > 1e-2


def test_invalid_frames_hold_the_previous_output_and_state(projector, recordings):
    pos = recordings[0][:30]
    clean, clean_states = _stream(projector, pos)

    bad_nan = pos[5].copy()
    bad_nan[7] = np.nan  # lost joint
    bad_zero = np.zeros((20, 3), np.float32)  # degenerate body frame
    bad_shoulders = pos[5].copy()
    bad_shoulders[8] = bad_shoulders[4]  # ShoulderRight on ShoulderLeft: no body frame
    bad_inf = np.full((20, 3), np.inf, np.float32)
    # two leading invalid frames, then the clean recording with invalid frames inserted
    frames = [bad_nan, bad_zero]
    where_bad = {0, 1}
    for t, p in enumerate(pos):
        frames.append(p)
        if t in (9, 20):
            frames += [bad_shoulders, bad_inf]
            where_bad |= {len(frames) - 2, len(frames) - 1}
    angles, states = _stream(projector, np.stack(frames))

    assert np.isfinite(angles).all()
    # before any valid frame: the standing posture, smoother not started
    for t in (0, 1):
        np.testing.assert_array_equal(angles[t], STANDING)
        assert not states[t].started
    # an invalid frame repeats the previous output and leaves the state untouched, but for
    # its confidence: 0
    for t in sorted(where_bad - {0, 1}):
        np.testing.assert_array_equal(angles[t], angles[t - 1])
        for a, b in zip(states[t][:3], states[t - 1][:3], strict=True):
            np.testing.assert_array_equal(a, b)
        assert states[t].confidence == 0.0
    assert all(0.0 < states[t].confidence <= 1.0 for t in range(len(frames)) if t not in where_bad)
    # the valid frames are exactly the clean stream: invalid frames leave no trace
    valid = [t for t in range(len(frames)) if t not in where_bad]
    np.testing.assert_array_equal(angles[valid], clean)
    for t, s in zip(valid, clean_states, strict=True):
        np.testing.assert_array_equal(states[t].level, s.level)


def test_no_valid_frame_gives_the_standing_posture(projector):
    state = streaming.init(projector)
    for frame in (np.full((20, 3), np.nan, np.float32), np.zeros((20, 3), np.float32)):
        a, state = streaming.update(projector, state, frame)
        np.testing.assert_array_equal(np.asarray(a), STANDING)
        assert not bool(state.started)


def test_jit_traces_once(projector, recordings, monkeypatch):
    traces = []
    original = pipeline.descriptor

    def counting(*args, **kw):  # runs only while jax traces the step
        traces.append(1)
        return original(*args, **kw)

    monkeypatch.setattr(pipeline, "descriptor", counting)
    pos = recordings[1]
    state = streaming.init(projector)
    kw = dict(n_l=3, n_m=4)  # a (L, M) no other test compiles
    _, state = streaming.update(projector, state, pos[0], **kw)
    assert len(traces) == 1
    _, state = streaming.update(projector, state, pos[1], **kw)  # second frame
    _, state = streaming.update(projector, state, np.full((20, 3), np.nan), **kw)  # invalid
    _, state = streaming.update(projector, state, pos[2].astype(np.float64), **kw)  # cast
    _, state = streaming.update(projector, state, jax.numpy.asarray(pos[3]), **kw)  # device
    new_gains = SmoothingParams(alpha=0.5, gamma=0.1, eta=0.0)
    _, state = streaming.update(projector, state, pos[4], smoothing=new_gains, **kw)
    assert len(traces) == 1
    streaming.update(projector, state, pos[5], n_l=4, n_m=4)  # a new (L, M) compiles
    assert len(traces) == 2


def test_gains_reach_the_smoother(projector, recordings):
    pos = recordings[2][:20]
    paper, _ = _stream(projector, pos)
    raw, _ = _stream(projector, pos, smoothing=SmoothingParams(alpha=1.0, gamma=0.0, eta=0.0))
    r, _ = engine.project(projector, np.asarray(descriptor(pos)[0]), "relaxed", batch_size=1)
    # alpha = 1, no dead band: the output is the projection itself
    np.testing.assert_allclose(raw, r, rtol=0, atol=2e-5)
    assert np.abs(paper - raw).max() > 1e-2


def test_a_model_streams_like_its_projector(projector, recordings):
    pos = recordings[0][:10]
    model = engine.Model(projector, engine.BuildConfig(), 0.0, np.ones(200), 200)
    got, _ = _stream(model, pos)
    want, _ = _stream(projector, pos)
    np.testing.assert_array_equal(got, want)
    # a mirrored model mirrors the descriptor
    mirrored = engine.Model(projector, engine.BuildConfig(mirror=True), 0.0, np.ones(200), 200)
    a, _ = streaming.update(mirrored, streaming.init(mirrored), pos[0])
    d, _ = descriptor(pos[0], mirror=True)
    r, _ = engine.project(projector, np.asarray(d)[None], "relaxed", batch_size=1)
    # eager descriptor vs the one fused into the jitted step: a few ulp, up to ~8e-6 rad after
    # the kernels (see the first test)
    np.testing.assert_allclose(np.asarray(a), clip_driven_np(r[0]), rtol=0, atol=2e-5)
    assert np.abs(np.asarray(a) - want[0]).max() > 1e-2  # not the direct imitation


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(n_l=0), "L=0"),
        (dict(n_m=201), "M=201"),
        (dict(n_l=2.5), "integers"),
        (dict(n_l=True), "integers"),
        (dict(smoothing=(0.75, 0.3, 0.15)), "SmoothingParams"),
    ],
)
def test_bad_options_are_config_errors(projector, recordings, kw, match):
    with pytest.raises(ConfigError, match=match):
        streaming.update(projector, streaming.init(projector), recordings[0][0], **kw)


def test_bad_inputs_are_config_errors(projector, recordings):
    state = streaming.init(projector)
    frame = recordings[0][0]
    with pytest.raises(ConfigError, match="one frame"):
        streaming.update(projector, state, recordings[0][:2])
    with pytest.raises(ConfigError, match="one frame"):
        streaming.update(projector, state, frame[:19])
    with pytest.raises(ConfigError, match="StreamState"):
        streaming.update(projector, tuple(state), frame)
    with pytest.raises(ConfigError, match="does not fit"):
        streaming.update(projector, state._replace(level=state.level[:5]), frame)
    with pytest.raises(ConfigError, match="Model or a projection.Projector"):
        streaming.init(np.zeros((3, 3)))
    with pytest.raises(ConfigError, match="alpha"):
        streaming.update(projector, state, frame, smoothing=SmoothingParams(alpha=2.0))
    full = engine.Model(projector, engine.BuildConfig(bones="full"), 0.0, np.ones(200), 200)
    with pytest.raises(ConfigError, match="do not match"):
        streaming.update(full, state, frame)


def test_init_state(projector):
    s = streaming.init(projector)
    assert isinstance(s, streaming.StreamState)
    np.testing.assert_array_equal(np.asarray(s.level), STANDING)
    np.testing.assert_array_equal(np.asarray(s.trend), np.zeros(10, np.float32))
    assert not bool(s.started) and float(s.confidence) == 0.0
    assert PAPER_SMOOTHING == SmoothingParams()  # update's default gains are the paper's


def test_a_robot_with_a_continuity_pass_streams_it_as_retarget_runs_it(recordings):
    """The G1 (``Robot.track_step``): streamed frame by frame, each frame's projection goes
    through the forward half of the continuity pass that ``retarget`` runs over the whole
    motion (``GenericIK.track`` one way: ``TrackConfig(both_ways=False)``; offline, ``retarget``
    also runs it backwards and joins the two), carried in the state. A projector whose
    landmarks hold random G1 poses makes the raw answers jump as the person moves: the pass
    must hold them."""
    from jaxproj import robots

    g1 = robots.get("unitree_g1")
    cfg = engine.BuildConfig(chains="whole", k=16, hidden=16, lam=1e-3, input_scale=0.5,
                             robot="unitree_g1")  # fmt: skip
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1]), bones=cfg.bones)
    human = np.unique(train, axis=0)[::40][:60].astype(np.float32)
    rng = np.random.default_rng(0)
    poses = rng.uniform(g1.lower_driven, g1.upper_driven, (len(human), g1.n_driven))
    proj = engine.build_from_landmarks(human, poses.astype(np.float32), cfg,
                                       lower=g1.lower_driven, upper=g1.upper_driven)  # fmt: skip
    model = engine.Model(projector=proj, config=cfg, bandwidth=(0.0,),
                         counts=(np.ones(len(human)),), n_train=len(human))  # fmt: skip
    pos = recordings[0][:16]
    state = streaming.init(model)
    tracked, answers = [], []
    for frame in pos:
        _, state = streaming.update(model, state, frame, n_l=4, n_m=4)
        tracked.append(np.asarray(state.tracked))
        answers.append(np.asarray(state.answer))
    tracked, answers = np.stack(tracked), np.stack(answers)
    d = np.asarray(descriptor(pos, cfg.bones)[0])
    one_way = TrackConfig(both_ways=False)
    ik = g1.track.__self__.build()  # type: ignore[union-attr]  # the GenericSolver behind it
    whole = np.asarray(jax.jit(lambda q, d: ik.track(q, np.ones(len(q), bool), d, cfg.bones,
                                                     one_way))(answers, d))  # fmt: skip
    np.testing.assert_allclose(tracked, whole, atol=2e-4)
    # the raw answers jump between random poses; the pass moves a joint at most
    # TrackConfig.min_step (15 deg) or 1.8 times the limb's turn a frame
    assert np.abs(np.diff(answers, axis=0)).max() > np.radians(60)
    assert np.abs(np.diff(tracked, axis=0)).max() < np.abs(np.diff(answers, axis=0)).max() / 2
