"""Would grouped (mixture-of-experts) backward kernels pay on a CPU? Two measurements.

    python -m benchmarks.experiments.grouped_cpu [--model P.npz] [--batch 4096] [--json OUT]

Grouping evaluates each landmark's kernel once per group of (candidate, landmark) pairs routed
to it, so its weights are read once per group instead of once per pair. It can only pay where
reading the gathered weights is what the back-projection waits on. On the default model
(or ``--model``), relaxed L = M = 10, the back-projection of ``--batch`` held-out MSR queries
(``relaxed.least_deviations_rows``, XLA, in the engine's 8-query sub-batches), timed with

1. the routing the searches give (``real``),
2. every pair of a chain routed to one landmark (``one landmark``: every weight read after the
   first is a cache hit, the most any grouping can save),
3. every pair routed to a uniformly random landmark of its chain (``random``: no reuse);

and how many distinct landmarks the pairs of one query / one sub-batch touch. If ``real`` is
no slower than ``one landmark``, the caches already do what grouping would, and the
back-projection is bound by its arithmetic (the sigmoid of every hidden unit of every pair).
Second, XLA's grouped GEMM (``jax.lax.ragged_dot``) against the per-pair gather and einsum on
800 pairs over 400 groups of 192 x 6 weights: what a grouped kernel written in XLA would run.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks import heldout
from benchmarks.experiments.selection_ab import held_out_queries
from jaxproj.projection import api as engine
from jaxproj.projection import relaxed
from jaxproj.timing import time_calls


def _best_us(fn, *args, per: int, repeats: int = 5) -> float:
    """Median us per ``per`` items of ``fn(*args)`` (compiled by a first call, untimed)."""
    jax.block_until_ready(fn(*args))
    timing = time_calls(lambda: fn(*args), min_repeats=repeats, max_repeats=repeats)
    return timing.median_s / per * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    p = model.projector
    b = args.batch
    h = jnp.asarray(held_out_queries(b))
    per_call = 16

    def searches(h: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        blocks = h.reshape(-1, per_call, h.shape[1])
        return jax.lax.map(lambda y: relaxed.relaxed_candidates(p, y, 10, 10, "xla"), blocks)

    x, cand, ridx = (a.reshape(b, *a.shape[2:]) for a in jax.jit(searches)(h))
    stack, lay = relaxed._chains(p)
    assert lay is not None
    dims = relaxed.backward_widths(p)
    sub = engine.sub_batch(p, "relaxed", 10, 10, b)

    def back(x: jax.Array, cand: jax.Array, ridx: jax.Array) -> jax.Array:
        parts = jax.tree.map(lambda a: a.reshape(b // sub, sub, *a.shape[1:]), (x, cand, ridx))
        return jax.lax.map(lambda a: relaxed.least_deviations_rows(stack, dims, *a, "xla"), parts)

    fn = jax.jit(back)
    ids = np.asarray(ridx)
    per_query = [len(np.unique(ids[i, c])) for i in range(0, b, 7) for c in range(ids.shape[1])]
    per_sub = [
        len(np.unique(ids[i : i + sub, c])) for i in range(0, b, sub) for c in range(ids.shape[1])
    ]
    sizes = np.asarray(lay.landmarks)
    rng = np.random.default_rng(0)
    routes = {
        "real": ridx,
        "one landmark": jnp.zeros_like(ridx),
        "random": jnp.asarray((rng.random(ids.shape) * sizes[:, None, None]).astype(np.int32)),
    }
    out: dict = {
        "device": jax.devices()[0].device_kind,
        "landmarks": model.landmarks,
        "batch": b,
        "sub_batch": sub,
        "pairs_per_query_per_chain": int(ids.shape[2] * ids.shape[3]),
        "distinct_landmarks_per_query_per_chain": float(np.mean(per_query)),
        "distinct_landmarks_per_sub_batch_per_chain": float(np.mean(per_sub)),
        "back_projection_us_per_query": {
            k: _best_us(fn, x, cand, r, per=b) for k, r in routes.items()
        },
    }
    # XLA's grouped GEMM against the per-pair gather
    n_pairs, hidden, m, groups = 800, 192, 6, 400
    lhs = jnp.asarray(rng.standard_normal((n_pairs, hidden)).astype(np.float32))
    rhs = jnp.asarray(rng.standard_normal((groups, hidden, m)).astype(np.float32))
    group_sizes = jnp.full((groups,), n_pairs // groups, jnp.int32)
    owner = jnp.repeat(jnp.arange(groups), n_pairs // groups)
    ragged = jax.jit(lambda a, w, s: jax.lax.ragged_dot(a, w, s))
    gather = jax.jit(lambda a, w: jnp.einsum("ph,phm->pm", a, w[owner]))
    np.testing.assert_allclose(
        ragged(lhs, rhs, group_sizes), gather(lhs, rhs), rtol=1e-4, atol=1e-3
    )
    out["ragged_dot_us_per_800_pairs"] = _best_us(ragged, lhs, rhs, group_sizes, per=1)
    out["gather_einsum_us_per_800_pairs"] = _best_us(gather, lhs, rhs, per=1)
    print(json.dumps(out, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
