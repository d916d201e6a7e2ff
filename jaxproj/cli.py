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

METHODS = ("ik", "relaxed", "full")


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

    mapping, bones, mirror = None, args.bones, args.mirror
    if args.method != "ik":
        from jaxproj import engine

        if args.model is None:
            raise JaxprojError(f"--method {args.method} needs --model P.npz (see `jaxproj build`)")
        model = engine.load(args.model)
        engine.check_neighbours(model, args.L, args.M)
        bones, mirror = model.config.bones, model.config.mirror

        def mapping(d):
            return engine.project(model, d, args.method, n_l=args.L, n_m=args.M)[0]

    rec = read_skeleton(args.input, format=args.format)
    result = retarget_positions(
        rec.positions,
        rec.valid,
        mapping=mapping,
        bones=bones,
        mirror=mirror,
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


def _parse_ints(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integers, got {text!r}"
        ) from None


def _progress(label: str, done: int, total: int) -> None:
    width = 24
    fill = int(width * done / max(total, 1))
    end = "\n" if done >= total else ""
    print(
        f"\r{label:<28s} [{'#' * fill}{'.' * (width - fill)}] {done}/{total}",
        end=end,
        file=sys.stderr,
        flush=True,
    )


def training_descriptors(data: str, subjects: list[int] | None, bones: str, mirror: bool):
    """``(N, m)`` descriptors of the valid training frames, and the number of frames read."""
    from jaxproj.landmarks import training_descriptors as valid_descriptors

    seqs = load_sequences(data, subjects)
    return valid_descriptors(seqs, bones=bones, mirror=mirror), sum(len(s.valid) for s in seqs)


def _build(args: argparse.Namespace) -> int:
    import time

    from jaxproj import engine

    cfg = engine.BuildConfig(
        landmarks=args.landmarks,
        bandwidth=args.bandwidth,
        k=args.k,
        hidden=args.hidden if args.hidden is not None else max(args.k, 96),
        lam=args.lam,
        input_scale=args.input_scale,
        seed=args.seed,
        mirror=args.mirror,
    ).check()
    t0 = time.perf_counter()
    d, n_frames = training_descriptors(args.data, args.subjects, cfg.bones, cfg.mirror)
    _progress("training descriptors", 1, 1)
    print(f"mean shift over {len(d)} descriptors ...", file=sys.stderr, flush=True)
    model = engine.build(d, cfg)
    _progress("landmarks + ELM kernel banks", 1, 1)
    engine.save(model, args.out)
    dt = time.perf_counter() - t0
    target = f" (target {cfg.landmarks})" if cfg.landmarks else ""
    print(
        f"built {model.n_landmarks} landmarks{target} from {model.n_train} valid frames "
        f"(of {n_frames}), bandwidth {model.bandwidth:.4f}, k={model.projector.forward.k}, "
        f"hidden={cfg.hidden}, "
        f"seed={cfg.seed} in {dt:.1f} s -> {args.out}"
    )
    return 0


def load_sequences(data: str, subjects: list[int] | None):
    """The bundled MSR Action3D sequences, or every recording in a folder.

    Folder files are read with ``readers.read_skeleton`` (format by extension / content); a name
    with ``sNN`` gives the subject (``aNN_`` the action), and with ``subjects`` given, files whose
    subject is another are skipped (files with no subject in their name are kept).
    """
    import re

    import numpy as np

    from jaxproj import datasets
    from jaxproj.readers import read_skeleton

    if data == "bundled":
        return datasets.msr_action3d(subjects=subjects)
    folder = Path(data)
    if not folder.is_dir():
        raise JaxprojError(f"{folder}: --data must be 'bundled' or a folder of recordings")
    files = sorted(p for p in folder.iterdir() if p.is_file())
    seqs = []
    for i, f in enumerate(files):
        subj = re.search(r"s(\d{2})", f.name)
        act = re.search(r"a(\d{2})_", f.name)
        subject = int(subj.group(1)) if subj else 0
        if subjects is not None and subj and subject not in subjects:
            continue
        rec = read_skeleton(f)
        conf = np.ones(rec.valid.shape + (20,), np.float32)
        action = int(act.group(1)) if act else 0
        seqs.append(
            datasets.MotionSequence(f.stem, action, subject, 0, rec.positions, conf, rec.valid)
        )
        _progress("reading recordings", i + 1, len(files))
    if not seqs:
        raise JaxprojError(f"{folder}: no recordings found (for subjects {subjects})")
    return seqs


def _evaluate(args: argparse.Namespace) -> int:
    import time

    import jax

    from jaxproj import engine, evaluate, report
    from jaxproj.smoothing import SmoothingParams

    if args.devices < 1 or args.devices > len(jax.devices()):
        raise JaxprojError(
            f"--devices {args.devices}: this machine has {len(jax.devices())} JAX device(s)"
        )
    model = engine.load(args.model)
    engine.check_neighbours(model, args.L, args.M)
    objectives = ["relaxed", "full"] if args.objective == "all" else [args.objective]
    methods = objectives + ["nearest_landmark", "knn_average", "global_elm"]
    t0 = time.perf_counter()
    seqs = load_sequences(args.data, args.subjects)
    data = evaluate.prepare(seqs, bones=model.config.bones, mirror=model.config.mirror)
    with engine.use_devices(args.devices):
        out = evaluate.evaluate(
            model,
            data,
            methods,
            n_l=args.L,
            n_m=args.M,
            smoothing=SmoothingParams() if args.smooth else None,
            progress=_progress,
        )
    out["wall_s"]["total"] = time.perf_counter() - t0
    out["subjects"] = args.subjects
    out["model"] = str(args.model)
    report.write_json(Path(args.json), out)
    print(report.summary_table(out["summary"], methods))
    print(f"{out['valid_frames']} valid frames of {out['sequences']} sequences -> {args.json}")
    return 0


def _demo(args: argparse.Namespace) -> int:
    from jaxproj import report
    from jaxproj.demo import run_demo

    out = run_demo(Path(args.out), quick=args.quick, progress=_progress)
    print(report.summary_table(out["summary"]))
    t = out["timings"]
    print(f"report: {Path(args.out) / 'report.md'} ({t['total_s']:.0f} s)")
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
    pr.add_argument("--model", help="projector file from `jaxproj build` (relaxed / full)")
    pr.add_argument("--L", type=int, default=10, help="human-landmark neighbours (candidates)")
    pr.add_argument("--M", type=int, default=10, help="robot-landmark neighbours per candidate")
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

    pb = sub.add_parser("build", help="build a projector (landmarks + ELM kernels)")
    pb.add_argument("--data", default="bundled", help="'bundled' or a folder of recordings")
    pb.add_argument(
        "--subjects",
        type=_parse_ints,
        default=[1, 3, 5, 7, 9],
        help="training subjects, e.g. 1,3,5,7,9 (default)",
    )
    size = pb.add_mutually_exclusive_group(required=True)
    size.add_argument("--landmarks", type=int, help="target landmark count (bisection)")
    size.add_argument("--bandwidth", type=float, help="mean-shift bandwidth, used as is")
    pb.add_argument("--k", type=int, default=96, help="training neighbours per ELM kernel")
    pb.add_argument("--hidden", type=int, default=None, help="hidden units (default max(k, 96))")
    pb.add_argument("--lam", type=float, default=1e-3, help="ELM ridge regulariser")
    pb.add_argument("--input-scale", type=float, default=0.5, help="hidden-weight std")
    pb.add_argument("--seed", type=int, default=0, help="PRNG seed of the hidden layers")
    pb.add_argument("--mirror", action="store_true", help="mirror imitation")
    pb.add_argument("--out", required=True, help="output projector .npz")
    pb.set_defaults(func=_build)

    pe = sub.add_parser("evaluate", help="batch evaluation against the IK, with baselines")
    pe.add_argument("--model", required=True, help="projector file from `jaxproj build`")
    pe.add_argument("--data", default="bundled", help="'bundled' or a folder of recordings")
    pe.add_argument("--subjects", type=_parse_ints, default=[2, 4, 6, 8, 10])
    pe.add_argument("--objective", default="all", choices=("relaxed", "full", "all"))
    pe.add_argument("--L", type=int, default=10)
    pe.add_argument("--M", type=int, default=10)
    pe.add_argument("--smooth", action=argparse.BooleanOptionalAction, default=True)
    pe.add_argument("--devices", type=int, default=1, help="JAX devices to shard batches over")
    pe.add_argument("--json", required=True, help="output report JSON")
    pe.set_defaults(func=_evaluate)

    pd = sub.add_parser("demo", help="the main job: build, evaluate, roll out, report")
    pd.add_argument("--out", default="jaxproj-report", help="report folder")
    pd.add_argument("--quick", action="store_true", help="fewer rollouts and sweep points")
    pd.set_defaults(func=_demo)

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
