"""Reports: ``report.json``, ``report.md`` with tables, and PNG plots (matplotlib, Agg backend).

Plots written by ``write_report``:

* ``motion_<name>.png`` — a sample motion: the human skeleton and the robot (projected and IK
  poses, from MuJoCo forward kinematics of its MJCF, drawn as ``robot.mjcf.figure`` says) side by
  side at a few frames, front and side
  views in the body / torso frame, and M_max / M_avg over time per method;
* ``error_distributions.png`` — cumulative distributions of M_avg and M_max per method;
* ``landmark_size.png`` — median M_avg and p95 M_max against the landmark count;
* ``efficiency.png`` — time per projection and accuracy against L = M (when measured);
* ``per_joint_error.png`` — p50 / p95 error per driven joint of the projection methods.

Tables (``jaxproj.viz.tables``, re-exported here): ``summary_table`` (the headline M_avg /
M_max), ``where_error_table`` (M_max with and without ElbowYaw, task-space errors per arm) and
``per_joint_table`` (p50 / p95 per driven joint), all from the per-method blocks of
``jaxproj.eval.metrics.summarize_errors``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from jaxproj._internal.atomic import atomic_write, check_output
from jaxproj.human.skeleton import BONES, J, body_frame
from jaxproj.robots import Robot
from jaxproj.viz.panels import kinematics, robot_label
from jaxproj.viz.tables import per_joint_table as per_joint_table  # re-exported
from jaxproj.viz.tables import summary_table as summary_table
from jaxproj.viz.tables import where_error_table as where_error_table

_COLORS = {
    "relaxed": "tab:blue",
    "full": "tab:orange",
    "nearest_landmark": "tab:gray",
    "knn_average": "tab:green",
    "global_elm": "tab:purple",
}


PROJECTION_METHODS: tuple[str, ...] = ("relaxed", "full")
"""The paper's projection objectives (``plot_per_joint`` shows these by default)."""


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(plt, fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def suptitle(fig: Any, title: str, margin: float = 0.02, fontsize: float | None = None) -> Any:
    """``fig.suptitle(title)``, wrapped at word breaks onto as many lines as it takes to fit the
    figure's width less ``margin`` (a fraction) on each side, measured on the figure's renderer
    (a long title, e.g. ``retarget --plot``'s file name and time source, was clipped at both
    edges). Returns the title's ``Text``."""
    import textwrap

    text = fig.suptitle(title) if fontsize is None else fig.suptitle(title, fontsize=fontsize)
    renderer = fig.canvas.get_renderer()
    room = fig.bbox.width * (1.0 - 2.0 * margin)
    width = len(title)
    while text.get_window_extent(renderer).width > room and width > 10:
        width = int(width * 0.9)
        text.set_text("\n".join(line for part in title.split("\n")
                                 for line in textwrap.wrap(part, width)))  # fmt: skip
    return text


def to_jsonable(obj: Any) -> Any:
    """Drop private keys (leading ``_``) and turn numpy values into plain Python."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items() if not str(k).startswith("_")}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def human_points(positions: np.ndarray) -> np.ndarray:
    """``(20, 3)`` camera-frame joints -> body frame (x fwd, y left, z up), hips at 0."""
    rot, _ = body_frame(positions[None])  # type: ignore[arg-type]  # a NumPy array is fine
    r = np.asarray(rot)[0]
    return (positions - positions[J["HipCenter"]]) @ r.T


def robot_points(robot: Robot, model: Any, angles: np.ndarray) -> dict[str, np.ndarray]:
    """The sketch's points (root frame, m) of one ``(n_joints,)`` configuration: the sites of
    ``robot.mjcf.figure.links`` and, with ``figure.head``, the head body's origin
    (``"head_root"``) and the head point (``"head"``)."""
    figure = robot.require_mjcf().figure
    names = tuple(dict.fromkeys(n for link in figure.links for n in link))
    fk = kinematics(robot, model, angles, names)
    out = dict(zip(names, fk.sites, strict=True))
    if figure.head is not None:
        body, length = figure.head
        b = model.body(body).id
        out["head_root"] = fk.bodies[b]
        out["head"] = fk.bodies[b] + length * fk.axes[b][:, 2]
    return out


def _side(name: str) -> tuple[float, float, float]:
    """The house colour rule (``viz.panels.side_color``, as ``render`` draws): left limbs
    orange, right limbs blue, the rest dark grey."""
    from jaxproj.viz.panels import side_color

    return side_color(name)


def _draw_human(ax, pts: np.ndarray, axes: tuple[int, int]) -> None:
    a, b = axes
    for p, c in BONES:
        i, j = J[p], J[c]
        ax.plot([pts[i, a], pts[j, a]], [pts[i, b], pts[j, b]], "-", color=_side(c), lw=2)
    ax.plot(pts[J["Head"], a], pts[J["Head"], b], "o", color=_side("Head"), ms=8)


def _draw_robot(
    ax: Any,
    links: tuple[tuple[str, str], ...],
    pts: dict[str, np.ndarray],
    axes: tuple[int, int],
    style: str,
) -> None:
    """One robot pose (``robot_points``): ``style`` ``"-"`` (the output, thick) or ``"--"``
    (the IK, thin)."""
    a, b = axes
    lw = 2.0 if style == "-" else 1.2
    for p, c in links:
        ax.plot([pts[p][a], pts[c][a]], [pts[p][b], pts[c][b]], style, color=_side(c), lw=lw)
    if "head" not in pts:
        return
    grey = _side("head")
    root, head = pts["head_root"], pts["head"]
    ax.plot([root[a], head[a]], [root[b], head[b]], style, color=grey)
    ax.plot(head[a], head[b], "o", color=grey, ms=8 if style == "-" else 5,
            fillstyle="full" if style == "-" else "none")  # fmt: skip


def _legend(fig: Any, label: str, name: str) -> None:
    """One legend for the figure's colour and line rule (``name``: the robot's)."""
    from matplotlib.lines import Line2D

    from jaxproj.viz.panels import LEFT_COLOR, RIGHT_COLOR

    handles = [
        Line2D([], [], color=LEFT_COLOR, lw=2, label="left limbs"),
        Line2D([], [], color=RIGHT_COLOR, lw=2, label="right limbs"),
        Line2D([], [], color="k", lw=2, ls="-", label=f"{name}: {label}"),
        Line2D([], [], color="k", lw=1.2, ls="--", label=f"{name}: per-frame IK"),
    ]
    fig.legend(handles=handles, loc="upper right", ncol=4, fontsize=8, frameon=False)


def _key_frames(
    fig: Any,
    grid: Any,
    picks: np.ndarray,
    when: list[str],
    positions: np.ndarray,
    angles: np.ndarray,
    ik_angles: np.ndarray,
    label: str,
    robot: Robot,
) -> None:
    """The top two rows of ``plot_motion`` / ``plot_retarget``: at each key frame ``picks[col]``
    (titled by ``when[col]``) the human (front and side view) and the robot playing ``angles``
    (solid, ``label``) over the per-frame IK ``ik_angles`` (dashed); left limbs orange, right
    limbs blue (``_side``), with one legend for the figure.

    Args:
      positions: ``(T, 20, 3)`` human joints, Kinect order.
      angles, ik_angles: ``(T, n_driven)`` radians, ``robot.driven_joints`` order.
    """
    model = robot.load_model("fixed")
    links = robot.require_mjcf().figure.links
    name = robot_label(robot)
    for col, t in enumerate(picks):
        hp = human_points(positions[t])
        out = robot_points(robot, model, np.asarray(robot.driven_to_full(angles[t])))
        ik_p = robot_points(robot, model, np.asarray(robot.driven_to_full(ik_angles[t])))
        for row, (axes, view) in enumerate((((1, 2), "front"), ((0, 2), "side"))):
            sub = grid[row, col].subgridspec(1, 2, wspace=0.05)
            ax_h, ax_r = fig.add_subplot(sub[0]), fig.add_subplot(sub[1])
            # front view: seen from in front, so the person's left (+y, orange) is on the
            # right; side view: seen from the person's right, forward (+x) to the right
            _draw_human(ax_h, hp, axes)
            _draw_robot(ax_r, links, ik_p, axes, "--")
            _draw_robot(ax_r, links, out, axes, "-")
            for ax in (ax_h, ax_r):
                ax.set_aspect("equal")
                ax.set_xticks([])
                ax.set_yticks([])
            ax_h.set_title(f"human, {when[col]} ({view})", fontsize=8)
            ax_r.set_title(f"{name}: {label} / IK (dashed)", fontsize=8)
    _legend(fig, label, name)


def plot_motion(
    path: Path,
    title: str,
    positions: np.ndarray,
    valid: np.ndarray,
    truth: np.ndarray,
    predictions: dict[str, np.ndarray],
    key_frames: int = 3,
    *,
    robot: Robot,
    overwrite: bool = True,
) -> None:
    """One motion: skeleton vs robot at a few frames, and the errors over time.

    Args:
      positions: ``(T, 20, 3)`` human joints; ``valid`` ``(T,)``.
      truth: ``(T, n_driven)`` IK angles (driven joints); ``predictions``: method ->
        ``(T, n_driven)``.
      robot: the robot the angles are for.
    """
    check_output(path, overwrite=overwrite)
    plt = _plt()
    frames = np.flatnonzero(valid)
    picks = frames[np.linspace(0, len(frames) - 1, key_frames).round().astype(int)]
    fig = plt.figure(figsize=(4.0 * key_frames, 9.5))
    grid = fig.add_gridspec(3, key_frames, height_ratios=[1.0, 1.0, 0.9])
    method = "relaxed" if "relaxed" in predictions else next(iter(predictions))
    when = [f"frame {t}" for t in picks]
    _key_frames(fig, grid, picks, when, positions, predictions[method], truth, method, robot)
    ax = fig.add_subplot(grid[2, :])
    for name, pred in predictions.items():
        err = np.degrees(np.abs(pred - truth))
        e_max = np.where(valid, err.max(axis=1), np.nan)
        e_avg = np.where(valid, err.mean(axis=1), np.nan)
        c = _COLORS.get(name, None)
        ax.plot(e_max, "--", color=c, lw=1, label=f"{name} M_max")
        ax.plot(e_avg, "-", color=c, lw=2, label=f"{name} M_avg")
    for t in picks:
        ax.axvline(t, color="k", lw=0.5, alpha=0.4)
    ax.set_xlabel("frame (15 fps)")
    ax.set_ylabel("error vs IK (deg)")
    ax.legend(fontsize=7, ncol=3)
    ax.grid(alpha=0.3)
    suptitle(fig, title)
    _save(plt, fig, path)


def _gaps(times: np.ndarray) -> np.ndarray:
    """Indices ``i`` where the step ``times[i] - times[i - 1]`` is a tracker gap (more than 3x
    the median step): a line must not be drawn across it."""
    steps = np.diff(np.asarray(times, np.float64))
    if steps.size == 0:
        return np.zeros(0, np.int64)
    return np.flatnonzero(steps > 3.0 * np.median(steps)) + 1


def _gapped(x: np.ndarray, cut: np.ndarray) -> np.ndarray:
    """``x`` with a NaN inserted before each index of ``cut`` (matplotlib breaks the line)."""
    return np.insert(np.asarray(x, np.float64), cut, np.nan)


def plot_retarget(
    path: Path,
    title: str,
    positions: np.ndarray,
    valid: np.ndarray,
    times: np.ndarray,
    angles: np.ndarray,
    ik_angles: np.ndarray,
    label: str = "output",
    key_frames: int = 4,
    *,
    robot: Robot,
    overwrite: bool = True,
) -> None:
    """One retargeted recording (``jaxproj retarget --plot``): the figure of ``plot_motion`` with
    the joint angles over time instead of the errors.

    Top rows: the human (body frame, front and side view) and the robot playing ``angles``
    (solid) and the per-frame IK (dashed) at ``key_frames`` frames spread over the valid ones;
    left limbs orange, right limbs blue, as ``render`` draws them, with a legend. Bottom: the
    driven joints over time, one row per chain of ``robot.chains`` (the default robot's: head /
    left arm / right arm), ``angles`` solid and the IK dashed
    (not drawn at invalid frames); no line across a tracker gap (a step over 3x the median).

    Args:
      positions: ``(T, 20, 3)`` human joints, Kinect order; ``valid`` ``(T,)``; ``times``
        ``(T,)`` seconds.
      angles, ik_angles: ``(T, n_driven)`` radians, ``robot.driven_joints`` order.
      robot: the robot the angles are for.
    """
    check_output(path, overwrite=overwrite)
    plt = _plt()
    frames = np.flatnonzero(valid)
    if frames.size == 0:
        frames = np.arange(len(valid))
    picks = frames[np.linspace(0, len(frames) - 1, key_frames).round().astype(int)]
    fig = plt.figure(figsize=(3.6 * key_frames, 14.0))
    chains = robot.chains
    grid = fig.add_gridspec(2 + len(chains), key_frames,
                            height_ratios=[1.0, 1.0, *(0.7 for _ in chains)])  # fmt: skip
    when = [f"{times[t]:.2f} s" for t in picks]
    _key_frames(fig, grid, picks, when, positions, angles, ik_angles, label, robot)
    cut = _gaps(times)
    t_gap = _gapped(np.asarray(times, np.float64), cut)
    for row, chain in enumerate(chains, start=2):
        ax = fig.add_subplot(grid[row, :])
        name = chain.name.replace("_", " ")
        for k, i in enumerate(robot.chain_joints(chain)):
            c = f"C{k}"
            ax.plot(t_gap, _gapped(np.degrees(angles[:, i]), cut), "-", color=c, lw=1.5,
                    label=robot.driven_joints[i])  # fmt: skip
            ik_deg = np.where(valid, np.degrees(ik_angles[:, i]), np.nan)  # no IK where invalid
            ax.plot(t_gap, _gapped(ik_deg, cut), "--", color=c, lw=0.8, alpha=0.7)
        for t in picks:
            ax.axvline(times[t], color="k", lw=0.5, alpha=0.4)
        ax.set_ylabel(f"{name} (deg)")
        ax.legend(fontsize=7, ncol=4, loc="upper right")
        ax.grid(alpha=0.3)
    ax.set_xlabel(f"time (s); solid: {label}, dashed: per-frame IK")
    suptitle(fig, title)
    _save(plt, fig, path)


def plot_distributions(
    path: Path,
    predictions: dict[str, np.ndarray],
    truth: np.ndarray,
    title: str = "Error distributions on held-out subjects (valid frames)",
    *,
    overwrite: bool = True,
) -> None:
    """CDFs of M_avg and M_max per method on a logarithmic error axis (one scale over its whole
    range: no kink where a symlog axis turns linear); ``predictions[m]`` and ``truth``:
    ``(F, 10)``. Frames with an error of exactly 0 count in the fraction but have no place on a
    log axis (the curve starts at the smallest non-zero error). ``overwrite``: ``write_text``'s."""
    check_output(path, overwrite=overwrite)
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for name, pred in predictions.items():
        err = np.degrees(np.abs(pred - truth))
        for ax, vals in zip(axes, (err.mean(axis=1), err.max(axis=1)), strict=True):
            v = np.sort(vals)
            ax.plot(v, np.arange(1, len(v) + 1) / len(v), color=_COLORS.get(name), label=name)
    for ax, label in zip(axes, ("M_avg (deg, log scale)", "M_max (deg, log scale)"), strict=True):
        ax.set_xlabel(label)
        ax.set_ylabel("fraction of frames")
        ax.set_xscale("log")
        ax.set_ylim(0.0, 1.0)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    suptitle(fig, title)
    _save(plt, fig, path)


def _size_label(row: dict) -> str:
    """A landmark-size row's target, in words."""
    return "default" if row.get("target") is None else str(row["target"])


def plot_landmark_size(
    path: Path, study: dict, title: str | None = None, *, overwrite: bool = True
) -> None:
    """``study``: ``{"sizes": [{"landmarks": K, "M_avg_median": .., "M_max_p95": ..}, ...]}``
    (``experiments.landmark_size_study``: ``landmarks`` is the mean of the two arm chains of a
    per-chain model, the x axis says so; each point is labelled by its target, ``default`` for
    the row of ``target`` ``None``)."""
    check_output(path, overwrite=overwrite)
    plt = _plt()
    rows = sorted(study["sizes"], key=lambda r: r["landmarks"])
    k = [r["landmarks"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(k, [r["M_avg_median"] for r in rows], "o-", label="median M_avg")
    ax.plot(k, [r["M_max_p95"] for r in rows], "s--", label="p95 M_max")
    if "pose8_M_max" in rows[0]:
        ax.plot(k, [r["pose8_M_max"] for r in rows], "^:", label="POSE_8 motion, max M_max")
    for r in rows:
        if "target" in r:
            ax.annotate(
                f"target {_size_label(r)}", (r["landmarks"], r["M_avg_median"]),
                textcoords="offset points", xytext=(0, 6), ha="center", fontsize=7,
            )  # fmt: skip
    ax.set_xscale("log")
    per_chain = "left_arm" in rows[0].get("landmarks_per_chain", {})
    ax.set_xlabel("landmarks per arm chain (mean of left and right)" if per_chain else "landmarks")
    ax.set_ylabel("error vs IK (deg)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend()
    suptitle(fig, title or "Landmark-set size (relaxed, held-out subjects)", fontsize=10)
    _save(plt, fig, path)


def plot_efficiency(
    path: Path, study: dict, title: str | None = None, *, overwrite: bool = True
) -> None:
    """``study``: ``{"rows": [{"L": .., "batch": .., "us_per_projection": ..,
    "M_avg_median": ..}, ...]}`` (``experiments.efficiency_study``). Both axes start at 0, so
    that a change of a few hundredths of a degree is drawn as the flat line it is; the batch
    size of the timed calls is in the title when every point shares it, else at each point."""
    check_output(path, overwrite=overwrite)
    plt = _plt()
    rows = study["rows"]
    fig, ax = plt.subplots(figsize=(6, 4))
    ls = [r["L"] for r in rows]
    us = [r["us_per_projection"] for r in rows]
    acc = [r["M_avg_median"] for r in rows]
    ax.plot(ls, us, "o-", color="tab:blue")
    ax.set_xlabel("L = M")
    ax.set_ylabel("us per projection", color="tab:blue")
    ax.set_ylim(0.0, 1.15 * max(us))
    ax2 = ax.twinx()
    ax2.plot(ls, acc, "s--", color="tab:orange")
    ax2.set_ylabel("median M_avg (deg)", color="tab:orange")
    ax2.set_ylim(0.0, 1.5 * max(acc) if max(acc) > 0 else 1.0)
    batches = sorted({int(r["batch"]) for r in rows if "batch" in r})
    if len(batches) > 1:
        for r in rows:
            ax.annotate(
                f"batch {r['batch']}", (r["L"], r["us_per_projection"]),
                textcoords="offset points", xytext=(0, 6), ha="center", fontsize=7,
            )  # fmt: skip
    ax.grid(alpha=0.3)
    head = title or f"Efficiency vs neighbourhood size ({study.get('device', '')})"
    batch = f"\nbatch {batches[0]} per timed call" if len(batches) == 1 else ""
    suptitle(fig, head + batch, fontsize=10)
    _save(plt, fig, path)


def plot_per_joint(
    path: Path, summary: dict, methods: list[str] | None = None, *, overwrite: bool = True
) -> None:
    """Bars of the p50 (solid) and p95 (light) error per driven joint, one group per joint.

    Args:
      summary: ``{method: block}`` with ``block["per_joint"][joint]["p50" | "p95"]`` in degrees
        (``jaxproj.eval.metrics.summarize_errors``), e.g. ``evaluate``'s ``summary``.
      methods: which methods; default the projection methods present (``PROJECTION_METHODS``),
        else every method of ``summary``.
    """
    check_output(path, overwrite=overwrite)
    methods = methods or [m for m in PROJECTION_METHODS if m in summary] or list(summary)
    plt = _plt()
    joints = list(summary[methods[0]]["per_joint"])  # the robot's driven joints, in order
    x = np.arange(len(joints), dtype=np.float64)
    width = 0.8 / len(methods)
    fig, ax = plt.subplots(figsize=(11, 4))
    for i, m in enumerate(methods):
        pj = summary[m]["per_joint"]
        pos = x - 0.4 + (i + 0.5) * width
        c = _COLORS.get(m)
        ax.bar(pos, [pj[j]["p95"] for j in joints], width, color=c, alpha=0.35,
               label=f"{m} p95")  # fmt: skip
        ax.bar(pos, [pj[j]["p50"] for j in joints], width * 0.6, color=c, label=f"{m} p50")
    ax.set_xticks(x)
    ax.set_xticklabels(joints, rotation=30, ha="right")
    ax.set_ylabel("|error| vs IK (deg)")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8, ncol=len(methods))
    ax.set_title("Error per driven joint (valid frames): median and 95th percentile")
    _save(plt, fig, path)


def write_json(path: Path, report: dict, *, overwrite: bool = True) -> None:
    """Write ``report`` (private keys dropped) as indented JSON, atomically (``write_text``)."""
    write_text(path, json.dumps(to_jsonable(report), indent=2) + "\n", overwrite=overwrite)


def write_text(path: Path, text: str, *, overwrite: bool = True) -> None:
    """Write a report file atomically: a temporary file beside ``path``, then renamed, so a
    failed or interrupted write never leaves a half-written report (``InputError`` when the
    file cannot be written). ``overwrite=False``: an existing file is a ConfigError, here and
    in every ``plot_*`` (checked before drawing); default ``True``, replace it."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    atomic_write(path, write, overwrite=overwrite)
