"""The continuity pass both ways against one way, on the training people (issue 57).

``benchmarks.g1_playable``'s measures of the default G1 output (``jaxproj retarget --robot
unitree_g1``, the IK method) on the UTKinect-Action3D people the default model trains on (3, 4,
6: their six recordings; ``benchmarks.experiments.g1_min_step.TRAINING``), with
``TrackConfig.both_ways`` on (the default) and off, each in a process of its own and without the
command line's caches (a traced program keeps the value it was traced with). The join's rules
were chosen looking at the held-out files; these recordings were not looked at before.

    python -m benchmarks.experiments.g1_both_ways [--data FOLDER] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from benchmarks import g1_playable as gp
from benchmarks.experiments.g1_min_step import TRAINING, in_children, summary, training_rows


def measure(both: bool, data: Path) -> dict:
    """The six recordings' measures with ``both_ways`` = ``both`` (``training_rows``)."""
    rows = training_rows(data, both_ways=both)
    return {"both_ways": both, **summary(rows), "flip_examples": [r["examples"] for r in rows]}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", type=Path, default=gp._SHARED / "utkinect_action3d")
    p.add_argument("--json", default=None)
    p.add_argument("--one", choices=("0", "1"), default=None, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.one is not None:
        print(json.dumps(measure(a.one == "1", a.data)))
        return 0
    out = in_children("benchmarks.experiments.g1_both_ways", a.data, ["1", "0"])
    if a.json:
        Path(a.json).write_text(json.dumps({"files": TRAINING, "rows": out}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
