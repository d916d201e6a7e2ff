"""What the Frank-Wolfe stop test (``FullConfig.gap_tol``) costs: Newton with and without it.

1,024 held-out MSR arm-action poses (a fixed shuffle, seed 0) through the public
``jaxproj.project(model, d, "full")``, ``FullConfig()`` (``gap_tol=1e-2``) against
``FullConfig(gap_tol=0)`` (the stop of 0.2.0), both compiled first, then interleaved rounds
(A, B, A, B, ...) so that a shared machine's load falls on both.

    python -m benchmarks.experiments.full_gap_ab MODEL.npz [--rounds 4] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import time

import jax
import numpy as np

from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = engine.load(args.model)
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    h = datasets.valid_descriptors(seqs)
    h = h[np.random.default_rng(0).choice(len(h), 1024, replace=False)]
    cfgs = {"gap_tol=1e-2 (FullConfig())": FullConfig(), "gap_tol=0": FullConfig(gap_tol=0.0)}
    for cfg in cfgs.values():
        engine.project(model, h, "full", full=cfg)  # compile
    times: dict[str, list[float]] = {k: [] for k in cfgs}
    for _ in range(args.rounds):
        for name, cfg in cfgs.items():
            t0 = time.perf_counter()
            engine.project(model, h, "full", full=cfg)
            times[name].append(time.perf_counter() - t0)
    out = {
        "queries": len(h),
        "device": str(jax.devices()[0].device_kind),
        **{
            k: {
                "ms_per_pose_best": 1e3 * min(v) / len(h),
                "ms_per_pose_median": 1e3 * float(np.median(v)) / len(h),
                "rounds_s": v,
            }
            for k, v in times.items()
        },
    }
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
