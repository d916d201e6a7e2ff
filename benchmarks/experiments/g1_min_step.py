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


def training_rows(data: Path, **track: object) -> list[dict]:
    """``g1_playable.measure`` of the six training recordings with ``TrackConfig`` fields
    ``track`` set (in this process: call it in a fresh one per setting, as ``in_children``
    does; a traced program keeps the value it was traced with)."""
    default = generic_ik.TrackConfig
    # the pass reads TrackConfig() when the robot gives none: this setting instead
    generic_ik.TrackConfig = lambda: default(**track)  # type: ignore[misc,arg-type]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            # --no-cache: a kept executable is keyed by the code's bytes, not by this patch
            return [gp.measure(data / f, ["--no-cache"], Path(tmp), gp.ROBOT) for f in TRAINING]
    finally:
        generic_ik.TrackConfig = default  # type: ignore[misc]


def in_children(module: str, data: Path, values: list[str]) -> list[dict]:
    """``python -m module --data data --one v`` for each of ``values``, each in a process of
    its own; the JSON line each prints last, printed as it comes and returned in order."""
    out = []
    for v in values:
        cmd = [sys.executable, "-m", module, "--data", str(data), "--one", v]
        run = subprocess.run(cmd, capture_output=True, text=True, check=True)
        res = json.loads(run.stdout.strip().splitlines()[-1])
        out.append(res)
        print(json.dumps(res), flush=True)
    return out


def measure(deg: float, data: Path) -> dict:
    """The six recordings' measures with ``min_step`` = ``deg`` (``training_rows``)."""
    return {"min_step_deg": deg, **summary(training_rows(data, min_step=math.radians(deg)))}


def summary(rows: list[dict]) -> dict:
    """``KEYS`` per recording, and the flips' sum and the arms' p90 mean over them."""
    return {
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
    steps = [str(float(s)) for s in a.steps.split(",")]
    out = in_children("benchmarks.experiments.g1_min_step", a.data, steps)
    if a.json:
        Path(a.json).write_text(json.dumps({"files": TRAINING, "rows": out}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
