"""The per-frame confidence (jaxproj.projection.confidence) falls off away from the landmarks."""

import dataclasses
import json

import numpy as np
import pytest

from jaxproj.io import datasets
from jaxproj.motion.retarget import retarget
from jaxproj.projection import api as engine
from jaxproj.projection.confidence import (
    CALIBRATION_FRAMES,
    DEVIATION_SCALE,
    HELD_OUT_RATIO,
    LOW_CONFIDENCE,
    confidence,
    rescale,
)
from jaxproj.robots.nao_h25 import ik


@pytest.fixture(scope="module")
def setup():
    d = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3], actions=[1, 2, 5]))
    human = d[np.random.default_rng(0).choice(len(d), 300, replace=False)]
    cfg = engine.BuildConfig(landmarks=None, bandwidth=1.0, k=16, hidden=32, input_scale=1.0)
    return engine.from_landmarks(human, np.asarray(ik.solve_driven(human)), cfg), human


def _away(h: np.ndarray, scale: float, rng: np.random.Generator) -> np.ndarray:
    """Each bone unit vector turned by noise of ``scale`` and normalised again."""
    v = h.reshape(len(h), -1, 3) + rng.normal(scale=scale, size=(len(h), h.shape[1] // 3, 3))
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).reshape(h.shape).astype(np.float32)


def test_confidence_falls_off_away_from_the_landmarks(setup):
    model, human = setup
    rng = np.random.default_rng(1)
    scales = (0.0, 0.1, 0.2, 0.4, 0.8)
    means = []
    for s in scales:
        _, v = engine.project(model, _away(human, s, rng) if s else human, "relaxed")
        c = np.asarray(confidence(v))
        assert ((c >= 0) & (c <= 1)).all()
        means.append(float(c.mean()))
    assert means[0] > 0.9  # at a landmark the candidate back-projects onto the query
    assert all(a > b for a, b in zip(means, means[1:], strict=False)), means
    assert means[-1] < LOW_CONFIDENCE  # far from every landmark: low confidence


def test_confidence_formula():
    v = np.array([0.0, DEVIATION_SCALE, 2 * DEVIATION_SCALE, np.inf, np.nan], np.float32)
    np.testing.assert_allclose(
        np.asarray(confidence(v)), [1.0, np.exp(-1), np.exp(-2), 0.0, 0.0], rtol=1e-6
    )


def test_rescale_is_the_confidence_on_another_scale():
    v = np.array([0.0, 0.05, 0.3, 1.2, np.inf], np.float32)
    np.testing.assert_allclose(
        np.asarray(rescale(confidence(v, 0.174), 0.174, 0.5)),
        np.asarray(confidence(v, 0.5)),
        rtol=1e-5,
        atol=1e-7,
    )


def test_a_model_keeps_its_own_scale_and_an_old_file_falls_back(setup, tmp_path):
    model, human = setup
    assert model.deviation_scale is None  # from_landmarks: not calibrated
    assert model.confidence_scale == DEVIATION_SCALE  # the NAO's robot scale
    own = dataclasses.replace(model, deviation_scale=0.5)
    assert own.confidence_scale == 0.5
    engine.save(own, tmp_path / "own.npz")
    assert engine.load(tmp_path / "own.npz").deviation_scale == 0.5
    # a file written before models were calibrated: no scale in its metadata
    with np.load(tmp_path / "own.npz") as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["deviation_scale"]
    np.savez(tmp_path / "old.npz", **{**arrays, "meta": np.array(json.dumps(meta))})
    old = engine.load(tmp_path / "old.npz")
    assert old.deviation_scale is None and old.confidence_scale == DEVIATION_SCALE
    # retarget reads the confidence on the model's scale
    rec = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    a = retarget(rec.positions, rec.valid, model=model).confidence
    b = retarget(rec.positions, rec.valid, model=own).confidence
    np.testing.assert_allclose(b, np.asarray(rescale(a, DEVIATION_SCALE, 0.5)), rtol=1e-5)


def test_a_model_is_calibrated_on_its_own_training_frames(setup):
    model, human = setup
    own = engine.calibrated(model, human)
    rows = np.linspace(0, len(human) - 1, min(CALIBRATION_FRAMES, len(human))).round()
    _, v = engine.project(model, human[rows.astype(int)], "relaxed", n_l=10, n_m=10)
    want = float(np.percentile(np.asarray(v), 90)) * HELD_OUT_RATIO
    assert own.deviation_scale == pytest.approx(want, rel=1e-5)
    assert own.confidence_scale == own.deviation_scale
