"""A/B of the CPU relaxed projection's batching: one search and back-projection call per
back-projection sub-batch (``engine.sub_batch``, 8 queries at N = 1644; the engine before
2026-11-23) against searches over ``engine.search_batch`` queries (64 there) with the
back-projection looped 8 at a time inside (``project_relaxed_rows``' ``chunk``), in one process,
interleaved, on the same model and queries; both checked against the float64 reference first.

    python -m benchmarks.experiments.two_level_ab MODEL.npz [--batch 4096] [--rounds 5]
        [--ref-queries 64]

Prints us per pose of one jitted ``engine.project_batch`` (relaxed, L = M = 10) for each
batching (median of the interleaved rounds; compilation apart), how many of their answers are
identical, and both engines' distance from the float64 reference. Meant for the CPU (on
accelerators ``search_batch`` returns the sub-batch: both variants are the same program).
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from benchmarks.experiments.selection_ab import (
    compile_with_search_batch,
    held_out_queries,
    print_reference_errors,
)
from jaxproj import testing
from jaxproj.projection import api as engine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--ref-queries", type=int, default=64)
    args = ap.parse_args()
    model = engine.load(args.model)
    sp = model.projector
    q = jax.device_put(held_out_queries(args.batch))
    sub = engine.sub_batch(sp, "relaxed", 10, 10, args.batch)
    outer = engine.search_batch(args.batch, sub)
    print(
        f"{jax.devices()[0].device_kind} ({jax.default_backend()}), jax {jax.__version__}, "
        f"landmarks {model.landmarks}; batch {args.batch}: back-projection sub-batch {sub}, "
        f"search batch {outer}",
        flush=True,
    )
    compiled, answers = {}, {}
    one_level = lambda batch, sub: sub  # noqa: E731
    for name, search in (("one level", one_level), ("two levels", engine.search_batch)):
        compiled[name], secs = compile_with_search_batch(sp, q, search)
        answers[name] = np.asarray(compiled[name](sp, q)[0])
        print(f"{name}: compiled in {secs:.1f} s", flush=True)
    diff = np.degrees(np.abs(answers["one level"] - answers["two levels"])).max(axis=1)
    print(
        f"answers identical on {np.mean(diff == 0):.5f} of {args.batch} poses, within 0.001 deg "
        f"on {np.mean(diff <= 1e-3):.5f}, max diff {diff.max():.2e} deg",
        flush=True,
    )
    print_reference_errors(sp, q, answers, args.ref_queries)
    moved = np.flatnonzero(diff > 1e-3)
    if moved.size:  # where the two disagree beyond 0.001 deg: which one the float64 answer backs
        reference = testing.StackedReference(sp)
        want = np.stack([reference.project(np.asarray(q[i]), "relaxed", 10, 10)[0] for i in moved])
        err = {n: np.degrees(np.abs(a[moved] - want)).max(axis=1) for n, a in answers.items()}
        one, two = err["one level"], err["two levels"]
        print(
            f"on the {moved.size} poses moved beyond 0.001 deg the float64 reference is within "
            f"0.001 deg of one level on {int(np.sum(one <= 1e-3))}, of two levels on "
            f"{int(np.sum(two <= 1e-3))}; largest errors {one.max():.3g} / {two.max():.3g} deg",
            flush=True,
        )
    times: dict[str, list[float]] = {name: [] for name in compiled}
    for _ in range(args.rounds):  # interleaved: a noisy machine slows both alike
        for name, c in compiled.items():
            t0 = time.perf_counter()
            jax.block_until_ready(c(sp, q))
            times[name].append(time.perf_counter() - t0)
    per_pose = {name: np.median(ts) / args.batch * 1e6 for name, ts in times.items()}
    for name, us in per_pose.items():
        print(f"{name}: {us:.1f} us per pose (median of {args.rounds} interleaved rounds)")
    print(f"speed-up {per_pose['one level'] / per_pose['two levels']:.2f}x")


if __name__ == "__main__":
    main()
