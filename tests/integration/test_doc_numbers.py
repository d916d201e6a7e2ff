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
REPORT = "jaxproj/paper/demo_report.py"


def _us(poses_per_s: float) -> float:
    return 1e6 / poses_per_s


G1_CPU = "robot_thesis_g1_cpu.json"
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
    ("docs/results.md", r"against the IK's 27.1 us per pose \| \*\*([\d.]+)x\*\*", G1_H200,
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
    (REPORT, r"took (\d+) s to build", G1_CPU, lambda r: r["model_build_s"], "{:.0f}"),
    (REPORT, r"answers \"?\s*\"?(\d+) poses/s", G1_CPU,
     lambda r: r["speed"]["ik"]["poses_per_s"], "{:.0f}"),
    (REPORT, r"after a (\d+)-s first call", G1_CPU,
     lambda r: r["speed"]["ik"]["first_call_s"], "{:.0f}"),
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
    """A quoted figure that differs from its file is caught (here: the 14x of the H100 run)."""
    page, pattern, result, read, fmt = NUMBERS[0]
    want = fmt.format(read(json.loads((RESULTS / result).read_text(encoding="utf-8"))))
    assert re.findall(pattern, "14x on an H200 (relaxed") == ["14"] != [want]
