"""Where a relaxed pose's time goes, stage by stage and chain by chain (issue 46, items 1 and 3).

The default NAO model (built here unless ``--model`` names a file), relaxed L = M = 10,
``--batch`` held-out MSR descriptors (subjects 2,4,6,8,10, tiled) on the default device. Timed
(compile apart: a first call; then the median of ``--repeats`` calls, blocked until ready, in
ns per pose), on the backend ``project_batch`` picks there (``ops.resolve_impl``: the Pallas
kernels on CUDA GPUs, XLA elsewhere):

* ``whole``: ``api.project_chunk`` (the jitted core of ``jaxproj.project``);
* per chain, at its own size (``StackedProjector.chain_slice``), each stage alone on the
  previous stage's real outputs: the human-landmark search (``L`` per query), the forward
  kernels (``L`` candidates), the robot-landmark search (``M`` per candidate; both searches
  with the projector's pruning indices where it has them), the back-projection (``L * M``
  backward kernels) and the pick;
* with ``--no-prune``, the human and robot searches' full scans as well (``knn_pallas.PRUNE =
  False``); on CUDA GPUs, the share of each search's rows its pruned pass certifies.

On a CPU the stages run in the engine's CPU batching: searches ``search_batch(...)`` queries
per call, the back-projection ``sub_batch(...)`` at a time, both looped with ``lax.map``. The
stages' sum is not ``whole`` (each stage alone has its own launch and loop costs; on the CPU the
engine runs the chains stacked): it says which stage binds.

    python -m benchmarks.experiments.stage_split [--model P.npz] [--batch 65536] [--repeats 7]
        [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks import heldout
from benchmarks.harness import report
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed
from jaxproj.projection.elm import predict
from jaxproj.projection.ops import Impl, knn_pallas, resolve_impl

L = M = 10


def ns_per_pose(fn: Callable, args: tuple, batch: int, repeats: int) -> float:
    jax.block_until_ready(fn(*args))  # compiles
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        ts.append(time.perf_counter() - t0)
    return round(1e9 * float(np.median(ts)) / batch, 1)


def chain_stages(
    pc: engine.Projector,
    h: jax.Array,
    outer: int,
    sub: int,
    repeats: int,
    no_prune: bool,
) -> dict:
    """The stages of one chain's relaxed projection (``relaxed.relaxed_candidates`` and
    ``project_relaxed_rows`` step by step), each timed alone, ns per pose."""
    impl = resolve_impl("auto")
    stack, _ = relaxed._chains(pc)
    batch = h.shape[0]

    def looped(f: Callable) -> Callable:
        """``f`` over ``outer`` queries per call, ``lax.map``-looped as the engine does."""

        def run(*a: jax.Array) -> object:
            if outer >= batch:
                return f(*a)
            split = jax.tree.map(lambda x: x.reshape(batch // outer, outer, *x.shape[1:]), a)
            out = jax.lax.map(lambda t: f(*t), split)
            return jax.tree.map(lambda x: x.reshape(batch, *x.shape[2:]), out)

        return jax.jit(run)

    def human(x: jax.Array) -> jax.Array:
        return relaxed.search_chains(stack.human, stack.human_sq, x[None], L, None, impl, True,
                                     stack.human_index)[0]  # fmt: skip

    def forward(x: jax.Array, hidx: jax.Array) -> jax.Array:
        return jax.vmap(lambda q, i: predict(pc.forward, q, i))(x, hidx)  # (S, L, n)

    def robot(cand: jax.Array) -> jax.Array:
        rows = cand.reshape(1, -1, cand.shape[-1])
        idx = relaxed.search_chains(stack.robot, stack.robot_sq, rows, M, None, impl, True,
                                    stack.robot_index)  # fmt: skip
        return idx[0].reshape(cand.shape[0], L, M)

    dims = relaxed.backward_widths(pc)

    def back(x: jax.Array, cand: jax.Array, ridx: jax.Array) -> jax.Array:
        def part(t: tuple[jax.Array, jax.Array, jax.Array]) -> jax.Array:
            xs, cs, rs = t
            return relaxed.least_deviations_rows(stack, dims, xs[:, None], cs[:, None],
                                                 rs[:, None], impl)[:, 0]  # fmt: skip

        s = x.shape[0]
        if sub >= s:
            return part((x, cand, ridx))
        parts = jax.tree.map(lambda a: a.reshape(s // sub, sub, *a.shape[1:]), (x, cand, ridx))
        return jax.lax.map(part, parts).reshape(s, L)

    def pick(cand: jax.Array, best: jax.Array) -> tuple[jax.Array, jax.Array]:
        return relaxed.pick_rows(pc, cand[:, None], best[:, None])

    fns = {k: looped(f) for k, f in
           (("human_search", human), ("forward", forward), ("robot_search", robot),
            ("back_projection", back), ("pick", pick))}  # fmt: skip
    hidx = fns["human_search"](h)
    cand = fns["forward"](h, hidx)
    ridx = fns["robot_search"](cand)
    best = fns["back_projection"](h, cand, ridx)
    args = {
        "human_search": (h,),
        "forward": (h, hidx),
        "robot_search": (cand,),
        "back_projection": (h, cand, ridx),
        "pick": (cand, best),
    }
    out = {k: ns_per_pose(fns[k], args[k], batch, repeats) for k in fns}
    if no_prune:
        knn_pallas.PRUNE = False  # read while tracing
        out["robot_search_full_scan"] = ns_per_pose(looped(robot), (cand,), batch, repeats)
        out["human_search_full_scan"] = ns_per_pose(looped(human), (h,), batch, repeats)
        knn_pallas.PRUNE = True
    if impl is Impl.PALLAS and stack.human_index is not None:
        valid = jnp.isfinite(stack.human_sq)
        ok = knn_pallas.knn_pruned(stack.human, valid, h[None], L, index=stack.human_index)[2]
        out["human_certified_share"] = round(float(jnp.mean(ok)), 4)
    if impl is Impl.PALLAS and stack.robot_index is not None:
        valid = jnp.isfinite(stack.robot_sq)
        rows = cand.reshape(1, -1, cand.shape[-1])
        ok = knn_pallas.knn_pruned(stack.robot, valid, rows, M, index=stack.robot_index)[2]
        out["robot_certified_share"] = round(float(jnp.mean(ok)), 5)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model")
    ap.add_argument("--batch", type=int)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--no-prune", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = heldout.default_model(args.model)
    p = model.projector
    batch = args.batch or engine.default_batch_size()
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = datasets.valid_descriptors(seqs, bones=model.config.bones)
    h = jax.device_put(np.resize(d, (batch, d.shape[1])).astype(np.float32))
    impl = resolve_impl("auto")
    sub = engine.sub_batch(p, "relaxed", L, M, batch, impl)
    outer = engine.search_batch(batch, sub)
    out: dict = {
        "device": jax.devices()[0].device_kind,
        "backend": jax.default_backend(),
        "impl": str(impl.value),
        "host": platform.node(),
        "jax": jax.__version__,
        "model": args.model or "default (jaxproj build)",
        "model_s": round(time.perf_counter() - t0, 1),
        "landmarks": dict(zip(p.layout.names, map(int, p.layout.landmarks), strict=True)),
        "batch": batch,
        "search_batch": outer,
        "sub_batch": sub,
    }
    out["whole"] = ns_per_pose(engine.project_chunk, (p, h), batch, args.repeats)
    print(json.dumps(out), flush=True)
    stages: dict[str, float] = {}
    for c, (name, cols) in enumerate(zip(p.layout.names, p.layout.inputs, strict=True)):
        pc = p.chain_slice(c)
        out[name] = chain_stages(pc, h[:, list(cols)], outer, sub, args.repeats, args.no_prune)
        for k, v in out[name].items():
            if k in ("human_search", "forward", "robot_search", "back_projection", "pick"):
                stages[k] = round(stages.get(k, 0.0) + v, 1)
        print(name, json.dumps(out[name]), flush=True)
    out["stages_summed_over_chains"] = stages
    out["stages_sum"] = round(sum(stages.values()), 1)
    report(out, args.json)


if __name__ == "__main__":
    jnp.zeros(())  # start the backend before timing anything
    main()
