"""Do the full objective's jumps under a one-ulp input change go away with more Newton steps?

``full_continuity`` (held-out MSR subject 2, every joint coordinate moved by one float32 ulp)
lists the frames whose full-objective answer moves by more than 0.1 deg, and why. This reruns
only those frames (read from its JSON), as recorded and nudged, under the default
``FullConfig`` and with the step cap raised (``iterations``) and every problem solved to the
end (``finalists=0``): if a jump were a run stopped short of its minimum, a higher cap would
close it; if it stays, the two runs ended at different converged minima of the same
objective (different basins of the non-convex problem).

    python -m benchmarks.experiments.full_continuity_cap MODEL.npz
        [--cases benchmarks/results/full_continuity_cpu_msr_utk.json] [--json OUT]

The frames are projected as one small batch; the default row reproduces the recorded jumps
(checked by the printout, not assumed).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import jax
import numpy as np

from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig

SETTINGS = (
    {},
    {"iterations": 100},
    {"iterations": 300},
    {"iterations": 300, "finalists": 0},
)
"""``FullConfig`` changes tried, the default first."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--cases", default="benchmarks/results/full_continuity_cpu_msr_utk.json")
    ap.add_argument("--json")
    args = ap.parse_args()
    model = engine.load(args.model)
    cases = json.load(open(args.cases))["cases"]
    frames = sorted({c["frame"] for c in cases})
    seqs = datasets.msr_action3d(subjects=[2])  # full_continuity's --subjects 2
    pos = np.concatenate([s.positions[s.valid] for s in seqs]).astype(np.float32)
    d0, ok0 = descriptor(pos)
    d1, ok1 = descriptor(np.nextafter(pos, np.float32(np.inf)))
    ok = np.asarray(ok0) & np.asarray(ok1)
    d0, d1 = np.asarray(d0)[ok][frames], np.asarray(d1)[ok][frames]
    rows = []
    for change in SETTINGS:
        cfg = dataclasses.replace(FullConfig(), **change)
        t0 = time.perf_counter()
        r0, f0 = engine.project(model, d0, "full", full=cfg)
        r1, f1 = engine.project(model, d1, "full", full=cfg)
        move = np.degrees(np.abs(r0 - r1)).max(axis=1)
        gap = np.abs(f0 - f1) / np.maximum(np.minimum(f0, f1), 1e-30)
        row = {
            "change": change,
            "frames_over_0.1_deg": int(np.sum(move > 0.1)),
            "max_deg": float(move.max()),
            "deg": [round(float(x), 4) for x in move],
            "objective_gap_rel": [float(x) for x in gap],
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if k != "objective_gap_rel"}), flush=True)
    out = {"frames": frames, "device": str(jax.devices()[0].device_kind), "rows": rows}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
