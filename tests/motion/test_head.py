"""The NAO head: NAOqi's anti-collision envelope on every output, and a neck neutral that
transfers across capture set-ups (``skeleton.level_neck``, ``retarget(neck_neutral=...)``).

The envelope reference is Aldebaran's table interpolated here with NumPy in float64,
independently of ``robot.HEAD_ENVELOPE`` and ``jnp.interp``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from jaxproj.human.skeleton import (
    NECK_TILT_REFERENCE,
    J,
    body_frame,
    descriptor,
    level_neck,
    recording_neck_tilt,
)
from jaxproj.io import datasets
from jaxproj.motion import streaming
from jaxproj.motion.feasible import FeasibleConfig, feasibility_report
from jaxproj.motion.retarget import retarget
from jaxproj.projection import api as engine
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik, robot

YAW, PITCH = robot.IDX["HeadYaw"], robot.IDX["HeadPitch"]
TABLE = np.array([  # yaw, pitch min, pitch max (deg): ALD-JOINTS "anti collision"
    (0.0, -38.5, 29.51), (27.85, -38.5, 24.18), (43.32, -31.40, 21.20), (51.74, -27.50, 18.91),
    (62.45, -24.64, 17.19), (87.49, -18.91, 11.46), (119.52, -25.73, 18.91),
])  # fmt: skip
TOL = 8 * 2.0**-24
"""rad: float32 interpolation and clipping (a few roundings of angles below 2.1 rad) against the
float64 reference."""


def _envelope(yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """HeadPitch (lo, hi), rad, at HeadYaw ``yaw`` (rad): the table, symmetric in yaw."""
    a = np.abs(np.degrees(yaw.astype(np.float64)))
    return tuple(np.radians(np.interp(a, TABLE[:, 0], TABLE[:, c])) for c in (1, 2))


def _outside(angles: np.ndarray) -> np.ndarray:
    """(T,) rad by which HeadPitch leaves the envelope at its HeadYaw (<= 0 inside)."""
    lo, hi = _envelope(angles[:, YAW])
    p = angles[:, PITCH].astype(np.float64)
    return np.maximum(lo - p, p - hi)


def _skeleton(neck: np.ndarray) -> np.ndarray:
    """(T, 20, 3) skeletons in body-frame axes (x forward, y left, z up) whose neck bone points
    along ``neck`` (T, 3); arms hang, legs stand."""
    base = np.zeros((20, 3), np.float32)
    pts = {
        "Spine": (0, 0, 0.25), "ShoulderCenter": (0, 0, 0.5), "ShoulderLeft": (0, 0.18, 0.45),
        "ElbowLeft": (0.02, 0.2, 0.2), "WristLeft": (0.1, 0.2, 0.0), "HandLeft": (0.12, 0.2, -0.05),
        "ShoulderRight": (0, -0.18, 0.45), "ElbowRight": (0.02, -0.2, 0.2),
        "WristRight": (0.1, -0.2, 0.0), "HandRight": (0.12, -0.2, -0.05),
        "HipLeft": (0, 0.1, -0.05), "KneeLeft": (0, 0.1, -0.5), "AnkleLeft": (0, 0.1, -0.9),
        "FootLeft": (0.1, 0.1, -0.95), "HipRight": (0, -0.1, -0.05),
        "KneeRight": (0, -0.1, -0.5), "AnkleRight": (0, -0.1, -0.9),
        "FootRight": (0.1, -0.1, -0.95),
    }  # fmt: skip
    for name, p in pts.items():
        base[J[name]] = p
    pos = np.tile(base, (len(neck), 1, 1))
    pos[:, J["Head"]] = base[J["ShoulderCenter"]] + 0.2 * neck
    return pos


@pytest.fixture(scope="module")
def sweep() -> np.ndarray:
    """A head sweep: the neck's sideways lean takes HeadYaw across its whole range (and past
    it) while its forward tilt alternates between pitches far beyond both extremes."""
    t = 240
    yaw = np.radians(np.linspace(-150.0, 150.0, t))
    pitch = np.radians(np.where(np.arange(t) // 6 % 2 == 0, 60.0, -70.0))
    tilt = pitch + NECK_TILT_REFERENCE
    # direction with atan2(y, z) = yaw, atan2(x, z') = tilt on the forward half
    n = np.stack([np.sin(tilt) * np.abs(np.cos(yaw)) + 0.3 * np.sin(tilt), np.sin(yaw),
                  np.cos(yaw)], axis=1)  # fmt: skip
    return _skeleton(n / np.linalg.norm(n, axis=1, keepdims=True))


@pytest.fixture(scope="module")
def model(sweep):
    """A tiny model whose landmarks are every 3rd frame of the sweep (cheap; its answers blend
    landmark poses, which need not lie inside the non-convex envelope)."""
    human = np.asarray(descriptor(sweep)[0])[::3]  # the arms never move: one whole chain
    cfg = engine.BuildConfig(chains="whole", landmarks=None, bandwidth=1.0, k=16, hidden=32,
                             input_scale=1.0)  # fmt: skip
    return engine.from_landmarks(human, np.asarray(ik.solve_driven(human)), cfg)


def test_the_sweep_leaves_the_envelope_unless_clipped(sweep):
    """The raw per-frame head angles (the IK's formulas, NumPy) break the envelope, so the
    checks below can fail; the IK's own answer is exactly their clip to it."""
    d, ok = descriptor(sweep)
    assert np.asarray(ok).all()
    n = np.asarray(d, np.float64)[:, :3]
    raw = np.zeros((len(n), robot.N_JOINTS))
    raw[:, YAW] = np.clip(np.arctan2(n[:, 1], n[:, 2]), robot.LOWER[YAW], robot.UPPER[YAW])
    raw[:, PITCH] = np.clip(np.arctan2(n[:, 0], n[:, 2]) - ik.HEAD_PITCH_NEUTRAL,
                            robot.LOWER[PITCH], robot.UPPER[PITCH])  # fmt: skip
    out = _outside(raw)
    assert (out > np.radians(5.0)).sum() > 50  # many frames far outside
    assert (np.abs(raw[:, YAW]) > np.radians(119.0)).sum() > 20  # both yaw ends reached
    got = np.asarray(ik.solve(d))
    assert (_outside(got) <= TOL).all()
    expect = np.clip(raw[:, PITCH], *_envelope(raw[:, YAW]))
    np.testing.assert_allclose(got[:, PITCH], expect, rtol=0, atol=2e-5)  # the IK's float32


@pytest.mark.parametrize(("method", "smooth"), [("ik", True), ("relaxed", False)])
def test_retarget_and_the_feasibility_filter_stay_inside(sweep, model, method, smooth):
    kw = {"model": model} if method == "relaxed" else {}
    smoothing = {} if smooth else {"smoothing": None}
    # the filter on the 15 fps grid, and on irregular times (read back between grid points)
    steps = np.where(np.arange(len(sweep)) % 7 == 3, 3.0, 1.0) / 15.0
    irregular = np.cumsum(steps) + 0.013 * (np.arange(len(sweep)) % 2)
    grids = (np.arange(len(sweep)) / 15.0, irregular) if smooth else (irregular,)
    for times in grids:
        f = retarget(sweep, method=method, times=times, feasible=FeasibleConfig(), **kw,
                     **smoothing)  # fmt: skip
        assert f.unfiltered is not None
        assert (_outside(f.unfiltered) <= TOL).all()  # retarget's own output
        assert (_outside(f.angles) <= TOL).all()
        rep = feasibility_report(f.angles, times, robot=NAO_H25)
        assert rep["limit_violation_frames"] == 0 and rep["speed_violation_frames"] == 0


def test_streaming_stays_inside(sweep, model):
    state = streaming.init(model)
    out = []
    for frame in sweep[::4]:
        q, state = streaming.update(model, state, frame)
        out.append(np.asarray(q))
    full = np.asarray(robot.STANDING_POSTURE)[None].repeat(len(out), 0)
    full[:, robot.DRIVEN_INDEX] = np.stack(out)
    assert (_outside(full) <= TOL).all()


def test_feasibility_report_counts_frames_outside_the_envelope():
    q = np.tile(robot.STANDING_POSTURE, (4, 1))
    q[:, YAW] = np.radians(60.0)
    q[:, PITCH] = np.radians([0.0, 17.0, 17.5, -30.0])  # bound at 60 deg: -25.3 .. 17.6
    q[2, PITCH] = np.radians(18.0)
    assert feasibility_report(q, np.arange(4) / 100.0, robot=NAO_H25)["limit_violation_frames"] == 2


# ------------------------------------------------------------------ the neck's neutral


def _tilt(d: np.ndarray) -> np.ndarray:
    return np.arctan2(d[:, 0].astype(np.float64), d[:, 2].astype(np.float64))


def test_recording_neck_tilt_is_the_median_of_valid_frames():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(41, 3)) + (0.0, 0.0, 2.0)
    d = np.concatenate([n / np.linalg.norm(n, axis=1, keepdims=True), rng.normal(size=(41, 12))],
                       axis=1).astype(np.float32)  # fmt: skip
    valid = rng.random(41) < 0.7
    valid[:2] = (True, False)
    for v in (valid, valid & (np.arange(41) != np.flatnonzero(valid)[-1])):  # odd and even
        got = float(recording_neck_tilt(d, v))
        assert got == pytest.approx(np.median(_tilt(d[v])), abs=2e-7)
    assert float(recording_neck_tilt(d, np.zeros(41, bool))) == pytest.approx(NECK_TILT_REFERENCE)


def test_level_neck_moves_the_neutral_to_the_reference_and_keeps_the_rest():
    rng = np.random.default_rng(4)
    d = rng.normal(size=(9, 15)).astype(np.float32)
    neutral = 0.4
    out = np.asarray(level_neck(d, neutral))
    np.testing.assert_array_equal(out[:, 3:], d[:, 3:])
    np.testing.assert_allclose(out[:, 1], d[:, 1])  # the sideways part
    np.testing.assert_allclose(np.linalg.norm(out[:, :3], axis=1), np.linalg.norm(d[:, :3], axis=1),
                               rtol=1e-6)  # fmt: skip
    shift = np.angle(np.exp(1j * (_tilt(out) - _tilt(d))))
    np.testing.assert_allclose(shift, NECK_TILT_REFERENCE - neutral, atol=1e-6)


def _tilted(positions: np.ndarray, angle: float) -> np.ndarray:
    """The same motion seen from a set-up whose Head joint sits ``angle`` rad further forward:
    each frame's neck bone turned about the body's left axis (built from the frame itself)."""
    rot = np.asarray(body_frame(positions)[0], np.float64)  # rows: forward, left, up
    neck = positions[:, J["Head"]] - positions[:, J["ShoulderCenter"]]
    local = np.einsum("tij,tj->ti", rot, neck)
    c, s = math.cos(angle), math.sin(angle)
    local = np.stack([c * local[:, 0] + s * local[:, 2], local[:, 1],
                      c * local[:, 2] - s * local[:, 0]], axis=1)  # fmt: skip
    out = positions.copy()
    out[:, J["Head"]] = positions[:, J["ShoulderCenter"]] + np.einsum("tji,tj->ti", rot, local)
    return out.astype(np.float32)


def test_the_recording_neutral_transfers_to_another_set_up():
    """A recording seen with its Head joint 40 deg further forward (UTKinect's neck sits ~41 deg
    forward of MSR Action3D's): the levelled default retargets it to the same head angles; with
    no levelling (``neck_neutral=None``) the head stares down at its limit."""
    seq = datasets.msr_action3d(subjects=[2], actions=[2])[0]
    moved = _tilted(seq.positions, math.radians(40.0))
    base = retarget(seq.positions, seq.valid, smoothing=None)
    same = retarget(moved, seq.valid, smoothing=None)
    np.testing.assert_allclose(same.angles[:, PITCH], base.angles[:, PITCH], rtol=0, atol=1e-4)
    np.testing.assert_allclose(same.angles[:, YAW], base.angles[:, YAW], rtol=0, atol=1e-4)
    fixed = retarget(moved, seq.valid, smoothing=None, neck_neutral=None)
    near = [(_outside(r.angles) > -np.radians(0.5)).mean() for r in (fixed, same)]
    assert near[0] > 0.4 and near[1] < 0.1  # measured 0.48 and 0.07
    assert np.median(fixed.angles[:, PITCH] - same.angles[:, PITCH]) > np.radians(20.0)
    # a given neutral: the recording's own median, passed in, gives the default's answer
    d, ok = descriptor(moved)
    own = float(recording_neck_tilt(d, np.asarray(ok) & seq.valid))
    given = retarget(moved, seq.valid, smoothing=None, neck_neutral=own)
    np.testing.assert_array_equal(given.angles, same.angles)
