"""Synthetic poses and motions: bone lengths, noise estimate, skeletons, basic poses, motions."""

import jax
import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import BONE_NAMES, BONES, J, descriptor
from jaxproj.io import datasets
from jaxproj.paper import synthetic
from jaxproj.robots.nao_h25 import ik, robot

DRIVEN = {n: i for i, n in enumerate(robot.DRIVEN_JOINTS)}
LO = np.degrees(robot.LOWER[robot.DRIVEN_INDEX])
HI = np.degrees(robot.UPPER[robot.DRIVEN_INDEX])


def _bone(name):
    return BONE_NAMES.index(name)


# ------------------------------------------------------------------------- data statistics


def test_bone_lengths_are_plausible_and_the_medians_of_the_recordings():
    lengths = synthetic.median_bone_lengths()
    assert lengths.shape == (19,) and lengths.dtype == np.float32
    for side in ("left", "right"):
        assert 0.2 < lengths[_bone(f"upper_arm_{side}")] < 0.35
        assert 0.2 < lengths[_bone(f"forearm_{side}")] < 0.35
        assert 0.35 < lengths[_bone(f"thigh_{side}")] < 0.65
        assert 0.3 < lengths[_bone(f"shin_{side}")] < 0.5
    assert abs(lengths[_bone("upper_arm_left")] - lengths[_bone("upper_arm_right")]) < 0.02
    # recomputed independently from the bundled data: one subject's median is close, the
    # median over every valid frame is exact
    seqs = datasets.msr_action3d()
    pos = np.concatenate([s.positions[s.valid] for s in seqs]).astype(np.float64)
    par = [J[a] for a, _ in BONES]
    chi = [J[b] for _, b in BONES]
    ref = np.median(np.linalg.norm(pos[:, chi] - pos[:, par], axis=-1), axis=0)
    np.testing.assert_allclose(lengths, ref, atol=1e-6)
    # a copy: callers cannot corrupt the cache
    lengths[:] = 0.0
    assert synthetic.median_bone_lengths()[0] > 0.1


def test_kinect_noise_estimate_is_millimetres_and_hands_are_noisiest():
    pooled = synthetic.kinect_noise_std()
    per = synthetic.kinect_noise_std(per_joint=True)
    assert 0.0035 < pooled < 0.004  # 3.7 mm (module docstring)
    assert per.shape == (20,) and (per > 0.002).all() and (per < 0.01).all()
    assert 0.003 < np.median(per) < 0.005
    assert per[J["HandLeft"]] > per[J["KneeLeft"]]
    assert per[J["HandRight"]] > per[J["HipCenter"]]


# ----------------------------------------------------------------------------- skeletons


@pytest.mark.parametrize("name", synthetic.POSE_NAMES)
def test_descriptor_recovers_the_pose_directions(name):
    dirs = synthetic.BASIC_POSES[name]
    assert dirs.shape == (19, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, atol=1e-6)
    for lengths in (None, np.random.default_rng(1).uniform(0.05, 0.6, 19)):
        pos = synthetic.skeleton_from_directions(dirs, lengths)
        assert pos.shape == (20, 3)
        np.testing.assert_allclose(pos[J["HipCenter"]], 0.0)
        d, ok = descriptor(pos, bones="full")
        assert bool(ok)
        np.testing.assert_allclose(np.asarray(d).reshape(19, 3), dirs, atol=1e-5)


def test_skeleton_from_directions_places_each_child_at_bone_length():
    lengths = synthetic.median_bone_lengths()
    dirs = np.stack([synthetic.BASIC_POSES["POSE_3"], synthetic.BASIC_POSES["POSE_8"]])
    pos = synthetic.skeleton_from_directions(dirs, lengths)  # batched
    assert pos.shape == (2, 20, 3)
    for b, (p, c) in enumerate(BONES):
        vec = pos[:, J[c]] - pos[:, J[p]]
        np.testing.assert_allclose(np.linalg.norm(vec, axis=-1), lengths[b], rtol=1e-5)
        np.testing.assert_allclose(vec / lengths[b], dirs[:, b], atol=1e-5)


def test_an_inconsistent_body_does_not_round_trip():
    # a tilted spine changes the body frame, so the other bones' descriptors change
    dirs = np.array(synthetic.BASIC_POSES["POSE_3"])
    dirs[_bone("spine_lower")] = [0.5, 0.0, np.sqrt(0.75)]
    d, ok = descriptor(synthetic.skeleton_from_directions(dirs), bones="full")
    assert bool(ok)
    assert np.abs(np.asarray(d).reshape(19, 3) - dirs).max() > 0.05


# ---------------------------------------------------------------------- what poses mean


def _ik_deg(name):
    d, _ = descriptor(synthetic.skeleton_from_directions(synthetic.BASIC_POSES[name]))
    return np.degrees(np.asarray(ik.solve_driven(d), np.float64))


def _q(q, joint):
    return q[DRIVEN[joint]]


def test_poses_mean_what_they_say():
    q = {n: _ik_deg(n) for n in synthetic.POSE_NAMES}
    for n, a in q.items():
        assert abs(_q(a, "HeadYaw")) < 0.5 and abs(_q(a, "HeadPitch")) < 0.5, n
        # reachable: nothing at (or beyond) a joint limit
        assert ((a > LO + 0.5) & (a < HI - 0.5)).all(), (n, a)
    for side in "LR":
        assert abs(_q(q["POSE_1"], f"{side}ShoulderPitch") - 90) < 3  # arms hanging
        assert abs(_q(q["POSE_1"], f"{side}ShoulderRoll")) < 10
        assert abs(_q(q["POSE_2"], f"{side}ShoulderPitch") - 90) < 3  # sideways ...
        assert 60 < abs(_q(q["POSE_2"], f"{side}ShoulderRoll")) < 76  # ... below the limit
        assert abs(_q(q["POSE_3"], f"{side}ShoulderPitch")) < 3  # arms forward
        assert abs(_q(q["POSE_4"], f"{side}ShoulderPitch") + 90) < 3  # arms up
        assert abs(_q(q["POSE_6"], f"{side}ShoulderPitch") - 90) < 3
        assert 75 < abs(_q(q["POSE_6"], f"{side}ElbowRoll")) < 88.5  # elbows bent ~ 90
        assert abs(_q(q["POSE_7"], f"{side}ShoulderPitch") + 90) < 3  # upper arms raised
        assert 45 < abs(_q(q["POSE_7"], f"{side}ShoulderRoll"))
        assert 45 < abs(_q(q["POSE_7"], f"{side}ElbowRoll"))  # forearms up
        for n in ("POSE_2", "POSE_3", "POSE_4"):  # straight arms
            assert abs(_q(q[n], f"{side}ElbowRoll")) < 10
    assert abs(_q(q["POSE_5"], "LShoulderPitch") + 90) < 3  # left up
    assert abs(_q(q["POSE_5"], "RShoulderPitch")) < 3  # right forward
    assert abs(_q(q["POSE_8"], "LShoulderPitch") - 45) < 3  # left forward-down
    assert abs(_q(q["POSE_8"], "RShoulderPitch") + 90) < 3  # right raised sideways ...
    assert abs(_q(q["POSE_8"], "RElbowRoll")) > 30  # ... elbow bent
    # symmetric poses give mirrored angles
    for n in ("POSE_1", "POSE_2", "POSE_3", "POSE_4", "POSE_6", "POSE_7"):
        a = q[n]
        left = a[[DRIVEN[f"LShoulder{j}"] for j in ("Pitch", "Roll")]]
        right = a[[DRIVEN[f"RShoulder{j}"] for j in ("Pitch", "Roll")]]
        np.testing.assert_allclose(left, right * np.array([1, -1]), atol=1e-3)
    # eight different poses
    names = list(q)
    for i in range(len(names)):
        for k in range(i + 1, len(names)):
            assert np.abs(q[names[i]] - q[names[k]]).max() > 20, (names[i], names[k])
    # basic_pose_angles reports the same
    table = synthetic.basic_pose_angles()
    assert table["POSE_4"]["LShoulderPitch"] == pytest.approx(_q(q["POSE_4"], "LShoulderPitch"))


# -------------------------------------------------------------------------------- motions


def _angles(a, b):
    a = np.asarray(a).reshape(-1, 3)
    b = np.asarray(b).reshape(-1, 3)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, -1), -1, 1)))


def test_motion_goes_from_rest_to_the_pose_with_an_ease_in_out():
    key = jax.random.PRNGKey(0)
    clean = synthetic.basic_motion("POSE_4", noise_std=0.0, key=key)
    assert clean.shape == (31, 20, 3) and clean.dtype == np.float32
    rest = synthetic.skeleton_from_directions(synthetic.BASIC_POSES["POSE_1"])
    pose = synthetic.skeleton_from_directions(synthetic.BASIC_POSES["POSE_4"])
    np.testing.assert_allclose(clean[0], rest, atol=1e-6)
    np.testing.assert_allclose(clean[-1], pose, atol=1e-6)
    # every frame is a consistent skeleton; the upper arm turns monotonically, slowly at the ends
    d, ok = descriptor(clean, bones="full")
    assert np.asarray(ok).all()
    dirs = np.asarray(d).reshape(-1, 19, 3)
    u = dirs[:, _bone("upper_arm_left")]
    from_rest = _angles(u, np.broadcast_to(u[0], u.shape))
    steps = np.diff(from_rest)
    assert (steps > 0).all()
    assert steps[0] < 0.2 * steps[len(steps) // 2] and steps[-1] < 0.2 * steps[len(steps) // 2]
    np.testing.assert_allclose(
        dirs[:, _bone("spine_lower")], np.broadcast_to([0, 0, 1], (31, 3)), atol=1e-5
    )
    # other length / rate
    assert synthetic.basic_motion("POSE_2", seconds=1.0, fps=30.0, key=key).shape[0] == 31


def test_raised_arms_swing_through_the_front_and_the_ik_moves_smoothly():
    key = jax.random.PRNGKey(0)
    for name in synthetic.POSE_NAMES:
        motion = synthetic.basic_motion(name, noise_std=0.0, key=key)
        d, _ = descriptor(motion)
        q = np.degrees(np.asarray(ik.solve_driven(d), np.float64))
        smooth = [i for i, j in enumerate(robot.DRIVEN_JOINTS) if "ElbowYaw" not in j]
        # no ShoulderPitch flip over the shoulder axis: every non-yaw joint moves < 12 deg/frame
        assert np.abs(np.diff(q[:, smooth], axis=0)).max() < 12, name
    up = synthetic.basic_motion("POSE_4", noise_std=0.0, key=key)
    d, _ = descriptor(up, bones="full")
    u = np.asarray(d).reshape(-1, 19, 3)[:, _bone("upper_arm_left")]
    assert u[len(u) // 2, 0] > 0.9  # forward halfway
    pitch = np.degrees(np.asarray(ik.solve_driven(descriptor(up)[0]))[:, DRIVEN["LShoulderPitch"]])
    assert (np.diff(pitch) < 1e-3).all() and pitch[0] > 85 and pitch[-1] < -85


def test_shoulder_coordinates_round_trip():
    v = np.random.default_rng(0).normal(size=(100, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    p, r = synthetic.shoulder_coordinates(v)
    np.testing.assert_allclose(synthetic.from_shoulder_coordinates(p, r), v, atol=1e-12)
    p, r = synthetic.shoulder_coordinates(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(np.degrees(p), [90.0, 0.0])
    np.testing.assert_allclose(r, 0.0)


def test_motion_noise_matches_the_requested_std_and_is_deterministic():
    key = jax.random.PRNGKey(3)
    clean = synthetic.basic_motion("POSE_8", noise_std=0.0, key=key, seconds=10.0)
    noisy = synthetic.basic_motion("POSE_8", noise_std=0.01, key=key, seconds=10.0)
    res = noisy - clean
    assert abs(res.std() - 0.01) < 0.0005 and abs(res.mean()) < 0.001
    # noise-free ends up to noise: rest first, the pose last
    d0, _ = descriptor(noisy[[0, -1]], bones="full")
    ref, _ = descriptor(clean[[0, -1]], bones="full")
    err = _angles(d0, ref)
    assert 0.1 < err.mean() < 10
    # default: the per-joint Kinect estimate
    dflt = synthetic.basic_motion("POSE_8", key=key, seconds=20.0) - synthetic.basic_motion(
        "POSE_8", noise_std=0.0, key=key, seconds=20.0
    )
    per_joint = dflt.reshape(-1, 20, 3).std(axis=(0, 2))
    np.testing.assert_allclose(per_joint, synthetic.kinect_noise_std(per_joint=True), rtol=0.1)
    # deterministic for a key, different for another
    again = synthetic.basic_motion("POSE_8", noise_std=0.01, key=key, seconds=10.0)
    np.testing.assert_array_equal(noisy, again)
    other = synthetic.basic_motion(
        "POSE_8", noise_std=0.01, key=jax.random.PRNGKey(4), seconds=10.0
    )
    assert np.abs(other - noisy).max() > 1e-3


def test_bad_arguments_are_config_errors():
    key = jax.random.PRNGKey(0)
    with pytest.raises(ConfigError):
        synthetic.basic_motion("POSE_9", key=key)
    with pytest.raises(ConfigError):
        synthetic.basic_motion("POSE_2", noise_std=-1.0, key=key)
    with pytest.raises(ConfigError):
        synthetic.skeleton_from_directions(np.zeros((19, 3)))
    with pytest.raises(ConfigError):
        synthetic.skeleton_from_directions(np.ones((18, 3)))
    with pytest.raises(ConfigError):
        synthetic.basic_motion("POSE_2", seconds=0.0, key=key)
    with pytest.raises(ConfigError, match="unknown pose"):
        synthetic.check_pose("POSE_0")
    np.testing.assert_array_equal(synthetic.check_pose("POSE_3"), synthetic.BASIC_POSES["POSE_3"])
