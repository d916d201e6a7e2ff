"""Where the test suite's time goes: XLA compiles and traces per test file and per jitted
function, recorded with ``jax.monitoring`` (a pytest plugin), then summed.

    python -m pytest -p benchmarks.experiments.compile_profile [pytest args]
    python -m benchmarks.experiments.compile_profile [--top 30]    # the summary

The plugin writes one JSON file per process (each xdist worker) to ``$JAXPROJ_COMPILE_PROFILE``
(default ``compile_profile/`` in the working directory): for every (test file, event, function)
the seconds and the count, for JAX's ``backend_compile_duration`` (an XLA compile, or a load
from the persistent cache) and ``jaxpr_trace_duration`` events. Child processes (the CLI and
notebook tests) are not recorded. Measured on the 2-core VM, 2026-11-24, the whole suite at
cbe523a: ~750 s of XLA compiles in ~1,560 worker-seconds; what it named (``elm.train_bank`` 86
compiles, ``ik.solve_driven`` 57, ``skeleton.descriptor`` thousands of eager op programs) led to
``jaxproj._internal.buckets``.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
from pathlib import Path
from typing import Any

EVENTS = ("backend_compile_duration", "jaxpr_trace_duration")


def _folder() -> Path:
    return Path(os.environ.get("JAXPROJ_COMPILE_PROFILE", "compile_profile"))


_totals: collections.Counter[tuple[str, str, str]] = collections.Counter()
_counts: collections.Counter[tuple[str, str, str]] = collections.Counter()
_current: list[str] = [""]


def _listen(event: str, duration: float, **kwargs: Any) -> None:
    name = event.rsplit("/", 1)[-1]
    if name in EVENTS and _current[0]:
        key = (_current[0], name, str(kwargs.get("fun_name", "?")))
        _totals[key] += duration
        _counts[key] += 1


def pytest_configure(config: Any) -> None:
    import jax

    jax.monitoring.register_event_duration_secs_listener(_listen)


def pytest_runtest_logstart(nodeid: str, location: Any) -> None:
    _current[0] = nodeid.split("::")[0]


def pytest_sessionfinish(session: Any) -> None:
    folder = _folder()
    folder.mkdir(parents=True, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    rows = [[*k, v, _counts[k]] for k, v in _totals.items()]
    (folder / f"{worker}.json").write_text(json.dumps(rows))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--top", type=int, default=30)
    args = ap.parse_args()
    rows = []
    for f in sorted(_folder().glob("*.json")):
        rows += json.loads(f.read_text())
    by_fun: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0])
    by_file: dict[str, list[float]] = collections.defaultdict(lambda: [0.0, 0.0])
    for file, event, fun, seconds, count in rows:
        if event == "backend_compile_duration":
            by_fun[fun][0] += seconds
            by_fun[fun][1] += count
            by_file[file][0] += seconds
        else:
            by_file[file][1] += seconds
    total = sum(v[0] for v in by_fun.values())
    print(f"XLA compiles: {total:.0f} s in {sum(int(v[1]) for v in by_fun.values())} programs")
    print("\nper jitted function (compile s, programs):")
    for fun, (sec, n) in sorted(by_fun.items(), key=lambda kv: -kv[1][0])[: args.top]:
        print(f"  {sec:7.1f} {int(n):5d}  {fun}")
    print("\nper test file (compile s, trace s):")
    for file, (sec, tr) in sorted(by_file.items(), key=lambda kv: -kv[1][0])[: args.top]:
        print(f"  {sec:7.1f} {tr:6.1f}  {file}")


if __name__ == "__main__":
    main()
