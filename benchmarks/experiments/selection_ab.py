"""A/B of the exact k-nearest selection on an accelerator: XLA ``TopK`` (the old selection)
against repeated minima (``search.smallest``'s accelerator path), in one run, on the same model
and queries; then the public ``jaxproj.project`` on 1 M host poses.

    python -m benchmarks.experiments.selection_ab MODEL.npz

Prints ns per pose of one jitted ``engine.project_batch`` (relaxed, L = M = 10, batch 65,536)
for both selections and whether their answers are bit-identical. Needs a GPU (on a CPU both
paths are ``TopK``).
"""

from __future__ import annotations

import argparse
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj import testing
from jaxproj._internal.jit import jit
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed, search
from jaxproj.projection.ops import ImplLike
from jaxproj.projection.projector import StackedProjector
from jaxproj.timing import compile_timed

BATCH = 65536


def per_pose_ns(f, *args, repeats: int = 5) -> float:
    """Median ns per pose of ``f(*args)`` on a ``BATCH``-pose batch (compile and warm-up apart)."""
    jax.block_until_ready(f(*args))  # compile + warm up
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(f(*args))
        ts.append(time.perf_counter() - t)
    return float(np.median(ts)) / BATCH * 1e9


def held_out_queries(n: int) -> np.ndarray:
    """``(n, 15)`` float32 descriptors of the held-out MSR subjects, shuffled (seed 0), tiled."""
    test = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS))
    test = test[np.random.default_rng(0).permutation(len(test))].astype(np.float32)
    return np.tile(test, (n // len(test) + 1, 1))[:n]


def public_rate(model: engine.Model, hosts: np.ndarray) -> float:
    """``jaxproj.project``'s relaxed poses per second on ``hosts`` (default arguments; compile
    apart, median of 3 calls)."""
    engine.project(model, hosts)  # compile
    ts = []
    for _ in range(3):
        t = time.perf_counter()
        engine.project(model, hosts)
        ts.append(time.perf_counter() - t)
    return len(hosts) / float(np.median(ts))


def print_public_rate(model: engine.Model) -> None:
    """Print ``jaxproj.project``'s relaxed rate on 1 M held-out host poses (default arguments)."""
    rate = public_rate(model, held_out_queries(2**20))
    print(f"public jaxproj.project relaxed, 1 M host poses: {rate / 1e6:.3f} M/s")


def ab_setup(doc: str, ref_queries: int) -> tuple[argparse.Namespace, engine.Model, jax.Array]:
    """The A/B scripts' common start: ``MODEL.npz [--ref-queries N]`` parsed, the model loaded,
    ``BATCH`` held-out queries on the device, the device printed."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--ref-queries", type=int, default=ref_queries)
    args = ap.parse_args()
    model = engine.load(args.model)
    q = jax.device_put(held_out_queries(BATCH))
    print(jax.devices()[0].device_kind, "landmarks", model.landmarks, flush=True)
    return args, model, q


def relaxed_batch(impl: ImplLike = "auto"):
    """A freshly traced, jitted relaxed ``engine.project_batch`` (L = M = 10, backend ``impl``)
    through the library's jit policy (full float32 matmul precision), so a patched function is
    picked up."""
    return jit(lambda p, h: engine.project_batch(p, h, "relaxed", 10, 10, impl=impl))


def relaxed_rows_batch(search_impl: ImplLike, back_impl: ImplLike):
    """A jitted relaxed projection (L = M = 10) with the k-NN searches on ``search_impl`` and
    the back-projection on ``back_impl``: ``engine.project_batch``'s program on an accelerator
    (``engine.sub_batch`` queries per ``lax.map`` step, each searched and back-projected at
    once), built from ``relaxed``'s steps, so one kernel can be A/B'd with the other fixed."""

    def batch(p: StackedProjector, h: jax.Array) -> tuple[jax.Array, jax.Array]:
        sub = engine.sub_batch(p, "relaxed", 10, 10, h.shape[0])
        dims = relaxed.backward_widths(p)

        def rows(x: jax.Array) -> tuple[jax.Array, jax.Array]:
            xs, cand, ridx = relaxed.relaxed_candidates(p, x, 10, 10, impl=search_impl)
            best = relaxed.least_deviations_rows(p.stack, dims, xs, cand, ridx, impl=back_impl)
            return relaxed.pick_rows(p, cand, best)

        if sub >= h.shape[0]:
            return rows(h)
        r, v = jax.lax.map(rows, h.reshape(-1, sub, h.shape[1]))
        return r.reshape(h.shape[0], -1), v.reshape(-1)

    return jit(batch)


def compile_with_search_batch(
    sp: StackedProjector, q: jax.Array, search_batch
) -> tuple[object, float]:
    """``engine.project_batch`` (relaxed, L = M = 10) on ``q`` compiled with
    ``engine.search_batch`` replaced by ``search_batch`` while it is traced (restored after):
    ``(compiled, compile seconds)``."""
    default = engine.search_batch
    engine.search_batch = search_batch
    try:
        fn = jit(lambda p, h: engine.project_batch(p, h, "relaxed", 10, 10))
        return compile_timed(fn, sp, q)
    finally:
        engine.search_batch = default


def print_reference_errors(
    sp: StackedProjector, q: jax.Array, answers: dict[str, np.ndarray], nq: int
) -> None:
    """Print each named engine's largest distance (deg) from the float64 reference (relaxed,
    L = M = 10) on the first ``nq`` queries of ``q``, and how many are beyond 0.001 / 0.01 deg."""
    reference = testing.StackedReference(sp)
    nq = min(nq, q.shape[0])
    want = np.stack([reference.project(np.asarray(q[i]), "relaxed", 10, 10)[0] for i in range(nq)])
    for name, r in answers.items():
        d = np.degrees(np.abs(r[:nq] - want)).max(axis=1)
        print(
            f"{name} vs float64 reference on {nq} queries: max {d.max():.2e} deg, "
            f"> 0.001 deg on {int(np.sum(d > 1e-3))}, > 0.01 deg on {int(np.sum(d > 1e-2))}",
            flush=True,
        )


def _top_k(v: jax.Array, n: int) -> tuple[jax.Array, jax.Array]:
    neg, pos = jax.lax.top_k(-v, n)
    return pos.astype(jnp.int32), -neg


def main(path: str) -> None:
    model = engine.load(path)
    sp = model.projector
    q = jax.device_put(held_out_queries(BATCH))
    # both selections live in the XLA search; since 2026-11-23 CUDA GPUs run the fused kernel
    # (fused_knn_ab.py) instead, so the XLA search (impl="xla") is asked for in both variants,
    # the back-projection left at its default

    # relaxed_rows_batch traces through the library's jit policy (full float32 matmul
    # precision); a bare jax.jit ran at XLA's TF32 default on GPUs until 2026-11-23 (RESULTS.md)
    new = relaxed_rows_batch("xla", "auto")
    r_new, t_new = np.asarray(new(sp, q)[0]), per_pose_ns(new, sp, q)
    # search.smallest's per-platform choice is not a backend (ops.Impl's doc): the old selection
    # is patched in for the second variant
    default = search.smallest
    search.smallest = _top_k  # the selection before this change, traced anew
    try:
        old = relaxed_rows_batch("xla", "auto")
        r_old, t_old = np.asarray(old(sp, q)[0]), per_pose_ns(old, sp, q)
    finally:
        search.smallest = default
    diff = np.degrees(np.abs(r_new - r_old)).max(axis=1)
    print(
        f"{jax.devices()[0].device_kind}: relaxed L=M=10, batch {BATCH}: TopK {t_old:.1f} ns/pose, "
        f"repeated minima {t_new:.1f} ns/pose; identical answers {np.mean(diff == 0):.5f}, "
        f"max diff {diff.max():.2e} deg"
    )
    print_public_rate(model)


if __name__ == "__main__":
    main(sys.argv[1])
