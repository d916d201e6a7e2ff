"""The figures the docs quote are the committed result files' (``benchmarks/results/*.json``).

Each row: a page, a pattern whose group is the quoted figure, a result file, how to read the
number from it, and how the page writes it. A re-measured result file (or an edited page) that
no longer agrees fails here, so a figure cannot go stale unseen. No computation: JSON reads.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"


def _us(poses_per_s: float) -> float:
    return 1e6 / poses_per_s


G1_H100 = "g1_time_split_h100.json"
G1_H200 = "robot_thesis_g1_msr_h200.json"
G1_CPU_NOW = "robot_thesis_g1_msr_cpu.json"

NUMBERS: list[tuple[str, str, str, Callable[[dict], float], str]] = [
    # (page, pattern with the figure as group 1, result file, reader, format)
    ("docs/index.md", r"(\d+)x on an H200 \(relaxed", G1_H200,
     lambda r: r["speed"]["ik"]["us_per_pose"] / r["speed"]["relaxed"]["us_per_pose"], "{:.0f}"),
    ("docs/index.md", r"relaxed, ([\d.]+) vs [\d.]+ us per pose", G1_H200,
     lambda r: r["speed"]["relaxed"]["us_per_pose"], "{:.2f}"),
    ("docs/index.md", r"relaxed, [\d.]+ vs ([\d.]+) us per pose", G1_H200,
     lambda r: r["speed"]["ik"]["us_per_pose"], "{:.1f}"),
    ("docs/index.md", r"([\d.]+)x with `separate`", G1_H200,
     lambda r: r["speed"]["ik"]["us_per_pose"] / r["speed"]["relaxed_separated"]["us_per_pose"],
     "{:.1f}"),
    ("docs/index.md", r"median M_avg ([\d.]+) deg against it", G1_H200,
     lambda r: r["msr_held_out"]["relaxed"]["vs_ik_M_avg_median"], "{:.2f}"),
    ("docs/results.md", r"vs the IK: median M_avg \| \*\*([\d.]+)\*\*", G1_H200,
     lambda r: r["msr_held_out"]["relaxed"]["vs_ik_M_avg_median"], "{:.2f}"),
    ("docs/results.md", r"against the IK's [\d.]+ us per pose \| \*\*([\d.]+)x\*\*", G1_H200,
     lambda r: r["speed"]["ik"]["us_per_pose"] / r["speed"]["relaxed"]["us_per_pose"], "{:.1f}"),
    ("docs/results.md", r"relaxed projection \*\*([\d.]+) us\*\* per pose", G1_H100,
     lambda r: r["projection"]["whole"]["us_per_pose"], "{:.2f}"),
    ("docs/results.md", r"collision-aware IK [\d.]+ us: \*\*([\d.]+)x\*\*", G1_H100,
     lambda r: r["ik"]["whole"]["us_per_pose"] / r["projection"]["whole"]["us_per_pose"], "{:.1f}"),
    ("docs/index.md", r"2-core CPU: ([\d.]+)x", G1_CPU_NOW,
     lambda r: r["speed"]["relaxed"]["poses_per_s"] / r["speed"]["ik"]["poses_per_s"], "{:.1f}"),
    ("docs/index.md", r"\(([\d,]+) vs [\d,]+ us per pose, same day\)", G1_CPU_NOW,
     lambda r: _us(r["speed"]["relaxed"]["poses_per_s"]), "{:,.0f}"),
    ("docs/index.md", r"\([\d,]+ vs ([\d,]+) us per pose, same day\)", G1_CPU_NOW,
     lambda r: _us(r["speed"]["ik"]["poses_per_s"]), "{:,.0f}"),
    ("docs/results.md", r"2-core VM: relaxed ([\d,]+) us per pose", G1_CPU_NOW,
     lambda r: _us(r["speed"]["relaxed"]["poses_per_s"]), "{:,.0f}"),
    ("docs/guide/cli.md", r"five chains, about ([\d,]+) landmarks each", G1_H100,
     lambda r: round(float(np.mean(list(r["landmarks"].values()))), -3), "{:,.0f}"),
    ("docs/results.md", r"--full-queries 8192` \| [\d.]+ M poses/s \| [\d.]+ M \S+ \| ([\d.]+)x",
     "multi_device_shard_map_nao_h200x2.json", lambda r: r["relaxed"]["speedup"], "{:.2f}"),
    ("docs/results.md", r"full --queries 4194304` \| [\d.]+ M \S+ \| [\d.]+ M \S+ \| ([\d.]+)x",
     "multi_device_shard_map_g1_h200x2.json", lambda r: r["relaxed"]["speedup"], "{:.2f}"),
    ("docs/results.md", r"\| back-projection \(`back_min`\) \| ([\d.]+) ms",
     "kernel_outside_jax_back_min_h200.json", lambda r: r["jax_median_ms"], "{:.2f}"),
    ("docs/results.md", r"\| k-NN, full scan \(`knn_full`\) \| ([\d.]+) ms",
     "kernel_outside_jax_knn_full_h200.json", lambda r: r["jax_median_ms"], "{:.2f}"),
]  # fmt: skip


def _text(page: str) -> str:
    text = (ROOT / page).read_text(encoding="utf-8")
    return re.sub(r"\s+", " ", text)  # a figure's words may wrap across lines


@pytest.mark.parametrize(("page", "pattern", "result", "read", "fmt"), NUMBERS)
def test_the_docs_quote_the_result_files(
    page: str, pattern: str, result: str, read: Callable[[dict], float], fmt: str
) -> None:
    found = re.findall(pattern, _text(page))
    assert found, f"{page}: no figure matches {pattern!r} (reworded? update this table)"
    want = fmt.format(read(json.loads((RESULTS / result).read_text(encoding="utf-8"))))
    assert all(x == want for x in found), f"{page} quotes {found} where {result} gives {want}"


def test_the_table_can_fail() -> None:
    """A quoted figure that differs from its file is caught (here: the 23x of 2026-11-28's run)."""
    page, pattern, result, read, fmt = NUMBERS[0]
    want = fmt.format(read(json.loads((RESULTS / result).read_text(encoding="utf-8"))))
    assert re.findall(pattern, "23x on an H200 (relaxed") == ["23"] != [want]


PLAYABLE_FILES = {
    "UTKinect s07 e01": "joints_s07_e01.txt",
    "UTKinect s07 e02": "joints_s07_e02.txt",
    "UTKinect s09 e01": "joints_s09_e01.txt",
    "UTKinect s09 e02": "joints_s09_e02.txt",
    "CMU 131_01": "131_01.bvh",
    "CMU 131_03": "131_03.bvh",
}


def _playable_rows(heading: str, page: str = "docs/results.md") -> dict[str, dict[str, str]]:
    """The first table after ``heading`` in ``page``: recording -> {column: cell}."""
    text = (ROOT / page).read_text(encoding="utf-8")
    lines = text[text.index(heading) :].split("\n| recording", 1)[1].splitlines()
    header = [c.strip() for c in ("| recording" + lines[0]).strip("|").split("|")]
    rows = {}
    for line in lines[2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        name = re.sub(r" \(.*\)$", "", cells[0])
        if name in PLAYABLE_FILES:
            rows[name] = dict(zip(header, cells, strict=True))
    return rows


PLAYABLE_COLUMNS: dict[str, Callable[[dict], str]] = {
    "flip steps": lambda r: str(r["flip_steps"]),
    "speed-limit catch-ups": lambda r: str(r["catch_up_steps"]),
    "steps > 90 deg": lambda r: str(r["steps_over_90"]),
    "contact frames": lambda r: str(r["contact_frames"]),
    "lean robot / person, deg": lambda r: (
        f"{r['lean_robot_median']:.1f} / {r['lean_person_median']:.1f}"
    ),
    "foot pitch robot / person, deg": lambda r: (
        f"{r['foot_pitch_robot_median']:.1f} / {r['foot_pitch_person_median']:.1f}"
    ),
    "arms median / p90, deg": lambda r: f"{r['arm_median']:.1f} / {r['arm_p90']:.1f}",
}
"""The columns of the G1 playable tables that quote the result file, and how."""


@pytest.mark.parametrize(
    ("heading", "result"),
    [
        ("## The Unitree G1's output as a G1 would play it", "g1_playable_ik_cpu.json"),
        ("With `--method relaxed --model G1.npz`", "g1_playable_relaxed_cpu.json"),
    ],
)
def test_the_g1_playable_tables_are_the_result_files(heading: str, result: str) -> None:
    """Every column of the results page's G1 playable tables that a result file holds (flip
    steps, speed-limit catch-ups, steps over 90 deg, contact frames, the lean, the foot pitch,
    the arms' median / p90), recording by recording."""
    rows = _playable_rows(heading)
    assert set(rows) == set(PLAYABLE_FILES), f"{heading}: rows {sorted(rows)}"
    got = json.loads((RESULTS / result).read_text(encoding="utf-8"))["rows"]
    by_file = {r["file"]: r for r in got}
    for name, cells in rows.items():
        r = by_file[PLAYABLE_FILES[name]]
        quoted = {k: read(r) for k, read in PLAYABLE_COLUMNS.items() if k in cells}
        assert len(quoted) >= 5, f"{heading}: columns {sorted(cells)}"
        page = {k: cells[k] for k in quoted}
        assert page == quoted, f"{result}, {name}: the page says {page}, the file {quoted}"


WHOLE_BODY_COLUMNS: dict[str, Callable[[dict], str]] = {
    "contact L / R": lambda r: " / ".join(f"{100 * x:.0f}" for x in r["contact_share"]) + " %",
    "sliding median / p95, cm/s": lambda r: (
        f"{r['slide_cm_s_median']:.2f} / {r['slide_cm_s_p95']:.2f}"
    ),
    "penetration, mm": lambda r: f"{r['penetration_mm']:.0f}",
    "root jump, cm": lambda r: f"{r['root_jump_cm']:.1f}",
    "trunk, deg": lambda r: f"{r['trunk_deg_median']:.1f}",
    "legs, deg": lambda r: f"{r['legs_deg_median']:.1f}",
    "self-contact frames": lambda r: str(r["contact_frames"]),
    "speed spikes": lambda r: str(r["speed_spikes"]),
    "fixed / whole-body retarget, s": lambda r: f"{r['fixed_s']:.1f} / {r['world_s']:.1f}",
}


def test_the_whole_body_table_is_the_result_file() -> None:
    """The whole-body guide's measured table, every column, recording by recording, against
    ``benchmarks/results/whole_body_cpu.json``."""
    rows = _playable_rows("## Measured", "docs/guide/whole-body.md")
    assert set(rows) == set(PLAYABLE_FILES), sorted(rows)
    got = json.loads((RESULTS / "whole_body_cpu.json").read_text(encoding="utf-8"))["rows"]
    by_file = {r["file"]: r for r in got}
    for name, cells in rows.items():
        quoted = {k: read(by_file[PLAYABLE_FILES[name]]) for k, read in WHOLE_BODY_COLUMNS.items()}
        page = {k: cells[k] for k in quoted}
        assert page == quoted, f"{name}: the page says {page}, the file {quoted}"
