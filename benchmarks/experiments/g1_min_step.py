"""The continuity pass's free step (``TrackConfig.min_step``), chosen on training people only.

``benchmarks.g1_playable``'s measures of the default G1 output (``jaxproj retarget --robot
unitree_g1``, the IK method) on the UTKinect-Action3D people the default model trains on (3, 4,
6: their six recordings), with ``TrackConfig.min_step`` (how far a joint may move in one frame
whatever its limb did) set to each value of ``--steps`` (deg; the default 15 first). Printed per
value: flip steps, catch-ups, steps over 20 / 90 deg, contacts and the arms' median / p90, per
recording, and their sums / mean.

    python -m benchmarks.experiments.g1_min_step [--data FOLDER] [--steps 15,10,7.5] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks import g1_playable as gp
from jaxproj.robots import generic_ik

TRAINING = [f"joints_s{p:02d}_e{e:02d}.txt" for p in (3, 4, 6) for e in (1, 2)]
"""The training people's UTKinect recordings (``datasets.UTK_TRAIN_SUBJECTS``)."""

KEYS = ("flip_steps", "catch_up_steps", "steps_over_20", "steps_over_90", "contact_frames",
        "arm_median", "arm_p90")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", type=Path, default=gp._SHARED / "utkinect_action3d")
    p.add_argument("--steps", default="15,10,7.5", help="min_step values, deg")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    files = [a.data / f for f in TRAINING]
    default = generic_ik.TrackConfig
    out = []
    try:
        for deg in (float(s) for s in a.steps.split(",")):
            # the pass reads TrackConfig() when the robot gives none: this value instead
            generic_ik.TrackConfig = lambda deg=deg: default(min_step=math.radians(deg))  # type: ignore[misc]
            with tempfile.TemporaryDirectory() as tmp:
                # --no-cache: a kept executable is keyed by the code's bytes, not by this
                # patch, and would run the first value's program for every value
                rows = [gp.measure(f, ["--no-cache"], Path(tmp), gp.ROBOT) for f in files]
            res = {
                "min_step_deg": deg,
                **{k: [r[k] for r in rows] for k in KEYS},
                "flip_sum": sum(r["flip_steps"] for r in rows),
                "arm_p90_mean": round(float(np.mean([r["arm_p90"] for r in rows])), 2),
            }
            out.append(res)
            print(json.dumps(res), flush=True)
    finally:
        generic_ik.TrackConfig = default
    if a.json:
        Path(a.json).write_text(json.dumps({"files": TRAINING, "rows": out}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
