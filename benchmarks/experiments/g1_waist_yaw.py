"""The G1's waist yaw from its IK (issue 57, item 3): held-out people and a twisted person.

The G1's collision-aware generic IK (``robots.get("unitree_g1").ik``, one call, compile
included) on ``--frames`` evenly spaced valid frames of the held-out MSR Action3D subjects
(2, 4, 6, 8, 10; ``bones="full"``), and on a synthetic person standing with the upper body
turned +-``--turn`` deg about the vertical against the hips (x forward, y left, z up): the waist
yaw should follow the turn in sign and size (a left turn of the shoulders is a positive yaw).
Prints the median / p90 / max of |yaw|, |roll|, |pitch| in deg and the synthetic answers; with
the hip-line row unread (before the fix) the yaw is 0 on every frame.

    python -m benchmarks.experiments.g1_waist_yaw [--frames 576] [--turn 20] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np

import jaxproj
from jaxproj import robots
from jaxproj.human import skeleton
from jaxproj.io import datasets


def spine_rest() -> tuple[float, float, float]:
    """The G1's calibrated ``spine_lower`` direction (its correspondence row's ``rest``)."""
    solver = robots.UNITREE_G1.generic
    assert solver is not None
    (row,) = solver.correspondence.rows(("spine_lower",))
    assert row.rest is not None
    return row.rest


def twisted_skeleton(turn: float) -> np.ndarray:
    """``(20, 3)`` Kinect v1 joints (m; x forward, y left, z up) of a person standing with the
    upper body, from the Spine point up, turned ``turn`` deg about the vertical through the hip
    centre (the spine at the G1's calibrated rest, its ``spine_lower`` row's ``rest``: no waist
    pitch)."""
    j = skeleton.JOINT_NAMES.index
    pos = np.zeros((20, 3))
    pos[j("Spine")] = 0.1 * np.asarray(spine_rest())
    pos[j("ShoulderCenter")] = (0.0, 0.0, 0.45)
    pos[j("Head")] = (0.0, 0.0, 0.65)
    for side, y in (("Left", 1.0), ("Right", -1.0)):
        pos[j(f"Shoulder{side}")] = (0.0, 0.18 * y, 0.42)
        pos[j(f"Elbow{side}")] = (0.0, 0.2 * y, 0.15)
        pos[j(f"Wrist{side}")] = (0.0, 0.2 * y, -0.1)
        pos[j(f"Hand{side}")] = (0.02, 0.2 * y, -0.18)
        pos[j(f"Hip{side}")] = (0.03, 0.08 * y, -0.05)
        pos[j(f"Knee{side}")] = (0.03, 0.09 * y, -0.45)
        pos[j(f"Ankle{side}")] = (0.0, 0.09 * y, -0.85)
        pos[j(f"Foot{side}")] = (0.1, 0.09 * y, -0.88)
    c, s = np.cos(np.radians(turn)), np.sin(np.radians(turn))
    upper = [j(n) for n in skeleton.JOINT_NAMES[1:12]]  # Spine .. HandRight
    pos[upper] = pos[upper] @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
    return pos


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=576)
    ap.add_argument("--turn", type=float, default=20.0)
    ap.add_argument("--json")
    args = ap.parse_args()
    g1 = robots.get("unitree_g1")
    seqs = datasets.msr_action3d(subjects=datasets.TEST_SUBJECTS)
    d = np.asarray(datasets.valid_descriptors(seqs, bones="full"))
    d = d[np.linspace(0, len(d) - 1, args.frames).astype(int)]
    turns = (args.turn, -args.turn)
    synth, ok = skeleton.descriptor(
        np.stack([twisted_skeleton(t) for t in turns]).astype(np.float32), "full"
    )
    assert np.asarray(ok).all()
    t0 = time.perf_counter()
    q = np.degrees(np.asarray(g1.ik(np.concatenate([d, np.asarray(synth)]))))  # one program
    seconds = time.perf_counter() - t0
    col = {k: g1.driven_joints.index(f"waist_{k}_joint") for k in ("yaw", "roll", "pitch")}
    out: dict = {
        "jaxproj": jaxproj.__version__,
        "machine": platform.machine(),
        "frames": len(d),
        "ik_seconds_with_compile": round(seconds, 1),
        "held_out": {},
        "twisted": {},
    }
    for k, c in col.items():
        a = np.abs(q[: len(d), c])
        out["held_out"][k] = {
            "median_abs_deg": round(float(np.median(a)), 2),
            "p90_abs_deg": round(float(np.percentile(a, 90)), 2),
            "max_abs_deg": round(float(a.max()), 2),
        }
    for i, t in enumerate(turns):
        out["twisted"][f"{t:+g}"] = {k: round(float(q[len(d) + i, c]), 3) for k, c in col.items()}
    print(json.dumps(out, indent=2))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)


if __name__ == "__main__":
    main()
