"""Speed of the full objective through the public API, default settings (``FullConfig()``).

    python -m benchmarks.experiments.full_speed [--model P.npz] [--queries 262144]

The default model (or ``--model``), ``jaxproj.project(model, h, "full")`` on a host array of
``--queries`` held-out MSR descriptors (tiled), compiled first (timed apart), best of 2 calls;
``ADAM_30`` in the same run as the baseline. Prints JSON.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from benchmarks import heldout
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import ADAM_30, FullConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=None)
    ap.add_argument("--queries", type=int, default=1 << 18)
    args = ap.parse_args()
    model = heldout.default_model(args.model)
    test = datasets.valid_descriptors(heldout.splits()["msr_held_out_arm"])
    h = np.ascontiguousarray(np.tile(test, (-(-args.queries // len(test)), 1))[: args.queries])
    out: dict = {"landmarks": model.landmarks, "queries": args.queries}
    for name, cfg in (("FullConfig()", FullConfig()), ("ADAM_30", ADAM_30)):
        t0 = time.perf_counter()
        engine.project(model, h, "full", full=cfg)
        first = time.perf_counter() - t0
        best = np.inf
        for _ in range(2):
            t0 = time.perf_counter()
            engine.project(model, h, "full", full=cfg)
            best = min(best, time.perf_counter() - t0)
        out[name] = {"first_call_s": first, "poses_per_s": args.queries / best}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
