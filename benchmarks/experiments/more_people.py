"""Does a model trained on more people shrink the tail on people it never saw? (issue 29, item 3)

Two models per fold, both with the default settings (``BuildConfig()``): MSR Action3D training
subjects 1,3,5,7,9 only (the default model), and the same plus the whole recordings of some
UTKinect-Action3D people. Evaluated, relaxed L = M = 10, unsmoothed, against the IK, on the
UTKinect people left out of that fold (upper-body segments) and on the held-out MSR subjects
2,4,6,8,10 (arm actions). Folds over the five bundled UTKinect people: train {3, 4, 6} / test
{7, 9}, and train {7, 9} / test {3, 4, 6}; the UTKinect rows pool both folds' test frames.

    python -m benchmarks.experiments.more_people [--msr-model P.npz] [--json OUT]

``--msr-model``: the MSR-only default model when already built (``jaxproj build``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from jaxproj.eval import evaluate as ev
from jaxproj.eval import metrics
from jaxproj.io import datasets
from jaxproj.projection import api as engine

FOLDS = (((3, 4, 6), (7, 9)), ((7, 9), (3, 4, 6)))


def scores(model: engine.Model, data: ev.EvalData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame (M_max, M_avg, M_max without ElbowYaw) of the relaxed projection, deg."""
    h = data.descriptors[data.valid]
    q, _ = engine.project(model, h)
    truth = data.truth[data.valid]
    m_max, m_avg = metrics.frame_errors(q, truth)
    return m_max, m_avg, metrics.m_max_without(q, truth)


def summary(m_max: np.ndarray, m_avg: np.ndarray, no_ey: np.ndarray) -> dict:
    return {
        "frames": len(m_max),
        "M_avg_median": float(np.median(m_avg)),
        "M_max_p95": float(np.percentile(m_max, 95)),
        "M_max_no_elbow_yaw_p95": float(np.percentile(no_ey, 95)),
        "share_M_max_over_30": float(np.mean(m_max > 30)),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--msr-model", help="the MSR-only default model (else built)")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    msr_train = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS))
    if args.msr_model:
        msr_only = engine.load(args.msr_model)
    else:
        msr_only = engine.build(msr_train, engine.BuildConfig())
    msr_test = ev.prepare(
        datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    )
    pooled: dict[str, list] = {"msr_only": [], "msr_plus_utkinect": []}
    out: dict = {"folds": []}
    for train_people, test_people in FOLDS:
        utk_train = datasets.valid_descriptors(
            datasets.utkinect_action3d(subjects=train_people, segments=False)
        )
        both = engine.build(np.concatenate([msr_train, utk_train]), engine.BuildConfig())
        test = ev.prepare(
            datasets.utkinect_action3d(
                subjects=test_people, actions=datasets.UTK_UPPER_BODY_ACTIONS
            )
        )
        fold: dict = {"train_utkinect": train_people, "test_utkinect": test_people,
                      "utkinect_train_frames": len(utk_train),
                      "landmarks": both.landmarks}  # fmt: skip
        for name, model in (("msr_only", msr_only), ("msr_plus_utkinect", both)):
            s = scores(model, test)
            pooled[name].append(s)
            msr = summary(*scores(model, msr_test))
            fold[name] = {"utkinect": summary(*s), "msr_held_out": msr}
        out["folds"].append(fold)
        print(f"fold {train_people} / {test_people}: {json.dumps(fold)}", file=sys.stderr)
    print("| model | UTKinect held-out people: median M_avg / p95 M_max / p95 no EY / share > 30 | "
          "MSR held out (fold 1, fold 2): median M_avg / p95 M_max |\n|---|---|---|")  # fmt: skip
    for name, parts in pooled.items():
        u = summary(*(np.concatenate(x) for x in zip(*parts, strict=True)))
        out[name] = u
        m = [f[name]["msr_held_out"] for f in out["folds"]]
        msr = ", ".join(f"{x['M_avg_median']:.2f} / {x['M_max_p95']:.1f}" for x in m)
        print(f"| {name} | {u['M_avg_median']:.2f} / {u['M_max_p95']:.1f} / "
              f"{u['M_max_no_elbow_yaw_p95']:.1f} / {100 * u['share_M_max_over_30']:.1f} % "
              f"({u['frames']} frames) | {msr} |")  # fmt: skip
    out["wall_s"] = time.perf_counter() - t0
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
