"""The report's Markdown tables of per-method error blocks
(``jaxproj.eval.metrics.summarize_errors``), re-exported by ``jaxproj.viz.report``."""

from __future__ import annotations


def summary_table(summary: dict, methods: list[str] | None = None) -> str:
    """Markdown table of ``summary.<method>.<M_avg|M_max>.<stat>``."""
    methods = methods or list(summary)
    lines = [
        "| method | M_avg median | M_avg mean | M_avg p95 | M_max median | M_max p95 | M_max max |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for m in methods:
        a, x = summary[m]["M_avg"], summary[m]["M_max"]
        lines.append(
            f"| {m} | {a['median']:.2f} | {a['mean']:.2f} | {a['p95']:.2f} | "
            f"{x['median']:.2f} | {x['p95']:.2f} | {x['max']:.1f} |"
        )
    return "\n".join(lines)


def _mp(d: dict, digits: int = 1) -> str:
    """``"median / p95"`` of a ``describe`` dict."""
    return f"{d['median']:.{digits}f} / {d['p95']:.{digits}f}"


def where_error_table(summary: dict, methods: list[str] | None = None) -> str:
    """Markdown table: where each method's error is.

    Per method: p95 of M_max with and without the two ElbowYaw joints (deg), then per arm
    (L / R) the hand (wrist point) and elbow position errors (cm) and the upper-arm and forearm
    direction errors (deg) as ``median / p95``; from ``summary.<method>`` blocks of
    ``jaxproj.eval.metrics.summarize_errors``.
    """
    methods = methods or list(summary)
    lines = [
        "| method | M_max p95 | M_max p95 without ElbowYaw | hand L (cm) | hand R (cm) "
        "| elbow L (cm) | elbow R (cm) | upper arm L (deg) | upper arm R (deg) "
        "| forearm L (deg) | forearm R (deg) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for m in methods:
        b = summary[m]
        ts = b["task_space"]
        cells = [f"{b['M_max']['p95']:.1f}", f"{b['M_max_no_elbow_yaw']['p95']:.1f}"]
        for key, digits in (("hand_cm", 2), ("elbow_cm", 2), ("upper_arm_deg", 1),
                            ("forearm_deg", 1)):  # fmt: skip
            cells += [_mp(ts["left"][key], digits), _mp(ts["right"][key], digits)]
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def per_joint_table(summary: dict, methods: list[str] | None = None) -> str:
    """Markdown table: ``p50 / p95`` error (deg) per driven joint (rows, the robot's driven
    joints in the order of the blocks' ``per_joint``) and method (columns)."""
    methods = methods or list(summary)
    lines = [
        "| joint | " + " | ".join(methods) + " |",
        "|---|" + "---:|" * len(methods),
    ]
    for j in summary[methods[0]]["per_joint"]:
        cells = [
            f"{summary[m]['per_joint'][j]['p50']:.1f} / {summary[m]['per_joint'][j]['p95']:.1f}"
            for m in methods
        ]
        lines.append(f"| {j} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
