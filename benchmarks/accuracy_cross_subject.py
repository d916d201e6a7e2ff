"""Accuracy on people the landmarks never saw: whole-body vs per-chain, both objectives, the
baselines, on held-out MSR Action3D subjects and on a second dataset (UTKinect-Action3D).

Landmarks and kernels from the default training set (``datasets.training_sequences``: MSR
Action3D subjects 1,3,5,7,9, all actions, and the whole recordings of the UTKinect-Action3D people
``--utkinect-people``, default 3, 4, 6; ``none``: MSR alone, the default model of 0.2.0; valid
frames). Splits, people no model here trained on:

* ``msr``: every valid frame of the arm-heavy actions (a01-a12, a17-a19) of subjects 2,4,6,8,10
  (the paper's cross-subject protocol; 8,355 frames);
* ``utkinect``: every valid frame of the upper-body segments (throw, push, pull, waveHands,
  clapHands) of the bundled UTKinect-Action3D people not in ``--utkinect-people`` (7 and 9 by
  default, 578 frames; all five with ``none``: 1,345 frames; ``datasets.utkinect_held_out``),
  another room and capture program.

Unsmoothed, L = M = 10, degrees over ``robot.DRIVEN_JOINTS`` against the analytic IK. Each
method's block is ``jaxproj.eval.metrics.summarize_errors``: the paper's M_max / M_avg,
per-joint p50 / p95, M_max without the two ElbowYaw joints, and task-space errors from forward
kinematics of the MJCF (wrist and elbow position in cm, upper-arm / forearm direction in degrees).
The baselines
(nearest landmark, kNN average, global ELM) run on the same landmarks, per chain for a per-chain
model. Identity: each chain's landmarks projected through its own kernels.

    python -m benchmarks.accuracy_cross_subject [--chains upper,whole] [--datasets msr,utkinect]
        [--utkinect-people 3,4,6|none] [--landmarks 1644] [--seed 0] [--json OUT]
    python -m benchmarks.accuracy_cross_subject --quick    # smoke run (see --help)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import jax
import numpy as np

from jaxproj.eval import evaluate, metrics
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig
from jaxproj.robots import NAO_H25
from jaxproj.robots.nao_h25 import ik

OBJECTIVES = {
    "relaxed": ("relaxed", None),
    "full": ("full", FullConfig()),
    "full_min_with_candidate": ("full", FullConfig(objective="min", include_candidate=True)),
}
BASELINES = ("nearest_landmark", "knn_average", "global_elm")


def split(name: str, utkinect_people: tuple[int, ...]) -> np.ndarray:
    """``(F, 15)`` valid descriptors of a held-out split (see the module doc)."""
    if name == "msr":
        seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS, actions=datasets.ARM_ACTIONS)
    elif name == "utkinect":
        seqs = datasets.utkinect_held_out(utkinect_people)
    else:
        raise SystemExit(f"unknown split {name!r}")
    return datasets.valid_descriptors(seqs)


def identity(model: engine.Model, objective: str, cfg: FullConfig | None) -> dict:
    """Worst joint error (deg) projecting every chain's landmarks through the model."""
    sp = model.projector
    worst = []
    for c in range(sp.layout.n_chains):
        p = sp.chain(c)
        got, _ = engine.project(p, np.asarray(p.human), objective, full=cfg)
        worst.append(np.degrees(np.abs(got - np.asarray(p.robot))).max(axis=1))
    w = np.concatenate(worst)
    return {
        "median": float(np.median(w)),
        "p95": float(np.percentile(w, 95)),
        "max": float(w.max()),
    }


def run(args: argparse.Namespace) -> dict:
    people = args.utkinect_people
    train = datasets.valid_descriptors(datasets.training_sequences(people))
    tests = {name: split(name, people) for name in args.datasets}
    if args.quick:
        train = train[::4]
        tests = {k: v[::20] for k, v in tests.items()}
    truth = {k: np.asarray(ik.solve_driven(v)) for k, v in tests.items()}
    points = {k: metrics.arm_points(v, robot=NAO_H25) for k, v in truth.items()}  # one FK per split
    objectives = dict(OBJECTIVES)
    if args.quick:
        objectives.pop("full_min_with_candidate")
    out: dict = {
        "train_frames": len(train),
        "utkinect_people": list(people),
        "test_frames": {k: len(v) for k, v in tests.items()},
        "device": str(jax.devices()[0]),
        "quick": args.quick,
        "models": {},
    }
    for chains in args.chains:
        cfg = engine.BuildConfig(chains=chains, seed=args.seed, utkinect_people=people)
        if args.landmarks is not None:
            cfg = dataclasses.replace(cfg, landmarks=args.landmarks)
        t0 = time.perf_counter()
        model = engine.build(train, cfg)
        rec: dict = {
            "landmarks": model.landmarks,
            "bandwidth": list(model.bandwidth),
            "build_s": time.perf_counter() - t0,
            "config": dataclasses.asdict(model.config),
            "identity_M_max": {},
            "splits": {},
        }
        for name, (objective, fc) in objectives.items():
            rec["identity_M_max"][name] = identity(model, objective, fc)
        for split_name, d in tests.items():
            methods = {}
            for name, (objective, fc) in objectives.items():
                t0 = time.perf_counter()
                pred, _ = engine.project(model, d, objective, full=fc)
                wall = time.perf_counter() - t0
                methods[name] = metrics.summarize_errors(
                    pred, truth[split_name], truth_points=points[split_name], robot=NAO_H25
                ) | {"wall_s": wall}
            for name in BASELINES:
                pred = evaluate.predict_method(model, name, d)
                methods[name] = metrics.summarize_errors(
                    pred, truth[split_name], truth_points=points[split_name], robot=NAO_H25
                )
            rec["splits"][split_name] = methods
        out["models"][chains] = rec
    return out


def print_table(out: dict) -> None:
    print(f"landmarks from {out['train_frames']} training frames; held out: {out['test_frames']}")
    head = (
        f"{'model':6s} {'split':9s} {'method':24s} {'M_avg med':>9s} {'M_max p95':>9s} "
        f"{'p95 no EY':>9s} {'hand cm med/p95 (L, R)':>24s}"
    )
    for chains, rec in out["models"].items():
        print(f"\n{chains}: landmarks {rec['landmarks']}, build {rec['build_s']:.1f} s")
        print(head)
        for split_name, methods in rec["splits"].items():
            for name, s in methods.items():
                hand = [s["task_space"][side]["hand_cm"] for side in metrics.sides(NAO_H25)]
                print(
                    f"{chains:6s} {split_name:9s} {name:24s} {s['M_avg']['median']:9.2f} "
                    f"{s['M_max']['p95']:9.1f} {s['M_max_no_elbow_yaw']['p95']:9.1f} "
                    + " ".join(f"{h['median']:5.1f}/{h['p95']:5.1f}" for h in hand)
                )
        for name, ident in rec["identity_M_max"].items():
            print(f"  identity {name}: max {ident['max']:.4f} deg")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--chains", default="upper,whole", type=lambda s: s.split(","))
    ap.add_argument("--datasets", default="msr,utkinect", type=lambda s: s.split(","))
    ap.add_argument(
        "--utkinect-people",
        default=datasets.UTK_TRAIN_SUBJECTS,
        type=lambda s: () if s == "none" else tuple(int(x) for x in s.split(",")),
        help="UTKinect people in training (default 3,4,6; none: MSR alone)",
    )
    ap.add_argument("--landmarks", type=int, default=None, help="per arm (default: BuildConfig)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: every 4th training frame, every 20th test frame, no min variant",
    )
    args = ap.parse_args()
    if args.quick and args.landmarks is None:
        args.landmarks = 150
    out = run(args)
    print_table(out)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
