"""IK tests, independent of the IK code: MuJoCo FK of our MJCF is the reference."""

import math

import jax
import numpy as np
import pytest

from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.robots.nao_h25 import ik, robot

ARM = {
    "L": ("LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll"),
    "R": ("RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll"),
}
SITES = ("l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist")


@pytest.fixture(scope="module")
def model():
    return robot.load_model("fixed")


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _robot_arm_dirs(model, q: np.ndarray) -> np.ndarray:
    """(T, 4, 3): robot L upper arm, L forearm, R upper arm, R forearm directions from FK."""
    p = robot.site_positions(model, q, SITES)
    return _unit(
        np.stack(
            [p[:, 1] - p[:, 0], p[:, 2] - p[:, 1], p[:, 4] - p[:, 3], p[:, 5] - p[:, 4]], axis=1
        )
    )


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between vectors (rad), in float64 and well-conditioned at 0 and pi.

    Not ``arccos`` of the dot product of unit vectors: near 0 that turns a rounding of the dot
    product into sqrt(2 * rounding), e.g. 0.02 deg from float32 unit vectors that are parallel.
    """
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def test_fk_round_trip_recovers_arm_angles(model):
    rng = np.random.default_rng(0)
    n = 400
    q = np.tile(robot.STANDING_POSTURE, (n, 1)).astype(np.float64)
    for names in ARM.values():
        for name in names:
            i = robot.IDX[name]
            q[:, i] = rng.uniform(robot.LOWER[i], robot.UPPER[i], size=n)
    dirs = _robot_arm_dirs(model, q)
    d = np.zeros((n, 15), np.float32)
    d[:, 0:3] = (0.0, 0.0, 1.0)
    d[:, 3:15] = dirs.reshape(n, 12)
    # scale each bone vector: the IK must not need unit-length input
    d = d * np.repeat(rng.uniform(0.3, 3.0, size=(n, 5)), 3, axis=1).astype(np.float32)
    got = np.asarray(ik.solve(d))
    # away from the elbow-yaw blend: the forearm bent > 30 deg from the upper-arm segment
    for k, names in enumerate(ARM.values()):
        flex = np.degrees(_angle(dirs[:, 2 * k], dirs[:, 2 * k + 1]))
        far = flex > 30.5
        assert far.sum() > 150
        idx = [robot.IDX[m] for m in names]
        np.testing.assert_allclose(got[far][:, idx], q[far][:, idx], atol=1e-4)
        # inside the band the shoulder angles are still exact
        sh = idx[:2]
        np.testing.assert_allclose(got[~far][:, sh], q[~far][:, sh], atol=1e-4)


def test_head_pitch_and_yaw_follow_the_neck():
    pitch = np.radians([-20.0, 0.0, 15.0, 25.0])
    yaw = np.radians([-30.0, 10.0, 0.0, 40.0])
    tilt = pitch + ik.HEAD_PITCH_NEUTRAL
    neck = _unit(np.stack([np.tan(tilt), np.tan(yaw), np.ones(4)], axis=1))
    d = np.zeros((4, 15), np.float32)
    d[:, 0:3] = neck
    d[:, 3:15] = np.tile([0.0, 0.0, -1.0], 4)
    got = np.asarray(ik.solve(d))
    # pitch within NAOqi's head envelope at that yaw (the table, independently interpolated):
    # 25 deg at yaw 40 deg lies above its 21.84 deg bound and is clipped to it
    yaw_deg = np.array([0.0, 27.85, 43.32, 51.74, 62.45, 87.49, 119.52])
    top = np.radians(np.interp(np.abs(np.degrees(yaw)), yaw_deg,
                               [29.51, 24.18, 21.20, 18.91, 17.19, 11.46, 18.91]))  # fmt: skip
    assert pitch[3] > top[3] and (pitch[:3] < top[:3]).all()
    np.testing.assert_allclose(got[:, robot.IDX["HeadPitch"]], np.minimum(pitch, top), atol=1e-5)
    np.testing.assert_allclose(got[:, robot.IDX["HeadYaw"]], yaw, atol=1e-5)


def test_undriven_joints_hold_the_standing_posture():
    d = np.tile(np.array([0, 0, 1] + [1, 0, 0] * 4, np.float32), (3, 1))
    got = np.asarray(ik.solve(d))
    undriven = np.setdiff1d(np.arange(robot.N_JOINTS), robot.DRIVEN_INDEX)
    np.testing.assert_array_equal(
        got[:, undriven], np.tile(robot.STANDING_POSTURE[undriven], (3, 1))
    )


def test_singular_and_degenerate_inputs_are_finite_and_deterministic():
    d = np.zeros((6, 15), np.float32)
    d[:, 0:3] = (0.0, 0.0, 1.0)
    # straight arm hanging: elbow yaw ill-defined (and on the atan2 branch cut, see ik.py)
    d[0, 3:9] = (0, 0, -1, 0, 0, -1)
    d[1, 3:9] = (0, 1, 0, 0, 1, 0)  # arm along the shoulder axis: pitch undefined
    d[2, 3:9] = 0.0  # zero vectors
    d[3, 3:9] = np.nan  # non-finite
    d[4, 3:9] = (0, -1, 0, 0, -1, 0)  # across the body, unreachable
    d[5, 3:9] = (-1, 0, 0, 0, 0, 1)  # straight back, beyond the pitch limit
    d[:, 9:15] = d[:, 3:9] * np.array([1, -1, 1, 1, -1, 1], np.float32)
    q1 = np.asarray(ik.solve(d))
    q2 = np.asarray(ik.solve(d.copy()))
    assert np.isfinite(q1).all()
    np.testing.assert_array_equal(q1, q2)
    assert (q1 >= robot.LOWER).all() and (q1 <= robot.UPPER).all()
    assert q1[0, robot.IDX["LElbowYaw"]] == pytest.approx(ik.ELBOW_YAW_NEUTRAL)
    assert q1[1, robot.IDX["LShoulderPitch"]] == pytest.approx(0.0, abs=1e-6)
    # zero and NaN vectors fall back to the hanging arm
    assert q1[2, robot.IDX["LShoulderPitch"]] == pytest.approx(math.pi / 2, abs=1e-5)
    np.testing.assert_array_equal(q1[2], q1[3])
    # left/right mirror inputs give mirrored angles (pitch equal, the rest opposite)
    for a, b, sign in (
        ("LShoulderPitch", "RShoulderPitch", 1),
        ("LShoulderRoll", "RShoulderRoll", -1),
        ("LElbowYaw", "RElbowYaw", -1),
        ("LElbowRoll", "RElbowRoll", -1),
    ):
        np.testing.assert_allclose(q1[:, robot.IDX[a]], sign * q1[:, robot.IDX[b]], atol=1e-6)


@pytest.fixture(scope="module")
def arm_frames():
    seqs = datasets.msr_action3d(actions=datasets.ARM_ACTIONS)
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    assert np.asarray(ok).all()
    return np.asarray(d)


def test_robot_arms_point_where_the_human_arms_point(model, arm_frames):
    rng = np.random.default_rng(0)
    d = arm_frames[rng.choice(len(arm_frames), size=3000, replace=False)]
    q = np.asarray(ik.solve(d))
    robot_dirs = _robot_arm_dirs(model, q)
    human_dirs = d.reshape(-1, 5, 3)[:, 1:5]
    dev = np.degrees(_angle(robot_dirs, human_dirs))  # (N, 4)
    # exact wherever no limit and no singularity blend is active
    margin = 1e-4
    inside = np.ones_like(dev, dtype=bool)
    for k, side in enumerate("LR"):
        idx = [robot.IDX[m] for m in ARM[side]]
        free = np.all(
            (q[:, idx] > robot.LOWER[idx] + margin) & (q[:, idx] < robot.UPPER[idx] - margin),
            axis=1,
        )
        bent = np.degrees(_angle(human_dirs[:, 2 * k], human_dirs[:, 2 * k + 1])) > 30.5
        inside[:, 2 * k] = free
        inside[:, 2 * k + 1] = free & bent
    assert inside.mean() > 0.5
    # float32 IK: each angle of the chain (pitch, roll, yaw, elbow roll) is within a few float32
    # steps of its own size, ~8 u rad (u = 2^-24), so each robot direction is within 32 u rad
    # (1.1e-4 deg) of the human's; measured 8e-6 deg
    assert dev[inside].max() < np.degrees(32 * 2.0**-24)
    # and overall, limits included: the acceptance numbers of the foundation issue
    assert np.median(dev) <= 8.0
    assert np.percentile(dev, 90) <= 20.0


def test_whole_bundled_dataset_in_one_jitted_call():
    seqs = datasets.msr_action3d()
    pos = np.concatenate([s.positions for s in seqs])  # invalid frames included
    assert pos.shape[0] == 23478
    d, _ = descriptor(pos)
    q = np.asarray(jax.block_until_ready(ik.solve(d)))
    assert q.shape == (23478, 26)
    assert np.isfinite(q).all()
    assert (q >= robot.LOWER).all() and (q <= robot.UPPER).all()


def test_chains_cover_the_driven_joints_once_and_factorise_the_ik():
    """Perturbing one chain's bones leaves every other chain's IK output bit-identical, and
    changes the chain's own output (so the chains are exactly the IK's factorisation)."""
    from jaxproj.human.skeleton import UPPER_BODY

    joints = [j for c in ik.CHAINS for j in c.joints]
    assert sorted(joints) == sorted(robot.DRIVEN_JOINTS) and len(joints) == len(set(joints))
    seqs = datasets.msr_action3d(subjects=[2], actions=[1, 5, 9])
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    d = np.asarray(d)[np.asarray(ok)]
    base = np.asarray(ik.solve_driven(d))
    rng = np.random.default_rng(0)
    for chain in ik.CHAINS:
        cols = np.concatenate([np.arange(3) + 3 * UPPER_BODY.index(b) for b in chain.bones])
        bumped = d.copy()
        bumped[:, cols] = rng.normal(size=(len(d), len(cols))).astype(np.float32)
        out = np.asarray(ik.solve_driven(bumped))
        own = [robot.DRIVEN_JOINTS.index(j) for j in chain.joints]
        rest = [i for i in range(len(robot.DRIVEN_JOINTS)) if i not in own]
        np.testing.assert_array_equal(out[:, rest], base[:, rest])
        assert (np.abs(out[:, own] - base[:, own]).max(axis=1) > 1e-3).mean() > 0.9
