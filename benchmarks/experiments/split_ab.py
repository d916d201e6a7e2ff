"""Stacked chains padded to the largest against chain after chain at its own size, and the
relaxed path's sub-batches sized for XLA against one Pallas batch (issue 46, item 1).

For each robot's default model (``jaxproj build``'s NAO model first, then the G1's; built here
unless ``--nao`` / ``--g1`` name model files), on ``--poses`` held-out MSR descriptors (subjects
2,4,6,8,10, tiled) already on the device, the jitted relaxed core (L = M = 10) four ways:

* ``stacked_xla_sub``: the old program: every chain padded to the largest (``split=False``),
  ``lax.map`` over sub-batches sized for XLA's gathered kernels (``sub_batch(impl="xla")``);
* ``split_xla_sub``: chain after chain at its own size, the same sub-batches;
* ``stacked_own_sub``: padded, sub-batches sized for the path's own memory (``impl``'s);
* ``split_own_sub``: both (today's ``project_batch``).

With ``--prune-ab``, one more: today's program with the fused k-NN search scanning every
landmark for every row (``knn_pallas.PRUNE = False``, the search before 2026-11-27). With
``--knn-ab``, two more: today's program with the fused k-NN search computing every tile
of its power-of-two padding (``knn_pallas.SKIP_EMPTY_TILES = False``), and with blocks of 16
landmarks however large the set (``knn_pallas.MAX_BLOCKS`` unbounded): the search before
2026-11-26 in each respect. With ``--index-ab``, one more: today's program on the projector
without its precomputed robot-landmark pruning index (``robot_index=None``: the pruned search
computes the k-d order and block boxes in every call, as before ``with_search_index``); every
variant's answers are also compared bit for bit with ``split_own_sub``'s on every pose, and the
index's own cost, once per projector, is timed.

Compile apart (the first call), then the median of repeated calls, blocked until ready,
variants interleaved round by round. Correctness first: each variant's answers on the first
``--check`` poses judged against the float64 reference under the near-tie rule
(``jaxproj.testing.StackedReference.judge``; ``exact`` / ``tie`` / ``differs``). Then the public
``jaxproj.project`` on ``--host-poses`` host poses (today's program; poses per second).

    python -m benchmarks.experiments.split_ab [--poses 65536] [--check 500] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

import jaxproj
from benchmarks.harness import report
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed
from jaxproj.projection.ops import knn_pallas, resolve_impl
from jaxproj.projection.projector import with_search_index
from jaxproj.testing import StackedReference

L = M = 10


def core(p: engine.AnyProjector, batch: int, split: bool, own_sub: bool) -> Callable:
    impl = resolve_impl("auto")
    sub = engine.sub_batch(p, "relaxed", L, M, batch, impl if own_sub else "xla")
    outer = engine.search_batch(batch, sub)

    def run(p: engine.AnyProjector, h: jax.Array) -> tuple[jax.Array, jax.Array]:
        def rows(x: jax.Array) -> tuple[jax.Array, jax.Array]:
            return relaxed.project_relaxed_rows(p, x, L, M, chunk=sub, impl=impl, split=split)

        if outer >= h.shape[0]:
            return rows(h)
        r, v = jax.lax.map(rows, h.reshape(-1, outer, h.shape[1]))
        return r.reshape(h.shape[0], -1), v.reshape(-1)

    with jax.default_matmul_precision("float32"):
        fn = jax.jit(run)
    return lambda *a: fn(*a), sub


def held_out(bones: str | tuple[str, ...], n: int) -> np.ndarray:
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = datasets.valid_descriptors(seqs, bones=bones)
    return np.resize(d, (n, d.shape[1])).astype(np.float32)


def one_robot(model: engine.Model, args: argparse.Namespace) -> dict:
    p = model.projector
    h_host = held_out(model.config.bones, args.poses)
    h = jax.device_put(h_host)
    variants = {
        "stacked_xla_sub": (False, False),
        "split_xla_sub": (True, False),
        "stacked_own_sub": (False, True),
        "split_own_sub": (True, True),
    }
    if args.knn_ab:
        variants["split_own_sub_all_tiles"] = (True, True)
        variants["split_own_sub_blocks_of_16"] = (True, True)
    if args.prune_ab:
        variants["split_own_sub_full_scan"] = (True, True)
    if args.index_ab:
        variants["split_own_sub_index_in_trace"] = (True, True)
    if args.variants:
        variants = {k: v for k, v in variants.items() if k in args.variants.split(",")}
    ref = StackedReference(p)
    max_blocks = knn_pallas.MAX_BLOCKS
    out: dict = {"landmarks": list(p.layout.landmarks), "chains": list(p.layout.names)}
    fns, projs, answers = {}, {}, {}
    if args.index_ab:  # the index's own cost, once per projector (compile, then again)
        bare = dataclasses.replace(p, robot_index=None)
        for key in ("index_first_s", "index_again_s"):
            t0 = time.perf_counter()
            jax.block_until_ready(jax.tree.leaves(with_search_index(bare).robot_index))
            out[key] = round(time.perf_counter() - t0, 4)
    for name, (split, own) in variants.items():
        fn, sub = core(p, args.poses, split, own)
        pv = dataclasses.replace(p, robot_index=None) if name.endswith("_index_in_trace") else p
        knn_pallas.SKIP_EMPTY_TILES = not name.endswith("_all_tiles")  # read while tracing
        knn_pallas.MAX_BLOCKS = 1 << 30 if name.endswith("_blocks_of_16") else max_blocks
        knn_pallas.PRUNE = not name.endswith("_full_scan")
        t0 = time.perf_counter()
        with jax.default_matmul_precision("float32"):
            r, v = jax.block_until_ready(fn(pv, h))
        compile_s = time.perf_counter() - t0
        answers[name] = (np.asarray(r), np.asarray(v))
        knn_pallas.SKIP_EMPTY_TILES, knn_pallas.MAX_BLOCKS = True, max_blocks
        knn_pallas.PRUNE = True
        r = np.asarray(r)
        verdicts = [ref.judge(h_host[i], r[i], L, M, 1e-4) for i in range(args.check)]
        out[name] = {
            "sub_batch": sub,
            "compile_and_first_call_s": round(compile_s, 2),
            "judged": {v: verdicts.count(v) for v in ("exact", "tie", "differs")},
        }
        fns[name], projs[name] = fn, pv
    if "split_own_sub" in answers:
        a, b = answers["split_own_sub"]
        for name, (r, v) in answers.items():
            same = np.array_equal(r, a) and np.array_equal(v, b)
            out[name]["bitwise_as_split_own_sub"] = bool(same)
    times: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(args.rounds):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            with jax.default_matmul_precision("float32"):
                jax.block_until_ready(fn(projs[name], h))
            times[name].append(time.perf_counter() - t0)
    for name in variants:
        out[name]["ns_per_pose"] = round(1e9 * float(np.median(times[name])) / args.poses, 1)
    if "stacked_xla_sub" in variants:
        base = out["stacked_xla_sub"]["ns_per_pose"]
        for name in variants:
            out[name]["speedup_vs_stacked_xla_sub"] = round(base / out[name]["ns_per_pose"], 3)
    # the public API on host poses (today's program)
    hp = np.resize(h_host, (args.host_poses, h_host.shape[1]))
    jaxproj.project(model, hp[: 2 * engine.default_batch_size()])  # compiles
    t0 = time.perf_counter()
    jaxproj.project(model, hp)
    dt = time.perf_counter() - t0
    out["public_project_host_poses_per_s"] = round(args.host_poses / dt)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nao")
    ap.add_argument("--g1")
    ap.add_argument("--poses", type=int, default=65536)
    ap.add_argument("--host-poses", type=int, default=1 << 20)
    ap.add_argument("--check", type=int, default=500)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--robots", default="nao_h25,unitree_g1")
    ap.add_argument("--landmarks", type=int, help="smoke runs: this many landmarks a chain")
    ap.add_argument(
        "--knn-ab",
        action="store_true",
        help="also today's program with the fused search computing every padding tile "
        "(knn_pallas.SKIP_EMPTY_TILES = False): the variant split_own_sub_all_tiles",
    )
    ap.add_argument(
        "--prune-ab",
        action="store_true",
        help="also today's program with the full-scan k-NN search for every row "
        "(knn_pallas.PRUNE = False): the variant split_own_sub_full_scan",
    )
    ap.add_argument(
        "--index-ab",
        action="store_true",
        help="the projector without its precomputed pruning index: split_own_sub_index_in_trace",
    )
    ap.add_argument("--variants", help="comma-separated subset of the variants to run")
    ap.add_argument("--json")
    args = ap.parse_args()
    result: dict = {
        "device": jax.devices()[0].device_kind,
        "host": platform.node(),
        "jax": jax.__version__,
        "poses": args.poses,
        "L": L,
        "M": M,
    }
    for robot in args.robots.split(","):
        path = args.nao if robot == "nao_h25" else args.g1
        t0 = time.perf_counter()
        if path:
            model = engine.load(path)
        else:
            cfg = engine.BuildConfig(robot=robot)
            if args.landmarks:
                cfg = engine.BuildConfig(robot=robot, landmarks=args.landmarks)
            seqs = datasets.training_sequences(cfg.utkinect_people)
            model = engine.build(datasets.valid_descriptors(seqs, bones=cfg.bones), cfg)
        build_s = time.perf_counter() - t0
        print(f"{robot}: model ready in {build_s:.0f} s", flush=True)
        result[robot] = {"model_s": round(build_s, 1), **one_robot(model, args)}
        print(json.dumps(result[robot], indent=1), flush=True)
    report(result, args.json)


if __name__ == "__main__":
    jnp.zeros(())  # start the backend before timing anything
    main()
