"""Whole-body throughput (issue 59): the bundled data retargeted to the G1 in one batch, with
the root in the world (``--root world``) against the fixed base, the same recordings, the same
machine, the same run.

The recordings are ``benchmarks.batch_cli``'s: every MSR Action3D sequence and UTKinect action
segment of ``jaxproj/data`` and the two CMU clips, as files (``--every N``: every N-th of
them). Each way is one ``jaxproj retarget FOLDER --robot unitree_g1 --out OUT`` (packed, the
default) in its own process, run twice with one fresh compilation cache: the first run compiles
(``*_cold_s``), the second loads the compiled programs from the cache (``*_warm_s``: compiling
apart; each run's time is also printed on stderr as it ends). Checked first: both ways write
the same recordings, and every whole-body file loads back with a finite root and contacts of
its length.

A machine whose time per command holds neither pass of the whole data can run them in two
commands: ``--work DIR`` keeps the recordings, outputs and compilation caches in DIR, and
``--passes cold`` then ``--passes warm`` run one pass each (the warm pass needs the cold one's
cache in DIR).

Usage::

    python -m benchmarks.whole_body_batch [--robot unitree_g1] [--every 1] [--ways fixed,world]
        [--passes cold,warm] [--work DIR] [--json OUT]
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

import numpy as np

from benchmarks.batch_cli import write_bundled
from benchmarks.harness import report
from jaxproj.io.motion_files import load_motion


def _run(argv: list[str], cache: Path) -> tuple[float, list[str]]:
    env = {**os.environ, "JAXPROJ_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "jaxproj.cli", *argv], check=False, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)  # fmt: skip
    wall = time.perf_counter() - t0
    return wall, [ln for ln in res.stderr.splitlines() if ln.startswith("jaxproj: error:")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", default="unitree_g1")
    ap.add_argument("--every", type=int, default=1, help="keep every N-th recording (1: all)")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--ways", default="fixed,world",
                    help="which ways to run, in order (fixed, world): one alone when a machine's "
                    "time per command does not hold both")  # fmt: skip
    ap.add_argument("--passes", default="cold,warm",
                    help="which passes to run (cold: compiling into a fresh cache; warm: from the "
                    "cache the cold pass left in --work)")  # fmt: skip
    ap.add_argument(
        "--work",
        type=Path,
        default=None,
        help="keep recordings, outputs and caches here (default: a temporary folder)",
    )
    args = ap.parse_args(argv)
    ways = args.ways.split(",")
    if not ways or set(ways) - {"fixed", "world"}:
        ap.error("--ways takes fixed, world or both, comma-separated")
    passes = args.passes.split(",")
    if not passes or set(passes) - {"cold", "warm"}:
        ap.error("--passes takes cold, warm or both, comma-separated")
    if "cold" not in passes and args.work is None:
        ap.error("--passes warm alone needs --work: the folder a cold pass left its cache in")
    res: dict = {"robot": args.robot, "cpus": os.cpu_count(), "platform": platform.machine(),
                 "load_before": os.getloadavg()[0]}  # fmt: skip
    keep = nullcontext(str(args.work)) if args.work else tempfile.TemporaryDirectory()
    with keep as tmp:
        root = Path(tmp)
        if not (root / "all").is_dir():
            files = write_bundled(root / "all")
            for i, f in enumerate(files):
                if i % args.every:
                    f.unlink()
        res["every"] = args.every
        res["recordings"] = len(list((root / "all").iterdir()))
        for way in ways:
            extra = ["--root", "world"] if way == "world" else []
            out, cache = root / way, root / f"cache_{way}"
            cmd = ["retarget", str(root / "all"), "--robot", args.robot, "--out", str(out), *extra]
            errors: list[str] = []
            for run in passes:
                if run == "warm" and not cache.is_dir():
                    raise SystemExit(f"whole_body_batch: no cache at {cache}: run --passes cold")
                if run == "cold":
                    shutil.rmtree(cache, ignore_errors=True)  # a fresh cache: compiling counts
                force = ["--force"] if run == "warm" or out.is_dir() else []
                res[f"{way}_{run}_s"], errors = _run([*cmd, *force], cache)
                print(f"whole_body_batch: {way} {run} {res[f'{way}_{run}_s']:.1f} s",
                      file=sys.stderr, flush=True)  # fmt: skip
            written = sorted(p.name for p in out.glob("*.npz"))
            res[f"{way}_written"] = len(written)
            res[f"{way}_errors"] = [e.replace(str(root), "DATA") for e in errors]
            res[f"{way}_files"] = written
        if len(ways) == 2 and res["fixed_files"] != res["world_files"]:
            raise SystemExit("whole_body_batch: the two ways wrote different recordings")
        frames = 0
        for name in res[f"{ways[-1]}_files"]:
            m = load_motion(root / ways[-1] / name)
            n = len(m.times)
            frames += n
            if ways[-1] == "fixed":
                continue
            assert m.root_pos is not None and m.contacts is not None, name
            if m.root_pos.shape != (n, 3) or not np.isfinite(m.root_pos).all():
                raise SystemExit(f"whole_body_batch: {name}: root {m.root_pos.shape}, not finite")
            if m.contacts.shape[0] != n:
                raise SystemExit(f"whole_body_batch: {name}: contacts {m.contacts.shape}")
        res["frames_written"] = frames
    for way in ways:
        del res[f"{way}_files"]
        for run in passes:
            s = res[f"{way}_{run}_s"]
            res[f"{way}_{run}_recordings_per_s"] = res[f"{way}_written"] / s
            res[f"{way}_{run}_frames_per_s"] = res["frames_written"] / s
    report(res, None if args.json is None else str(args.json))
    return 0


if __name__ == "__main__":
    sys.exit(main())
