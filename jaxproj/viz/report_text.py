"""The demo report's prose: the words around its tables (``jaxproj.paper.demo``), kept apart
from the figures and tables of ``jaxproj.viz.report``."""

from __future__ import annotations


def smoother_label(settings: dict | None) -> str:
    """Words for ``evaluate``'s ``"smoothing"`` block."""
    if not settings:
        return "no smoother"
    if settings.get("kind") == "offline":
        return (f"zero-lag offline RTS smoother, accel_std {settings['accel_std']:g}, "
                f"noise_std {settings['noise_std']:g}")  # fmt: skip
    return (f"the paper's causal smoother, alpha {settings['alpha']:g}, gamma "
            f"{settings['gamma']:g}, eta {settings['eta']:g}")  # fmt: skip


def confidence_md(blocks: dict, caption: str = "") -> list[str]:
    """Markdown: error against the per-frame confidence by decile, per projection objective
    (``evaluate``'s ``"confidence"`` blocks), ``caption`` (a line) above the table; ``[]``
    without any block."""
    if not blocks:
        return []
    lines = [
        "",
        "## Confidence: which frames to distrust",
        "",
        "Each frame's confidence (`jaxproj.projection.confidence`: exp(-deviation / 0.174), "
        "from the projection's least back-projection deviation) against its unsmoothed error, "
        "the held-out frames in ten equal groups from the least confident. `low` = frames "
        "below exp(-1), the least trusted tenth of training people's frames on models that "
        "never saw them.",
        "",
        *([caption, ""] if caption else []),
        "| method | decile | confidence up to | median M_max | p95 M_max | share M_max > 30 |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for method, b in blocks.items():
        for i, d in enumerate(b["deciles"]):
            lines.append(
                f"| {method} | {i + 1} | {d['confidence_max']:.2f} | {d['M_max_median']:.1f} | "
                f"{d['M_max_p95']:.1f} | {100 * d['share_over']:.1f} % |"
            )
    for method, b in blocks.items():
        lines.append("")
        lines.append(
            f"{method}: {100 * b['low_share']:.1f} % of the frames are low-confidence and hold "
            f"{100 * b['low_recall']:.0f} % of the frames with M_max > {b['over_deg']:.0f} deg "
            f"({100 * b['share_over']:.1f} % of all frames)."
        )
    return lines


def pose_notes(bp: dict, objective: str = "relaxed") -> list[str]:
    """Markdown: what the basic-pose table means (``experiments.run_pose_experiments``'s
    ``bp``): for each pose over 10 deg, its worst joint and its M_max without the ElbowYaw
    joints, and why those differ."""
    rows, loose, far = [], 0, []
    for pose, res in bp["poses"].items():
        err = res[objective]["joint_errors_deg"]
        if res[objective]["M_max"] <= 10.0:
            continue
        worst = max(err, key=err.get)
        rest = max((v for j, v in err.items() if "ElbowYaw" not in j), default=0.0)
        loose += "ElbowYaw" in worst
        if "ElbowYaw" not in worst:
            far.append(bp["coverage_deg"][pose]["pose"])
        near = bp["coverage_deg"][pose]["pose"]
        rows.append(f"{pose} {res[objective]['M_max']:.1f} deg at {worst}, {rest:.1f} without "
                    f"ElbowYaw (nearest landmark {near:.1f} deg)")  # fmt: skip
    if not rows:
        return ["", f"Every basic pose is within 10 deg ({objective})."]
    return [
        "",
        f"What the table means ({objective}): the poses over 10 deg are " + "; ".join(rows) + ". "
        f"In {loose} of {len(rows)} the worst joint is an ElbowYaw: the basic poses hold the arms "
        "nearly straight, where the IK's ElbowYaw turns the forearm about its own length and is "
        "set by round-off (or, in the motions, by the noise), so a projection that is right "
        "about the arm can be far from that angle; the error without ElbowYaw is the pose's "
        "real error. The motions' largest M_max is likewise one frame's worst joint, which is "
        "why it need not fall as landmarks are added (the landmark-size table's POSE_8 column: "
        "the mean M_avg is the steadier measure)." + _far_note(far),
    ]


def _far_note(far: list[float]) -> str:
    """The sentence on the poses whose worst joint is not an ElbowYaw: how far their nearest
    landmarks are (one value, or a range where they differ at the printed precision)."""
    if not far:
        return ""
    lo, hi = f"{min(far):.0f}", f"{max(far):.0f}"
    span = lo if lo == hi else f"{lo}-{hi}"
    if len(far) == 1:
        return (f" The other one lies far from every landmark (its nearest {span} deg away: the "
                "training people never held that pose), where the kernels extrapolate: there "
                "the error is the projection's own.")  # fmt: skip
    return (f" The other {len(far)} lie far from every landmark (their nearest {span} deg away: "
            "the training people never held those poses), where the kernels extrapolate: there "
            "the error is the projection's own.")  # fmt: skip


def _cell(value: float | None, fmt: str) -> str:
    """A table cell: ``value`` formatted (no ``-0.00``: a value that prints as zero is zero),
    or ``n/a`` where there is none."""
    if value is None or value != value:
        return "n/a"
    text = format(value, fmt)
    return format(0.0, fmt) if float(text) == 0.0 else text


def smoothness_md(smoothness: dict) -> list[str]:
    """Markdown rows of the jerk / lag table (``evaluate``'s ``"smoothness"``): ``n/a`` where a
    row has no such value (the IK, the reference, is neither smoothed nor lagged against
    itself), never ``nan``."""
    rows = []
    for m, v in smoothness.items():
        cells = [
            _cell(v.get("jerk_raw"), ".3g"),
            _cell(v.get("jerk_smoothed"), ".3g"),
            _cell(v.get("lag_frames_raw"), "+.2f"),
            _cell(v.get("lag_frames_smoothed"), "+.2f"),
        ]
        label = "ik (the reference: its own jerk; not smoothed)" if m == "ik" else m
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return rows


def bandwidths(values: dict[str, float] | list[float], digits: int = 4) -> str:
    """Bandwidths at ``digits`` significant digits, ``head 0.01125 / left_arm 0.01875 / ...``
    (a dict) or ``0.01125 / 0.01875`` (a list), not 17 digits of float noise."""
    if isinstance(values, dict):
        return " / ".join(f"{k} {v:.{digits}g}" for k, v in values.items())
    return " / ".join(f"{v:.{digits}g}" for v in values)
