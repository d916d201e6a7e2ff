"""The demo report's plots draw what their numbers say (jaxproj.viz.report): no false kink, no
noise drawn as a large V, no clipped title, axes that say what they count."""

import numpy as np
import pytest

from jaxproj.viz import report


@pytest.fixture
def figures(monkeypatch):
    """The figures the plot functions would save, kept open for inspection."""
    kept = []

    def keep(plt, fig, path):
        fig.tight_layout()
        fig.canvas.draw()
        kept.append(fig)

    monkeypatch.setattr(report, "_save", keep)
    yield kept
    import matplotlib.pyplot as plt

    for fig in kept:
        plt.close(fig)


def _inside(fig, text) -> bool:
    box = text.get_window_extent(fig.canvas.get_renderer())
    return box.x0 >= 0 and box.x1 <= fig.bbox.width


def test_distributions_on_one_log_scale(figures, tmp_path):
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(200, 10))
    preds = {"relaxed": truth + rng.normal(scale=0.01, size=truth.shape), "nearest_landmark": truth}
    report.plot_distributions(tmp_path / "d.png", preds, truth, title="held out (200 frames)")
    (fig,) = figures
    for ax in fig.axes:
        # one scale over the whole range: a symlog axis turned linear at 1 deg (a false kink)
        assert ax.get_xscale() == "log" and "log scale" in ax.get_xlabel()
    assert fig._suptitle.get_text() == "held out (200 frames)"


def test_efficiency_axes_start_at_zero_and_say_the_batch(figures, tmp_path):
    rows = [
        {"L": 10, "batch": 64, "us_per_projection": 300.0, "M_avg_median": 1.1875},
        {"L": 20, "batch": 64, "us_per_projection": 900.0, "M_avg_median": 1.170},
        {"L": 50, "batch": 64, "us_per_projection": 5000.0, "M_avg_median": 1.18},
    ]
    report.plot_efficiency(tmp_path / "e.png", {"rows": rows, "device": "cpu:0"})
    (fig,) = figures
    ax, ax2 = fig.axes
    assert ax.get_ylim()[0] == 0.0 and ax2.get_ylim()[0] == 0.0
    # 0.02 deg of noise is a sliver of the accuracy axis, not a V spanning it
    lo, hi = ax2.get_ylim()
    assert (1.1875 - 1.170) / (hi - lo) < 0.02
    assert "batch 64 per timed call" in fig._suptitle.get_text()
    # different batches: each point says its own
    rows[2] = {**rows[2], "batch": 16}
    report.plot_efficiency(tmp_path / "e2.png", {"rows": rows, "device": "cpu:0"})
    notes = [t.get_text() for t in figures[1].axes[0].texts]
    assert notes == ["batch 64", "batch 64", "batch 16"]
    assert "per timed call" not in figures[1]._suptitle.get_text()


def test_landmark_size_axis_says_what_it_counts(figures, tmp_path):
    rows = [
        {"target": t, "landmarks": k, "landmarks_per_chain": {"head": 799, "left_arm": k,
         "right_arm": k}, "M_avg_median": e, "M_max_p95": 20.0}
        for t, k, e in ((86, 86, 3.0), (1644, 1690, 0.9), (None, 5384, 0.33))
    ]  # fmt: skip
    report.plot_landmark_size(tmp_path / "s.png", {"sizes": rows})
    (fig,) = figures
    ax = fig.axes[0]
    assert ax.get_xlabel() == "landmarks per arm chain (mean of left and right)"
    assert [t.get_text() for t in ax.texts] == ["target 86", "target 1644", "target default"]


def test_long_titles_are_wrapped_inside_the_figure(figures):
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(6, 3))
    figures.append(fig)
    title = (
        "joints_s03_e01_a_rather_long_recording_name.txt: relaxed, 742 frames over 132.0 s "
        "(frame numbers at 30 fps, gaps kept; 5.62 frames/s on average)"
    )
    text = report.suptitle(fig, title)
    assert text.get_text().count("\n") >= 1 and _inside(fig, text)
    assert text.get_text().replace("\n", " ") == title  # wrapped at spaces, nothing lost
    short = report.suptitle(fig, "short")
    assert short.get_text() == "short"
