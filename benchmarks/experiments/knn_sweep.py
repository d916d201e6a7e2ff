"""Sweep of the fused k-NN kernel's tile shape on a CUDA GPU (issue 46: the robot-landmark search
toward its floor).

The robot-landmark search of the relaxed projection at batch 65,536 (L = 10 candidate rows per
pose: 655,360 rows), on landmark sets of the default models' sizes and widths (NAO right arm
10,617 x 5, left arm 6,693 x 5, head 1,010 x 2; a G1 leg 4,194 x 6), uniform random in the
joints' range (the kernel's work does not depend on where the points are: every tile of
landmarks is computed, then a fixed selection), n = 10. For each ``(ROWS, BLOCK, TILE_BLOCKS,
WARPS)`` of ``knn_pallas`` (module constants, read when the kernel is traced): compile apart,
then the median of repeated calls, blocked until ready, in ns per pose (10 rows); exactness
first: the neighbour sets of 4,096 rows against XLA's exact ``top_k`` of all distances (rows
whose n-th and n+1-th distances tie within float32 round-off are not counted).

    python -m benchmarks.experiments.knn_sweep [--json OUT]
"""

from __future__ import annotations

import argparse
import itertools
import json
import time

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.projection.ops import knn_pallas

SETS = {"nao_right_arm": (10617, 5), "nao_left_arm": (6693, 5), "nao_head": (1010, 2),
        "g1_leg": (4194, 6)}  # fmt: skip
ROWS = 655_360
N = 10


def exact(points: jax.Array, x: jax.Array) -> tuple[np.ndarray, np.ndarray]:
    d2 = jnp.sum((x[:, None, :] - points[None]) ** 2, axis=-1)
    v, i = jax.lax.top_k(-d2, N + 1)
    return np.asarray(i[:, :N]), np.asarray(-v)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sets", default=",".join(SETS))
    ap.add_argument("--rows", default="16,32")
    ap.add_argument("--blocks", default="16,32")
    ap.add_argument("--tiles", default="4,8,16")
    ap.add_argument("--warps", default="4,8")
    args = ap.parse_args()
    rng = np.random.default_rng(0)

    def ints(text: str) -> tuple[int, ...]:
        return tuple(int(v) for v in text.split(","))

    grid = list(itertools.product(*(ints(a) for a in (args.rows, args.blocks, args.tiles,
                                                       args.warps))))  # fmt: skip
    base = (knn_pallas.ROWS, knn_pallas.BLOCK, knn_pallas.TILE_BLOCKS, knn_pallas.WARPS)
    out: dict = {"device": jax.devices()[0].device_kind, "rows": ROWS, "n": N, "base": base,
                 "sets": {}}  # fmt: skip
    for name in args.sets.split(","):
        k, d = SETS[name]
        pts = jnp.asarray(rng.uniform(-2, 2, size=(1, k, d)).astype(np.float32))
        x = jnp.asarray(rng.uniform(-2, 2, size=(1, ROWS, d)).astype(np.float32))
        valid = jnp.ones((1, k), bool)
        want_i, want_v = exact(pts[0], x[0, :4096])
        clear = want_v[:, N] - want_v[:, N - 1] > 1e-5 * (1 + want_v[:, N])
        rows = []
        for r, b, t, w in grid:
            knn_pallas.ROWS, knn_pallas.BLOCK, knn_pallas.TILE_BLOCKS, knn_pallas.WARPS = r, b, t, w
            fn = jax.jit(lambda p, q, v: knn_pallas.knn(p, v, q, N))
            try:
                t0 = time.perf_counter()
                idx, _ = jax.block_until_ready(fn(pts, x, valid))
                compile_s = time.perf_counter() - t0
            except Exception as err:  # a shape Triton refuses
                rows.append({"rows": r, "block": b, "tile": t, "warps": w, "error": str(err)[:200]})
                continue
            got = np.sort(np.asarray(idx[0, :4096]), axis=1)
            same = (got == np.sort(want_i, axis=1)).all(axis=1)
            times = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                jax.block_until_ready(fn(pts, x, valid))
                times.append(time.perf_counter() - t0)
            ns = 1e9 * float(np.median(times)) / (ROWS / 10)
            rows.append({"rows": r, "block": b, "tile": t, "warps": w, "ns_per_pose": round(ns, 1),
                         "compile_s": round(compile_s, 2),
                         "wrong_clear_rows": int((~same & clear).sum())})  # fmt: skip
            print(name, rows[-1], flush=True)
            if args.json:  # what is done so far survives a time limit
                with open(args.json, "w") as fh:
                    json.dump({**out, "partial": {name: rows}}, fh)
        knn_pallas.ROWS, knn_pallas.BLOCK, knn_pallas.TILE_BLOCKS, knn_pallas.WARPS = base
        ok = [x for x in rows if "ns_per_pose" in x and x["wrong_clear_rows"] == 0]
        best = min(ok, key=lambda x: x["ns_per_pose"])
        out["sets"][name] = {"k": k, "d": d, "grid": rows, "best": best}
        print(name, "best", best, flush=True)
    text = json.dumps(out, indent=1)
    if args.json:
        with open(args.json, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
