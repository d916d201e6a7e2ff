"""Synthetic pose / motion benchmarks: skeletons, poses, motions, noise, experiment drivers."""

import json

import jax
import numpy as np
import pytest

from jaxproj import datasets, engine, experiments, ik, robot
from jaxproj.skeleton import BONE_NAMES, BONES, J, descriptor

CFG = engine.BuildConfig(
    landmarks=None, bandwidth=1.0, k=16, hidden=32, lam=1e-3, input_scale=1.0, seed=0
)
DRIVEN = {n: i for i, n in enumerate(robot.DRIVEN_JOINTS)}
LO = np.degrees(robot.LOWER[robot.DRIVEN_INDEX])
HI = np.degrees(robot.UPPER[robot.DRIVEN_INDEX])


def _bone(name):
    return BONE_NAMES.index(name)


def _train_descriptors(subjects=(1, 3)):
    seqs = datasets.msr_action3d(subjects=subjects)
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    return np.asarray(d)[np.asarray(ok)]


def _pose_descriptors(bones="upper"):
    pos = experiments.skeleton_from_directions(
        np.stack([experiments.BASIC_POSES[n] for n in experiments.POSE_NAMES])
    )
    d, ok = descriptor(pos, bones=bones)
    assert np.asarray(ok).all()
    return np.asarray(d)


def _small_model(extra=None, n=300, seed=0):
    d = _train_descriptors()
    human = d[np.random.default_rng(seed).choice(len(d), n, replace=False)]
    if extra is not None:
        human = np.concatenate([human, extra])
    robot_poses = np.asarray(ik.solve_driven(human))
    projector = engine.build_from_landmarks(human, robot_poses, CFG)
    return engine.Model(projector, CFG, 1.0, np.ones(len(human), np.int64), len(d))


# ------------------------------------------------------------------------- data statistics


def test_bone_lengths_are_plausible_and_the_medians_of_the_recordings():
    lengths = experiments.median_bone_lengths()
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
    assert experiments.median_bone_lengths()[0] > 0.1


def test_kinect_noise_estimate_is_millimetres_and_hands_are_noisiest():
    pooled = experiments.kinect_noise_std()
    per = experiments.kinect_noise_std(per_joint=True)
    assert 0.0035 < pooled < 0.004  # 3.7 mm (module docstring)
    assert per.shape == (20,) and (per > 0.002).all() and (per < 0.01).all()
    assert 0.003 < np.median(per) < 0.005
    assert per[J["HandLeft"]] > per[J["KneeLeft"]]
    assert per[J["HandRight"]] > per[J["HipCenter"]]


# ----------------------------------------------------------------------------- skeletons


@pytest.mark.parametrize("name", experiments.POSE_NAMES)
def test_descriptor_recovers_the_pose_directions(name):
    dirs = experiments.BASIC_POSES[name]
    assert dirs.shape == (19, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, atol=1e-6)
    for lengths in (None, np.random.default_rng(1).uniform(0.05, 0.6, 19)):
        pos = experiments.skeleton_from_directions(dirs, lengths)
        assert pos.shape == (20, 3)
        np.testing.assert_allclose(pos[J["HipCenter"]], 0.0)
        d, ok = descriptor(pos, bones="full")
        assert bool(ok)
        np.testing.assert_allclose(np.asarray(d).reshape(19, 3), dirs, atol=1e-5)


def test_skeleton_from_directions_places_each_child_at_bone_length():
    lengths = experiments.median_bone_lengths()
    dirs = np.stack([experiments.BASIC_POSES["POSE_3"], experiments.BASIC_POSES["POSE_8"]])
    pos = experiments.skeleton_from_directions(dirs, lengths)  # batched
    assert pos.shape == (2, 20, 3)
    for b, (p, c) in enumerate(BONES):
        vec = pos[:, J[c]] - pos[:, J[p]]
        np.testing.assert_allclose(np.linalg.norm(vec, axis=-1), lengths[b], rtol=1e-5)
        np.testing.assert_allclose(vec / lengths[b], dirs[:, b], atol=1e-5)


def test_an_inconsistent_body_does_not_round_trip():
    # a tilted spine changes the body frame, so the other bones' descriptors change
    dirs = np.array(experiments.BASIC_POSES["POSE_3"])
    dirs[_bone("spine_lower")] = [0.5, 0.0, np.sqrt(0.75)]
    d, ok = descriptor(experiments.skeleton_from_directions(dirs), bones="full")
    assert bool(ok)
    assert np.abs(np.asarray(d).reshape(19, 3) - dirs).max() > 0.05


# ---------------------------------------------------------------------- what poses mean


def _ik_deg(name):
    d, _ = descriptor(experiments.skeleton_from_directions(experiments.BASIC_POSES[name]))
    return np.degrees(np.asarray(ik.solve_driven(d), np.float64))


def _q(q, joint):
    return q[DRIVEN[joint]]


def test_poses_mean_what_they_say():
    q = {n: _ik_deg(n) for n in experiments.POSE_NAMES}
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
    table = experiments.basic_pose_angles()
    assert table["POSE_4"]["LShoulderPitch"] == pytest.approx(_q(q["POSE_4"], "LShoulderPitch"))


# -------------------------------------------------------------------------------- motions


def _angles(a, b):
    a = np.asarray(a).reshape(-1, 3)
    b = np.asarray(b).reshape(-1, 3)
    return np.degrees(np.arccos(np.clip(np.sum(a * b, -1), -1, 1)))


def test_motion_goes_from_rest_to_the_pose_with_an_ease_in_out():
    key = jax.random.PRNGKey(0)
    clean = experiments.basic_motion("POSE_4", noise_std=0.0, key=key)
    assert clean.shape == (31, 20, 3) and clean.dtype == np.float32
    rest = experiments.skeleton_from_directions(experiments.BASIC_POSES["POSE_1"])
    pose = experiments.skeleton_from_directions(experiments.BASIC_POSES["POSE_4"])
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
    assert experiments.basic_motion("POSE_2", seconds=1.0, fps=30.0, key=key).shape[0] == 31


def test_raised_arms_swing_through_the_front_and_the_ik_moves_smoothly():
    key = jax.random.PRNGKey(0)
    for name in experiments.POSE_NAMES:
        motion = experiments.basic_motion(name, noise_std=0.0, key=key)
        d, _ = descriptor(motion)
        q = np.degrees(np.asarray(ik.solve_driven(d), np.float64))
        smooth = [i for i, j in enumerate(robot.DRIVEN_JOINTS) if "ElbowYaw" not in j]
        # no ShoulderPitch flip over the shoulder axis: every non-yaw joint moves < 12 deg/frame
        assert np.abs(np.diff(q[:, smooth], axis=0)).max() < 12, name
    up = experiments.basic_motion("POSE_4", noise_std=0.0, key=key)
    d, _ = descriptor(up, bones="full")
    u = np.asarray(d).reshape(-1, 19, 3)[:, _bone("upper_arm_left")]
    assert u[len(u) // 2, 0] > 0.9  # forward halfway
    pitch = np.degrees(np.asarray(ik.solve_driven(descriptor(up)[0]))[:, DRIVEN["LShoulderPitch"]])
    assert (np.diff(pitch) < 1e-3).all() and pitch[0] > 85 and pitch[-1] < -85


def test_shoulder_coordinates_round_trip():
    v = np.random.default_rng(0).normal(size=(100, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    p, r = experiments.shoulder_coordinates(v)
    np.testing.assert_allclose(experiments.from_shoulder_coordinates(p, r), v, atol=1e-12)
    p, r = experiments.shoulder_coordinates(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(np.degrees(p), [90.0, 0.0])
    np.testing.assert_allclose(r, 0.0)


def test_motion_noise_matches_the_requested_std_and_is_deterministic():
    key = jax.random.PRNGKey(3)
    clean = experiments.basic_motion("POSE_8", noise_std=0.0, key=key, seconds=10.0)
    noisy = experiments.basic_motion("POSE_8", noise_std=0.01, key=key, seconds=10.0)
    res = noisy - clean
    assert abs(res.std() - 0.01) < 0.0005 and abs(res.mean()) < 0.001
    # noise-free ends up to noise: rest first, the pose last
    d0, _ = descriptor(noisy[[0, -1]], bones="full")
    ref, _ = descriptor(clean[[0, -1]], bones="full")
    err = _angles(d0, ref)
    assert 0.1 < err.mean() < 10
    # default: the per-joint Kinect estimate
    dflt = experiments.basic_motion("POSE_8", key=key, seconds=20.0) - experiments.basic_motion(
        "POSE_8", noise_std=0.0, key=key, seconds=20.0
    )
    per_joint = dflt.reshape(-1, 20, 3).std(axis=(0, 2))
    np.testing.assert_allclose(per_joint, experiments.kinect_noise_std(per_joint=True), rtol=0.1)
    # deterministic for a key, different for another
    again = experiments.basic_motion("POSE_8", noise_std=0.01, key=key, seconds=10.0)
    np.testing.assert_array_equal(noisy, again)
    other = experiments.basic_motion(
        "POSE_8", noise_std=0.01, key=jax.random.PRNGKey(4), seconds=10.0
    )
    assert np.abs(other - noisy).max() > 1e-3


def test_bad_arguments_are_config_errors():
    from jaxproj.exceptions import ConfigError

    key = jax.random.PRNGKey(0)
    with pytest.raises(ConfigError):
        experiments.basic_motion("POSE_9", key=key)
    with pytest.raises(ConfigError):
        experiments.basic_motion("POSE_2", noise_std=-1.0, key=key)
    with pytest.raises(ConfigError):
        experiments.skeleton_from_directions(np.zeros((19, 3)))
    with pytest.raises(ConfigError):
        experiments.skeleton_from_directions(np.ones((18, 3)))


# ---------------------------------------------------------------------------- experiments


@pytest.fixture(scope="module")
def model_with_poses():
    """300 real landmarks plus the eight basic poses themselves."""
    return _small_model(extra=_pose_descriptors())


def test_pose_experiments_are_finite_json_and_exact_at_landmarks(model_with_poses):
    res = experiments.run_pose_experiments(
        model_with_poses, key=jax.random.PRNGKey(0), seconds=1.0, n_l=5, n_m=5
    )
    json.dumps(res)
    assert res["landmarks"] == 308 and res["frames_per_motion"] == 16
    for name in experiments.POSE_NAMES:
        for objective in ("relaxed", "full"):
            pose = res["poses"][name][objective]
            # the pose is a landmark: the projection returns its IK pose
            assert pose["M_max"] < 0.05 and pose["M_avg"] < 0.05, (name, objective, pose)
            motion = res["motions"][name][objective]
            assert len(motion["M_max"]) == 16 and len(motion["M_avg"]) == 16
            vals = np.array(motion["M_max"] + motion["M_avg"])
            assert np.isfinite(vals).all() and (vals >= 0).all()
            assert motion["M_max_max"] == pytest.approx(max(motion["M_max"]))
            assert (np.array(motion["M_avg"]) <= np.array(motion["M_max"]) + 1e-9).all()
    truth = res["truth_deg"]["POSE_4"]
    assert truth["LShoulderPitch"] == pytest.approx(-90, abs=3)
    for name in experiments.POSE_NAMES:
        assert res["coverage_deg"][name]["pose"] < 0.01  # the pose is a landmark
        assert res["coverage_deg"][name]["motion_max"] > 1.0  # its motion is not
        joint_err = res["poses"][name]["relaxed"]["joint_errors_deg"]
        assert set(joint_err) == set(robot.DRIVEN_JOINTS)
        assert max(joint_err.values()) == pytest.approx(res["poses"][name]["relaxed"]["M_max"])
    assert set(res["summary"]) == {"relaxed", "full"}


def test_pose_experiments_measure_real_errors_off_the_landmarks(model_with_poses):
    # noisy copies of the poses are not landmarks: errors are real (non-zero) numbers
    res = experiments.run_pose_experiments(
        model_with_poses,
        key=jax.random.PRNGKey(1),
        seconds=1.0,
        n_l=5,
        n_m=5,
        objectives=("relaxed",),
        noise_std=0.02,
        poses=("POSE_3", "POSE_6"),
    )
    assert set(res["poses"]) == {"POSE_3", "POSE_6"}
    for name in ("POSE_3", "POSE_6"):
        m = res["motions"][name]["relaxed"]
        assert 0.1 < m["M_avg_mean"] and np.isfinite(m["M_max"]).all()
    assert res["noise_std_m"] == 0.02
    # motion POSE_i does not depend on which other poses are run
    one = experiments.run_pose_experiments(
        model_with_poses,
        key=jax.random.PRNGKey(1),
        seconds=1.0,
        n_l=5,
        n_m=5,
        objectives=("relaxed",),
        noise_std=0.02,
        poses=("POSE_6",),
    )
    assert one["motions"]["POSE_6"] == res["motions"]["POSE_6"]


def test_landmark_size_study_builds_one_model_per_size(model_with_poses, monkeypatch):
    # engine.build (mean shift + kernels, tested in test_landmarks / test_projection) is
    # replaced by a recorder returning the small model: this tests the study's own plumbing
    train = _train_descriptors(subjects=(1,))[::50]
    evald = _train_descriptors(subjects=(2,))[::20]
    seen = []

    def fake_build(descriptors, config):
        seen.append((len(descriptors), config))
        return model_with_poses

    monkeypatch.setattr(experiments.engine, "build", fake_build)
    base = engine.BuildConfig(k=8, hidden=16, seed=3)
    res = experiments.landmark_size_study(
        train,
        sizes=(300, 30),
        key=jax.random.PRNGKey(0),
        eval_descriptors=evald,
        config=base,
        n_l=5,
        n_m=5,
    )
    json.dumps(res)
    assert [c.landmarks for _, c in seen] == [300, 30]
    assert all(n == len(train) and c.bandwidth is None for n, c in seen)
    assert all(c.k == 8 and c.hidden == 16 and c.seed == 3 for _, c in seen)
    rows = res["sizes"]
    assert [r["target"] for r in rows] == [300, 30]
    for r in rows:
        assert r["landmarks"] == 308
        assert r["pose8_static_M_max"] < 0.05  # POSE_8 is one of this model's landmarks
        for k in ("pose8_M_max", "pose8_M_avg_mean", "M_avg_median", "M_max_p95"):
            assert np.isfinite(r[k]) and r[k] >= 0
        assert r["pose8_M_max"] == pytest.approx(max(r["pose8_M_max_frames"]))
        assert r["eval_frames"] == len(evald) and len(r["pose8_M_max_frames"]) == 31
    # the same POSE_8 motion for every size
    assert rows[0]["pose8_M_max_frames"] == rows[1]["pose8_M_max_frames"]


def test_efficiency_study_times_and_scores_each_neighbourhood(model_with_poses):
    d = _train_descriptors(subjects=(2,))[:200]
    res = experiments.efficiency_study(model_with_poses, d, ls=(2, 5), batch=256, repeats=2)
    json.dumps(res)
    assert [r["L"] for r in res["rows"]] == [2, 5]
    for r in res["rows"]:
        assert r["us_per_projection"] > 0 and r["compile_s"] > 0
        assert np.isfinite(r["M_avg_median"]) and np.isfinite(r["M_max_p95"])
    assert res["n_queries"] == 200 and res["batch"] == 256
    assert [r["batch"] for r in res["rows"]] == [256, 256]
    # a small memory budget halves the batch (same answers)
    small = experiments.efficiency_study(
        model_with_poses, d[:50], ls=(5,), batch=256, repeats=1, max_bytes=100 * 5 * 5 * 32 * 18 * 4
    )
    assert small["rows"][0]["batch"] == 64
