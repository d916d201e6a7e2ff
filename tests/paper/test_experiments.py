"""The paper's studies: pose / motion benchmarks, landmark-set size study, efficiency study."""

import dataclasses
import json

import jax
import numpy as np
import pytest

from jaxproj import timing
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.paper import experiments, synthetic
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import ik, robot

CFG = engine.BuildConfig(
    chains="whole", landmarks=None, bandwidth=1.0, k=16, hidden=32, lam=1e-3, input_scale=1.0
)


def _train_descriptors(subjects=(1, 3)):
    seqs = datasets.msr_action3d(subjects=subjects)
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    return np.asarray(d)[np.asarray(ok)]


def _pose_descriptors(bones="upper"):
    pos = synthetic.skeleton_from_directions(
        np.stack([synthetic.BASIC_POSES[n] for n in synthetic.POSE_NAMES])
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
    return engine.from_landmarks(human, robot_poses, CFG, n_train=len(d))


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
    for name in synthetic.POSE_NAMES:
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
    for name in synthetic.POSE_NAMES:
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
    # engine.build (mean shift + kernels, tested in test_meanshift / test_landmarks /
    # test_projection) is replaced by a recorder returning the small model: this tests the
    # study's own plumbing
    train = _train_descriptors(subjects=(1,))[::50]
    evald = _train_descriptors(subjects=(2,))[::20]
    seen = []

    def fake_build(descriptors, config, calibrate=True):
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


def test_landmark_size_rows_count_the_chains_the_target_drove():
    # the per-chain model keeps the head at its fixed bandwidth (799 landmarks on the training
    # people): a size row's x value is the arms' count, not the largest chain's (the report once
    # drew 86, 961 and 1644 all at 799)
    per_chain = {"head": 799, "left_arm": 86, "right_arm": 90}
    assert experiments._targeted_landmarks(engine.BuildConfig(landmarks=86), per_chain) == 88
    whole = engine.BuildConfig(landmarks=400, chains="whole")
    assert experiments._targeted_landmarks(whole, {"whole": 402}) == 402
    # explicit per-chain targets: every chain counts
    three = engine.BuildConfig(landmarks=(50, 60, 70))
    assert (
        experiments._targeted_landmarks(three, {"head": 50, "left_arm": 60, "right_arm": 70}) == 60
    )


def test_landmark_size_study_reuses_a_model_the_caller_built(model_with_poses, monkeypatch):
    # the demo passes its per-chain model: the size with that config is not built again
    train = _train_descriptors(subjects=(1,))[::50]
    seen = []

    def fake_build(descriptors, config, calibrate=True):
        seen.append(config.landmarks)
        return model_with_poses

    monkeypatch.setattr(experiments.engine, "build", fake_build)
    base = engine.BuildConfig(k=8, hidden=16, seed=3)
    given = dataclasses.replace(base, landmarks=300)
    res = experiments.landmark_size_study(
        train,
        sizes=(None, 300, 30),  # None: ``config`` itself, with its own (default) sizes
        key=jax.random.PRNGKey(0),
        config=base,
        n_l=5,
        n_m=5,
        built={given: (model_with_poses, 12.5), base: (model_with_poses, 7.0)},
    )
    assert seen == [30]  # 300 and the base config came from ``built``
    assert [r["target"] for r in res["sizes"]] == [None, 300, 30]
    assert [r["build_s"] for r in res["sizes"]][:2] == [7.0, 12.5]
    assert res["sizes"][0]["pose8_M_max"] == res["sizes"][1]["pose8_M_max"]  # the same model


def test_efficiency_study_times_and_scores_each_neighbourhood(model_with_poses):
    d = _train_descriptors(subjects=(2,))[:200]
    res = experiments.efficiency_study(model_with_poses, d, ls=(2, 5), batch=256, repeats=2)
    json.dumps(res)
    assert [r["L"] for r in res["rows"]] == [2, 5]
    for r in res["rows"]:
        assert r["us_per_projection"] > 0 and r["compile_s"] > 0 and r["first_call_s"] > 0
        assert np.isfinite(r["M_avg_median"]) and np.isfinite(r["M_max_p95"])
    assert res["n_queries"] == 200 and res["batch"] == 256
    assert [r["batch"] for r in res["rows"]] == [256, 256]
    # a small memory budget halves the batch until the largest L fits, and every L is timed
    # at that one batch (L = 2 alone would fit 256), so that the rows' times compare
    small = experiments.efficiency_study(
        model_with_poses, d[:50], ls=(2, 5), batch=256, repeats=1,
        max_bytes=100 * 5 * 5 * 32 * 18 * 4,
    )  # fmt: skip
    assert [r["batch"] for r in small["rows"]] == [64, 64] and small["batch"] == 64


def test_efficiency_study_compiles_only_the_executable_it_times(model_with_poses, monkeypatch):
    """``compile_s`` is the compilation: nothing of ``project_chunk`` compiles outside it."""
    d = _train_descriptors(subjects=(2,))[:200]
    inside = [False]
    compiles = {True: 0, False: 0}

    def timed_compile(*args, **kwargs):
        inside[0] = True
        try:
            return timing.compile_timed(*args, **kwargs)
        finally:
            inside[0] = False

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            if "project_batch" in str(kwargs.get("fun_name", "")):
                compiles[inside[0]] += 1

    monkeypatch.setattr(experiments, "compile_timed", timed_compile)
    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        # L = 3, 4 and batch 128: shapes no other test compiles, so each is compiled here
        res = experiments.efficiency_study(model_with_poses, d, ls=(3, 4), batch=128, repeats=2)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert compiles == {True: 2, False: 0}
    assert [r["batch"] for r in res["rows"]] == [128, 128]
