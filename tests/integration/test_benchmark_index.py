"""``benchmarks/README.md`` indexes every benchmark script, and the result files it names exist.
No computation: it reads files."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"


def _scripts() -> set[str]:
    files = [*BENCH.glob("*.py"), *(BENCH / "experiments").glob("*.py")]
    return {
        ".".join(f.relative_to(ROOT).with_suffix("").parts)
        for f in files
        if f.name != "__init__.py"
    }


def test_every_benchmark_script_is_in_the_index() -> None:
    index = (BENCH / "README.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"^\| `(benchmarks\.[\w.]+)` \|", index, flags=re.MULTILINE))
    assert _scripts() - listed == set(), "add these to benchmarks/README.md"
    assert listed - _scripts() == set(), "these are gone: drop them from benchmarks/README.md"


def test_the_result_files_the_index_names_exist() -> None:
    index = (BENCH / "README.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`([\w.-]+\.(?:json|log))`", index))
    assert named, "the index names no result file"
    missing = sorted(n for n in named if not (BENCH / "results" / n).exists())
    assert missing == []
