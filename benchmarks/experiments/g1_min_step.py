"""The continuity pass's free step (``TrackConfig.min_step``), chosen on training people only.

``benchmarks.g1_playable``'s measures of the default G1 output (``jaxproj retarget --robot
unitree_g1``, the IK method) on the UTKinect-Action3D people the default model trains on (3, 4,
6: their six recordings), with ``TrackConfig.min_step`` (how far a joint may move in one frame
whatever its limb did) set to each value of ``--steps`` (deg; the default 15 first), each in a
process of its own and without the command line's caches (a traced program keeps the value it
was traced with). Printed per value: flip steps, catch-ups, steps over 20 / 90 deg, contacts
and the arms' median / p90, per recording, and their sums / mean.

    python -m benchmarks.experiments.g1_min_step [--data FOLDER] [--steps 15,10,7.5] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
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


def measure(deg: float, data: Path) -> dict:
    """The six recordings' measures with ``min_step`` = ``deg`` (in this process: call it in a
    fresh one per value, as ``main`` does; a traced program keeps the value it was traced with)."""
    default = generic_ik.TrackConfig
    # the pass reads TrackConfig() when the robot gives none: this value instead
    generic_ik.TrackConfig = lambda: default(min_step=math.radians(deg))  # type: ignore[misc]
    with tempfile.TemporaryDirectory() as tmp:
        # --no-cache: a kept executable is keyed by the code's bytes, not by this patch
        rows = [gp.measure(data / f, ["--no-cache"], Path(tmp), gp.ROBOT) for f in TRAINING]
    return {
        "min_step_deg": deg,
        **{k: [r[k] for r in rows] for k in KEYS},
        "flip_sum": sum(r["flip_steps"] for r in rows),
        "arm_p90_mean": round(float(np.mean([r["arm_p90"] for r in rows])), 2),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", type=Path, default=gp._SHARED / "utkinect_action3d")
    p.add_argument("--steps", default="15,10,7.5", help="min_step values, deg")
    p.add_argument("--json", default=None)
    p.add_argument("--one", type=float, default=None, help=argparse.SUPPRESS)  # a child's value
    a = p.parse_args(argv)
    if a.one is not None:
        print(json.dumps(measure(a.one, a.data)))
        return 0
    out = []
    for deg in (float(s) for s in a.steps.split(",")):
        cmd = [sys.executable, "-m", "benchmarks.experiments.g1_min_step", "--data", str(a.data),
               "--one", str(deg)]  # fmt: skip
        run = subprocess.run(cmd, capture_output=True, text=True, check=True)
        res = json.loads(run.stdout.strip().splitlines()[-1])
        out.append(res)
        print(json.dumps(res), flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps({"files": TRAINING, "rows": out}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
