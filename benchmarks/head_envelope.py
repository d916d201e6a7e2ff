"""The NAO head with default ``retarget``: frames outside the head envelope, frames at a limit.

For every recording of the bundled MSR Action3D and UTKinect-Action3D data and the BVH clips in
``tests/data/cmu_bvh``, retarget with the defaults (``jaxproj.retarget``; method ``ik``, and
``relaxed`` with a small model built here on MSR Action3D's training people) and count, over the
frames of each dataset:

* ``outside``: frames whose (HeadYaw, HeadPitch) lie outside NAOqi's head anti-collision envelope
  (Aldebaran's table, interpolated here with NumPy in float64) by more than 1e-6 rad;
* ``at_limit``: frames whose HeadPitch lies within 0.5 deg of the envelope's bound at their
  HeadYaw (or of the joint limits).

``--neck off`` measures the former behaviour (no per-recording levelling: every recording's
neutral is MSR Action3D's median neck tilt); the envelope clip is always on in this code, so the
"before" envelope count is taken on the unclipped head angles of that run (the IK's raw pitch).

    python -m benchmarks.head_envelope [--neck recording|off] [--out FILE]

Writes JSON (default ``benchmarks/results/head_envelope_<neck>.json``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import jaxproj
from jaxproj.errors import NoValidFrameError
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.robots.nao_h25 import robot

YAW_DEG = np.array([0.0, 27.85, 43.32, 51.74, 62.45, 87.49, 119.52])
PITCH_MIN_DEG = np.array([-38.5, -38.5, -31.40, -27.50, -24.64, -18.91, -25.73])
PITCH_MAX_DEG = np.array([29.51, 24.18, 21.20, 18.91, 17.19, 11.46, 18.91])
BVH = Path(__file__).resolve().parents[1] / "tests" / "data" / "cmu_bvh"


def envelope_deg(yaw_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pitch bounds (deg) at ``yaw_deg``: the table, symmetric in yaw, within the joint limits."""
    a = np.abs(yaw_deg)
    lo = np.maximum(np.interp(a, YAW_DEG, PITCH_MIN_DEG), math.degrees(robot.LOWER[1]))
    hi = np.minimum(np.interp(a, YAW_DEG, PITCH_MAX_DEG), math.degrees(robot.UPPER[1]))
    return lo, hi


def head_counts(yaw: np.ndarray, pitch: np.ndarray) -> dict[str, int]:
    """Frames outside the envelope and within 0.5 deg of a bound (angles in rad)."""
    y, p = np.degrees(yaw.astype(np.float64)), np.degrees(pitch.astype(np.float64))
    lo, hi = envelope_deg(y)
    tol = math.degrees(1e-6)
    return {
        "frames": int(len(p)),
        "outside": int(((p < lo - tol) | (p > hi + tol)).sum()),
        "at_limit": int(((p <= lo + 0.5) | (p >= hi - 0.5)).sum()),
    }


def _model():
    """A small model: 300 landmarks per chain from MSR Action3D's training people."""
    from jaxproj.projection import api

    train = datasets.valid_descriptors(datasets.msr_action3d(subjects=datasets.TRAIN_SUBJECTS))
    return api.build(train, api.BuildConfig(landmarks=300, seed=0))


def run(neck: str) -> dict:
    sets = {
        "msr_action3d": datasets.msr_action3d(),
        "utkinect": datasets.utkinect_action3d(),
        "cmu_bvh": datasets.load_folder(BVH).sequences,
    }
    neutral = "recording" if neck == "recording" else None
    model = _model()
    out: dict = {"neck_neutral": neck, "datasets": {}}
    y_i, p_i = robot.IDX["HeadYaw"], robot.IDX["HeadPitch"]
    for name, seqs in sets.items():
        res: dict = {"recordings": len(seqs)}
        for method in ("ik", "relaxed"):
            yaw, pitch, raw_yaw, raw_pitch = [], [], [], []
            skipped = 0
            for s in seqs:
                kw = {"model": model} if method == "relaxed" else {}
                try:
                    r = jaxproj.retarget(s.positions, s.valid, times=s.times,
                                         neck_neutral=neutral, **kw)  # fmt: skip
                except NoValidFrameError:  # nothing to retarget: not counted
                    skipped += 1
                    continue
                yaw.append(r.angles[:, y_i])
                pitch.append(r.angles[:, p_i])
                if method == "ik" and neck == "off":  # the former IK: no envelope clip
                    d, _ = descriptor(s.positions)
                    n = np.asarray(d)[:, :3].astype(np.float64)
                    raw_yaw.append(np.clip(np.arctan2(n[:, 1], n[:, 2]), robot.LOWER[0],
                                           robot.UPPER[0]))  # fmt: skip
                    raw_pitch.append(np.clip(np.arctan2(n[:, 0], n[:, 2]) - math.radians(-27.1),
                                             robot.LOWER[1], robot.UPPER[1]))  # fmt: skip
            c = head_counts(np.concatenate(yaw), np.concatenate(pitch))
            res[method] = {**c, "at_limit_share": c["at_limit"] / max(c["frames"], 1),
                           "skipped_no_valid_frame": skipped}  # fmt: skip
            if raw_yaw:
                raw = head_counts(np.concatenate(raw_yaw), np.concatenate(raw_pitch))
                res["ik_unclipped_per_frame"] = {
                    **raw,
                    "at_limit_share": raw["at_limit"] / max(raw["frames"], 1),
                }
        out["datasets"][name] = res
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--neck", choices=("recording", "off"), default="recording")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    result = run(args.neck)
    result["seconds"] = round(time.perf_counter() - t0, 1)
    path = args.out or Path(__file__).parent / "results" / f"head_envelope_{args.neck}.json"
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
