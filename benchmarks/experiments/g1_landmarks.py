"""How many landmarks should the G1's chains have, and what do the IK's human ranges do?

(Issue 44.) Tuned on training people only: models are built on a fold of the default training
set (MSR Action3D subjects 1, 3, 5 and UTKinect-Action3D people 3, 4) and scored on the rest of
it (MSR subjects 7, 9 and UTKinect person 6, every frame of every recording); the held-out people
(MSR 2, 4, 6, 8, 10; UTKinect 7, 9) are not read. Per setting: the landmarks per chain, the build
time, the relaxed projection (L = M = 10, unsmoothed, ``jaxproj.project``) against the G1's
generic IK (its own labels: the IK of the same setting), median M_avg and p95 M_max over the 21
driven joints (deg) and the median M_avg per chain, the 90th percentile of the relaxed value
(the least back-projection deviation: the G1's ``confidence`` scale, people the model did not
see, as ``projection.confidence.DEVIATION_SCALE`` is the NAO's), and the projection's time per
pose (one
batch of the validation descriptors, the median of 5 calls after a warm-up, on the default JAX
device).

Settings: ``--landmarks`` a list of per-chain landmark targets (``BuildConfig.landmarks``), each
with the G1's correspondence as it is (``Correspondence.ranges``: ``HUMAN_RANGES``); and with
``--no-ranges N`` one more model of N landmarks whose IK uses the robot's full limits.

    python -m benchmarks.experiments.g1_landmarks [--landmarks 1000,2000,4000,8000]
        [--no-ranges 4000] [--json OUT]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import time

import jax
import numpy as np

import jaxproj
from jaxproj import robots
from jaxproj.io import datasets
from jaxproj.robots.generic import with_generic_ik

TRAIN_MSR, TRAIN_UTK = (1, 3, 5), (3, 4)
VALID_MSR, VALID_UTK = (7, 9), (6,)


_G1 = robots.UNITREE_G1


def _use_ranges(on: bool) -> None:
    """Register the G1 with its human ranges or without them (a variant of its generic IK)."""
    solver = _G1.generic
    assert solver is not None
    ranges = solver.correspondence.ranges if on else ()
    corr = dataclasses.replace(solver.correspondence, ranges=ranges)
    robots.register(_G1 if on else with_generic_ik(_G1, corr, solver.config), replace=True)


def _descriptors(seqs: list) -> np.ndarray:
    return np.asarray(datasets.valid_descriptors(seqs, bones="full"), np.float32)


def run(landmarks: int, ranges: bool, train: np.ndarray, valid: np.ndarray) -> dict:
    _use_ranges(ranges)
    g1 = robots.get("unitree_g1")
    t0 = time.perf_counter()
    model = jaxproj.build(train, jaxproj.BuildConfig(robot="unitree_g1", landmarks=landmarks))
    build_s = time.perf_counter() - t0
    truth = np.asarray(g1.solve_ik(valid, "full"))
    q, value = (np.asarray(a) for a in jaxproj.project(model, valid))  # compile and warm
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        q = np.asarray(jaxproj.project(model, valid)[0])
        times.append(time.perf_counter() - t0)
    err = np.degrees(np.abs(q - truth))
    chains = {c.name: [g1.driven_joints.index(j) for j in c.joints] for c in g1.chains}
    return {
        "landmarks_target": landmarks,
        "ranges": ranges,
        "landmarks": dict(model.landmarks),
        "build_s": round(build_s, 1),
        "median_m_avg_deg": round(float(np.median(err.mean(1))), 3),
        "p95_m_max_deg": round(float(np.percentile(err.max(1), 95)), 2),
        "median_m_avg_per_chain_deg": {
            k: round(float(np.median(err[:, v].mean(1))), 3) for k, v in chains.items()
        },
        "relaxed_value_p90": round(float(np.percentile(value, 90)), 4),
        "us_per_pose": round(float(np.median(times)) / len(valid) * 1e6, 3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--landmarks", default="1000,2000,4000,8000")
    ap.add_argument("--no-ranges", type=int, default=None)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    train = _descriptors(datasets.training_sequences(TRAIN_UTK, TRAIN_MSR))
    valid = _descriptors(datasets.training_sequences(VALID_UTK, VALID_MSR))
    out = {
        "device": str(jax.devices()[0].device_kind),
        "platform": platform.platform(),
        "jax": jax.__version__,
        "train": {"msr": TRAIN_MSR, "utkinect": TRAIN_UTK, "frames": len(train)},
        "validation": {"msr": VALID_MSR, "utkinect": VALID_UTK, "frames": len(valid)},
        "runs": [],
    }
    settings = [(int(n), True) for n in args.landmarks.split(",")]
    if args.no_ranges:
        settings.append((args.no_ranges, False))
    for n, ranges in settings:
        row = run(n, ranges, train, valid)
        print(json.dumps(row), flush=True)
        out["runs"].append(row)
        if args.json:  # after each run: a long list can be cut short
            with open(args.json, "w") as f:
                json.dump(out, f, indent=1)
    _use_ranges(True)


if __name__ == "__main__":
    main()
