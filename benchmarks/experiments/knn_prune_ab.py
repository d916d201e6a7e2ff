"""The pruned exact k-NN search against the full scan, per chain on the default model's real
candidate rows, on a CUDA GPU (issue 46, item 1).

Builds the NAO's default model (``jaxproj build``'s; or ``--nao MODEL``), takes ``--poses``
held-out MSR descriptors (subjects 2,4,6,8,10, tiled), and per chain its real query rows of
the relaxed projection (L = M = 10): the ``L`` forward-kernel candidates of every pose, whose
``M`` nearest robot landmarks are searched (``relaxed.relaxed_candidates``). Per chain, the
full scan (``knn_pallas.knn_full``, today's kernel before 2026-11-27) and the pruned search with
its fallback (``knn_pallas.knn``, ``PRUNE = True``) over a grid of ``(PRUNE_BLOCK,
PRUNE_VISIT, PRUNE_ROWS, PRUNE_WARPS, PRUNE_SUB, PRUNE_TILED, FALLBACK_SHARE)`` (``--blocks``,
``--visits``, ``--rows``, ``--warps``, ``--subs``, ``--tiled``, ``--shares``; each defaults to
today's value but the first two) on every chain of at least ``--min-landmarks`` (default 0) or
those ``--chains`` names: exactness first (the neighbour sets of the first ``--check`` rows against
float64 distances; rows whose ``n``-th and ``n+1``-th float64 distances lie within 1e-5 relative
are near ties and not counted), the share of rows the certificate passes, then compile apart and
the median of ``--repeats`` calls blocked until ready, in ns per pose (``L`` rows). Also the
spatial order alone (``kd_order``), per call. Saves the model to ``--save`` for
``split_ab --nao``.

    python -m benchmarks.experiments.knn_prune_ab [--json OUT] [--save MODEL]
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.experiments.split_ab import held_out
from benchmarks.harness import report
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed
from jaxproj.projection.ops import knn_pallas

L = M = 10


def timed(fn, *a, repeats: int) -> tuple[float, float, object]:
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*a))
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*a))
        ts.append(time.perf_counter() - t0)
    return first, float(np.median(ts)), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nao")
    ap.add_argument("--save")
    ap.add_argument("--json")
    ap.add_argument("--poses", type=int, default=65536)
    ap.add_argument("--check", type=int, default=4096)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--blocks", default="32,64,128")
    ap.add_argument("--visits", default="4,8,16")
    ap.add_argument("--rows", default=str(knn_pallas.PRUNE_ROWS), help="PRUNE_ROWS values")
    ap.add_argument("--warps", default=str(knn_pallas.PRUNE_WARPS), help="PRUNE_WARPS values")
    ap.add_argument("--subs", default=str(knn_pallas.PRUNE_SUB), help="PRUNE_SUB values")
    ap.add_argument("--tiled", default=str(int(knn_pallas.PRUNE_TILED)), help="PRUNE_TILED 0/1")
    ap.add_argument("--shares", default=str(knn_pallas.FALLBACK_SHARE), help="FALLBACK_SHARE")
    ap.add_argument("--min-landmarks", type=int, default=0, help="PRUNE_MIN_LANDMARKS")
    ap.add_argument("--chains", help="comma-separated chain names (default: all)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.nao:
        model = engine.load(args.nao)
    else:
        cfg = engine.BuildConfig(robot="nao_h25")
        seqs = datasets.training_sequences(cfg.utkinect_people)
        model = engine.build(datasets.valid_descriptors(seqs, bones=cfg.bones), cfg)
        if args.save:
            engine.save(model, args.save)
    out: dict = {"device": jax.devices()[0].device_kind, "jax": jax.__version__,
                 "poses": args.poses, "model_s": round(time.perf_counter() - t0, 1),
                 "chains": {}}  # fmt: skip
    print(out, flush=True)
    p = model.projector
    h = jax.device_put(held_out(model.config.bones, args.poses))
    grid = list(itertools.product(*(tuple(int(v) for v in a.split(","))
                                    for a in (args.blocks, args.visits, args.rows,
                                              args.warps, args.subs, args.tiled,
                                              args.shares))))  # fmt: skip
    names = ("PRUNE_BLOCK", "PRUNE_VISIT", "PRUNE_ROWS", "PRUNE_WARPS", "PRUNE_SUB", "PRUNE_TILED",
             "FALLBACK_SHARE")  # fmt: skip
    base = tuple(getattr(knn_pallas, a) for a in names)
    small = (knn_pallas.PRUNE_SMALL_ROWS, knn_pallas.PRUNE_SMALL_WARPS)
    knn_pallas.PRUNE_MIN_LANDMARKS = args.min_landmarks  # default 0: every set, the head too
    for c, cols in enumerate(p.layout.inputs):
        pc = p.chain_slice(c)
        name = p.layout.names[c]
        if args.chains and name not in args.chains.split(","):
            continue
        _, cand, _ = jax.jit(lambda q, h: relaxed.relaxed_candidates(q, h, L, M))(
            pc, h[:, list(cols)]
        )
        stack = jax.tree.map(lambda a: a[None], pc) if not hasattr(pc, "stack") else pc.stack
        pts = jnp.asarray(stack.robot, jnp.float32)
        valid = jnp.isfinite(jnp.asarray(stack.robot_sq))
        rows = jnp.asarray(cand, jnp.float32).transpose(1, 0, 2, 3).reshape(1, -1, pts.shape[2])
        k = int(pts.shape[1])
        # the float64 reference on the first rows
        q = np.asarray(rows[0, : args.check], np.float64)
        pp = np.asarray(pts[0], np.float64)
        dist = np.concatenate([((q[i : i + 256, None] - pp[None]) ** 2).sum(-1)
                               for i in range(0, len(q), 256)])  # fmt: skip
        dist[:, ~np.asarray(valid[0])] = np.inf
        part = np.partition(dist, M, axis=1)[:, : M + 1]
        part.sort(axis=1)
        clear = part[:, M] - part[:, M - 1] > 1e-5 * (1 + part[:, M])
        kth = part[:, M - 1]

        def judge(idx: np.ndarray, dist=dist, kth=kth, clear=clear) -> int:
            got = np.take_along_axis(dist, idx[: args.check], axis=1)
            return int(((got.max(axis=1) > kth * (1 + 1e-6) + 1e-12) & clear).sum())

        res: dict = {"landmarks": k, "dims": int(pts.shape[2]), "rows": int(rows.shape[1]),
                     "near_ties_skipped": int((~clear).sum())}  # fmt: skip
        full = jax.jit(lambda a, v, x: knn_pallas.knn_full(a, v, x, M))
        first, med, (idx, _) = timed(full, pts, valid, rows, repeats=args.repeats)
        res["full_scan"] = {"ns_per_pose": round(1e9 * med / args.poses, 1),
                            "compile_and_first_s": round(first, 2),
                            "wrong_clear_rows": judge(np.asarray(idx[0]))}  # fmt: skip
        print(name, "full", res["full_scan"], flush=True)
        order = jax.jit(lambda a, v: knn_pallas.kd_order(a, v, knn_pallas.PRUNE_BLOCK))
        _, med, _ = timed(order, pts, valid, repeats=args.repeats)
        res["kd_order_us"] = round(1e6 * med, 1)
        res["pruned"] = []
        for point in grid:
            blk, vis, rws, wps, sub, tld, share = point
            for a, v in zip(names, point, strict=True):
                setattr(knn_pallas, a, bool(v) if a == "PRUNE_TILED" else v)
            # the grid's shape for every set, the head's too
            knn_pallas.PRUNE_SMALL_ROWS, knn_pallas.PRUNE_SMALL_WARPS = rws, wps
            where = {"block": blk, "visit": vis, "rows": rws, "warps": wps, "sub": sub,
                     "tiled": bool(tld), "fallback_share": share}  # fmt: skip
            alone = jax.jit(lambda a, v, x: knn_pallas.knn_pruned(a, v, x, M))
            both = jax.jit(lambda a, v, x: knn_pallas.knn(a, v, x, M, prune=True))
            try:
                _, med_a, (_, _, ok) = timed(alone, pts, valid, rows, repeats=args.repeats)
                first, med, (idx, _) = timed(both, pts, valid, rows, repeats=args.repeats)
            except Exception as err:  # a shape Triton refuses
                res["pruned"].append({**where, "error": str(err)[:300]})
                print(name, res["pruned"][-1], flush=True)
                continue
            okn = np.asarray(ok[0])
            res["pruned"].append({
                **where, "certified": round(float(okn.mean()), 5),
                "worst_pose_chunk_failures": int((~okn).sum()),
                "pruned_alone_ns_per_pose": round(1e9 * med_a / args.poses, 1),
                "ns_per_pose": round(1e9 * med / args.poses, 1),
                "compile_and_first_s": round(first, 2),
                "wrong_clear_rows": judge(np.asarray(idx[0])),
            })  # fmt: skip
            print(name, res["pruned"][-1], flush=True)
            out["chains"][name] = res
            if args.json:
                with open(args.json, "w") as fh:
                    json.dump(out, fh, indent=1)
        for a, v in zip(names, base, strict=True):
            setattr(knn_pallas, a, v)
        knn_pallas.PRUNE_SMALL_ROWS, knn_pallas.PRUNE_SMALL_WARPS = small
        out["chains"][name] = res
    report(out, args.json)


if __name__ == "__main__":
    main()
