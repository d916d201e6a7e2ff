"""Evaluation metrics: joint-space percentiles, M_max without ElbowYaw, task-space errors from FK.

The MJX forward kinematics compiles once per process (one fixed batch size, ~3-5 s on CPU); every
test below then reuses it.
"""

import json
import math

import mujoco
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.eval import evaluate, metrics
from jaxproj.paper.demo_report import _where_md
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik, robot
from jaxproj.viz import report

L, R = 0, 1  # side columns of ArmErrors
FOREARM = robot.LOWER_ARM_LENGTH  # elbow -> wrist site, m


def _random_configs(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.LOWER, robot.UPPER, (n, robot.N_JOINTS)).astype(np.float32)


def _set(q: np.ndarray, **angles: float | np.ndarray) -> np.ndarray:
    q = np.array(q, np.float32, copy=True)
    for name, value in angles.items():
        q[..., robot.IDX[name]] = value
    return q


def _errors(a: np.ndarray, b: np.ndarray) -> metrics.ArmErrors:
    return metrics.arm_errors(
        metrics.arm_points(a, robot=NAO_H25), metrics.arm_points(b, robot=NAO_H25)
    )


def test_fk_matches_cpu_mujoco_on_the_whole_model():
    # independent reference: CPU MuJoCo (float64) on the full fixed-mount MJCF (head and legs too)
    q = _random_configs(7, seed=1)
    q[0] = robot.STANDING_POSTURE
    got = metrics.arm_points(q, robot=NAO_H25)
    model = robot.load_model("fixed")
    data = mujoco.MjData(model)
    arm_sites = NAO_H25.require_mjcf().arm_sites
    names = [n for side in metrics.sides(NAO_H25) for n in arm_sites[side]]
    for i, qi in enumerate(q):
        data.qpos[:] = robot.config_to_qpos(model, qi)
        mujoco.mj_kinematics(model, data)
        want = np.array([data.site(n).xpos for n in names]).reshape(2, 3, 3)
        np.testing.assert_allclose(got[i], want, rtol=0, atol=1e-5)
    assert got.dtype == np.float32
    # the shoulder sits 0.098 m to the side and 0.1 m up of the torso point, whatever the pose
    np.testing.assert_allclose(got[:, L, 0], np.tile([0.0, 0.098, 0.1], (7, 1)), atol=1e-6)
    np.testing.assert_allclose(got[:, R, 0], np.tile([0.0, -0.098, 0.1], (7, 1)), atol=1e-6)


def test_fk_over_several_batches_and_driven_input():
    # more frames than one compiled batch: the padding never leaks into the answers
    n = metrics.FK_BATCH + 3
    q = _random_configs(n, seed=2)
    pts = metrics.arm_points(q, robot=NAO_H25)
    np.testing.assert_array_equal(pts[-3:], metrics.arm_points(q[-3:], robot=NAO_H25))
    np.testing.assert_array_equal(pts[:5], metrics.arm_points(q[:5], robot=NAO_H25))
    # (F, 10) driven angles: the other joints at the standing posture, as ik.driven_to_full
    drv = q[:5, robot.DRIVEN_INDEX]
    np.testing.assert_array_equal(
        metrics.arm_points(drv, robot=NAO_H25),
        metrics.arm_points(np.asarray(ik.driven_to_full(drv)), robot=NAO_H25),
    )
    assert metrics.arm_points(np.zeros((0, 26), np.float32), robot=NAO_H25).shape == (0, 2, 3, 3)


def test_identical_poses_have_zero_error():
    q = _random_configs(6, seed=3)
    block = metrics.summarize_errors(q, q, robot=NAO_H25)
    for key in ("M_max", "M_avg", "M_max_no_elbow_yaw"):
        assert block[key]["max"] == 0.0
    assert all(v == {"p50": 0.0, "p95": 0.0} for v in block["per_joint"].values())
    for side in metrics.sides(NAO_H25):
        for key in metrics.TASK_METRICS:
            assert block["task_space"][side][key]["max"] == 0.0


def test_elbow_roll_turns_only_the_left_forearm_by_exactly_d():
    base = _random_configs(5, seed=4)
    base = _set(base, LElbowRoll=-0.8)
    d = np.array([-0.7, -0.25, 0.01, 0.3, 0.72], np.float32)
    moved = _set(base, LElbowRoll=-0.8 + d)
    e = _errors(moved, base)
    np.testing.assert_allclose(np.degrees(e.forearm[:, L]), np.degrees(np.abs(d)), atol=1e-3)
    # the wrist moves on a circle of the forearm's length about the elbow: a chord
    np.testing.assert_allclose(e.hand[:, L], 2 * FOREARM * np.sin(np.abs(d) / 2), atol=1e-6)
    assert np.abs(e.upper_arm[:, L]).max() < 1e-5 and np.abs(e.elbow[:, L]).max() < 1e-6
    for field in e:
        assert np.abs(field[:, R]).max() < 1e-6  # nothing moved on the right
    ts = metrics.task_space_errors(moved, base, robot=NAO_H25)
    want = np.degrees(np.abs(d))
    assert ts["left"]["forearm_deg"]["max"] == pytest.approx(want.max(), abs=1e-3)
    assert ts["left"]["forearm_deg"]["median"] == pytest.approx(np.median(want), abs=1e-3)
    assert ts["right"]["forearm_deg"]["max"] < 1e-3


def test_shoulder_pitch_turns_the_upper_arm_by_d():
    # with ShoulderRoll = -/+ the ElbowOffsetY angle the shoulder->elbow segment is normal to
    # the pitch axis (torso y), so a pitch change d turns it by exactly |d|
    off = ik.ELBOW_OFFSET_ANGLE
    base = _set(_random_configs(4, seed=5), LShoulderRoll=-off, RShoulderRoll=off)
    d = np.array([-0.9, -0.05, 0.4, 1.1], np.float32)
    base = _set(base, LShoulderPitch=0.2, RShoulderPitch=-0.3)
    moved = _set(base, LShoulderPitch=0.2 + d, RShoulderPitch=-0.3 + d)
    e = _errors(moved, base)
    for side in (L, R):
        np.testing.assert_allclose(np.degrees(e.upper_arm[:, side]), np.degrees(np.abs(d)),
                                   atol=1e-3)  # fmt: skip
        seg = 2 * math.hypot(robot.UPPER_ARM_LENGTH, robot.ELBOW_OFFSET_Y)
        np.testing.assert_allclose(e.elbow[:, side], seg * np.sin(np.abs(d) / 2), atol=1e-6)
    # any other roll: the part of the segment along the pitch axis (y) does not turn
    base = _set(_random_configs(4, seed=6), LShoulderPitch=0.1)
    moved = _set(base, LShoulderPitch=0.1 + d)
    v = (
        metrics.arm_points(base, robot=NAO_H25)[:, L, 1]
        - metrics.arm_points(base, robot=NAO_H25)[:, L, 0]
    )
    v = v.astype(np.float64)
    along = v[:, 1] ** 2 / (v**2).sum(axis=1)
    want = np.arccos(along + (1 - along) * np.cos(d))
    np.testing.assert_allclose(_errors(moved, base).upper_arm[:, L], want, atol=2e-6)


def test_elbow_yaw_of_a_straight_arm_moves_no_point():
    # ElbowYaw turns the forearm about the upper-arm axis: with a straight elbow the wrist is on
    # that axis, so a large joint error is no task-space error at all
    base = _set(_random_configs(4, seed=7), LElbowRoll=0.0, RElbowRoll=0.0)
    d = np.array([-1.5, -0.5, 0.6, 1.9], np.float32)
    moved = _set(base, LElbowYaw=np.clip(base[:, robot.IDX["LElbowYaw"]] + d, -2.0, 2.0))
    dy = moved[:, robot.IDX["LElbowYaw"]] - base[:, robot.IDX["LElbowYaw"]]
    e = _errors(moved, base)
    assert e.hand[:, L].max() < 1e-6 and e.elbow[:, L].max() < 1e-6
    assert np.degrees(e.forearm[:, L]).max() < 1e-3
    block = metrics.summarize_errors(moved, base, robot=NAO_H25)
    assert block["M_max"]["max"] == pytest.approx(np.degrees(np.abs(dy)).max(), abs=1e-3)
    assert block["M_max_no_elbow_yaw"]["max"] == 0.0
    assert block["task_space"]["left"]["hand_cm"]["max"] < 1e-4
    # at the ElbowRoll limit (2 deg from straight) the wrist is FOREARM * sin(2 deg) off the axis
    roll = float(robot.UPPER[robot.IDX["LElbowRoll"]])
    base, moved = _set(base, LElbowRoll=roll), _set(moved, LElbowRoll=roll)
    chord = 2 * FOREARM * abs(math.sin(roll)) * np.sin(np.abs(dy) / 2)
    np.testing.assert_allclose(_errors(moved, base).hand[:, L], chord, atol=1e-6)


def test_joint_metrics_against_numpy():
    rng = np.random.default_rng(8)
    truth = rng.uniform(-1, 1, (301, 10))
    pred = truth + rng.normal(0, 0.2, truth.shape)
    err = np.degrees(np.abs(pred - truth))
    got = metrics.joint_percentiles(pred, truth, robot=NAO_H25)
    assert list(got) == list(robot.DRIVEN_JOINTS)
    for j, name in enumerate(robot.DRIVEN_JOINTS):
        assert got[name]["p50"] == pytest.approx(np.median(err[:, j]), rel=1e-12)
        assert got[name]["p95"] == pytest.approx(np.percentile(err[:, j], 95), rel=1e-12)
    keep = [j for j, n in enumerate(robot.DRIVEN_JOINTS) if "ElbowYaw" not in n]
    assert len(keep) == 8
    np.testing.assert_allclose(
        metrics.m_max_without(pred, truth, robot=NAO_H25), err[:, keep].max(axis=1)
    )
    only_head = metrics.m_max_without(pred, truth, exclude=robot.DRIVEN_JOINTS[2:], robot=NAO_H25)
    np.testing.assert_allclose(only_head, err[:, :2].max(axis=1))
    # (F, 26) configurations give the driven joints' numbers
    full = np.asarray(ik.driven_to_full(pred)), np.asarray(ik.driven_to_full(truth))
    drv = full[0][:, robot.DRIVEN_INDEX], full[1][:, robot.DRIVEN_INDEX]
    np.testing.assert_array_equal(
        metrics.m_max_without(*full, robot=NAO_H25), metrics.m_max_without(*drv, robot=NAO_H25)
    )
    assert metrics.joint_percentiles(*full, robot=NAO_H25) == metrics.joint_percentiles(
        *drv, robot=NAO_H25
    )
    # the block agrees with the functions; the headline is the paper's frame_errors
    block = metrics.summarize_errors(pred, truth, robot=NAO_H25)
    m_max, m_avg = metrics.frame_errors(pred, truth)
    assert block["M_max"] == metrics.describe(m_max) and block["M_avg"] == metrics.describe(m_avg)
    assert block["per_joint"] == got
    assert block["M_max_no_elbow_yaw"] == metrics.describe(
        metrics.m_max_without(pred, truth, robot=NAO_H25)
    )
    assert block["M_max_no_elbow_yaw"]["p95"] < block["M_max"]["p95"]


def test_summary_block_keys_and_truth_points_reuse():
    rng = np.random.default_rng(9)
    truth = np.asarray(ik.driven_to_full(rng.uniform(-0.5, 0.5, (40, 10))))
    pred = truth + rng.normal(0, 0.1, truth.shape).astype(np.float32)
    pts = metrics.arm_points(truth, robot=NAO_H25)
    block = metrics.summarize_errors(pred, truth, truth_points=pts, robot=NAO_H25)
    assert block == metrics.summarize_errors(pred, truth, robot=NAO_H25)
    assert set(block) == {"M_max", "M_avg", "per_joint", "M_max_no_elbow_yaw", "task_space"}
    stats = {"mean", "median", "p95", "max", "n"}
    assert set(block["M_max"]) == set(block["M_max_no_elbow_yaw"]) == stats
    assert set(block["per_joint"]) == set(robot.DRIVEN_JOINTS)
    assert set(block["task_space"]) == {"left", "right"}
    for side in metrics.sides(NAO_H25):
        assert set(block["task_space"][side]) == set(metrics.TASK_METRICS)
        for v in block["task_space"][side].values():
            assert set(v) == stats and v["n"] == 40 and v["median"] > 0
    assert block["task_space"] == metrics.task_space_errors(
        pred, truth, truth_points=pts, robot=NAO_H25
    )
    back = json.loads(json.dumps(block, allow_nan=False))
    assert back == block
    # empty input: NaN-free zeros
    empty = metrics.summarize_errors(np.zeros((0, 10)), np.zeros((0, 10)), robot=NAO_H25)
    assert empty["M_max"]["n"] == 0 and empty["task_space"]["left"]["hand_cm"]["n"] == 0
    json.dumps(empty, allow_nan=False)


def test_typed_errors():
    q = np.zeros((3, 10))
    with pytest.raises(ConfigError, match="shape"):
        metrics.summarize_errors(np.zeros((3, 9)), np.zeros((3, 9)), robot=NAO_H25)
    with pytest.raises(ConfigError, match="same shape"):
        metrics.joint_percentiles(q, np.zeros((4, 10)), robot=NAO_H25)
    with pytest.raises(ConfigError, match="non-finite"):
        metrics.arm_points(np.full((2, 26), np.nan), robot=NAO_H25)
    with pytest.raises(ConfigError, match="not driven"):
        metrics.m_max_without(q, q, exclude=("LWristYaw",), robot=NAO_H25)
    with pytest.raises(ConfigError, match="every driven joint"):
        metrics.m_max_without(q, q, exclude=robot.DRIVEN_JOINTS, robot=NAO_H25)
    with pytest.raises(ConfigError, match="frames"):
        metrics.summarize_errors(q, q, truth_points=np.zeros((2, 2, 3, 3)), robot=NAO_H25)
    with pytest.raises(ConfigError, match="arm_points"):
        metrics.arm_errors(np.zeros((3, 6, 3)), np.zeros((3, 6, 3)))


def test_evaluate_keeps_the_old_names():
    assert evaluate.frame_errors is metrics.frame_errors
    assert evaluate.describe is metrics.describe


def _fake_summary() -> dict:
    rng = np.random.default_rng(10)
    truth = rng.uniform(-0.5, 0.5, (30, 10))
    pts = metrics.arm_points(truth, robot=NAO_H25)
    return {
        m: metrics.summarize_errors(
            truth + rng.normal(0, s, truth.shape), truth, truth_points=pts, robot=NAO_H25
        )
        for m, s in (("relaxed", 0.05), ("full", 0.04), ("nearest_landmark", 0.2))
    }


def test_report_tables_and_plot(tmp_path):
    s = _fake_summary()
    table = report.where_error_table(s)
    rows = table.splitlines()
    assert len(rows) == 2 + 3 and rows[2].startswith("| relaxed |")
    assert all(r.count("|") == rows[0].count("|") == 12 for r in rows)
    b = s["nearest_landmark"]
    assert f"| {b['M_max']['p95']:.1f} | {b['M_max_no_elbow_yaw']['p95']:.1f} |" in rows[4]
    h = b["task_space"]["right"]["hand_cm"]
    assert f"{h['median']:.2f} / {h['p95']:.2f}" in rows[4]
    pj = report.per_joint_table(s, ["relaxed"]).splitlines()
    assert len(pj) == 2 + len(robot.DRIVEN_JOINTS)
    x = s["relaxed"]["per_joint"]["RElbowRoll"]
    assert pj[-1] == f"| RElbowRoll | {x['p50']:.1f} / {x['p95']:.1f} |"
    split = {"test_subjects": [2, 4], "test_actions": [1, 2, 3, 9], "sequences": 7}
    md = "\n".join(_where_md({"summary": s, "valid_frames": 1234, **split}))
    assert "## Where the error is" in md and table in md and report.per_joint_table(s) in md
    assert "subjects 2,4, arm actions a01-a03, a09 (7 recordings, 1,234 valid frames)" in md
    report.plot_per_joint(tmp_path / "per_joint_error.png", s)
    raw = (tmp_path / "per_joint_error.png").read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n" and len(raw) > 10_000
