"""Time of the landmark build's mean shift: bandwidth search to 1644 / 961 / 86 landmarks.

The paper's three landmark-set sizes (section IV) on the upper-body descriptors of the valid
frames of MSR Action3D subjects 1, 3, 5, 7, 9 (``datasets.valid_descriptors``, ~11k points).
Timed with the shared helpers of ``jaxproj.timing``:

* ``compile_s``: ``lower().compile()`` of the two jitted stages (``meanshift._iterate`` and
  ``meanshift._merge``) for this data's shapes, timed apart (``timing.compile_timed``);
* ``first_call_s``: the first ``mean_shift`` call of the process after that, at h = 0.2 (on jax
  0.10.2 the jit reuses the executables compiled by ``compile_timed``: no trace, no compile);
* per target: ``find_bandwidth_s``, the median over ``--repeats`` calls of
  ``meanshift.find_bandwidth(points, target)`` (every call is the full search from the default
  start, ``evaluations`` mean-shift runs), and ``mean_shift_s``, the median of one
  ``meanshift.mean_shift`` run at the bandwidth found (``timing.time_calls``).

``K`` is the count reached (within 5 % of the target), ``singletons`` the landmarks that hold a
single training frame. The IK of the landmarks (``landmarks.build_landmarks``) is not included.

    python -m benchmarks.bench_build [--quick] [--repeats N] [--json OUT]

``--quick``: one timed call per figure (default 3). Earlier figures: ``benchmarks/RESULTS.md``,
section "Mean shift / landmark build times".
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError, JaxprojError
from jaxproj.io import datasets
from jaxproj.projection import meanshift
from jaxproj.timing import Timing, compile_timed, time_calls

SUBJECTS = (1, 3, 5, 7, 9)
TARGETS = (1644, 961, 86)


def _args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one timed call per figure")
    ap.add_argument("--repeats", type=int, default=None, help="timed calls per figure (3)")
    ap.add_argument("--json", type=Path, default=None, help="also write the records here")
    return ap.parse_args(argv)


def compile_stages(points: np.ndarray) -> float:
    """Seconds to lower and compile ``_iterate`` and ``_merge`` for ``points`` ``(N, m)``.

    The arguments have the shapes, dtypes and static values ``mean_shift`` / ``find_bandwidth``
    use for these points with the default (Gaussian) options.
    """
    prep = meanshift._prepare(points)
    h, tol, max_iter = jnp.float32(0.2), jnp.float32(meanshift.TOL), jnp.int32(meanshift.MAX_ITER)
    _, it_s = compile_timed(
        meanshift._iterate,
        prep.p,
        prep.p_valid,
        prep.p,
        prep.p_mask,
        h,
        tol,
        max_iter,
        kernel="gaussian",
        block=meanshift.BLOCK,
    )
    log_den = jnp.zeros(prep.p.shape[0], jnp.float32)
    _, merge_s = compile_timed(meanshift._merge, prep.p, log_den, prep.p_valid, h * h)
    return it_s + merge_s


def _time_search(
    points: np.ndarray, target: int, repeats: int
) -> tuple[Timing, list[tuple[float, int]], tuple[float, meanshift.MeanShiftResult]]:
    """Median time of ``find_bandwidth(points, target)``; also its history and result.

    No warm-up call: the stages were compiled for these shapes (``compile_stages``), and the
    search is deterministic, so every timed call runs the same evaluations.
    """
    calls: list[tuple[list[tuple[float, int]], tuple[float, meanshift.MeanShiftResult]]] = []

    def search_once() -> None:
        history: list[tuple[float, int]] = []
        calls.append((history, meanshift.find_bandwidth(points, target, history=history)))

    timing = time_calls(search_once, min_repeats=repeats, max_repeats=repeats)
    return timing, *calls[-1]


def run(repeats: int) -> dict:
    """Time the searches; returns ``{"environment", "n_points", "compile_s", "first_call_s",
    "rows": [{"target", "h", "K", "evaluations", "find_bandwidth_s", "mean_shift_s",
    "singletons", "repeats"}, ...]}``."""
    if repeats < 1:
        raise ConfigError(f"repeats must be >= 1, got {repeats}")
    points = datasets.valid_descriptors(datasets.msr_action3d(subjects=list(SUBJECTS)))
    compile_s = compile_stages(points)
    first = time_calls(lambda: meanshift.mean_shift(points, 0.2), min_repeats=1, max_repeats=1)
    rows = []
    for target in TARGETS:
        search, history, (h, res) = _time_search(points, target, repeats)
        one = time_calls(
            lambda h=h: meanshift.mean_shift(points, h), min_repeats=repeats, max_repeats=repeats
        )
        rows.append(
            {
                "target": target,
                "h": h,
                "K": res.n_modes,
                "evaluations": len(history),
                "find_bandwidth_s": search.median_s,
                "mean_shift_s": one.median_s,
                "singletons": int(np.sum(res.counts == 1)),
                "repeats": repeats,
            }
        )
    return {
        "environment": {
            "jax": jax.__version__,
            "device": str(jax.devices()[0]),
            "cpu_count": os.cpu_count(),
            "python": platform.python_version(),
        },
        "subjects": list(SUBJECTS),
        "n_points": int(points.shape[0]),
        "compile_s": compile_s,
        "first_call_s": first.median_s,
        "rows": rows,
    }


def table(result: dict) -> str:
    """The result as a Markdown table (one row per target) with its header lines."""
    env = result["environment"]
    lines = [
        f"MSR Action3D subjects {result['subjects']}: {result['n_points']} points; "
        f"{env['device']}, {env['cpu_count']} CPUs, jax {env['jax']}",
        f"compile (_iterate + _merge, lower+compile): {result['compile_s']:.2f} s; "
        f"first mean_shift call after it: {result['first_call_s']:.2f} s",
        "",
        "| target | h | K | evaluations | find_bandwidth (s) | mean_shift at h (s) | singletons |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in result["rows"]:
        lines.append(
            f"| {r['target']} | {r['h']:.4f} | {r['K']} | {r['evaluations']} | "
            f"{r['find_bandwidth_s']:.2f} | {r['mean_shift_s']:.2f} | {r['singletons']} |"
        )
    lines.append(f"(median of {result['rows'][0]['repeats']} timed calls per figure)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = _args(argv)
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else 3)
    try:
        result = run(repeats)
    except JaxprojError as e:
        print(f"bench_build: error: {e}", file=sys.stderr)
        return 2
    print(table(result))
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
