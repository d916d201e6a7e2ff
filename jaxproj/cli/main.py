"""The ``jaxproj`` command line.

Subcommands: ``info`` (versions, devices, robot, bundled data), ``retarget`` (a skeleton
recording or BVH clip -> a robot-feasible NAO joint trajectory as NPZ, CSV or NAOqi JSON),
``render`` (a motion file -> MP4 / GIF), ``build`` (a projector), ``evaluate`` (batch
evaluation against the IK) and ``demo`` (the main job). Every user error prints one line naming
the file and the problem on stderr and exits with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from jaxproj import __version__
from jaxproj.errors import ConfigError, JaxprojError
from jaxproj.projection.api import HEAD_BANDWIDTH

METHODS = ("ik", "relaxed", "full")


def _info(args: argparse.Namespace) -> int:
    import jax
    import mujoco

    from jaxproj.io import datasets
    from jaxproj.robots.nao_h25 import robot

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
    from jaxproj.io.motion_files import Motion, save_motion
    from jaxproj.io.readers import read_skeleton
    from jaxproj.motion import feasible
    from jaxproj.motion.retarget import retarget
    from jaxproj.motion.smoothing import PAPER_SMOOTHING
    from jaxproj.projection import api as engine

    model = None
    bones = "upper" if args.bones is None else args.bones
    mirror = bool(args.mirror)
    if args.method != "ik":
        if args.model is None:
            raise ConfigError(f"--method {args.method} needs --model P.npz (see `jaxproj build`)")
        model = engine.load(args.model)
        fixed = {"--bones": (args.bones, model.config.bones)}
        fixed["--mirror"] = (args.mirror, model.config.mirror)
        for flag, (given, own) in fixed.items():
            if given is not None and given != own:
                raise ConfigError(
                    f"{flag} {given} conflicts with the model {args.model}, built with "
                    f"{flag.lstrip('-')}={own}: leave {flag} out (the model fixes it)"
                )
        bones, mirror = model.config.bones, model.config.mirror
    out = Path(args.out)
    if out.suffix.lower() not in (".npz", ".csv", ".json"):
        raise ConfigError(f"--out {out}: use a .npz, .csv or .json file name")
    plot = None if args.plot is None else Path(args.plot)
    if plot is not None and plot.suffix.lower() != ".png":
        raise ConfigError(f"--plot {plot}: use a .png file name")
    rec = read_skeleton(
        args.input, format=args.format, fps=args.fps, bvh_map=args.bvh_map, scale=args.bvh_scale
    )
    result = retarget(
        rec.positions,
        rec.valid,
        model=model,
        method=args.method,
        n_l=args.L,
        n_m=args.M,
        bones=bones,
        mirror=mirror,
        smoothing=PAPER_SMOOTHING if args.smooth else None,
        times=rec.times,
        feasible=feasible.DEFAULT_FEASIBLE if args.feasible else None,
    )
    angles = result.angles
    unfiltered = angles if result.unfiltered is None else result.unfiltered
    before = feasible.feasibility_report(unfiltered, result.times)
    after = feasible.feasibility_report(angles, result.times)
    meta = {
        "method": args.method,
        "smoothed": bool(args.smooth),
        "feasible": bool(args.feasible),
        "source": str(args.input),
        "time_source": rec.time_source,
        "fps": round(rec.fps, 6),
        "format": rec.format,
    }
    motion = Motion(angles, result.times, result.valid, rec.positions, meta)
    save_motion(out, motion, joints=args.joints)
    n, nv = len(result.valid), int(result.valid.sum())
    print(
        f"{args.input}: {n} frames ({nv} valid, {result.times[-1]:.2f} s, {rec.time_source}) -> "
        f"{out} [method={args.method}]"
    )
    label = "feasible" if args.feasible else "not filtered (--no-feasible)"
    print(
        f"  speed-limit frames {before['speed_violation_frames']} -> "
        f"{after['speed_violation_frames']}, max step {before['max_step_deg']:.1f} -> "
        f"{after['max_step_deg']:.1f} deg, max accel {before['max_accel']:.0f} -> "
        f"{after['max_accel']:.0f} rad/s^2 [{label}]"
    )
    if plot is not None:
        _plot_retarget(plot, args, rec, angles, result, bones, mirror)
    return 0


def _plot_retarget(plot: Path, args: argparse.Namespace, rec, angles, result, bones, mirror):
    """``retarget --plot``: the demo's motion figure for this recording (``report.plot_retarget``):
    human and NAO at key frames, the driven joints over time against the per-frame IK."""
    import numpy as np

    from jaxproj.motion.retarget import retarget
    from jaxproj.robots.nao_h25 import robot
    from jaxproj.viz import report

    truth = retarget(
        rec.positions, rec.valid, method="ik", bones=bones, mirror=mirror, smoothing=None,
        times=rec.times,
    )  # fmt: skip
    out = angles[:, robot.DRIVEN_INDEX]
    ik_q = truth.angles[:, robot.DRIVEN_INDEX]
    ranges = np.degrees(out.max(axis=0) - out.min(axis=0))
    widest = ", ".join(f"{robot.DRIVEN_JOINTS[i]} {ranges[i]:.0f}" for i in np.argsort(-ranges)[:4])
    title = f"{Path(args.input).name}: {args.method}, {len(out)} frames at {rec.fps:.3g} fps"
    report.plot_retarget(plot, title, rec.positions, result.valid, result.times, out, ik_q,
                         label=args.method)  # fmt: skip
    print(f"  plot -> {plot} (widest joint ranges, deg: {widest})")


def _parse_ints(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integers, got {text!r}"
        ) from None


def _parse_floats(text: str) -> list[float]:
    try:
        return [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None


def _one_or_tuple(values: list | None) -> object:
    """CLI lists: ``None``, one value, or a per-chain tuple."""
    if values is None:
        return None
    return values[0] if len(values) == 1 else tuple(values)


def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _load(
    data: str,
    subjects: list[int] | None,
    split: str,
    strict: bool = False,
    bvh_map: str = "auto",
):
    """Recordings of ``--data`` and, for a folder, its ``datasets.FolderContents`` (else
    ``None``). ``--subjects`` defaults to the MSR Action3D protocol's ``split`` (train / test
    subjects) on the bundled MSR data, to every recording elsewhere. For a folder, what was
    skipped (not a recording), left out (``--subjects``) or unreadable is noted on stderr;
    an unreadable recording stops the command only with ``--strict``."""
    from jaxproj._internal.progress import bar
    from jaxproj.io import datasets

    if subjects is None and data in ("bundled", "msr"):
        subjects = list(datasets.TRAIN_SUBJECTS if split == "train" else datasets.TEST_SUBJECTS)
    if data in ("bundled", "msr", "utkinect"):
        return datasets.load_sequences(data, subjects), None
    contents = datasets.load_folder(
        data,
        subjects,
        strict=strict,
        progress=lambda files: bar(files, "reading recordings"),
        bvh_map=bvh_map,
    )
    for line in contents.notes():
        _log(f"jaxproj: note: {line}")
    return contents.sequences, contents


def _unreadable_note(contents) -> str:
    """`` (N unreadable recording(s) not used: ...)`` for a summary line, or ``""``."""
    if contents is None or not contents.unreadable:
        return ""
    names = ", ".join(name for name, _ in contents.unreadable)
    n = len(contents.unreadable)
    return f" ({n} unreadable recording(s) not used: {names}; --strict stops at the first)"


def _build(args: argparse.Namespace) -> int:
    import time

    from jaxproj.io import datasets
    from jaxproj.projection import api as engine

    cfg = engine.BuildConfig(
        chains=args.chains,
        landmarks=_one_or_tuple(args.landmarks),
        bandwidth=_one_or_tuple(args.bandwidth),
        k=args.k,
        hidden=args.hidden if args.hidden is not None or args.k is None else max(args.k, 192),
        lam=args.lam,
        input_scale=args.input_scale,
        seed=args.seed,
        mirror=args.mirror,
    )
    t0 = time.perf_counter()
    seqs, contents = _load(args.data, args.subjects, "train", args.strict, args.bvh_map)
    d = datasets.valid_descriptors(seqs, bones=cfg.bones, mirror=cfg.mirror)
    n_frames = sum(len(s.valid) for s in seqs)
    engine.check_training_data(d, cfg)  # a landmark count the data cannot reach: before the log
    _log(f"mean shift over {len(d)} descriptors, then the ELM kernel banks ...")
    model = engine.build(d, cfg)
    engine.save(model, args.out)
    dt = time.perf_counter() - t0
    lay = model.projector.layout
    parts = []
    for c, name in enumerate(lay.names):
        target = cfg.chain_config(c).landmarks
        aim = f"target {target}, " if target else ""
        parts.append(
            f"{name} {lay.landmarks[c]} ({aim}bandwidth {model.bandwidth[c]:.4f}, k={lay.k[c]})"
        )
    per_chain = ", ".join(parts)
    print(
        f"built {cfg.chains} chains: {per_chain} from {model.n_train} valid frames "
        f"(of {n_frames}), hidden={cfg.hidden}, seed={cfg.seed} in {dt:.1f} s -> {args.out}"
        + _unreadable_note(contents)
    )
    return 0


def _devices(value: str) -> list | None:
    """``--devices N|all`` -> ``engine.resolve_devices``, errors naming the flag."""
    from jaxproj.projection import api as engine

    try:
        return engine.resolve_devices(value)
    except ConfigError as e:
        raise ConfigError(f"--devices {value}: {e}") from None


def _evaluate(args: argparse.Namespace) -> int:
    import time

    from jaxproj.eval import evaluate
    from jaxproj.motion.smoothing import PAPER_SMOOTHING
    from jaxproj.projection import api as engine
    from jaxproj.viz import report

    devices = _devices(args.devices)
    model = engine.load(args.model)
    engine.check_neighbours(model, args.L, args.M)
    objectives = ["relaxed", "full"] if args.objective == "all" else [args.objective]
    methods = objectives + ["nearest_landmark", "knn_average", "global_elm"]
    t0 = time.perf_counter()
    seqs, contents = _load(args.data, args.subjects, "test", args.strict, args.bvh_map)
    data = evaluate.prepare(seqs, bones=model.config.bones, mirror=model.config.mirror)
    out = evaluate.evaluate(
        model,
        data,
        methods,
        n_l=args.L,
        n_m=args.M,
        smoothing=PAPER_SMOOTHING if args.smooth else None,
        devices=devices,
        progress=True,
    )
    out["wall_s"]["total"] = time.perf_counter() - t0
    out["subjects"] = sorted({int(s.subject) for s in seqs})
    out["data"] = args.data
    out["model"] = str(args.model)
    if contents is not None:
        out["data_files"] = contents.to_json()
    report.write_json(Path(args.json), out)
    print(report.summary_table(out["summary"], methods))
    print(
        f"{out['valid_frames']} valid frames of {out['sequences']} sequences -> {args.json}"
        + _unreadable_note(contents)
    )
    return 0


def _demo(args: argparse.Namespace) -> int:
    from jaxproj.paper.demo import run_demo
    from jaxproj.viz import report

    devices = _devices(args.devices)
    out = run_demo(Path(args.out), quick=args.quick, progress=True, devices=devices)
    print(report.summary_table(out["summary"]))
    t = out["timings"]
    print(f"report: {Path(args.out) / 'report.md'} ({t['total_s']:.0f} s)")
    return 0


def _parse_size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT in pixels, e.g. 480x360, got {text!r}"
        ) from None
    return width, height


def _render(args: argparse.Namespace) -> int:
    from jaxproj.io.motion_files import load_motion
    from jaxproj.viz import render

    out = Path(args.out)
    render.check_video_path(out)  # before the (slow) rendering
    motion = load_motion(args.motion)
    path, n, backend, fps = render.render_to_file(
        motion, out, fps=args.fps, backend=args.backend, size=args.size, stride=args.stride
    )
    print(f"{args.motion}: {n} frames -> {path} [backend={backend}, {fps:g} fps]")
    return 0


def _bvh_options(parser: argparse.ArgumentParser, scale: bool = False) -> None:
    parser.add_argument(
        "--bvh-map",
        default="auto",
        help="BVH input: joint map, Kinect joint -> BVH joint: auto (the built-in map that fits "
        "the hierarchy), cmu (CMU 3dsMax-friendly release), cmu-mb (CMU MotionBuilder-friendly) "
        "or a JSON / TOML file of {Kinect joint: BVH joint} (jaxproj.io.bvh)",
    )
    if scale:
        parser.add_argument(
            "--bvh-scale",
            default="auto",
            help="BVH input: metres per file unit: auto (CMU units for the CMU maps, else the "
            "unit of m, cm, mm, in that gives a human-sized skeleton), a unit name (cmu, m, "
            "cm, mm, in) or a number",
        )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``jaxproj`` command."""
    fmt = argparse.ArgumentDefaultsHelpFormatter
    p = argparse.ArgumentParser(
        prog="jaxproj", description=__doc__.splitlines()[0], formatter_class=fmt
    )
    p.add_argument("--version", action="version", version=f"jaxproj {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    pi = sub.add_parser(
        "info", formatter_class=fmt, help="versions, devices, robot model and bundled data"
    )
    pi.add_argument("--json", action="store_true", help="print JSON")
    pi.set_defaults(func=_info)

    pr = sub.add_parser(
        "retarget", formatter_class=fmt, help="retarget a skeleton recording to NAO joint angles"
    )
    pr.add_argument("input", help="recording: MSR Action3D / UTKinect text, NPZ, CSV or BVH")
    pr.add_argument(
        "--out",
        required=True,
        help="output: .npz (angles, times, valid, joint_names, positions, meta), .csv (time + 26 "
        "joints, rad) or .json (NAOqi ALMotion.angleInterpolation arguments)",
    )
    pr.add_argument(
        "--format",
        default="auto",
        choices=("auto", "msr", "utkinect", "npz", "csv", "bvh"),
        help="input format (auto: by extension and content)",
    )
    _bvh_options(pr, scale=True)
    pr.add_argument(
        "--method",
        default="ik",
        choices=METHODS,
        help="ik: the analytic IK; relaxed / full: the projector of --model",
    )
    pr.add_argument("--model", help="projector file from `jaxproj build` (relaxed / full)")
    pr.add_argument("--L", type=int, default=10, help="human-landmark neighbours (candidates)")
    pr.add_argument("--M", type=int, default=10, help="robot-landmark neighbours per candidate")
    pr.add_argument(
        "--bones",
        default=None,
        choices=("upper", "full"),
        help="descriptor bones (None: upper; a model fixes its own, a different value is refused)",
    )
    pr.add_argument(
        "--mirror",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="mirror imitation: human left drives robot right (None: off, or the model's)",
    )
    pr.add_argument(
        "--smooth",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="double exponential smoothing (alpha 0.75, gamma 0.3, eta 0.15 per frame at 15 fps; "
        "scaled to each frame's time step)",
    )
    pr.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frame rate of the input (None: the file's own timing: UTKinect frame numbers at "
        "30 fps, MSR Action3D 15 fps, CSV / NPZ 30 fps unless the NPZ has times or fps). A BVH "
        "states its own rate (Frame Time): there --fps F resamples the clip to F frames/s "
        "(linear interpolation of joint positions), e.g. 30; None keeps the clip's rate",
    )
    pr.add_argument(
        "--feasible",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="make the output robot-feasible: joint limits, 90%% of the NAO's speed limits, "
        "80 rad/s^2 (jaxproj.motion.feasible)",
    )
    pr.add_argument(
        "--joints",
        default="upper",
        choices=("upper", "body"),
        help="joints in a .json output: upper = NAOqi's Head, LArm, RArm chains (the legs stay "
        "with the robot's own balance); body = all 26",
    )
    pr.add_argument(
        "--plot",
        default=None,
        help="also write a PNG: human and NAO at key frames, the 10 driven joints over time "
        "against the per-frame IK (the demo report's motion figure)",
    )
    pr.set_defaults(func=_retarget)

    pb = sub.add_parser(
        "build", formatter_class=fmt, help="build a projector (landmarks + ELM kernels)"
    )
    pb.add_argument("--data", default="bundled", help="'bundled'/'msr', 'utkinect' or a folder")
    pb.add_argument(
        "--subjects",
        type=_parse_ints,
        default=None,
        help="training subjects, comma-separated (None: 1,3,5,7,9 of the bundled MSR data; every "
        "recording of 'utkinect' or a folder; a folder's left-out files are noted on stderr)",
    )
    pb.add_argument(
        "--chains",
        default="upper",
        choices=("upper", "whole"),
        help="upper: one projector per chain (head, left arm, right arm); whole: the paper's "
        "whole-body projector",
    )
    size = pb.add_mutually_exclusive_group()
    size.add_argument(
        "--landmarks",
        type=_parse_ints,
        help="target landmark count, bisected: one number for each arm (head: bandwidth "
        f"{HEAD_BANDWIDTH}) or one per chain, e.g. 400,1644,1644 (neither this nor --bandwidth: "
        "engine.DEFAULTS, the tuned bandwidths)",
    )
    size.add_argument(
        "--bandwidth", type=_parse_floats, help="mean-shift bandwidth: one, or one per chain"
    )
    tuned = "None: engine.DEFAULTS of the chain set"
    pb.add_argument("--k", type=int, default=None, help=f"training neighbours per kernel ({tuned})")
    pb.add_argument(
        "--hidden", type=int, default=None, help=f"hidden units ({tuned}; with --k: max(k, 192))"
    )
    pb.add_argument("--lam", type=float, default=None, help=f"ELM ridge regulariser ({tuned})")
    pb.add_argument("--input-scale", type=float, default=None, help=f"hidden-weight std ({tuned})")
    pb.add_argument("--seed", type=int, default=0, help="PRNG seed of the hidden layers")
    pb.add_argument("--mirror", action="store_true", help="mirror imitation")
    pb.add_argument(
        "--strict",
        action="store_true",
        help="with a folder: stop at the first unreadable recording (default: report it on "
        "stderr and use the others)",
    )
    _bvh_options(pb)
    pb.add_argument("--out", required=True, help="output projector .npz")
    pb.set_defaults(func=_build)

    pe = sub.add_parser(
        "evaluate", formatter_class=fmt, help="batch evaluation against the IK, with baselines"
    )
    pe.add_argument("--model", required=True, help="projector file from `jaxproj build`")
    pe.add_argument("--data", default="bundled", help="'bundled'/'msr', 'utkinect' or a folder")
    pe.add_argument(
        "--subjects",
        type=_parse_ints,
        default=None,
        help="evaluated subjects (None: 2,4,6,8,10 of the bundled MSR data; every recording of "
        "'utkinect' or a folder; a folder's left-out files are noted on stderr)",
    )
    pe.add_argument(
        "--objective",
        default="all",
        choices=("relaxed", "full", "all"),
        help="projection objective(s); the baselines always run",
    )
    pe.add_argument("--L", type=int, default=10, help="human-landmark neighbours (candidates)")
    pe.add_argument("--M", type=int, default=10, help="robot-landmark neighbours per candidate")
    pe.add_argument(
        "--smooth",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="score the smoothed motions (unsmoothed figures are reported too)",
    )
    pe.add_argument(
        "--devices",
        default="1",
        help="JAX devices to shard the queries over: a count or 'all' (shard_map, one device "
        "program per shard)",
    )
    pe.add_argument(
        "--strict",
        action="store_true",
        help="with a folder: stop at the first unreadable recording (default: report it on "
        "stderr and in the JSON's data_files, and evaluate the others)",
    )
    _bvh_options(pe)
    pe.add_argument("--json", required=True, help="output report JSON")
    pe.set_defaults(func=_evaluate)

    pd = sub.add_parser(
        "demo", formatter_class=fmt, help="the main job: build, evaluate, roll out, report"
    )
    pd.add_argument("--out", default="jaxproj-report", help="report folder")
    pd.add_argument("--quick", action="store_true", help="fewer rollouts and sweep points")
    pd.add_argument(
        "--devices",
        default="1",
        help="JAX devices for the evaluation and the MJX rollout: a count or 'all'",
    )
    pd.set_defaults(func=_demo)

    pv = sub.add_parser(
        "render", formatter_class=fmt, help="render a robot motion file to an MP4 / GIF video"
    )
    pv.add_argument("motion", help="motion file: .npz, .csv or NAOqi .json (jaxproj.io.motion_files)")
    pv.add_argument(
        "--out", required=True, help="output video: .mp4 (needs imageio-ffmpeg) or .gif"
    )
    pv.add_argument(
        "--backend",
        default="auto",
        choices=("auto", "mujoco", "matplotlib"),
        help="robot panel: MuJoCo OpenGL (needs MUJOCO_GL=egl / osmesa or a display), matplotlib "
        "stick figure, or auto (MuJoCo, else matplotlib)",
    )
    pv.add_argument("--stride", type=int, default=1, help="render every N-th frame")
    pv.add_argument(
        "--size", type=_parse_size, default=(480, 360), help="one panel's WIDTHxHEIGHT, pixels"
    )
    pv.add_argument(
        "--fps", type=float, default=None, help="playback rate (None: the motion's rate / stride)"
    )
    pv.set_defaults(func=_render)

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
