"""``jaxproj demo``: the main job (build, evaluate, roll out, report; ``jaxproj.paper.demo``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from jaxproj.cli import options
from jaxproj.errors import ConfigError


def add_parsers(sub: Any) -> None:
    p = options.add_parser(sub, "demo", "the main job: build, evaluate, roll out, report")
    p.add_argument(
        "--out",
        default="jaxproj-report",
        help="report folder, created if missing (its parent folder must exist); one that "
        "holds an earlier report is refused without --force",
    )
    options.add_force_option(p, "report of an earlier run in --out (files of other names stay)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="a smoke run: fewer training frames, held-out recordings, landmarks, rollouts and "
        "sweep points",
    )
    options.add_devices_option(p, "for the evaluation and the rollout (then in MJX)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from jaxproj.paper.demo_report import check_report_folder

    out_dir = Path(args.out)
    try:  # before anything else: a refusal is the only line
        check_report_folder(out_dir, args.force)
    except ConfigError as e:
        message = str(e).replace("--force (CLI) / overwrite=True (Python)", "--force")
        raise ConfigError(f"--out {message}") from None
    # the first line, before MuJoCo, the plots and the first compile (minutes of silence else)
    print(
        f"jaxproj demo{' --quick' if args.quick else ''}: 5 stages (build, evaluate, roll out, "
        "the paper's experiments, report), a progress line with estimates at least every 30 s",
        file=sys.stderr,
        flush=True,
    )
    from jaxproj._internal.mjx import import_mjx

    import_mjx()  # before jaxproj.eval imports it: without Warp's notice
    from jaxproj.paper.demo import run_demo
    from jaxproj.paper.demo_report import stdout_summary

    devices = options.devices(args.devices)
    out = run_demo(out_dir, quick=args.quick, progress=True, devices=devices, overwrite=args.force)
    print(stdout_summary(out))
    t = out["timings"]
    print(f"report: {out_dir / 'report.md'} ({t['total_s']:.0f} s)")
    return 0
