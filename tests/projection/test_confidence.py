"""The per-frame confidence (jaxproj.projection.confidence) falls off away from the landmarks."""

import numpy as np
import pytest

from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.confidence import DEVIATION_SCALE, LOW_CONFIDENCE, confidence
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
