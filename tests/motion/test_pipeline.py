"""The one motion pipeline (``jaxproj.motion.pipeline``): its stages against plain NumPy loops,
the transformations (jit, vmap), and its three callers (retarget, streaming, evaluate) agreeing
where the module doc says they should."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import clip_driven_np, small_projector

from jaxproj.eval import evaluate
from jaxproj.human.skeleton import J, descriptor
from jaxproj.io import datasets
from jaxproj.motion import feasible, pipeline, streaming
from jaxproj.motion.retarget import retarget
from jaxproj.motion.smoothing import PAPER_SMOOTHING, SmoothingParams, frame_gains
from jaxproj.projection import api as engine
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import robot

LO, HI = robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX]
STANDING = robot.STANDING_POSTURE[robot.DRIVEN_INDEX]


SMOOTH_TOL_RAD = 1e-5
"""float32 smoother against the float64 NumPy loop: a few ulp per step, accumulated over ~50
frames of angles up to ~2 rad (measured ~1e-6)."""

ENVELOPE_TOL_RAD = 8 * 2.0**-24
"""The head envelope's float32 interpolation (``jnp.interp``) against NumPy's float64: a few
roundings of angles below 2.1 rad."""

BATCH_TOL_RAD = 2e-5
"""The same relaxed projection in differently shaped batches (one frame, the padded motion, the
valid frames of a dataset) and the descriptor eager or fused into a jitted call: a few float32
ulp, up to ~1.5e-5 rad after the kernels (``tests/motion/test_retarget.py``,
``test_streaming.py``)."""


def _fill_loop(q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The documented fill rule as a plain loop."""
    out = np.array(q, np.float64)
    if not valid.any():
        return np.where(np.isfinite(out), out, 0.0)
    first = int(np.argmax(valid))
    last = first
    for t in range(len(q)):
        if valid[t]:
            last = t
        out[t] = q[last]
    return out


def _smooth_loop(y: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """The double exponential smoother of ``jaxproj.motion.smoothing``'s doc, float64, with
    ``(T, 3)`` per-frame gains ``(alpha, gamma, eta)``."""
    y = np.asarray(y, np.float64)
    s, b = y[0].copy(), np.zeros(y.shape[1])
    out = [s.copy()]
    for t in range(1, len(y)):
        alpha, gamma, eta = gains[t]
        cand = alpha * y[t] + (1 - alpha) * (s + b)
        s_new = cand if np.linalg.norm(cand - s) >= eta else s
        b = gamma * (s_new - s) + (1 - gamma) * b
        s = s_new
        out.append(s.copy())
    return np.stack(out)


def _random_motion(rng: np.random.Generator, t: int) -> np.ndarray:
    walk = np.cumsum(rng.normal(0.0, 0.08, (t, len(robot.DRIVEN_JOINTS))), axis=0)
    return (0.5 * (LO + HI) + walk).astype(np.float32)


@pytest.mark.parametrize("pattern", ["leading", "middle", "none", "all"])
def test_fill_invalid_is_the_documented_rule(pattern):
    rng = np.random.default_rng(1)
    q = _random_motion(rng, 30)
    valid = np.ones(30, bool)
    if pattern == "leading":
        valid[:4] = False
        valid[10:13] = False
    elif pattern == "middle":
        valid[rng.choice(30, 12, replace=False)] = False
        valid[0] = True
    elif pattern == "none":
        valid[:] = False
    q[~valid] = np.nan  # whatever invalid frames hold never leaks
    got = np.asarray(jax.jit(pipeline.fill_invalid)(q, valid))
    np.testing.assert_array_equal(got, _fill_loop(q, valid).astype(np.float32))


@pytest.mark.parametrize("standing", ["first", "last"])
@pytest.mark.parametrize("gains", ["paper", "timed", None])
def test_finish_is_fill_smoothclip_driven_np(standing, gains):
    rng = np.random.default_rng(2)
    t, pad = 50, 14
    q = _random_motion(rng, t + pad)
    valid = np.ones(t + pad, bool)
    valid[[0, 1, 20, 21, 22]] = False
    valid[t:] = False  # padding
    times = np.cumsum(rng.uniform(1 / 40, 1 / 10, t + pad))
    g = {
        "paper": PAPER_SMOOTHING.gains(),
        "timed": frame_gains(PAPER_SMOOTHING, times, t),
        None: None,
    }[gains]
    fn = jax.jit(pipeline.finish, static_argnames=("standing", "robot"))
    filled, out = fn(q, valid, np.int32(t), g, standing=standing, robot=NAO_H25)
    filled, out = np.asarray(filled), np.asarray(out)
    want_filled = _fill_loop(q[:t], valid[:t])
    np.testing.assert_array_equal(filled[:t], want_filled.astype(np.float32))
    if g is None:  # no smoother; the clip still runs (the head envelope)
        np.testing.assert_allclose(out, clip_driven_np(filled), rtol=0, atol=ENVELOPE_TOL_RAD)
        return
    per_frame = np.broadcast_to(np.asarray(g, np.float64), (t + pad, 3))
    want = _smooth_loop(want_filled, per_frame[:t])
    np.testing.assert_allclose(out[:t], clip_driven_np(want), rtol=0, atol=SMOOTH_TOL_RAD)
    assert (out >= LO).all() and (out <= HI).all()


@pytest.mark.parametrize("standing", ["first", "last"])
def test_a_motion_without_valid_frames_stands(standing):
    q = np.full((16, 10), np.nan, np.float32)
    valid = np.zeros(16, bool)
    fn = jax.jit(pipeline.finish, static_argnames=("standing", "robot"))
    filled, out = fn(
        q, valid, np.int32(16), PAPER_SMOOTHING.gains(), standing=standing, robot=NAO_H25
    )
    np.testing.assert_array_equal(np.asarray(out), np.tile(STANDING, (16, 1)))
    if standing == "first":  # evaluate's order: the filled motion already stands
        np.testing.assert_array_equal(np.asarray(filled), np.tile(STANDING, (16, 1)))


def test_finish_vmapped_equals_a_loop_and_eager():
    rng = np.random.default_rng(3)
    q = np.stack([_random_motion(rng, 40) for _ in range(3)])
    valid = rng.random((3, 40)) > 0.2
    lengths = np.array([40, 25, 7], np.int32)
    g = PAPER_SMOOTHING.gains()
    one = jax.jit(lambda a, v, n: pipeline.finish(a, v, n, g, standing="last", robot=NAO_H25)[1])
    batch = jax.jit(
        jax.vmap(lambda a, v, n: pipeline.finish(a, v, n, g, standing="last", robot=NAO_H25)[1])
    )
    got = np.asarray(batch(q, valid, lengths))
    for i in range(3):
        np.testing.assert_allclose(got[i], np.asarray(one(q[i], valid[i], lengths[i])), atol=1e-6)
    eager = pipeline.finish(jnp.asarray(q[0]), valid[0], 40, g, standing="last", robot=NAO_H25)[1]
    np.testing.assert_allclose(got[0], np.asarray(eager), rtol=0, atol=1e-6)


def test_clip_to_limits_is_numpy_clip_then_the_head_envelope():
    x = np.random.default_rng(5).uniform(-4, 4, (9, 10)).astype(np.float32)
    got = np.asarray(pipeline.clip_to_limits(x, robot=NAO_H25))
    np.testing.assert_allclose(got, clip_driven_np(x), rtol=0, atol=ENVELOPE_TOL_RAD)
    assert (got[:, 1] != np.clip(x, LO, HI)[:, 1]).any()  # the envelope did clip some frames
    np.testing.assert_array_equal(got[:, 2:], np.clip(x, LO, HI)[:, 2:])  # the rest: np.clip
    np.testing.assert_array_equal(np.asarray(pipeline.clip_to_limits(x[0], robot=NAO_H25)), got[0])


# ------------------------------------------------------------------ the callers agree


@pytest.fixture(scope="module")
def projector():
    return small_projector()


@pytest.fixture(scope="module")
def model(projector):
    return engine.Model(projector, engine.BuildConfig(), 0.0, np.ones(200), 200)


@pytest.fixture(scope="module")
def sequences():
    """Two recordings of subject 2: one fully valid, one with lost-tracking frames."""
    seqs = datasets.msr_action3d(subjects=[2], actions=[1, 13])
    clean = next(s for s in seqs if np.asarray(descriptor(s.positions)[1]).all() and s.valid.all())
    lossy = next(s for s in seqs if (~s.valid).any())
    return clean, lossy


def test_streaming_frame_by_frame_equals_retarget_of_the_motion(model, sequences):
    """All frames valid, no times: the causal stream is retarget's smoothed, clipped motion."""
    pos = sequences[0].positions[:40]
    state = streaming.init(model)
    got = []
    for frame in pos:
        a, state = streaming.update(model, state, frame)
        got.append(np.asarray(a))
    whole = retarget(pos, model=model, method="relaxed", smoothing=PAPER_SMOOTHING,
                     neck_neutral=None)  # streaming reads the fixed neutral  # fmt: skip
    want = whole.angles[:, robot.DRIVEN_INDEX]
    np.testing.assert_allclose(np.stack(got), want, rtol=0, atol=BATCH_TOL_RAD)


def test_streaming_holds_where_retarget_fills(model, sequences):
    """Where they differ by design (module doc): leading invalid frames stand in the stream and
    take the first valid frame in retarget."""
    pos = np.concatenate([np.full((3, 20, 3), np.nan, np.float32), sequences[0].positions[:10]])
    state = streaming.init(model)
    first = []
    for frame in pos[:4]:
        a, state = streaming.update(model, state, frame)
        first.append(np.asarray(a))
    np.testing.assert_array_equal(np.stack(first[:3]), np.tile(STANDING, (3, 1)))
    whole = retarget(pos, model=model, smoothing=PAPER_SMOOTHING, neck_neutral=None)
    whole = whole.angles[:, robot.DRIVEN_INDEX]
    np.testing.assert_array_equal(whole[:3], np.tile(whole[3], (3, 1)))  # back-filled
    np.testing.assert_allclose(first[3], whole[3], rtol=0, atol=BATCH_TOL_RAD)


@pytest.mark.parametrize("smoothing", [PAPER_SMOOTHING, None])
def test_evaluate_scores_retargets_motion(model, sequences, smoothing):
    """evaluate's scored motion of a method is retarget's motion of each sequence (invalid
    frames filled the same way; smoothed and clipped the same way)."""
    data = evaluate.prepare(list(sequences))
    out = evaluate.evaluate(model, data, ("relaxed",), smoothing=smoothing, feasibility=None)
    scored = out["_predictions"]["relaxed"]
    truth = out["_truth"]
    for s, seq in enumerate(sequences):
        a, b = data.offsets[s], data.offsets[s + 1]
        # evaluate scores the fixed neutral (no per-recording levelling)
        r = retarget(seq.positions, seq.valid, model=model, smoothing=smoothing,
                     neck_neutral=None)  # fmt: skip
        np.testing.assert_array_equal(r.valid, data.valid[a:b])
        got = r.angles[:, robot.DRIVEN_INDEX]
        # without a smoother evaluate scores the per-frame answers (filled), retarget clips
        # them to the head envelope (every output's last stage)
        want = scored[a:b] if smoothing is not None else clip_driven_np(scored[a:b])
        np.testing.assert_allclose(want, got, rtol=0, atol=BATCH_TOL_RAD)
        ik = retarget(seq.positions, seq.valid, smoothing=None, neck_neutral=None)
        ik = ik.angles[:, robot.DRIVEN_INDEX]
        np.testing.assert_allclose(truth[a:b], ik, rtol=0, atol=1e-6)


def test_retarget_feasible_is_the_filter_of_the_unfiltered_motion(model, sequences):
    seq = sequences[1]
    plain = retarget(seq.positions, seq.valid, model=model)
    safe = retarget(seq.positions, seq.valid, model=model, feasible=feasible.DEFAULT_FEASIBLE)
    assert plain.unfiltered is None
    np.testing.assert_array_equal(safe.unfiltered, plain.angles)
    np.testing.assert_array_equal(
        safe.angles, feasible.make_feasible(plain.angles, plain.times, robot=NAO_H25)
    )
    assert not np.array_equal(safe.angles, plain.angles)


def test_exported_motion_respects_the_rated_speeds_and_the_limit_margin(sequences, tmp_path):
    """A fast motion (the raw per-frame IK of a wave) made feasible with the defaults and
    written as NAOqi JSON and CSV: every step in the files at most the joint's rated speed,
    every angle EXPORT_MARGIN inside its range."""
    from jaxproj.io.motion_files import EXPORT_MARGIN, Motion, save_motion

    seq = sequences[0]
    r = retarget(seq.positions, seq.valid, smoothing=None, feasible=feasible.DEFAULT_FEASIBLE)
    assert r.unfiltered is not None
    rated = robot.RATED_SPEEDS.astype(np.float64)
    raw_speed = np.abs(np.diff(r.unfiltered, axis=0)) / np.diff(r.times)[:, None]
    assert (raw_speed / rated).max() > 1.5  # the input is fast: the test can fail
    assert (np.isclose(r.unfiltered, robot.LOWER) | np.isclose(r.unfiltered, robot.UPPER)).any()
    m = Motion(r.angles, r.times, r.valid)
    doc = json.loads(save_motion(tmp_path / "m.json", m, joints="body").read_text())
    rows = save_motion(tmp_path / "m.csv", m).read_text().splitlines()
    csv = np.array([[float(c) for c in row.split(",")] for row in rows[1:]])
    for names, angles, times in (
        (doc["names"], np.array(doc["angleLists"]).T, np.array(doc["timeLists"][0])),
        (rows[0].split(",")[1:], csv[:, 1:], csv[:, 0]),
    ):
        idx = [robot.IDX[n] for n in names]
        speed = np.abs(np.diff(angles, axis=0)) / np.diff(times)[:, None]
        assert (speed <= rated[idx]).all()
        assert (angles >= robot.LOWER[idx].astype(np.float64) + EXPORT_MARGIN).all()
        assert (angles <= robot.UPPER[idx].astype(np.float64) - EXPORT_MARGIN).all()
        accel = np.abs(np.diff(speed * np.sign(np.diff(angles, axis=0)), axis=0))
        accel /= 0.5 * (np.diff(times)[1:] + np.diff(times)[:-1])[:, None]
        bound = feasible.DEFAULT_FEASIBLE.accel_limits(NAO_H25)[idx].astype(np.float64)
        assert (accel <= 1.01 * bound).all()  # the margin clips nothing


def test_frame_gains_of_one_motion_and_of_a_batch_agree():
    times = np.cumsum(np.full((2, 12), 1 / 30.0), axis=1)
    lengths = np.array([12, 7])
    batch = np.asarray(frame_gains(PAPER_SMOOTHING, times, lengths))
    for i, n in enumerate(lengths):
        one = np.asarray(frame_gains(PAPER_SMOOTHING, times[i], n))
        np.testing.assert_array_equal(batch[i], one)
    # padding frames get the gains of the reference rate
    np.testing.assert_allclose(batch[1, 7:], np.tile(np.asarray(PAPER_SMOOTHING.gains()), (5, 1)),
                               rtol=1e-6)  # fmt: skip
    params = SmoothingParams(alpha=0.5)
    np.testing.assert_array_equal(np.asarray(frame_gains(params, None, 3)), params.gains())


def _turned(v: np.ndarray, deg: float) -> np.ndarray:
    """``v`` (3,) turned by ``deg`` about z."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]], np.float32)


def test_glitch_frames_marks_a_bone_that_jumps_out_and_back_in_one_or_two_frames():
    """A read bone out by 120 deg on one frame and back: that frame (and only it) is a glitch;
    a bone turning 70 deg a frame steadily, one jumping out and staying, a glitch of a bone
    the robot does not read, and one beside an invalid frame are not."""
    bones = ("upper_arm_left", "forearm_left")
    base = np.array([1.0, 0.0, 0.0], np.float32)
    d = np.tile(np.concatenate([base, base]), (8, 1))
    d[3, 3:] = _turned(base, 120.0)  # the forearm out and back
    steady = d.copy()
    steady[:, :3] = np.stack([_turned(base, 70.0 * t) for t in range(8)])
    stays = np.tile(np.concatenate([base, base]), (8, 1))
    stays[3:, 3:] = _turned(base, 120.0)
    ok = np.ones(8, bool)

    def glitches(x: np.ndarray, valid: np.ndarray = ok, read: tuple[str, ...] = bones) -> list:
        g = pipeline.glitch_frames(jnp.asarray(x), jnp.asarray(valid), bones=bones, read=read)
        return np.flatnonzero(np.asarray(g)).tolist()

    assert glitches(d) == [3]
    assert glitches(steady) == [3]  # the forearm's glitch still; the steady upper arm is not one
    steady[3, 3:] = base
    assert glitches(steady) == []
    assert glitches(stays) == []
    assert glitches(d, read=("upper_arm_left",)) == []
    beside = ok.copy()
    beside[4] = False
    assert glitches(d, beside) == []
    # two frames out (turned 130 and 150 deg, 20 deg apart) and back: both frames
    two = np.tile(np.concatenate([base, base]), (8, 1))
    two[3, 3:], two[4, 3:] = _turned(base, 130.0), _turned(base, 150.0)
    assert glitches(two) == [3, 4]
    assert glitches(two, read=("upper_arm_left",)) == []
    beside = ok.copy()
    beside[5] = False
    assert glitches(two, beside) == []
    # out over two frames and not back (the next frame 80 deg from the last before): a move
    two[5:, 3:] = _turned(base, 80.0)
    assert glitches(two) == []
    # three frames out and back is not judged (a gesture can do that)
    three = np.tile(np.concatenate([base, base]), (8, 1))
    three[3:6, 3:] = _turned(base, 130.0)
    assert glitches(three) == []


def test_lost_frames_marks_a_limb_at_under_half_or_over_twice_its_length():
    """A thigh shrunk to 0.3 of its length on frames 4-5 and one stretched to 2.5 on frame 7
    are lost frames; 0.6 and 1.8 are not; an invalid frame is never one and does not count
    toward the median; a bone the robot does not read is not judged; with ``mirror`` the
    other side's bone is; a motion of fewer than ``LOST_MIN_FRAMES`` valid frames is not
    judged."""
    n = pipeline.LOST_MIN_FRAMES + 1
    base = np.asarray(datasets.msr_action3d()[0].positions[0], np.float32)
    p = np.tile(base, (n, 1, 1))
    hip, knee = J["HipLeft"], J["KneeLeft"]
    scale = np.ones(n, np.float32)
    scale[[4, 5]], scale[7], scale[2], scale[8] = 0.3, 2.5, 0.6, 1.8
    p[:, knee] = p[:, hip] + (p[:, knee] - p[:, hip]) * scale[:, None]
    ok = np.ones(n, bool)

    def lost(valid=ok, read=("thigh_left",), mirror=False) -> list:
        got = pipeline.lost_frames(jnp.asarray(p), jnp.asarray(valid), read=read, mirror=mirror)
        return np.flatnonzero(np.asarray(got)).tolist()

    assert lost() == [4, 5, 7]
    invalid = ok.copy()
    invalid[3] = False
    assert lost(invalid) == [4, 5, 7]
    invalid[4] = False  # now one frame short of LOST_MIN_FRAMES valid ones
    assert lost(invalid) == []
    assert lost(read=("thigh_right", "forearm_left")) == []
    assert lost(read=("thigh_right",), mirror=True) == [4, 5, 7]
    assert lost(np.zeros(n, bool)) == []


def test_playable_many_is_each_motions_own_pass_in_time_order():
    # a separation that depends on the previous frame's answer (``start``), so that each
    # motion's pass must run in its own time order and not mix with the others'
    def separate(q, start=None):
        return q if start is None else 0.5 * (q + start)

    toy = dataclasses.replace(NAO_H25, separate=separate)
    x = np.random.default_rng(0).uniform(-1.0, 1.0, (3, 7, NAO_H25.n_joints)).astype(np.float32)
    many = np.asarray(pipeline.playable_many(jnp.asarray(x), toy))
    for b in range(3):
        one = np.asarray(pipeline.playable_full(jnp.asarray(x[b]), toy))
        np.testing.assert_allclose(many[b], one, rtol=0, atol=1e-7)
    # the pass changed the driven joints (averaged with the frame before), clipped to the limits
    idx = NAO_H25.driven_index
    assert not np.allclose(many[:, 1:, idx], np.clip(x[:, 1:, idx], LO, HI))
    assert ((many[..., idx] >= LO) & (many[..., idx] <= HI)).all()
