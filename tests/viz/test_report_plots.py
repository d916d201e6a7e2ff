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


def test_retarget_plot_draws_the_g1_in_its_own_colours(monkeypatch, tmp_path):
    """`retarget --plot` for any robot: the G1's key frames are its figure's links (sites of
    its MJCF), left limbs orange and right limbs blue, one row of angles per chain. (The
    person's side is the CLI's test: here its points are drawn as given, the figure not saved.)"""
    from jaxproj import robots
    from jaxproj.viz.panels import LEFT_COLOR, RIGHT_COLOR

    figures = []
    monkeypatch.setattr(report, "_save", lambda plt, fig, path: figures.append(fig))
    monkeypatch.setattr(report, "human_points", lambda p: p)

    g1 = robots.get("unitree_g1")
    n = 6
    q = np.tile(g1.standing[g1.driven_index], (n, 1)).astype(np.float32)
    q[:, g1.driven_joints.index("left_shoulder_pitch_joint")] = np.linspace(0.0, -1.5, n)
    pos = np.zeros((n, 20, 3), np.float32)
    report.plot_retarget(tmp_path / "g1.png", "G1", pos, np.ones(n, bool), np.arange(n) / 30.0,
                         q, q, label="ik", key_frames=2, robot=g1)  # fmt: skip
    (fig,) = figures
    assert len(fig.axes) == 2 * 2 * 2 + len(g1.chains)  # (human, robot) x views x frames
    robot_ax = fig.axes[1]
    assert "G1" in robot_ax.get_title()
    colours = {tuple(np.round(line.get_color(), 2)) for line in robot_ax.get_lines()}
    assert {tuple(np.round(LEFT_COLOR, 2)), tuple(np.round(RIGHT_COLOR, 2))} <= colours
    assert len(robot_ax.get_lines()) >= 2 * len(g1.mjcf.figure.links)  # output and IK
    import matplotlib.pyplot as plt

    plt.close(fig)
