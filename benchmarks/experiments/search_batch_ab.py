"""A/B of the CPU relaxed projection's queries per search call (``engine.search_batch``).

    python -m benchmarks.experiments.search_batch_ab [--model P.npz] [--sizes 16,64,128,256]
        [--batch 4096] [--rounds 8] [--ref-queries 64] [--json OUT]

The default model (or ``--model``), one jitted ``engine.project_batch`` (relaxed, L = M = 10)
per search-call size, compiled apart, on the same ``--batch`` held-out MSR descriptors; every
variant's answers compared with the first one's and with the float64 reference on the first
``--ref-queries`` queries; then ``--rounds`` interleaved timing rounds (a noisy machine slows
every variant alike). Prints us per pose (median, min) per size. Meant for the CPU (on
accelerators ``search_batch`` returns the back-projection sub-batch).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import numpy as np

from benchmarks import heldout
from benchmarks.experiments.selection_ab import (
    compile_with_search_batch,
    held_out_queries,
    print_reference_errors,
)
from jaxproj.projection import api as engine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--sizes", default="16,64,128,256")
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--rounds", type=int, default=8)
    ap.add_argument("--ref-queries", type=int, default=64)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    sp = model.projector
    q = jax.device_put(held_out_queries(args.batch))
    sub = engine.sub_batch(sp, "relaxed", 10, 10, args.batch)
    sizes = [int(s) for s in args.sizes.split(",")]
    out: dict = {
        "device": jax.devices()[0].device_kind,
        "landmarks": model.landmarks,
        "batch": args.batch,
        "sub_batch": sub,
        "default_search_batch": engine.search_batch(args.batch, sub),
    }
    print(out, flush=True)
    compiled, answers = {}, {}
    for size in sizes:
        if size % sub or args.batch % size:
            raise SystemExit(f"--sizes: {size} must be a multiple of {sub} dividing {args.batch}")
        fixed = lambda batch, s, size=size: size  # noqa: E731
        compiled[size], secs = compile_with_search_batch(sp, q, fixed)
        answers[size] = np.asarray(compiled[size](sp, q)[0])
        diff = np.degrees(np.abs(answers[size] - answers[sizes[0]])).max(axis=1)
        print(
            f"{size} queries per search call: compiled in {secs:.1f} s; answers identical to "
            f"{sizes[0]}'s on {np.mean(diff == 0):.5f} of the poses "
            f"(max diff {diff.max():.2e} deg)",
            flush=True,
        )
        out.setdefault("identical_to_first", {})[size] = float(np.mean(diff == 0))
    print_reference_errors(sp, q, {f"search {s}": a for s, a in answers.items()}, args.ref_queries)
    times: dict[int, list[float]] = {s: [] for s in sizes}
    for _ in range(args.rounds):
        for size, c in compiled.items():
            t0 = time.perf_counter()
            jax.block_until_ready(c(sp, q))
            times[size].append((time.perf_counter() - t0) / args.batch * 1e6)
    out["us_per_pose"] = {}
    for size, ts in times.items():
        med, low = float(np.median(ts)), float(np.min(ts))
        out["us_per_pose"][size] = {"median": med, "min": low}
        print(f"{size} queries per search call: {med:.1f} us per pose (median; min {low:.1f})")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
