"""Notebooks run top to bottom, and what they produce holds up."""

from __future__ import annotations

import runpy
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib.image
import matplotlib.pyplot as plt
import numpy as np
import pytest

from jaxproj import engine, evaluate, robot

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.py"))
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _check_png(path: Path, fig: Any, dpi: int) -> None:
    """``path`` is a PNG of ``fig`` saved at ``dpi``, with a plot on it (not a blank canvas)."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR", "not a PNG file"
    width, height = struct.unpack(">II", data[16:24])
    want = np.round(fig.get_size_inches() * dpi).astype(int)
    assert (width, height) == tuple(want), (width, height, want)
    pixels = matplotlib.image.imread(path)  # also checks the whole file decodes
    assert pixels.shape[:2] == (height, width)
    colours = np.unique(pixels.reshape(-1, pixels.shape[-1]), axis=0)
    assert len(colours) > 16, "the figure is (nearly) blank"


def _check_quickstart(g: dict[str, Any], tmp_path: Path) -> None:
    """The quick start's projections, errors and model (its globals after the run)."""
    d, ok, truth, model = g["d"], g["ok"], g["truth"], g["model"]
    assert ok.sum() > 0 and truth.shape == (len(d), len(robot.DRIVEN_JOINTS))
    lo, hi = robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX]
    # a trivial answer to beat: the mean robot pose of the landmarks (each chain's own), for
    # every frame
    sp = model.projector
    mean = np.zeros(len(robot.DRIVEN_JOINTS))
    for c, joints in enumerate(sp.layout.outputs):
        mean[list(joints)] = np.asarray(sp.chain(c).robot).mean(axis=0)
    mean_pose = np.broadcast_to(mean, truth.shape)
    baseline = np.median(evaluate.frame_errors(mean_pose[ok], truth[ok])[1])
    saved = tmp_path / "model.npz"
    engine.save(model, saved)
    reloaded = engine.load(saved)
    assert set(g["projections"]) == set(g["results"]) == set(g["errors"]) == {"relaxed", "full"}
    for objective, r in g["projections"].items():
        assert r.shape == truth.shape and r.dtype == np.float32
        assert np.isfinite(r[ok]).all()
        assert ((r[ok] >= lo) & (r[ok] <= hi)).all(), f"{objective}: outside the joint limits"
        # the saved model projects exactly what the notebook's model projected
        again, _ = engine.project(reloaded, d, objective)
        np.testing.assert_array_equal(again, r, err_msg=objective)
        smooth = g["results"][objective]
        assert smooth.shape == r.shape and np.isfinite(smooth[ok]).all()
        m_max, m_avg = g["errors"][objective]
        want_max, want_avg = evaluate.frame_errors(smooth[ok], truth[ok])
        np.testing.assert_array_equal(m_max, want_max)
        np.testing.assert_array_equal(m_avg, want_avg)
        # a held-out person: not a copy of the ground truth, and better than the trivial answer
        # (measured: median M_avg 10.3 / 13.6 deg relaxed / full, trivial 32.9 deg)
        assert 0.0 < np.median(m_avg) < baseline, (objective, np.median(m_avg), baseline)


RESULT_CHECKS: dict[str, Callable[[dict[str, Any], Path], None]] = {
    "quickstart.py": _check_quickstart,
}
"""Every notebook's own checks of its results (a new notebook needs an entry)."""


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs_and_its_results_hold(
    path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "figure.png"
    monkeypatch.setenv("JAXPROJ_NOTEBOOK_OUT", str(out))
    g = runpy.run_path(str(path), run_name="__main__")
    try:
        _check_png(out, g["fig"], dpi=80)  # the notebooks save their figure at dpi=80
        RESULT_CHECKS[path.name](g, tmp_path)
    finally:
        plt.close("all")
