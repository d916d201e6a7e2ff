"""Upper body without hips (issue 60): the NAO driven by a recording whose hips are hidden,
against the same recording with its hips, as ``jaxproj retarget`` writes it by default.

For each recording that has hips (the UTKinect people the default model does not train on, the
two bundled CMU clips, and the MediaPipe copies of the CMU excerpts in
``tests/data/formats/same_motion``), two ways of hiding them, the hips then made from the
shoulders (``jaxproj.human.upper_body.hips_from_shoulders``, what ``read_skeleton(hips=
"shoulders")`` does with a MediaPipe file whose hips have a low visibility):

* ``all``: every frame's hips hidden: the capture's up, untilted (a webcam that never sees them);
* ``half``: the second half's hips hidden, the trunk's tilt from the first half (a person who
  leans in towards the camera).

Each version is retargeted to the NAO (``retarget``: the closed-form IK, the offline smoother
and the feasibility filter, the CLI's defaults) and its arms compared with the version with hips,
frame by frame over the hidden frames: the angle between the robot's upper arms and between its
forearms (forward kinematics of the NAO's MJCF, torso frame), median and p90 over the four bones
and the frames (deg). The target (issue 60): median within 5 deg on the MediaPipe recordings.

Usage::

    python -m benchmarks.upper_frame [--data FOLDER] [--json OUT]

``--data``: the UTKinect and CMU files in one folder (``joints_s07_e01.txt``, ...,
``131_01.bvh``; default ``../shared/data``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.g1_playable import default_files
from jaxproj import robots
from jaxproj.eval.fk import arm_points
from jaxproj.human.upper_body import hips_from_shoulders
from jaxproj.io.readers import read_skeleton
from jaxproj.motion.feasible import FeasibleConfig
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.retarget import retarget

_REPO = Path(__file__).resolve().parent.parent
SAME_MOTION = _REPO / "tests" / "data" / "formats" / "same_motion"


def _angles(positions: np.ndarray, valid: np.ndarray, times: np.ndarray) -> np.ndarray:
    res = retarget(positions, valid, method="ik", robot=robots.DEFAULT, times=times,
                   smoothing=OFFLINE_SMOOTHING, feasible=FeasibleConfig())  # fmt: skip
    return np.asarray(res.angles)


def _arm_dirs(angles: np.ndarray) -> np.ndarray:
    """``(T, 4, 3)`` unit upper arm and forearm of both arms, torso frame."""
    p = arm_points(angles, robot=robots.get(robots.DEFAULT))  # (T, sides, 3, 3)
    bones = np.concatenate([p[:, :, 1] - p[:, :, 0], p[:, :, 2] - p[:, :, 1]], axis=1)
    return bones / np.linalg.norm(bones, axis=-1, keepdims=True)


def measure(path: Path, fps: float | None) -> dict:
    rec = read_skeleton(path, fps=fps)
    valid = rec.valid
    t0 = time.perf_counter()
    ref = _arm_dirs(_angles(rec.positions, valid, rec.times))
    out: dict = {"file": path.name, "frames": int(valid.sum())}
    n = len(valid)
    for name in ("all", "half"):
        hidden = valid.copy()
        if name == "half":
            hidden[: n // 2] = False
        pos, tilt = hips_from_shoulders(rec.positions, hidden, valid & ~hidden)
        got = _arm_dirs(_angles(pos, valid, rec.times))
        cos = np.clip(np.sum(got * ref, axis=-1), -1.0, 1.0)
        deg = np.degrees(np.arccos(cos))[hidden]  # (hidden frames, 4)
        out[name] = {
            "hidden_frames": int(hidden.sum()),
            "tilt_deg": round(float(np.degrees(tilt)), 2),
            "arms_deg_median": round(float(np.median(deg)), 2),
            "arms_deg_p90": round(float(np.percentile(deg, 90)), 2),
        }
    out["seconds"] = round(time.perf_counter() - t0, 1)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    files: list[tuple[Path, float | None]] = [(f, None) for f in default_files(args.data)]
    files += [(f, 10.0) for f in sorted(SAME_MOTION.glob("*.mediapipe_pose.json"))]
    rows = []
    for f, fps in files:
        row = measure(f, fps)
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    head = f"{'recording':28s} {'frames':>6s}  all: median / p90  half: median / p90 (tilt)"
    print(head)
    for r in rows:
        a, h = r["all"], r["half"]
        one = f"{a['arms_deg_median']:5.2f} / {a['arms_deg_p90']:5.2f}"
        two = f"{h['arms_deg_median']:5.2f} / {h['arms_deg_p90']:5.2f} ({h['tilt_deg']:.1f})"
        print(f"{r['file']:28s} {r['frames']:6d}  {one}      {two}")
    if args.json is not None:
        args.json.write_text(json.dumps({"robot": robots.DEFAULT, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
