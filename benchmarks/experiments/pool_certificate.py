"""How often would an exact pruned robot-landmark search need no brute force?

For the relaxed projection each candidate ``r_j`` comes from human landmark ``j``'s forward
kernel; its ``M`` nearest robot landmarks are searched among all ``K``. A pruned search looks
only at the pool of the ``P`` robot landmarks nearest to landmark ``j``'s own robot pose ``c_j``
(precomputed). With ``rho_j`` the distance from ``c_j`` to the nearest landmark outside the pool
and ``delta = |r_j - c_j|``, every outside landmark is at least ``rho_j - delta`` from ``r_j``;
so if the ``M``-th nearest pool member is no farther, the pool's ``M`` nearest are the global
ones (the certificate). This prints, per chain and pool size, the fraction of candidates the
certificate proves (the rest would take the brute-force path), and checks that every proven
set equals the brute-force set. Held-out MSR subjects 2, 4, 6, 8, 10, the default per-chain
model at ``--landmarks``, L = M = 10.

    python -m benchmarks.experiments.pool_certificate [--landmarks 1644] [--queries 4096]
        [--pools 16,32,64,128,256] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import numpy as np

from benchmarks.bench_projection import TEST_SUBJECTS, TRAIN_SUBJECTS, descriptors, shuffled  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402
from jaxproj.projection.projector import candidates  # noqa: E402
from jaxproj.projection.search import nearest  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landmarks", type=int, default=1644)
    ap.add_argument("--queries", type=int, default=4096)
    ap.add_argument("--pools", default="16,32,64,128,256")
    ap.add_argument("--L", type=int, default=10)
    ap.add_argument("--M", type=int, default=10)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    pools = [int(x) for x in args.pools.split(",")]
    model = engine.build(descriptors(TRAIN_SUBJECTS),
                         engine.BuildConfig(chains="upper", landmarks=args.landmarks))  # fmt: skip
    sp = model.projector
    test = shuffled(descriptors(TEST_SUBJECTS))[: args.queries]
    out = {"device": jax.devices()[0].device_kind, "landmarks": model.landmarks,
           "queries": len(test), "L": args.L, "M": args.M, "chains": {}}  # fmt: skip
    print(out["device"], model.landmarks, f"{len(test)} held-out queries, L = {args.L}, "
          f"M = {args.M}")  # fmt: skip
    for c in range(sp.layout.n_chains):
        p = sp.chain(c)
        h = np.asarray(test[:, list(sp.layout.inputs[c])], np.float32)
        src = np.asarray(jax.vmap(lambda x, p=p: nearest(p.human, p.human_sq, x, args.L)[0])(h))
        cand = np.asarray(jax.vmap(lambda x, p=p: candidates(p, x, args.L))(h), np.float64)
        rob = np.asarray(p.robot, np.float64)  # (K, n)
        k = len(rob)
        d_ll = np.linalg.norm(rob[:, None] - rob[None], axis=-1)  # (K, K)
        order = np.argsort(d_ll, axis=1, kind="stable")
        r = cand.reshape(-1, rob.shape[1])
        j = src.reshape(-1)
        d_all = np.linalg.norm(r[:, None] - rob[None], axis=-1)  # (QL, K)
        brute = np.sort(np.argpartition(d_all, args.M - 1, axis=1)[:, : args.M], axis=1)
        delta = np.linalg.norm(r - rob[j], axis=1)
        row = {"K": k, "delta_median": float(np.median(delta))}
        for size in pools:
            if size + 1 > k:
                continue
            pool = order[j, :size]  # (QL, P)
            rho = d_ll[j, order[j, size]]
            d_pool = np.take_along_axis(d_all, pool, axis=1)
            part = np.argpartition(d_pool, args.M - 1, axis=1)[:, : args.M]
            d_m = np.take_along_axis(d_pool, part, axis=1).max(axis=1)
            proven = d_m <= rho - delta
            got = np.sort(np.take_along_axis(pool, part, axis=1), axis=1)
            other = proven & np.any(got != brute, axis=1)  # another index set ...
            d_got = np.sort(np.take_along_axis(d_all, got, axis=1), axis=1)
            d_brute = np.sort(np.take_along_axis(d_all, brute, axis=1), axis=1)
            wrong = int(np.sum(other & np.any(d_got != d_brute, axis=1)))  # ... not a tie
            row[f"P{size}"] = {"proven": float(proven.mean()), "other_set_same_distances":
                               int(other.sum()) - wrong, "proven_but_wrong": wrong}  # fmt: skip
            print(f"  {sp.layout.names[c]:>9} K={k:5d} P={size:4d}: certificate proves "
                  f"{proven.mean():6.1%} of {len(r)} candidates (another set at equal distances "
                  f"{int(other.sum()) - wrong}, wrong {wrong})")  # fmt: skip
        out["chains"][sp.layout.names[c]] = row
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
