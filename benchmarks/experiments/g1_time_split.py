"""Where the G1's projection and its IK spend their time, chain by chain (issue 44).

The G1's default model (``BuildConfig(robot="unitree_g1")``, built here, or MODEL.npz) and its
collision-aware generic IK, on ``--poses`` held-out MSR descriptors (subjects 2,4,6,8,10; host
arrays; compile apart: the first call; then the median of repeated calls, blocked until ready),
on the default JAX device:

* the relaxed projection of the whole model (``jaxproj.project``), and of each chain's projector
  alone on its own descriptor columns (``jaxproj.project(model.projector.chain(c), ...)``), with
  its landmark count;
* the IK of each chain alone (``GenericIK.build(..., chains=(chain,))``: one chain, its own
  rows; the legs' waist rows are the waist chain's) and the whole IK;
* the whole IK with fewer starts or iterations, and its median M_avg against the default IK:
  what a cheaper IK would cost in accuracy.

    python -m benchmarks.experiments.g1_time_split [--model M.npz] [--poses 65536] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
from collections.abc import Callable

import jax
import numpy as np

import jaxproj
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.robots.generic_ik import GenericIK
from jaxproj.timing import time_calls


def timed(fn: Callable[[], object], n: int) -> dict:
    fn()  # compiles
    t = time_calls(fn, min_repeats=3, min_time_s=2.0)
    return {"us_per_pose": round(1e6 * t.median_s / n, 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model")
    ap.add_argument("--poses", type=int, default=65536)
    ap.add_argument("--json")
    args = ap.parse_args()
    g1 = robots.get("unitree_g1")
    if args.model:
        model = engine.load(args.model)
    else:
        cfg = engine.BuildConfig(robot="unitree_g1")
        train = datasets.valid_descriptors(datasets.training_sequences(cfg.utkinect_people),
                                           bones=cfg.bones)  # fmt: skip
        model = engine.build(train, cfg)
    bones = model.config.bones
    msr = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS),
                                     bones=bones)  # fmt: skip
    d = np.tile(np.asarray(msr, np.float32), (args.poses // len(msr) + 1, 1))[: args.poses]
    n = len(d)
    out: dict = {"device": jax.devices()[0].device_kind, "platform": platform.machine(),
                 "poses": n, "landmarks": dict(model.landmarks)}  # fmt: skip
    out["projection"] = {"whole": timed(lambda: jaxproj.project(model, d)[0], n)}
    lay = model.projector.layout
    for c, name in enumerate(lay.names):
        p = model.projector.chain(c)
        x = np.ascontiguousarray(d[:, list(lay.inputs[c])])
        out["projection"][name] = timed(lambda p=p, x=x: jaxproj.project(p, x)[0], n)
        print(name, out["projection"][name], flush=True)
    out["ik"] = {}
    solver = g1.generic
    assert solver is not None
    for chain in g1.chains:
        ik = GenericIK.build(g1, solver.correspondence, solver.config, chains=(chain,))
        fn = jax.jit(lambda x, ik=ik: ik.solve(x, bones))
        out["ik"][chain.name] = timed(lambda fn=fn: jax.block_until_ready(fn(d)), n)
        print("ik", chain.name, out["ik"][chain.name], flush=True)
    whole = jax.jit(lambda x: solver.build().solve(x, bones))
    truth = np.asarray(whole(d))
    out["ik"]["whole"] = timed(lambda: jax.block_until_ready(whole(d)), n)
    out["cheaper_ik"] = {}
    for starts, iterations in ((1, 24), (2, 24), (4, 12), (2, 12)):
        cfg = dataclasses.replace(solver.config, starts=starts, iterations=iterations)
        ik = GenericIK.build(g1, solver.correspondence, cfg)
        fn = jax.jit(lambda x, ik=ik: ik.solve(x, bones))
        q = np.asarray(fn(d))
        row = timed(lambda fn=fn: jax.block_until_ready(fn(d)), n)
        row["median_M_avg_vs_default_ik_deg"] = round(
            float(np.median(np.degrees(np.abs(q - truth)).mean(1))), 3
        )
        out["cheaper_ik"][f"starts={starts},iterations={iterations}"] = row
        print(starts, iterations, row, flush=True)
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
