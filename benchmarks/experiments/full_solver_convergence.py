"""The full objective's solvers against long solves (experiment; CPU, ~6 min on 2 cores).

    python -m benchmarks.experiments.full_solver_convergence MODEL.npz

256 descriptors of the TRAINING subjects; per-chain model; L = M = 10; every cluster solved by
projected Adam (the library's, step 0.05) for 30 / 1,000 steps, and by a projected gradient
with a parallel line search ("pgls": 10 step sizes tried at once, the best kept, monotone) for
5 ... 300 steps. Prints, against Adam-1000 and against pgls-300, the fraction of answers within
0.1 deg, p99 / max difference and the median / smallest objective ratio.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from optax.projections import projection_simplex

from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig
from jaxproj.projection.full import cluster, cluster_objective, solve_cluster, start_value
from jaxproj.projection.projector import candidates
from jaxproj.projection.search import nearest

SCALES = jnp.asarray([8.0, 4, 2, 1, 0.5, 0.25, 0.125, 1 / 16, 1 / 32, 1 / 64], jnp.float32)
RUNS = (("adam", 30), ("adam", 1000), ("pgls", 5), ("pgls", 10), ("pgls", 20), ("pgls", 40),
        ("pgls", 300))  # fmt: skip


def solve_pgls(p, h, c, f0, cfg, iters):
    """Projected gradient, parallel line search over ``SCALES`` x the current step."""

    def obj(w):
        return cluster_objective(p, h, c, cfg, w)

    vg = jax.value_and_grad(obj)

    def step(state, _):
        w, fw, t = state
        _, g = vg(w)
        with jax.numpy_dtype_promotion("standard"):  # optax internals
            trial = jax.vmap(lambda s: projection_simplex(w - s * t * g))(SCALES)
        ft = jax.vmap(obj)(trial)
        i = jnp.argmin(ft)
        better = ft[i] < fw
        w2 = jnp.where(better, trial[i], w)
        f2 = jnp.where(better, ft[i], fw)
        t2 = jnp.where(better, t * SCALES[i] * 2.0, t / 64.0)
        return (w2, f2, t2), None

    (w, fw, _), _ = jax.lax.scan(step, (c.w0, f0, jnp.float32(1.0)), None, length=iters)
    return jnp.einsum("m,mn->n", w, c.verts), fw


def full_one(p, h, cfg, solver, iters):
    cand = candidates(p, h, 10)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, 10)
    cl = jax.vmap(cluster, in_axes=(None, 0, 0, None))(p, cand, ridx, cfg)
    f0 = jax.vmap(start_value, in_axes=(None, None, 0, None))(p, h, cl, cfg)
    if solver == "adam":
        c2 = dataclasses.replace(cfg, iterations=iters)
        solve = jax.vmap(solve_cluster, in_axes=(None, None, 0, 0, None))
        r, f = solve(p, h, cl, f0, c2)
    else:
        solve = jax.vmap(solve_pgls, in_axes=(None, None, 0, 0, None, None))
        r, f = solve(p, h, cl, f0, cfg, iters)
    j = jnp.argmin(f)
    return jnp.clip(r[j], p.lower, p.upper), f[j]


def run(sp, h, solver, iters):
    cfg = FullConfig()

    def one(x):
        lay = sp.layout
        xx = jnp.concatenate([x, jnp.zeros((1,), x.dtype)])[lay.input_index()]
        r, f = jax.vmap(lambda pc, xc: full_one(pc, xc, cfg, solver, iters))(sp.stack, xx)
        return r.reshape(-1)[lay.output_index()], jnp.sum(f)

    t = time.time()
    r, f = jax.jit(jax.vmap(one))(jnp.asarray(h))
    return np.asarray(r), np.asarray(f), time.time() - t


def main(path: str) -> None:
    sp = engine.load(path).projector
    train = datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS)
    h = datasets.valid_descriptors(train).astype(np.float32)
    h = h[np.random.default_rng(1).permutation(len(h))[:256]]
    res = {}
    for solver, iters in RUNS:
        res[(solver, iters)] = run(sp, h, solver, iters)
        print(solver, iters, f"{res[(solver, iters)][2]:.1f} s (compile included)", flush=True)
    for ref in (("adam", 1000), ("pgls", 300)):
        r_ref, f_ref, _ = res[ref]
        for key, (r, f, _) in res.items():
            d = np.degrees(np.abs(r - r_ref)).max(axis=1)
            ratio = f / np.maximum(f_ref, 1e-12)
            print(
                f"vs {ref}: {key}: within 0.1 deg {np.mean(d <= 0.1):.4f}, p99 "
                f"{np.quantile(d, 0.99):.2f}, max {d.max():.1f} deg; f / f_ref median "
                f"{np.median(ratio):.4f}, min {ratio.min():.4f}"
            )


if __name__ == "__main__":
    main(sys.argv[1])
