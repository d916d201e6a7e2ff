"""How many queries the full objective's Newton solver should vmap together (experiment).

    python -m benchmarks.experiments.full_batching [--queries 262144] [--subs 512,2048,8192]

Default model built from the training subjects; held-out MSR descriptors tiled to
``--queries``; the public ``jaxproj.project`` with ``FullConfig()`` (and the variants named in
``--configs``) timed (compiled first, best of 2) with ``api.sub_batch`` forced to each size.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np

from benchmarks import heldout
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model")
    p.add_argument("--queries", type=int, default=1 << 18)
    p.add_argument("--subs", default="512,2048,8192")
    p.add_argument("--configs", default="", help="e.g. screen=6:iterations=16,finalists=1")
    args = p.parse_args(argv)
    model = heldout.default_model(args.model)
    test = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS))
    h = np.resize(
        test[np.random.default_rng(0).permutation(len(test))], (args.queries, test.shape[1])
    )
    cfgs = [FullConfig()]
    for spec in filter(None, args.configs.split(",")):
        kw = {k: int(v) for k, v in (item.split("=") for item in spec.split(":"))}
        cfgs.append(dataclasses.replace(FullConfig(), **kw))
    original = engine.sub_batch
    engine.sub_batch = lambda *a, **k: a[-1]  # type: ignore[assignment] # one vmap per batch
    for sub in (int(s) for s in args.subs.split(",")):
        for cfg in cfgs:
            engine.project(model, h[:sub], "full", full=cfg, batch_size=sub)
            best = np.inf
            for _ in range(2):
                t0 = time.perf_counter()
                engine.project(model, h, "full", full=cfg, batch_size=sub)
                best = min(best, time.perf_counter() - t0)
            diff = {
                k: v for k, v in dataclasses.asdict(cfg).items() if getattr(FullConfig(), k) != v
            }
            print(f"sub {sub} {diff or 'default'}: {len(h) / best:,.0f} poses/s", flush=True)
    engine.sub_batch = original
    return 0


if __name__ == "__main__":
    sys.exit(main())
