"""Which people should the default model train on? MSR alone against MSR + UTKinect people.

(Issue 29, item 3; re-measured for issue 43, item 7.) Two models per fold, both with the default
settings (``BuildConfig()``): MSR Action3D training subjects 1,3,5,7,9 only, and the same plus
the whole recordings of some UTKinect-Action3D people. Scored, relaxed L = M = 10, unsmoothed,
against the IK, on people no model of the fold trained on: the UTKinect people left out of the
fold (upper-body segments) and the held-out MSR subjects 2,4,6,8,10 (arm actions). Folds over
the five bundled UTKinect people: train {3, 4, 6} / test {7, 9} (the default model's split),
and train {7, 9} / test {3, 4, 6}; the pooled UTKinect rows join both folds' test frames.

The scored frames are read as ``jaxproj.retarget`` reads them: each evaluated sequence's neck
levelled to its own median tilt (``pipeline.level``, ``neck="recording"``), and the IK truth of
the levelled descriptor (``eval: recording``); ``eval: off`` (the raw descriptors, as
``jaxproj evaluate`` and the first measurement of 2026-11-24 read them) is reported beside it.
Training data: ``train_neck="off"`` is what ``jaxproj build`` trains on (the raw valid
descriptors); ``"recording"`` levels each training recording first.

Besides the errors: each model's landmarks, file size (``engine.save``), build time (the first
build of the run includes compilation) and relaxed projection speed (one batch of 65,536 held-out
MSR queries, median of repeated calls after a warm-up, on the default JAX device).

    python -m benchmarks.experiments.more_people [--train-neck off,recording] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import jax
import numpy as np

from jaxproj.eval import evaluate as ev
from jaxproj.eval import metrics
from jaxproj.human.skeleton import NECK_TILT_REFERENCE, descriptor, level_neck, neck_tilt
from jaxproj.io import datasets
from jaxproj.io.sequences import MotionSequence
from jaxproj.projection import api as engine
from jaxproj.robots import get
from jaxproj.timing import time_calls

FOLDS = (((3, 4, 6), (7, 9)), ((7, 9), (3, 4, 6)))
EVAL_NECKS = ("recording", "off")
SPEED_BATCH = 65536


def frame_descriptors(
    seqs: Sequence[MotionSequence], neck: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(F, m)`` descriptors of every frame of ``seqs``, ``(F,)`` validity and ``(S + 1,)``
    offsets. ``neck="recording"``: each sequence's neck levelled to its median tilt over its
    valid frames, as ``retarget`` does (``pipeline.level``), in one vectorised call."""
    pos = np.concatenate([np.asarray(s.positions, np.float32) for s in seqs])
    valid = np.concatenate([np.asarray(s.valid, bool) for s in seqs])
    d_raw, ok_raw = descriptor(pos)
    d, ok = np.asarray(d_raw), np.asarray(ok_raw) & valid
    offsets = np.concatenate([[0], np.cumsum([len(s.valid) for s in seqs])]).astype(np.int64)
    if neck == "recording":
        tilt = np.asarray(neck_tilt(d))
        neutral = np.full(len(d), NECK_TILT_REFERENCE, np.float32)
        for a, b in zip(offsets[:-1], offsets[1:], strict=True):
            v = ok[a:b]
            if v.any():
                neutral[a:b] = np.median(tilt[a:b][v])
        d = np.where(ok[:, None], np.asarray(level_neck(d, neutral)), d)
    elif neck != "off":
        raise ValueError(f"neck must be 'recording' or 'off', got {neck!r}")
    return d, ok, offsets


def training(seqs: Sequence[MotionSequence], neck: str) -> np.ndarray:
    """The valid training descriptors of ``seqs`` (``neck`` as in ``frame_descriptors``)."""
    d, ok, _ = frame_descriptors(seqs, neck)
    return d[ok]


def prepare(seqs: Sequence[MotionSequence], neck: str) -> ev.EvalData:
    """``evaluate.prepare``'s data with the descriptors and the IK truth of ``neck``."""
    data = ev.prepare(seqs)
    d, ok, _ = frame_descriptors(seqs, neck)
    truth = np.asarray(get(data.robot).solve_ik(d, "upper"))
    return dataclasses.replace(data, descriptors=d, valid=ok, truth=truth)


def scores(model: engine.Model, data: ev.EvalData) -> tuple[np.ndarray, ...]:
    """Per-frame M_max, M_avg, M_max without ElbowYaw (deg) and ``(F, n)`` per-joint errors of
    the relaxed projection."""
    q, _ = engine.project(model, data.descriptors[data.valid])
    truth = data.truth[data.valid]
    m_max, m_avg = metrics.frame_errors(q, truth)
    per_joint = np.degrees(np.abs(np.asarray(q, np.float64) - truth))
    return m_max, m_avg, metrics.m_max_without(q, truth, robot=model.robot), per_joint


def summary(m_max: np.ndarray, m_avg: np.ndarray, no_ey: np.ndarray, per_joint: np.ndarray) -> dict:
    names = get(None).driven_joints
    return {
        "frames": len(m_max),
        "M_avg_median": float(np.median(m_avg)),
        "M_max_p95": float(np.percentile(m_max, 95)),
        "M_max_no_elbow_yaw_p95": float(np.percentile(no_ey, 95)),
        "share_M_max_over_30": float(np.mean(m_max > 30)),
        "per_joint_p95": {
            n: float(np.percentile(per_joint[:, j], 95)) for j, n in enumerate(names)
        },
    }


def cost(model: engine.Model, queries: np.ndarray, build_s: float) -> dict:
    """Landmarks, file size, build time and relaxed projection speed of ``model``."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.npz"
        engine.save(model, path)
        size = os.path.getsize(path)
    engine.project(model, queries)  # warm-up: compiles
    t = time_calls(lambda: engine.project(model, queries), min_repeats=5, min_time_s=2.0)
    return {
        "landmarks": model.landmarks,
        "landmarks_total": int(sum(model.landmarks.values())),
        "file_mb": size / 1e6,
        "n_train": model.n_train,
        "build_s": build_s,
        "poses_per_s": len(queries) / t.median_s,
        "speed_batch": len(queries),
    }


def timed_build(d: np.ndarray) -> tuple[engine.Model, float]:
    t0 = time.perf_counter()
    model = engine.build(d, engine.BuildConfig())
    jax.block_until_ready(model.projector)
    return model, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--train-neck",
        default="off",
        help="training descriptors: off (as `jaxproj build`), recording (levelled), or both "
        "comma-separated",
    )
    p.add_argument("--json", help="write the results here (rewritten after each step)")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    dev = jax.devices()[0]
    out: dict = {
        "device": f"{dev.platform}: {dev.device_kind}",
        "jax": jax.__version__,
        "date": time.strftime("%Y-%m-%d"),
        "protocol": (__doc__ or "").split("\n\n")[1].replace("\n", " "),
        "variants": {},
    }

    def write() -> None:
        out["wall_s"] = time.perf_counter() - t0
        if args.json:
            Path(args.json).write_text(json.dumps(out, indent=1))

    msr_seqs = datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS)
    msr_test_seqs = datasets.msr_action3d(
        subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS
    )
    msr_test = {n: prepare(msr_test_seqs, n) for n in EVAL_NECKS}
    queries = msr_test["off"].descriptors[msr_test["off"].valid]
    queries = np.resize(queries, (SPEED_BATCH, queries.shape[1]))
    for train_neck in args.train_neck.split(","):
        msr_train = training(msr_seqs, train_neck)
        msr_only, build_s = timed_build(msr_train)
        var: dict = {"msr_only_cost": cost(msr_only, queries, build_s), "folds": []}
        out["variants"][f"train_neck_{train_neck}"] = var
        pooled: dict = {n: {"msr_only": [], "msr_plus_utkinect": []} for n in EVAL_NECKS}
        for train_people, test_people in FOLDS:
            utk = datasets.utkinect_action3d(subjects=train_people, segments=False)
            both, build_s = timed_build(np.concatenate([msr_train, training(utk, train_neck)]))
            fold: dict = {
                "train_utkinect": train_people,
                "test_utkinect": test_people,
                "msr_plus_utkinect_cost": cost(both, queries, build_s),
            }
            test_seqs = datasets.utkinect_action3d(
                subjects=test_people, actions=datasets.UTK_UPPER_BODY_ACTIONS
            )
            for eval_neck in EVAL_NECKS:
                utk_test = prepare(test_seqs, eval_neck)
                block: dict = {}
                for name, model in (("msr_only", msr_only), ("msr_plus_utkinect", both)):
                    s = scores(model, utk_test)
                    pooled[eval_neck][name].append(s)
                    block[name] = {
                        "utkinect": summary(*s),
                        "msr_held_out": summary(*scores(model, msr_test[eval_neck])),
                    }
                fold[f"eval_neck_{eval_neck}"] = block
            var["folds"].append(fold)
            print(f"{train_neck} fold {train_people}/{test_people}: {json.dumps(fold)}",
                  file=sys.stderr, flush=True)  # fmt: skip
            write()
        for eval_neck in EVAL_NECKS:
            var[f"pooled_utkinect_eval_neck_{eval_neck}"] = {
                name: summary(*(np.concatenate(x) for x in zip(*parts, strict=True)))
                for name, parts in pooled[eval_neck].items()
            }
        write()
    print_table(out)
    return 0


def print_table(out: dict) -> None:
    """The markdown table of the results (docs/results.md)."""
    print("| training necks | eval necks | model | UTKinect held out, fold 1 {7, 9}; fold 2 "
          "{3, 4, 6}; pooled: median M_avg / p95 M_max / p95 no EY | MSR held out (fold 1; "
          "fold 2): median M_avg / p95 M_max / p95 no EY |\n|---|---|---|---|---|")  # fmt: skip

    def cell(x: dict) -> str:
        return f"{x['M_avg_median']:.2f} / {x['M_max_p95']:.1f} / {x['M_max_no_elbow_yaw_p95']:.1f}"

    for vname, var in out["variants"].items():
        for eval_neck in EVAL_NECKS:
            for name in ("msr_only", "msr_plus_utkinect"):
                blocks = [f[f"eval_neck_{eval_neck}"][name] for f in var["folds"]]
                pooled = var[f"pooled_utkinect_eval_neck_{eval_neck}"][name]
                utk = "; ".join([cell(b["utkinect"]) for b in blocks] + [cell(pooled)])
                msr = "; ".join(cell(b["msr_held_out"]) for b in blocks)
                print(f"| {vname[11:]} | {eval_neck} | {name} | {utk} | {msr} |")


if __name__ == "__main__":
    sys.exit(main())
