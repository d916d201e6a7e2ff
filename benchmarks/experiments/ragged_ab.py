"""A/B of the padding tax: every chain searched over its own landmarks (ragged, the engine since
2026-11-24) against every chain searched over the largest chain's padded ``K`` (before).

    python -m benchmarks.experiments.ragged_ab [--model P.npz] [--queries 1048576] [--rounds 3]

On the default model (``BuildConfig()`` on MSR training subjects 1,3,5,7,9 unless ``--model``;
799 / 3,668 / 7,099 landmarks, padded to 3 x 7,099 before), the public ``jaxproj.project``
(relaxed, L = M = 10, default arguments) on a host array of ``--queries`` held-out descriptors
(MSR subjects 2,4,6,8,10, tiled), for both layouts in one process: compiled first (timed
apart), then ``--rounds`` interleaved rounds, best of each. The padded variant is the same
model with a layout that declares every chain at the largest ``K`` (``search_chains`` then runs
the one batched search, as the engine did). Prints poses/s of both, the speed-up and how many
answers are bitwise identical (they must all be: padding is never returned).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

from benchmarks import heldout
from jaxproj.io import datasets
from jaxproj.projection import api as engine


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--queries", type=int, default=1 << 20)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    sp = model.projector
    k = max(sp.layout.landmarks)
    padded_layout = dataclasses.replace(sp.layout, landmarks=(k,) * sp.layout.n_chains)
    padded = dataclasses.replace(model, projector=dataclasses.replace(sp, layout=padded_layout))
    test = datasets.valid_descriptors(
        datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    )
    h = np.ascontiguousarray(np.tile(test, (-(-args.queries // len(test)), 1))[: args.queries])
    variants = {"ragged": model, "padded": padded}
    out: dict = {"landmarks": model.landmarks, "queries": args.queries}
    answers = {}
    for name, m in variants.items():
        t0 = time.perf_counter()
        answers[name] = engine.project(m, h)[0]
        out[f"{name}_first_call_s"] = time.perf_counter() - t0
    best = dict.fromkeys(variants, np.inf)
    for _ in range(args.rounds):
        for name, m in variants.items():
            t0 = time.perf_counter()
            engine.project(m, h)
            best[name] = min(best[name], time.perf_counter() - t0)
    for name in variants:
        out[f"{name}_poses_per_s"] = args.queries / best[name]
    out["speedup"] = best["padded"] / best["ragged"]
    out["identical"] = int(np.sum(np.all(answers["ragged"] == answers["padded"], axis=1)))
    print(json.dumps(out, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
