"""The ``jaxproj`` command line.

Subcommands: ``info`` (versions, devices, robot, bundled data) and ``retarget`` (a skeleton
recording -> NAO joint trajectories). Every user error prints one line naming the file and the
problem on stderr and exits with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from jaxproj import __version__
from jaxproj.exceptions import JaxprojError

METHODS = ("ik",)


def _info(args: argparse.Namespace) -> int:
    import jax
    import mujoco

    from jaxproj import datasets, robot

    summary = datasets.dataset_summary()
    info = {
        "jaxproj": __version__,
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "devices": [str(d) for d in jax.devices()],
        "robot": {
            "name": robot.NAME,
            "mjcf": str(robot.mjcf_path().resolve()),
            "joints": list(robot.JOINT_NAMES),
            "driven_joints": list(robot.DRIVEN_JOINTS),
        },
        "datasets": {
            "msr_action3d": {
                "sequences": summary["sequences"],
                "frames": summary["frames"],
                "subjects": summary["subjects"],
            }
        },
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"jaxproj {info['jaxproj']}  (jax {info['jax']}, mujoco {info['mujoco']})")
    print(f"devices: {', '.join(info['devices'])}")
    r = info["robot"]
    print(f"robot: {r['name']}, {len(r['joints'])} joints, mjcf {r['mjcf']}")
    print(f"driven joints ({len(r['driven_joints'])}): {', '.join(r['driven_joints'])}")
    m = info["datasets"]["msr_action3d"]
    print(
        f"dataset msr_action3d: {m['sequences']} sequences, {m['frames']} frames, "
        f"{m['subjects']} subjects"
    )
    return 0


def _retarget(args: argparse.Namespace) -> int:
    import numpy as np

    from jaxproj import robot
    from jaxproj.readers import read_skeleton
    from jaxproj.retarget import retarget_positions
    from jaxproj.smoothing import SmoothingParams

    rec = read_skeleton(args.input, format=args.format)
    result = retarget_positions(
        rec.positions,
        rec.valid,
        bones=args.bones,
        mirror=args.mirror,
        smoothing=SmoothingParams() if args.smooth else None,
    )
    out = Path(args.out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with open(out, "wb") as fh:
            np.savez(
                fh,
                angles=result.angles,
                joint_names=np.array(robot.JOINT_NAMES),
                valid=result.valid,
                driven_joints=np.array(robot.DRIVEN_JOINTS),
                method=np.array(args.method),
                smoothed=np.array(bool(args.smooth)),
            )
    except OSError as e:
        raise JaxprojError(f"{out}: cannot write output: {e.strerror or e}") from None
    n, nv = len(result.valid), int(result.valid.sum())
    print(f"{args.input}: {n} frames ({nv} valid) -> {out} [method={args.method}]")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``jaxproj`` command."""
    p = argparse.ArgumentParser(prog="jaxproj", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"jaxproj {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    pi = sub.add_parser("info", help="versions, devices, robot model and bundled data")
    pi.add_argument("--json", action="store_true", help="print JSON")
    pi.set_defaults(func=_info)

    pr = sub.add_parser("retarget", help="retarget a skeleton recording to NAO joint angles")
    pr.add_argument("input", help="recording: MSR Action3D / UTKinect text, NPZ or CSV")
    pr.add_argument("--out", required=True, help="output .npz (angles, joint_names, valid)")
    pr.add_argument("--format", default="auto", choices=("auto", "msr", "utkinect", "npz", "csv"))
    pr.add_argument("--method", default="ik", choices=METHODS)
    pr.add_argument("--bones", default="upper", choices=("upper", "full"))
    pr.add_argument(
        "--mirror", action="store_true", help="mirror imitation: human left drives robot right"
    )
    pr.add_argument(
        "--smooth",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="double exponential smoothing (alpha 0.75, gamma 0.3, eta 0.15)",
    )
    pr.set_defaults(func=_retarget)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``jaxproj`` console script; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except JaxprojError as e:
        print(f"jaxproj: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("jaxproj: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
