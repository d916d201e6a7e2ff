"""Accuracy against the number of given pairs: a projector from hand-given pairs (no mean shift,
``projection.api.from_landmarks``, what ``jaxproj build --pairs`` builds) against one from
mean-shift landmarks of the same count (``jaxproj build --landmarks N``).

The paper builds its landmarks from an IK "or manually when the number of samples is small".
Here the pairs stand in for hand-given ones: N frames of the training people (MSR Action3D
subjects 1,3,5,7,9, every action), evenly spaced over the recordings as someone sampling a
capture by hand would take them, each labelled by the robot's IK. The mean-shift model is the
regular build on the same training frames with N landmarks per chain (the NAO's head keeps its
tuned bandwidth, ``Chain.keep_bandwidth``). Both are scored on the held-out MSR subjects
2,4,6,8,10 (every action, valid frames): the relaxed projection (L = M = 10) against the IK,
median M_avg and p95 M_max over the robot's driven joints (deg). N: the paper's 86 / 961 /
1,644 landmarks.

    python -m benchmarks.pairs_accuracy [--robot nao_h25] [--sizes 86,961,1644] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import jax
import numpy as np

import jaxproj
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.projection import api as engine


def _score(q: np.ndarray, truth: np.ndarray) -> dict:
    err = np.degrees(np.abs(np.asarray(q) - np.asarray(truth)))
    return {
        "median_M_avg_deg": round(float(np.median(err.mean(axis=1))), 3),
        "p95_M_max_deg": round(float(np.percentile(err.max(axis=1), 95)), 2),
    }


def run(robot_name: str, sizes: tuple[int, ...]) -> dict:
    robot = robots.get(robot_name)
    cfg = engine.BuildConfig(robot=robot_name, utkinect_people=())
    train = np.asarray(
        datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS),
                                   bones=cfg.bones), np.float32,
    )  # fmt: skip
    held = np.asarray(
        datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS),
                                   bones=cfg.bones), np.float32,
    )  # fmt: skip
    truth = np.asarray(robot.solve_ik(held, cfg.bones))
    out: dict = {
        "robot": robot_name,
        "device": jax.devices()[0].device_kind,
        "platform": platform.processor() or platform.machine(),
        "train_frames": len(train),
        "held_out_frames": len(held),
        "driven_joints": len(robot.driven_joints),
        "rows": [],
    }
    for n in sizes:
        rows = np.linspace(0, len(train) - 1, n).round().astype(int)
        t0 = time.perf_counter()
        labels = np.asarray(robot.solve_ik(train[rows], cfg.bones))
        pairs = engine.from_landmarks(train[rows], labels, cfg)
        pairs_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        shifted = engine.build(train, engine.BuildConfig(robot=robot_name, utkinect_people=(),
                                                         landmarks=n), calibrate=False)  # fmt: skip
        shift_s = time.perf_counter() - t0
        row = {"pairs": n}
        for name, model, secs in (
            ("given_pairs", pairs, pairs_s),
            ("mean_shift", shifted, shift_s),
        ):
            q = np.asarray(jaxproj.project(model, held, "relaxed")[0])
            row[name] = {"landmarks": dict(model.landmarks), "build_s": round(secs, 1),
                         **_score(q, truth)}  # fmt: skip
        out["rows"].append(row)
        print(json.dumps(row), flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="nao_h25")
    ap.add_argument("--sizes", default="86,961,1644")
    ap.add_argument("--json")
    args = ap.parse_args()
    out = run(args.robot, tuple(int(x) for x in args.sizes.split(",")))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
