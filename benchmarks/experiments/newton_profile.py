"""Where the converged full objective (``NEWTON``) spends its CPU time, and what cheaper
settings would cost in answers.

    python -m benchmarks.experiments.newton_profile [--model P.npz] [--queries 256]
        [--chain-queries 128] [--json OUT]

Two parts, default model (or ``--model``), held-out MSR descriptors:

1. One chain (the right arm, the largest), ``--chain-queries`` queries x its ``L = 10``
   weighted problems (``M = 10`` kernels, 10 vertices each), vmapped and jitted piece by piece:
   a value ``F(w)``, the derivatives (``F``, gradient, Gauss-Newton Hessian: residuals then
   Jacobians), one KKT solve, one active-set QP (``QP_SWEEPS`` solves), one solver ``update``
   (``DAMPINGS`` trials: QP and value each), and how many steps the problems take to stop.
2. The public ``jaxproj.project(model, h, "full", full=...)`` on ``--queries`` queries, every
   chain: ``NEWTON`` against cheaper settings (fewer screening steps, a lower step cap, one
   damping per step), compiled apart, each answer compared with ``NEWTON``'s (angles within
   0.1 deg, objective worse by more than 1e-4 relative).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks import heldout
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import full
from jaxproj.projection import simplex_newton as sn
from jaxproj.projection.config import NEWTON
from jaxproj.projection.projector import candidates
from jaxproj.projection.search import nearest
from jaxproj.timing import time_calls

_BATCH = sn.Problem(0, 0, 0, 0, None, 0, 0, None, None)  # type: ignore[arg-type]
"""vmap axes over queries: the bank's ``W`` and the regularisers are shared."""


def _us(fn, *args, per: int, repeats: int = 5) -> float:
    """Median us per ``per`` items of ``fn(*args)`` (compiled by a first call, untimed)."""
    jax.block_until_ready(fn(*args))
    timing = time_calls(lambda: fn(*args), min_repeats=repeats, max_repeats=repeats)
    return timing.median_s / per * 1e6


def chain_costs(model: engine.Model, h_all: np.ndarray) -> dict:
    """Part 1: us per query (its 10 problems) of each piece, right arm."""
    sp = model.projector
    c = sp.layout.names.index("right_arm")
    p = sp.chain(c)
    h = jnp.asarray(h_all[:, list(sp.layout.inputs[c])])
    cfg = NEWTON
    b = h.shape[0]

    def build(x: jax.Array) -> tuple[sn.Problem, jax.Array]:
        cand = candidates(p, x, 10)
        ridx, _ = nearest(p.robot, p.robot_sq, cand, 10)
        return jax.vmap(full.problems, in_axes=(None, None, 0, 0, None))(p, x, cand, ridx, cfg)

    prs, w0 = jax.jit(jax.vmap(build))(h)
    rho, eps = jnp.asarray(cfg.proximal, h.dtype), jnp.asarray(cfg.ridge, h.dtype)
    prs = prs._replace(w_in=p.backward.w, h=h, rho=rho, eps=eps)
    solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol, cfg.gap_tol)

    def vv(f):  # over queries, then over their problems
        return jax.jit(jax.vmap(jax.vmap(f, in_axes=(full._AXES, 0)), in_axes=(_BATCH, 0)))

    state = vv(solver.init)(prs, w0)
    eye = jnp.eye(w0.shape[-1], dtype=w0.dtype)

    def one_qp(pr: sn.Problem, s: sn.NewtonState) -> jax.Array:
        a = s.d.hess + 1e-3 * eye
        return sn.simplex_qp(a, s.d.grad - a @ s.w, s.w, sn.QP_SWEEPS)

    def one_kkt(pr: sn.Problem, s: sn.NewtonState) -> jax.Array:
        return sn._cholesky_solve(s.d.hess + 1e-3 * eye, jnp.stack([s.d.grad, s.w], axis=1))

    def residuals(pr: sn.Problem, w: jax.Array) -> jax.Array:
        return sn.residuals(pr, pr.verts.T @ w)[0]

    run = vv(lambda pr, s: solver.run(pr, s, cfg.iterations))
    final = run(prs, state)
    return {
        "queries": b,
        "problems_per_query": int(w0.shape[1]),
        "us_per_query": {
            "value": _us(vv(sn.value), prs, w0, per=b),
            "residuals": _us(vv(residuals), prs, w0, per=b),
            "derivatives": _us(vv(sn.derivatives), prs, w0, per=b),
            "kkt_solve": _us(vv(one_kkt), prs, state, per=b),
            "qp": _us(vv(one_qp), prs, state, per=b),
            "update": _us(vv(solver.update), prs, state, per=b),
        },
        "steps_to_stop": {
            "mean": float(np.mean(final.steps)),
            "mean_of_each_querys_slowest": float(np.mean(np.max(final.steps, axis=1))),
            "max": int(np.max(final.steps)),
        },
    }


def variants(model: engine.Model, h: np.ndarray) -> dict:
    """Part 2: the public API under ``NEWTON`` and cheaper settings."""
    runs = {
        "NEWTON": (NEWTON, None),
        "screen=4": (dataclasses.replace(NEWTON, screen=4), None),
        "iterations=8 (no finalist tail)": (dataclasses.replace(NEWTON, iterations=8), None),
        "one damping per step": (NEWTON, (1.0,)),
    }
    out: dict = {}
    ref_r = ref_f = None
    for name, (cfg, dampings) in runs.items():
        saved = sn.DAMPINGS
        if dampings is not None:
            sn.DAMPINGS = dampings  # read when the solver is built, at trace time
        jax.clear_caches()
        try:
            t0 = time.perf_counter()
            engine.project(model, h, "full", full=cfg)
            first = time.perf_counter() - t0
            t0 = time.perf_counter()
            r, f = engine.project(model, h, "full", full=cfg)
            secs = time.perf_counter() - t0
        finally:
            sn.DAMPINGS = saved
        if ref_r is None:
            ref_r, ref_f = r, f
        moved = np.degrees(np.abs(r - ref_r)).max(axis=1)
        out[name] = {
            "ms_per_pose": secs / len(h) * 1e3,
            "compile_s": first - secs,
            "within_0.1deg_of_NEWTON": float(np.mean(moved <= 0.1)),
            "objective_worse_1e-4": float(np.mean(f > ref_f * (1 + 1e-4) + 1e-9)),
        }
        print(name, out[name], flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--queries", type=int, default=256)
    ap.add_argument("--chain-queries", type=int, default=128)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    test = datasets.valid_descriptors(heldout.splits()["msr_held_out_arm"])

    def spread(n: int) -> np.ndarray:
        pick = np.linspace(0, len(test) - 1, n).round().astype(int)
        return np.ascontiguousarray(test[pick], dtype=np.float32)

    out = {
        "device": jax.devices()[0].device_kind,
        "landmarks": model.landmarks,
        "chain": chain_costs(model, spread(args.chain_queries)),
    }
    print(json.dumps(out, indent=1), flush=True)
    out["public"] = variants(model, spread(args.queries))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
