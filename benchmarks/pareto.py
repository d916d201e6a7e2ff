"""The default model's Pareto front: landmark density against accuracy, speed and file size.

    python -m benchmarks.pareto [--bandwidths 0.01875,0.025,0.035,0.04352] [--queries 1048576]
        [--json OUT]

Per arm bandwidth (both arms; the head keeps the NAO file's bandwidth, every other setting is the
default's), one model built by ``BuildConfig(bandwidth=(head, b, b))`` on MSR
training subjects 1,3,5,7,9 (``0.01875`` is ``BuildConfig()``, the default model; ``0.04352``
gives the paper's ~1644 landmarks per arm): its landmarks per chain, its model file's size
(``jaxproj.save``), the relaxed projection's accuracy against the IK on the held-out splits
(``benchmarks.heldout``: MSR subjects 2,4,6,8,10 arm actions, UTKinect upper body; valid
frames, unsmoothed, L = M = 10; median M_avg and p95 M_max over the 10 driven joints, deg) and
the public ``jaxproj.project``'s speed on a host array of ``--queries`` held-out descriptors
(default arguments; compiled first, timed apart, best of 3 calls), on whatever device JAX
runs.

The held-out accuracy is reported, not used to choose: the default was chosen on the training
subjects' leave-one-subject-out folds (``docs/history/tuning.md``), and ``docs/results.md``
states the rule.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

from benchmarks import heldout
from jaxproj.eval.metrics import frame_errors
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik

HEAD = NAO_H25.chains[0].bandwidth
"""The NAO head chain's bandwidth (its robot file's, kept: ``Chain.keep_bandwidth``)."""


def accuracy(model: engine.Model) -> dict:
    """Relaxed, unsmoothed, L = M = 10, against the IK: per held-out split, the valid frames'
    median M_avg and p95 M_max (deg)."""
    out = {}
    for split, seqs in heldout.splits(model.config.utkinect_people).items():
        d = datasets.valid_descriptors(seqs)
        pred, _ = engine.project(model, d)
        m_max, m_avg = frame_errors(pred, np.asarray(ik.solve_driven(d)))
        out[split] = {
            "frames": len(d),
            "M_avg_median": float(np.median(m_avg)),
            "M_max_p95": float(np.percentile(m_max, 95)),
        }
    return out


def speed(model: engine.Model, queries: int) -> dict:
    """The public ``jaxproj.project`` (relaxed, defaults) on ``queries`` host poses."""
    test = datasets.valid_descriptors(heldout.splits()["msr_held_out_arm"])
    h = np.ascontiguousarray(np.tile(test, (-(-queries // len(test)), 1))[:queries])
    t0 = time.perf_counter()
    engine.project(model, h)
    first = time.perf_counter() - t0
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        engine.project(model, h)
        best = min(best, time.perf_counter() - t0)
    return {"queries": queries, "first_call_s": first, "poses_per_s": queries / best,
            "us_per_pose": best / queries * 1e6}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bandwidths", default="0.01875,0.025,0.035,0.04352")
    ap.add_argument("--queries", type=int, default=1 << 20)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS))
    rows = []
    device = str(jax.devices()[0].device_kind)
    for b in (float(t) for t in args.bandwidths.split(",")):
        # MSR alone, as measured (docs/results.md): UTKinect scored on all five people
        cfg = engine.BuildConfig(bandwidth=(HEAD, b, b), utkinect_people=())
        t0 = time.perf_counter()
        model = engine.build(train, cfg)
        build_s = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "model.npz"
            engine.save(model, path)
            size = path.stat().st_size
        row = {"arm_bandwidth": b, "landmarks": model.landmarks, "build_s": build_s,
               "file_bytes": size, "accuracy": accuracy(model),
               "speed": speed(model, args.queries), "device": device}  # fmt: skip
        rows.append(row)
        acc = row["accuracy"]
        print(
            f"arm bandwidth {b}: {model.landmarks}, {size / 1e6:.1f} MB, "
            + ", ".join(
                f"{k} {v['M_avg_median']:.2f} / {v['M_max_p95']:.1f}" for k, v in acc.items()
            )
            + f", {row['speed']['poses_per_s']:.3g} poses/s on {device}",
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
