"""Landmarks: mean-shift modes of training descriptors plus their IK robot poses."""

from __future__ import annotations

import numpy as np
import pytest

from jaxproj.errors import ConfigError
from jaxproj.io import datasets
from jaxproj.projection import landmarks, meanshift
from jaxproj.robots.nao_h25 import ik


def _train_points(subjects, actions=None):
    return datasets.valid_descriptors(datasets.msr_action3d(subjects=subjects, actions=actions))


# --- real data ------------------------------------------------------------------------------------


def test_find_bandwidth_on_two_subjects_and_landmarks_use_the_ik():
    seqs = datasets.msr_action3d(subjects=[1, 3])
    points = datasets.valid_descriptors(seqs)
    n_valid = sum(int(s.valid.sum()) for s in seqs)
    assert 0.9 * n_valid <= points.shape[0] <= n_valid
    target = 400
    h, res = meanshift.find_bandwidth(points, target)
    assert abs(res.n_modes - target) <= 0.05 * target
    # find_bandwidth's result is exactly mean_shift at the bandwidth found
    again = meanshift.mean_shift(points, h)
    np.testing.assert_array_equal(again.modes, res.modes)

    lm = landmarks.build_landmarks(seqs, bandwidth=h)
    assert lm.n_frames == points.shape[0]
    assert lm.human.shape == (res.n_modes, 15) and lm.human.dtype == np.float32
    assert lm.robot.shape == (res.n_modes, 10) and lm.robot.dtype == np.float32
    np.testing.assert_array_equal(lm.human, res.modes)
    np.testing.assert_array_equal(lm.counts, res.counts)
    np.testing.assert_allclose(lm.robot, np.asarray(ik.solve_driven(lm.human)), atol=1e-6)


def test_build_landmarks_drops_invalid_frames():
    seq = datasets.msr_action3d(subjects=[1], actions=[1])[0]
    positions = np.array(seq.positions)
    positions[::3] = 0.0  # lost skeletons
    valid = seq.valid & np.any(positions != 0, axis=(1, 2))
    lm = landmarks.build_landmarks([_Seq(positions, valid)], bandwidth=0.3)
    assert lm.n_frames == int(valid.sum())
    assert lm.counts.sum() == lm.n_frames
    assert np.isfinite(lm.human).all() and np.isfinite(lm.robot).all()


class _Seq:
    def __init__(self, positions, valid):
        self.positions, self.valid = positions, valid


def test_bad_arguments_raise_config_error_before_the_descriptors(monkeypatch):
    seqs = datasets.msr_action3d(subjects=[1], actions=[1])
    with pytest.raises(ConfigError, match="exactly one"):
        landmarks.build_landmarks(seqs, target=4, bandwidth=0.3)
    with pytest.raises(ConfigError, match="exactly one"):
        landmarks.build_landmarks(seqs)

    def no_descriptors(*args, **kwargs):
        raise AssertionError("descriptors computed before the options were checked")

    monkeypatch.setattr(landmarks, "valid_descriptors", no_descriptors)
    for bad in (
        dict(bandwidth=0.0),
        dict(bandwidth=float("nan")),
        dict(target=0),
        dict(bandwidth=0.3, kernel="epanechnikov"),
        dict(target=10, max_iter=0),
        dict(target=10, tol=-1.0),
        dict(target=10, merge_fraction=float("inf")),
    ):
        with pytest.raises(ConfigError):
            landmarks.build_landmarks(seqs, **bad)
    monkeypatch.undo()
    points = datasets.valid_descriptors(seqs)
    with pytest.raises(ConfigError, match="target"):  # N is known only after the descriptors
        landmarks.build_landmarks(points, target=points.shape[0] + 1)


@pytest.mark.slow
def test_paper_landmark_counts_on_training_subjects():
    """1644, 961 and 86 landmarks (paper section IV) from subjects 1, 3, 5, 7, 9.

    The time these searches take is measured by ``benchmarks/bench_build.py``, not here.
    """
    points = _train_points([1, 3, 5, 7, 9])
    assert points.shape[0] > 10_000
    previous = 0.0
    for target in (1644, 961, 86):
        h, res = meanshift.find_bandwidth(points, target)
        assert abs(res.n_modes - target) <= 0.05 * target
        assert res.converged
        assert h > previous  # fewer landmarks need a wider kernel
        previous = h
