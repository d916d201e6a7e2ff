"""The full objective's solvers: convergence, accuracy against the IK, and speed (experiment).

    python -m benchmarks.experiments.full_newton MODEL.npz [--queries 1000] [--long 1000]
        [--iterations 10,20,30] [--json OUT.json]

Held-out MSR people (subjects 2, 4, 6, 8, 10; valid frames in a fixed random order, the first
``--queries``), the model's default L = M = 10, every cluster solved. For the projected-Adam
solver (``FullConfig()``, 30 steps) and the projected-Newton solver
(``FullConfig(solver="newton")`` at each ``--iterations``), against a long solve of each
solver (``--long`` steps):
* the fraction of answers within 0.1 deg of the long solve on every joint, p99 / max;
* the objective over the long solve's (median, min, max ratio);
* M_avg / M_max against the IK (mean over the 10 driven joints / worst joint; degrees, no
  smoothing; median and p95 over the queries);
* throughput of the public ``engine.project`` on a host array (compile apart, best of 3).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax
import numpy as np

from benchmarks.bench_projection import TEST_SUBJECTS, descriptors, shuffled  # noqa: E402
from jaxproj.projection import api as engine  # noqa: E402
from jaxproj.projection.config import FullConfig  # noqa: E402
from jaxproj.robots.nao_h25 import ik  # noqa: E402


def timed(model, h, cfg):
    engine.project(model, h[:64], "full", full=cfg)  # compile the padded size of a short call
    r, f = engine.project(model, h, "full", full=cfg)  # compile this size
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        r, f = engine.project(model, h, "full", full=cfg)
        best = min(best, time.perf_counter() - t)
    return np.asarray(r), np.asarray(f), best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("model")
    ap.add_argument("--queries", type=int, default=1000)
    ap.add_argument("--long", type=int, default=1000)
    ap.add_argument("--iterations", default="10,20,30")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    model = engine.load(a.model)
    h = shuffled(descriptors(TEST_SUBJECTS))[: a.queries].astype(np.float32)
    truth = np.asarray(ik.solve_driven(h))
    configs = [("adam", 30)] + [("newton", int(i)) for i in a.iterations.split(",")]
    longs = {}
    out = dict(device=str(jax.devices()[0]), jax=jax.__version__, queries=len(h), runs=[])
    for solver, iters in configs:
        cfg = FullConfig(solver=solver, iterations=iters)
        if solver not in longs:
            t = time.perf_counter()
            long_cfg = dataclasses.replace(cfg, iterations=a.long)
            r_l, f_l = engine.project(model, h, "full", full=long_cfg)
            longs[solver] = (np.asarray(r_l), np.asarray(f_l))
            print(f"{solver}-{a.long} long solve: {time.perf_counter() - t:.1f} s", flush=True)
        r, f, sec = timed(model, h, cfg)
        r_l, f_l = longs[solver]
        d = np.degrees(np.abs(r - r_l)).max(axis=1)
        ratio = f / np.maximum(f_l, 1e-12)
        err = np.degrees(np.abs(r - truth))
        m_avg, m_max = err.mean(1), err.max(1)
        rec = dict(
            solver=solver, iterations=iters, long=a.long,
            within_0_1_deg=float(np.mean(d <= 0.1)), p99_deg=float(np.quantile(d, 0.99)),
            max_deg=float(d.max()), f_ratio_median=float(np.median(ratio)),
            f_ratio_min=float(ratio.min()), f_ratio_max=float(ratio.max()),
            m_avg_median=float(np.median(m_avg)), m_avg_p95=float(np.quantile(m_avg, .95)),
            m_max_median=float(np.median(m_max)), m_max_p95=float(np.quantile(m_max, .95)),
            seconds=sec, poses_per_s=len(h) / sec, us_per_pose=sec / len(h) * 1e6,
        )  # fmt: skip
        out["runs"].append(rec)
        print(json.dumps(rec), flush=True)
    # the two solvers' long solves against each other
    (ra, fa), (rn, fn) = longs["adam"], longs["newton"]
    out["newton_long_vs_adam_long"] = dict(
        f_ratio_median=float(np.median(fn / np.maximum(fa, 1e-12))),
        newton_lower_fraction=float(np.mean(fn < fa)),
        within_0_1_deg=float(np.mean(np.degrees(np.abs(rn - ra)).max(1) <= 0.1)),
    )
    print(json.dumps(out["newton_long_vs_adam_long"]), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
