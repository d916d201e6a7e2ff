"""jaxproj.motion.feasible: hard limits, acceleration bound, ElbowYaw rules, batching, errors."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError
from jaxproj.motion.feasible import (
    ACCEL_TIME,
    DEFAULT_FEASIBLE,
    FeasibleConfig,
    feasibility_report,
    make_feasible,
)
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import robot

NAO_ACCEL = 80.0
"""rad/s^2: the NAO's own bound on every joint (``nao_h25.robot.ACCELERATION_LIMITS``)."""

J = robot.JOINT_NAMES.index
DRIVEN = robot.DRIVEN_INDEX


def _jerky_motion(t: int, seed: int = 0) -> np.ndarray:
    """A motion far beyond the NAO's speeds: random jumps over the driven joints' full range."""
    rng = np.random.default_rng(seed)
    q = np.tile(robot.STANDING_POSTURE, (t, 1)).astype(np.float32)
    lo, hi = robot.LOWER[DRIVEN], robot.UPPER[DRIVEN]
    smooth = np.cumsum(rng.normal(scale=0.4, size=(t, len(DRIVEN))), axis=0)
    jumps = rng.uniform(lo, hi, size=(t, len(DRIVEN))) * (rng.random((t, 1)) < 0.1)
    q[:, DRIVEN] = np.clip(smooth + jumps, lo, hi)
    return q


@pytest.mark.parametrize("zero_phase", [False, True])
@pytest.mark.parametrize("fps", [15.0, 30.0])
def test_output_respects_limits_speed_and_acceleration(zero_phase: bool, fps: float) -> None:
    q = _jerky_motion(120)
    times = np.arange(len(q)) / fps
    cfg = FeasibleConfig(zero_phase=zero_phase)
    before = feasibility_report(q, times, cfg, robot=NAO_H25)
    assert before["speed_violation_frames"] > 10  # the input is really infeasible
    out = make_feasible(q, times, config=cfg, robot=NAO_H25)
    assert out.dtype == np.float32 and out.shape == q.shape and np.isfinite(out).all()
    rep = feasibility_report(out, times, cfg, robot=NAO_H25)
    assert rep["limit_violation_frames"] == 0
    margin = np.float32(cfg.limit_margin)  # 2e-4 rad inside, as the robot files hold it
    assert (
        margin > 0 and (out >= robot.LOWER + margin).all() and (out <= robot.UPPER - margin).all()
    )
    assert rep["speed_violation_frames"] == 0
    # the configured fraction of the rated speed, up to float32 round-off; and (the fraction's
    # headroom) never above the rated speed itself, with no tolerance
    speed = np.abs(np.diff(out.astype(np.float64), axis=0)) * fps
    assert (speed <= cfg.speed_fraction * robot.RATED_SPEEDS * (1 + 1e-4) + 1e-4).all()
    assert (speed <= robot.RATED_SPEEDS).all() and rep["rated_speed_ratio"] <= 1.0
    assert before["rated_speed_ratio"] > 1.0
    assert rep["accel_violation_frames"] == 0 and rep["max_accel"] <= NAO_ACCEL * 1.01
    # joints that never move are left exactly as they are
    still = np.setdiff1d(np.arange(len(robot.JOINT_NAMES)), DRIVEN)
    np.testing.assert_array_equal(out[:, still], q[:, still])


def test_rated_speeds_by_default_no_load_on_request() -> None:
    """The default caps at 99 % of the rated speeds; ``speeds="no-load"`` keeps the former cap,
    90 % of the no-load speeds, which lets the arms move faster than rated."""
    assert DEFAULT_FEASIBLE.speeds == "rated" and DEFAULT_FEASIBLE.speed_fraction == 0.99
    np.testing.assert_allclose(
        DEFAULT_FEASIBLE.params(robot=NAO_H25)[2], 0.99 * robot.RATED_SPEEDS, rtol=1e-6
    )
    free = FeasibleConfig(speeds="no-load")
    assert free.speed_fraction == 0.9
    np.testing.assert_allclose(
        free.params(robot=NAO_H25)[2], 0.9 * robot.VELOCITY_LIMITS, rtol=1e-6
    )
    assert FeasibleConfig(speeds="no-load", speed_fraction=0.5).speed_fraction == 0.5
    q = _jerky_motion(120)
    times = np.arange(len(q)) / 30.0
    fast = feasibility_report(
        make_feasible(q, times, config=free, robot=NAO_H25), times, robot=NAO_H25
    )
    assert fast["speed_violation_frames"] == 0 and fast["max_speed_ratio"] <= 0.9 + 1e-4
    assert fast["rated_speed_ratio"] > 1.1  # faster than the rated speeds


def test_a_feasible_motion_is_followed_closely() -> None:
    t = np.arange(90) / 30.0
    q = np.tile(robot.STANDING_POSTURE, (len(t), 1)).astype(np.float32)
    q[:, J("LShoulderPitch")] = 0.5 * np.sin(2 * np.pi * 0.5 * t)  # 1.6 rad/s, 4.9 rad/s^2
    q[:, J("LElbowRoll")] = -0.8 + 0.3 * np.sin(2 * np.pi * 0.3 * t)
    out = make_feasible(q, t, robot=NAO_H25)
    assert np.abs(out - q).max() < math.radians(1.0)


def test_zero_phase_cancels_the_lag_of_one_pass() -> None:
    t = np.arange(60) / 15.0
    q = np.tile(robot.STANDING_POSTURE, (len(t), 1)).astype(np.float32)
    q[20:, J("RShoulderPitch")] = -1.0  # a step: 2.2 rad (+1.4 -> -1.0, beyond one frame's reach)
    fwd = make_feasible(q, t, config=FeasibleConfig(zero_phase=False), robot=NAO_H25)
    both = make_feasible(q, t, robot=NAO_H25)
    j = J("RShoulderPitch")
    mid = 0.5 * (q[0, j] + q[-1, j])
    crossing = lambda x: int(np.argmax(x < mid))  # noqa: E731
    assert crossing(fwd[:, j]) >= 22  # one pass crosses half-way well after the step (lag)
    assert crossing(both[:, j]) in (19, 20)  # zero-phase: centred on the step, no delay
    assert np.all(np.diff(fwd[:, j]) <= 1e-6)  # monotone: no overshoot of the step
    assert abs(both[-1, j] - q[-1, j]) < 1e-3 and abs(both[0, j] - q[0, j]) < 1e-3


def test_elbow_yaw_flicker_at_the_range_ends_is_ignored_and_a_real_move_followed() -> None:
    fps = 30.0
    t = np.arange(120) / fps
    q = np.tile(robot.STANDING_POSTURE, (len(t), 1)).astype(np.float32)
    yaw, roll = J("LElbowYaw"), J("LElbowRoll")
    q[:, roll] = -1.2  # bent elbow: the yaw matters
    top, bottom = robot.UPPER[yaw], robot.LOWER[yaw]
    q[:, yaw] = top
    q[10:15, yaw] = bottom  # short visits (< wrap_patience) to the other end: the IK's
    q[25:31, yaw] = bottom  # wrap-around flicker
    q[70:, yaw] = bottom  # then the target really stays at the other end
    out = make_feasible(q, t, robot=NAO_H25)
    # flicker (frames 10..30): held. The real move is followed by the backward pass too: it
    # waits its patience after frame 70, then crosses the 239 deg range at the rated speed in
    # ~0.7 s (21 frames), leaving the top end from frame ~40 on
    assert np.abs(out[:40, yaw] - top).max() < math.radians(2.0)
    assert abs(out[-1, yaw] - bottom) < 1e-3  # a real move is followed
    plain = make_feasible(q, t, config=FeasibleConfig(wrap_patience=0.0), robot=NAO_H25)
    assert np.abs(plain[:40, yaw] - top).max() > math.radians(30.0)  # without the rule it moves


def test_elbow_yaw_of_a_straight_arm_is_held() -> None:
    t = np.arange(40) / 15.0
    q = np.tile(robot.STANDING_POSTURE, (len(t), 1)).astype(np.float32)
    yaw, roll = J("RElbowYaw"), J("RElbowRoll")
    q[:, roll] = robot.LOWER[roll]  # straight (0.0349 rad): yaw does not move the forearm
    q[::2, yaw] = 1.5
    q[1::2, yaw] = -1.5  # noise-driven yaw of a straight arm
    out = make_feasible(q, t, robot=NAO_H25)
    assert np.abs(out[:, yaw] - out[0, yaw]).max() < 1e-6
    bent = q.copy()
    bent[:, roll] = 1.2
    moved = make_feasible(bent, t, robot=NAO_H25)
    assert np.abs(moved[:, yaw] - moved[0, yaw]).max() > 0.5


def test_batch_with_padding_equals_one_by_one_and_is_deterministic() -> None:
    lengths = [50, 17, 1, 33]
    t_max = max(lengths)
    qs = [_jerky_motion(n, seed=i) for i, n in enumerate(lengths)]
    batch = np.zeros((len(qs), t_max, len(robot.JOINT_NAMES)), np.float32)
    times = np.zeros((len(qs), t_max))
    for i, q in enumerate(qs):
        batch[i, : len(q)] = q
        batch[i, len(q) :] = np.nan  # padding must not leak
        times[i] = np.arange(t_max) / 15.0
    out = make_feasible(batch, times, np.array(lengths), robot=NAO_H25)
    for i, q in enumerate(qs):
        one = make_feasible(q, times[i, : len(q)], robot=NAO_H25)
        np.testing.assert_allclose(out[i, : len(q)], one, rtol=0, atol=1e-6)
    again = make_feasible(batch, times, np.array(lengths), robot=NAO_H25)
    np.testing.assert_array_equal(np.nan_to_num(out), np.nan_to_num(again))
    # one frame: the input, held the limit margin inside the joint ranges (it has angles at a limit)
    m = np.float32(DEFAULT_FEASIBLE.limit_margin)
    one_frame = np.clip(qs[2], robot.LOWER + m, robot.UPPER - m)
    assert (one_frame != qs[2]).any()
    np.testing.assert_array_equal(make_feasible(qs[2], times[2, :1], robot=NAO_H25), one_frame)


def test_irregular_time_steps_are_respected() -> None:
    q = _jerky_motion(80, seed=3)
    steps = np.random.default_rng(4).choice([1 / 30, 2 / 30, 4 / 30], size=len(q))
    times = np.cumsum(steps) - steps[0]
    out = make_feasible(q, times, robot=NAO_H25)
    rep = feasibility_report(out, times, robot=NAO_H25)
    assert rep["speed_violation_frames"] == 0 and rep["limit_violation_frames"] == 0
    assert rep["max_accel"] <= NAO_ACCEL * 1.01


def test_bad_arguments_raise_config_errors() -> None:
    q = _jerky_motion(5)
    t = np.arange(5) / 15.0
    with pytest.raises(ConfigError, match="times"):
        make_feasible(q, t[:4], robot=NAO_H25)
    with pytest.raises(ConfigError, match="increase"):
        make_feasible(q, t[::-1], robot=NAO_H25)
    with pytest.raises(ConfigError, match=r"\(T, 26\)"):
        make_feasible(q[:, :10], t, robot=NAO_H25)
    bad = q.copy()
    bad[2, 0] = np.nan
    with pytest.raises(ConfigError, match="finite"):
        make_feasible(bad, t, robot=NAO_H25)
    with pytest.raises(ConfigError, match="lengths"):
        make_feasible(q[None], t[None], np.array([0]), robot=NAO_H25)
    for kw in ({"speed_fraction": 0.0}, {"speeds": "peak"}, {"accel": -1.0},
               {"straight_elbow": (0.3, 0.1)},
               {"wrap_band": -0.1}, {"wrap_patience": -1.0}):  # fmt: skip
        with pytest.raises(ConfigError):
            FeasibleConfig(**kw)


def test_a_robot_without_acceleration_limits_gets_its_speed_in_a_tenth_of_a_second() -> None:
    bare = dataclasses.replace(NAO_H25, acceleration_limits=None)
    np.testing.assert_allclose(
        DEFAULT_FEASIBLE.accel_limits(bare), NAO_H25.velocity_limits / ACCEL_TIME, rtol=1e-6
    )
    assert ACCEL_TIME == 0.1


def test_a_robots_own_acceleration_limits_bound_each_of_its_joints() -> None:
    g1 = robots.get("unitree_g1")
    assert (DEFAULT_FEASIBLE.accel_limits(NAO_H25) == NAO_ACCEL).all()  # its own, one value
    np.testing.assert_array_equal(DEFAULT_FEASIBLE.accel_limits(g1), g1.acceleration_limits)
    assert (FeasibleConfig(accel=50.0).accel_limits(g1) == 50.0).all()  # one bound: every joint
    rng = np.random.default_rng(0)
    t = 90
    q = np.tile(g1.standing, (t, 1)).astype(np.float32)
    idx = g1.driven_index
    lo, hi = g1.lower[idx], g1.upper[idx]
    q[:, idx] = rng.uniform(lo, hi, size=(t, len(idx))) * (rng.random((t, 1)) < 0.2)
    q[:, idx] = np.clip(np.cumsum(q[:, idx], axis=0) * 0.3, lo, hi)
    times = np.arange(t) / 30.0
    out = make_feasible(q, times, robot=g1)
    v = np.diff(out.astype(np.float64), axis=0) * 30.0
    acc = np.abs(np.diff(v, axis=0)) * 30.0
    bound = g1.acceleration_limits.astype(np.float64)
    assert (acc <= 1.01 * bound).all()
    rep = feasibility_report(out, times, robot=g1)
    assert rep["accel_violation_frames"] == 0 and rep["max_accel_ratio"] <= 1.01
    # per joint, not one number: the waist stays under the NAO's 80 while an arm goes past it
    waist = [g1.index(n) for n in ("waist_roll_joint", "waist_pitch_joint")]
    arm = [g1.index(n) for n in ("left_elbow_joint", "right_elbow_joint")]
    assert acc[:, waist].max() <= 1.01 * 30.0 and acc[:, arm].max() > NAO_ACCEL
