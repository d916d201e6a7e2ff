"""``jaxproj retarget``: a skeleton recording or BVH clip -> a robot-feasible joint trajectory of
the robot (``--robot`` or the model's) at a uniform rate (``--rate``), as NPZ, CSV or the
robot's own document (``Robot.exports``) (``jaxproj.motion.retarget``), optionally with a
plot; several recordings go to ``jaxproj.cli.batch``.

Size: one subcommand's options (reading, method, output, batch), the checks made before any work,
one recording's run with its summary lines, and the confidence lines they print."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jaxproj import robots
from jaxproj.cli import options
from jaxproj.errors import ConfigError, NoValidFrameError
from jaxproj.io.formats import format_names
from jaxproj.projection.config import FULL_READINGS

METHODS = ("ik", "relaxed", "full")

GAP_S = 1.0
"""``--rate``: an output frame between two input frames more than this many seconds apart is
invalid (a gap in the recording is filled by ``retarget``'s rule, not by made-up poses)."""


def _joint_counts() -> str:
    """The registered robots' joint counts: ``"<n_joints> <name>"`` per robot, comma-separated."""
    return ", ".join(f"{robots.get(n).n_joints} {n}" for n in robots.names())


def _documents() -> str:
    """The robots' own documents: ``"<suffix> (<export>, <robot>)"`` per export, joined by "or"."""
    robot_list = [robots.get(n) for n in robots.names()]
    docs = [f"{s} ({e.name}, {r.name})" for r in robot_list for s, e in r.exports.items()]
    return " or ".join(docs)


def parse_rate(text: str) -> float | str:
    """``--rate``: ``auto``, ``input`` or a frame rate (frames/s, > 0)."""
    if text in ("auto", "input"):
        return text
    try:
        rate = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not auto, input or a number: {text!r}") from None
    if not (math.isfinite(rate) and rate > 0):
        raise argparse.ArgumentTypeError(f"a rate must be a number > 0, got {text!r}")
    return rate


FPS = options.Bounded(float, 1.0, 1000.0)
"""``--fps``: 1..1000 frames/s. Above ~1 kHz the feasibility filter's acceleration bound cannot
be told from float32 round-off: one unit in the last place of an angle (~1.2e-7 rad near 1 rad)
over the squared step is 0.12 rad/s^2 at 1 kHz but 1,200 at 100 kHz (``--fps 1e5`` wrote
accelerations of 298 rad/s^2 against the bound of 80)."""


def add_parsers(sub: Any) -> None:
    pr = options.add_parser(
        sub, "retarget", "retarget a skeleton recording to a robot's joint angles"
    )
    pr.add_argument(
        "input",
        nargs="+",
        help=f"recording, one of the formats {', '.join(format_names())}; or several: files, "
        "folders (their recordings, sub-folders too) and @LIST files (one path a line), "
        "retargeted in this process, recordings of one length packed into one compiled "
        "call, into the folder --out (a batch: docs: Command line)",
    )
    pr.add_argument(
        "--out",
        required=True,
        help="output: .npz (angles, times, valid, joint_names, positions, confidence, meta), "
        f".csv (time + the robot's joints in its SDK order, rad: {_joint_counts()}; no other "
        f"column) or the robot's own document: {_documents()}; {options.OUTPUT_FOLDER_RULE}; "
        "a batch: a folder (made if missing), one OUT/<name>.npz (--out-format) a recording",
    )
    pr.add_argument(
        "--out-format",
        default=".npz",
        choices=(".npz", ".csv", ".json"),
        help="a batch: the suffix of each output (the formats of --out)",
    )
    pr.add_argument(
        "--processes",
        default=None,
        metavar="HOST:PORT,N,I",
        help="a batch over N processes (several hosts, or one): JAX's multi-process runtime "
        "(jax.distributed) with its coordinator at HOST:PORT (process 0's host), N processes, "
        "this one number I (0..N-1); each takes every N-th recording from the I-th (docs: "
        "Several GPUs and hosts)",
    )
    pr.add_argument(
        "--no-pack",
        action="store_true",
        help="a batch: retarget its recordings one at a time (each output then equals its own "
        "command's to the bit; packed, recordings of one length share a compiled call, and "
        "rounding can differ: docs: Command line)",
    )
    pr.add_argument(
        "--devices",
        default="auto",
        help="a batch: the JAX devices its packed calls are spread over, a thread each: a "
        "count, 'all', or auto (the default): every device on a GPU, one on a CPU (whose "
        "cores the generic IK already splits its rows over)",
    )
    pr.add_argument(
        "--resume",
        action="store_true",
        help="a batch: leave out a recording whose output exists (a batch stopped halfway goes "
        "on where it stopped; outputs are written whole or not at all)",
    )
    options.add_force_option(pr, "--out or --plot")
    pr.add_argument(
        "--format",
        default="auto",
        choices=("auto", *format_names()),
        help="input format (auto: by extension and content)",
    )
    options.add_bvh_options(pr, scale=True)
    options.add_reading_options(pr)
    pr.add_argument(
        "--method",
        default="ik",
        choices=METHODS,
        help="ik: the analytic IK; relaxed / full: the projector of --model (relaxed: the "
        "most accurate against the IK on held-out people; full: see --full-reading)",
    )
    pr.add_argument(
        "--model",
        help="projector file from `jaxproj build`, for --method relaxed / full (refused with "
        "--method ik, which uses no model)",
    )
    pr.add_argument(
        "--robot",
        default=None,
        type=options.robot_name,
        help=f"the robot of --method ik: a name ({', '.join(robots.names())}) or a robot file "
        "(robot.toml; docs: Robots) (None: the model's robot, which a model records; without "
        f"a model {robots.DEFAULT}); a robot other than the model's is refused",
    )
    options.add_neighbour_options(pr)
    options.add_full_reading_option(pr)
    pr.add_argument(
        "--bones",
        default=None,
        choices=("upper", "full"),
        help="descriptor bones (None: upper, or full for a robot whose IK reads more, e.g. a "
        "robot with legs; a model fixes its own, a different value is refused)",
    )
    pr.add_argument(
        "--mirror",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="mirror imitation: human left drives robot right (None: off, or the model's)",
    )
    options.add_smoother_option(pr, "the projected motion")
    pr.add_argument(
        "--fps",
        type=FPS,
        default=None,
        help=f"frame rate of the input, {FPS.RANGE} frames/s (None: the file's own timing: "
        "UTKinect frame numbers at 30 fps, MSR Action3D 15 fps, CSV / NPZ 30 fps unless the NPZ "
        "has times or fps). A BVH states its own rate (Frame Time): there --fps F resamples the "
        "clip to F frames/s (linear interpolation of joint positions), e.g. 30; None keeps the "
        "clip's rate. The range spans slow captures to 1 kHz motion capture; above it a float32 "
        "angle's resolution over the squared frame step outgrows the 80 rad/s^2 bound of "
        "--feasible (docs/reliability.md)",
    )
    pr.add_argument(
        "--rate",
        type=parse_rate,
        default="auto",
        help="frame rate of the output, frames/s: the recording is resampled onto the uniform "
        "grid k / RATE (joint positions interpolated linearly; a frame inside a gap of more "
        f"than {GAP_S:g} s is invalid, filled as lost frames are) before it is retargeted, so "
        "the feasibility filter runs on the output's own frames; auto: the input's median rate "
        "(UTKinect: 7.5; a uniform input is kept as it is); input: the input's own frame "
        "times, uneven where the tracker dropped frames",
    )
    pr.add_argument(
        "--feasible",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="make the output robot-feasible: joint limits, the speed limits of --speeds, "
        "80 rad/s^2 (jaxproj.motion.feasible)",
    )
    pr.add_argument(
        "--speeds",
        default="rated",
        choices=("rated", "no-load"),
        help="speed limits of --feasible: rated = 99%% of the robot's rated speeds (at nominal "
        "torque, Robot.rated_speeds; 75%% of no-load where none is published); no-load = 90%% "
        "of its no-load speeds (faster, closer to the person; the former default)",
    )
    pr.add_argument(
        "--joints",
        default=None,
        choices=("upper", "body"),
        help=f"joints in an output of a robot's own document ({_documents()}): upper = the "
        "document's upper-body chains (the legs stay with the robot's own balance); body = all "
        "of the robot's joints (None: upper; refused with another output, which holds every "
        "joint)",
    )
    pr.add_argument(
        "--root",
        default="fixed",
        choices=("fixed", "world"),
        help="fixed: joint angles only (the robot's base fixed); world: whole-body motion, the "
        "root body's position and orientation in a world frame with the floor at z = 0, the "
        "feet on the floor while the person's are (a robot whose correspondence has the legs, "
        "docs: Whole-body motion): .npz adds root_pos, root_rot (x, y, z, w), dof_pos, fps, "
        "contacts; .csv becomes the LAFAN1 retargeting layout (no header: root x y z, "
        "quaternion x y z w, the joints; evenly spaced frames)",
    )
    pr.add_argument(
        "--plot",
        default=None,
        help="also write a PNG: human and robot at key frames, the robot's driven joints over "
        "time against the per-frame IK (the demo report's motion figure)",
    )
    pr.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from jaxproj.cli import batch

    if batch.is_batch(args.input):
        return batch.run(args, retarget_file, None if args.no_pack else retarget_files,
                         check=lambda: batch_devices(args.devices))  # fmt: skip
    if args.processes is not None:
        raise ConfigError("--processes splits a batch: give several recordings or a folder")
    if args.no_pack:
        raise ConfigError("--no-pack is a batch's: give several recordings or a folder")
    if args.devices != "auto":
        raise ConfigError("--devices spreads a batch: give several recordings or a folder")
    args.input = args.input[0]
    retarget_file(args)
    return 0


def retarget_file(args: argparse.Namespace) -> dict[str, Any]:
    """One recording (``args.input``) to one motion file (``args.out``), with the command's
    summary lines; returns what a batch's table shows: ``frames``, ``valid``, ``seconds`` (of
    the motion) and ``low_confidence`` (the share of valid frames, or ``None`` for the IK)."""
    from jaxproj.motion.retarget import retarget

    prep = _prepare(args)
    try:
        result = retarget(prep.rec.positions, prep.rec.valid, times=prep.rec.times,
                          skeleton=prep.rec.skeleton, **_retarget_options(args, prep))  # fmt: skip
    except NoValidFrameError as e:
        raise _no_valid_frame(args, prep, e) from None
    return _write(args, prep, result)


def batch_devices(value: str) -> list | None:
    """``--devices`` of a batch -> ``retarget_many``'s ``devices``, this process's own devices
    (``jax.local_devices()``: with ``--processes`` every process spreads its share over its own
    host's): ``auto``, all of them where the default backend is not the CPU, else ``None`` (one
    device); ``all``; or a count ``N``, the first ``N``.

    Raises:
      ConfigError: a count outside ``1..len(jax.local_devices())``, or another word.
    """
    import jax

    local = jax.local_devices()
    if value in ("auto", "all"):
        spread = value == "all" or jax.default_backend() != "cpu"
        return local if spread and len(local) > 1 else None
    try:
        n = int(value)
    except ValueError:
        raise ConfigError(f"--devices {value}: a count, 'all' or 'auto'") from None
    if not 1 <= n <= len(local):
        raise ConfigError(f"--devices {value}: this process has {len(local)} JAX device(s) "
                          f"({', '.join(str(d) for d in local)}); use 1..{len(local)}")  # fmt: skip
    return local[:n] if n > 1 else None


def retarget_files(each: list[argparse.Namespace]) -> list[dict[str, Any] | Exception]:
    """``retarget_file`` of several recordings with one setting (a batch's: the arguments
    differ in ``input`` and ``out`` alone), their retargeting packed into few compiled calls
    (``jaxproj.motion.retarget.retarget_many``). One entry per recording, in order: its table
    row, or the exception ``retarget_file`` would have raised for it."""
    from jaxproj.motion.retarget import retarget_many

    out: list[Any] = [None] * len(each)
    ready: list[tuple[int, _Prepared]] = []
    for i, args in enumerate(each):
        try:
            ready.append((i, _prepare(args)))
        except Exception as err:  # noqa: BLE001 (the batch reports it with the file)
            out[i] = err
    if not ready:
        return out
    first_args, first = each[ready[0][0]], ready[0][1]
    recs = [prep.rec for _, prep in ready]
    results = retarget_many([r.positions for r in recs], [r.valid for r in recs],
                            [r.times for r in recs], [r.skeleton for r in recs],
                            devices=batch_devices(first_args.devices),
                            **_retarget_options(first_args, first))  # fmt: skip
    bodies = _root_motions(first_args, ready, results)
    for (i, prep), result, body in zip(ready, results, bodies, strict=True):
        try:
            if isinstance(result, NoValidFrameError):
                raise _no_valid_frame(each[i], prep, result)
            if isinstance(result, Exception):
                raise result
            if isinstance(body, Exception):
                raise body
            out[i] = _write(each[i], prep, result, body)
        except Exception as err:  # noqa: BLE001 (the batch reports it with the file)
            out[i] = err
    return out


def _root_motions(
    args: argparse.Namespace, ready: list[tuple[int, Any]], results: list[Any]
) -> list[Any]:
    """With ``--root world``, the whole-body stage of a batch's retargeted recordings at once
    (``whole_body.root_trajectories``: their stance IKs and last separations in one compiled call
    per length bucket): one ``RootMotion`` (or the error it raised) per recording, ``None``
    where there is none to compute."""
    if args.root != "world":
        return [None] * len(ready)
    from jaxproj.motion.whole_body import root_trajectories

    done = [k for k, r in enumerate(results) if not isinstance(r, Exception)]
    robot = ready[0][1].robot
    motions = [(ready[k][1].rec.positions, results[k].valid, results[k].times, results[k].angles)
               for k in done]  # fmt: skip
    try:
        got = root_trajectories(motions, robot)
    except Exception as err:  # noqa: BLE001 (the batch reports it with every file)
        got = [err] * len(done)
    out: list[Any] = [None] * len(ready)
    for k, body in zip(done, got, strict=True):
        out[k] = body
    return out


@dataclass
class _Prepared:
    """A recording read and its output checked (``retarget_file``'s first half)."""

    robot: robots.Robot
    bones: Any
    mirror: bool
    out: Path
    ext: str
    joints: str
    plot: Path | None
    rec: Any
    model: Any


def _prepare(args: argparse.Namespace) -> _Prepared:
    """Every check that needs no computation first (the options, the model's metadata, not
    its arrays, and the output paths), then the recording and the model's arrays."""
    from jaxproj.cli import batch
    from jaxproj.human import upper_body
    from jaxproj.io import motion_files
    from jaxproj.io.readers import read_skeleton
    from jaxproj.projection import api as engine

    robot, bones, mirror = _settings(args, engine)
    inputs = {"the recording": args.input, "--model": args.model}
    out = options.output_path(
        args.out, "--out", (".npz", ".csv", ".json"), force=args.force, inputs=inputs
    )
    ext = out.suffix.lower()
    if ext not in motion_files.formats(robot):
        raise ConfigError(
            f"--out {out}: a {ext} motion is not written for the {robot.name} (its formats: "
            f"{', '.join(motion_files.formats(robot))}; the robots' own documents: "
            f"{_documents()})"
        )
    if args.joints is not None and ext not in robot.exports:
        raise ConfigError(
            f"--joints picks the joints of a robot's own document; --out {out} holds every joint: "
            "leave --joints out"
        )
    if args.root == "world" and ext in robot.exports:
        raise ConfigError(f"--root world writes .npz or .csv; --out {out} is the {robot.name}'s "
                          "own document, which holds joint angles only")  # fmt: skip
    if args.root == "world":
        from jaxproj.motion.whole_body import check_robot

        check_robot(robot)
    if args.root == "world" and args.rate == "input":
        raise ConfigError("--root world needs evenly spaced frames: leave --rate at auto or "
                          "give a rate")  # fmt: skip
    joints = args.joints or "upper"
    for e in robot.exports.values():
        e.check(robot, joints, None)
    plot = None
    if args.plot is not None:
        plot = options.output_path(
            args.plot, "--plot", (".png",), force=args.force, inputs={**inputs, "--out": out}
        )
    rec = read_skeleton(
        args.input, format=args.format, fps=args.fps, bvh_map=args.bvh_map, scale=args.bvh_scale,
        rest_frame=args.bvh_rest_frame, skeleton=args.skeleton, body=args.body, up=args.up,
        units=args.units, hips=upper_body.hips_rule(bones, args.root),
    )  # fmt: skip
    rec = output_rate(rec, args.rate)
    model = None
    if args.method != "ik":
        model = batch.load_model(args.model)
        engine.check_neighbours(model, args.L, args.M)
    return _Prepared(robot, bones, mirror, out, ext, joints, plot, rec, model)


def _retarget_options(args: argparse.Namespace, prep: _Prepared) -> dict[str, Any]:
    """``retarget``'s keyword arguments for the command's options (all but the recording's)."""
    from jaxproj.motion import feasible

    return dict(
        model=prep.model,
        method=args.method,
        n_l=args.L,
        n_m=args.M,
        bones=prep.bones,
        mirror=prep.mirror,
        smoothing=options.smoothing(args.smoother),
        feasible=feasible.FeasibleConfig(speeds=args.speeds) if args.feasible else None,
        full=FULL_READINGS[args.full_reading],
        robot=None if prep.model is not None else prep.robot,
        level_legs=args.root == "fixed",
    )


def _no_valid_frame(
    args: argparse.Namespace, prep: _Prepared, e: NoValidFrameError
) -> NoValidFrameError:
    """``retarget``'s "no valid frame" naming the file (and the option that most often causes
    it, and what the reader says)."""
    from jaxproj.motion.retarget import no_valid_frame_problem

    rec = prep.rec
    hint = "; check --bvh-scale (metres per file unit)" if rec.format == "bvh" else ""
    problem = e.problem
    if rec.invalid_reason:  # the reader says why it marked frames (MediaPipe: visibility)
        import numpy as np

        finite = np.isfinite(rec.positions).all(axis=(1, 2))
        problem = no_valid_frame_problem(rec.valid, finite, rec.invalid_reason)
    return NoValidFrameError(args.input, f"{problem}{hint}; nothing written", e.n_frames)


def _write(
    args: argparse.Namespace, prep: _Prepared, result: Any, body: Any = None
) -> dict[str, Any]:
    """``retarget_file``'s second half: the motion file, the summary lines, the table row."""
    from jaxproj.io.motion_files import Motion, save_motion
    from jaxproj.motion import feasible
    from jaxproj.motion.retarget import MIN_VALID_SHARE

    robot, rec, model, out, joints, plot = (prep.robot, prep.rec, prep.model, prep.out,
                                            prep.joints, prep.plot)  # fmt: skip
    bones, mirror = prep.bones, prep.mirror
    angles = result.angles
    unfiltered = angles if result.unfiltered is None else result.unfiltered
    before = feasible.feasibility_report(unfiltered, result.times, robot=robot)
    after = feasible.feasibility_report(angles, result.times, robot=robot)
    meta = {
        "method": args.method,
        "smoothed": args.smoother != "none",
        "smoother": args.smoother,
        "feasible": bool(args.feasible),
        "speeds": args.speeds,
        "source": str(args.input),
        "time_source": rec.time_source,
        "fps": round(rec.fps, 6),
        "rate": args.rate if isinstance(args.rate, str) else round(float(args.rate), 6),
        "format": rec.format,
        "skeleton": rec.skeleton,
        "skeleton_from": rec.skeleton_from,
        "reading_notes": " | ".join(rec.notes),
    }
    if args.method == "full":
        meta["full_reading"] = args.full_reading
    root: dict[str, Any] = {}
    if args.root == "world":
        from jaxproj.motion.whole_body import root_trajectory

        # rec.positions are Kinect v1's 20 joints whatever the file recorded (rec.skeleton);
        # a batch has planted its recordings' feet at once (``body``)
        if body is None:
            body = root_trajectory(rec.positions, result.valid, result.times, angles, robot)
        root = {"root_pos": body.root_pos, "root_rot": body.root_rot, "contacts": body.contacts}
        angles = body.angles  # the stance feet planted
        meta["root"] = "world"
        meta["scale"] = round(body.world.scale, 6)
    motion = Motion(angles, result.times, result.valid, rec.positions, meta,
                    confidence=result.confidence, robot=robot, **root)  # fmt: skip
    save_motion(out, motion, joints=joints, overwrite=args.force)
    n, nv = len(result.valid), int(result.valid.sum())
    print(
        f"{args.input}: {n} frames ({nv} valid, {result.times[-1]:.2f} s, {rec.time_source}; "
        f"{rec.format}, skeleton {rec.skeleton}) -> {out} [method={args.method}]"
    )
    for note in rec.notes:
        print(f"  note: {note}")
    label = "feasible" if args.feasible else "not filtered (--no-feasible)"
    print(
        f"  speed-limit frames {before['speed_violation_frames']} -> "
        f"{after['speed_violation_frames']}, max step {before['max_step_deg']:.1f} -> "
        f"{after['max_step_deg']:.1f} deg, max accel / bound {before['max_accel_ratio']:.2f} -> "
        f"{after['max_accel_ratio']:.2f}, max speed / rated {before['rated_speed_ratio']:.2f} "
        f"-> {after['rated_speed_ratio']:.2f} [{label}]"
    )
    if root:
        import numpy as np

        travel = float(np.linalg.norm(root["root_pos"][-1, :2] - root["root_pos"][0, :2]))
        share = root["contacts"].mean(axis=0) * 100
        print(f"  whole body: scale {meta['scale']:.3f} robot m per person unit, root moved "
              f"{travel:.2f} m, feet in contact {share[0]:.0f} / {share[1]:.0f} % of frames "
              "(left / right)")  # fmt: skip
    if result.valid_share < MIN_VALID_SHARE:
        options.log(
            f"jaxproj: warning: {args.input}: only {nv} of {n} frames "
            f"({100 * result.valid_share:.0f} %) are valid, under the "
            f"{100 * MIN_VALID_SHARE:.0f} % jaxproj warns at: the others hold or bridge the "
            "valid poses around them (valid = false in the output); check the recording "
            f"({rec.invalid_reason or 'lost tracking, units'})"
        )
    if args.method != "ik":
        calibrated = model is None or model.deviation_scale is not None
        for line in confidence_lines(args.method, result.low_confidence_valid_share, calibrated):
            print(line)
    if plot is not None:
        _plot(plot, args, rec, angles, result, bones, mirror, robot)
    low = None if args.method == "ik" else float(result.low_confidence_valid_share)
    return {"frames": n, "valid": nv, "seconds": float(result.times[-1]), "low_confidence": low}


def output_rate(rec: Any, rate: float | str) -> Any:
    """``--rate``: the recording on the uniform grid the output is written at (``resample``,
    gaps over ``GAP_S`` invalid); ``"auto"``: the input's median rate (a recording already
    uniform at it is returned as it is); ``"input"``: unchanged."""
    import numpy as np

    from jaxproj.io.recording import resample

    if rate == "input" or len(rec.times) < 2:
        return rec
    hz = rec.fps if rate == "auto" else float(rate)
    if np.allclose(np.diff(rec.times), 1.0 / hz, rtol=1e-6, atol=0.0):
        return rec
    return resample(rec, hz, max_gap=GAP_S)


def _settings(args: argparse.Namespace, engine: Any) -> tuple[robots.Robot, str, bool]:
    """``(robot, bones, mirror)`` of the run: the model's (read from its metadata alone) with
    --method relaxed / full, where a differing --robot / --bones / --mirror is refused; else the
    options'. A model with --method ik, or no model with relaxed / full, is refused."""
    if args.method == "ik" and args.model is not None:
        raise ConfigError(
            f"--model {args.model} is used by --method relaxed / full only, and --method is ik "
            "(the default: the analytic IK, no model): add --method relaxed to use the model, "
            "or leave --model out"
        )
    if args.method == "ik":
        robot = robots.get(args.robot)
        bones = engine.BuildConfig(robot=robot.name, bones=args.bones or "auto").bones
        return robot, bones, bool(args.mirror)
    if args.model is None:
        raise ConfigError(f"--method {args.method} needs --model P.npz (see `jaxproj build`)")
    from jaxproj.projection.model_file import read_config

    config = read_config(args.model)
    fixed: dict[str, tuple[Any, Any]] = {"--bones": (args.bones, config.bones)}
    fixed["--robot"] = (args.robot, config.robot)
    fixed["--mirror"] = (args.mirror, config.mirror)
    for flag, (given, own) in fixed.items():
        if given is not None and given != own:
            raise ConfigError(
                f"{flag} {given} conflicts with the model {args.model}, built with "
                f"{flag.lstrip('-')}={own}: leave {flag} out (the model fixes it)"
            )
    return config.robot_spec, config.bones, config.mirror


EXPECTED_LOW_SHARE = 0.10
"""The share of valid frames under ``LOW_CONFIDENCE`` on held-out training people, relaxed
(the cut-off is their deviation's 90th percentile: ``jaxproj.projection.confidence``)."""

UNLIKE_FACTOR = 1.5
"""A relaxed share above ``UNLIKE_FACTOR * EXPECTED_LOW_SHARE`` (15 %) is reported as a
recording unlike the training people, with what to do about it."""


UNCALIBRATED = (
    "  this model file predates per-model calibration: its cut-off is the default model's, and "
    "a smaller model flags more frames; rebuild it (jaxproj build) for its own"
)
"""The line after the share for a model file without its own scale (``Model.deviation_scale``)."""


def confidence_lines(method: str, share: float, calibrated: bool = True) -> list[str]:
    """What ``jaxproj retarget`` prints about the low-confidence share of the valid frames
    (``RetargetResult.low_confidence_valid_share``) of ``method`` (relaxed / full): the share,
    what it means against the held-out training people the cut-off was calibrated on, and what
    to do when it is well above their tenth. ``calibrated`` False: the model has no scale of its
    own (an old file), and a line says so."""
    lines = _confidence_lines(method, share)
    return lines if calibrated else [lines[0], UNCALIBRATED, *lines[1:]]


def _confidence_lines(method: str, share: float) -> list[str]:
    from jaxproj.projection.confidence import LOW_CONFIDENCE

    head = (
        f"  low-confidence frames: {100 * share:.1f} % of the valid frames (confidence < "
        f"{LOW_CONFIDENCE:.2f}; "
    )
    if method != "relaxed":
        return [
            head + f"the cut-off is calibrated on --method relaxed, under which "
            f"{100 * EXPECTED_LOW_SHARE:.0f} % of held-out training people's frames fall; "
            f"--method {method}'s objective value runs lower and flags fewer frames: run "
            "--method relaxed on this file to judge it)"
        ]
    ratio = share / EXPECTED_LOW_SHARE
    if round(100 * share, 1) <= round(100 * UNLIKE_FACTOR * EXPECTED_LOW_SHARE, 1):  # as printed
        return [
            head + f"{100 * EXPECTED_LOW_SHARE:.0f} % of held-out training people's frames fall "
            "below it: this recording is like the people the model was built from)"
        ]
    return [
        head + f"{ratio:.1f}x the {100 * EXPECTED_LOW_SHARE:.0f} % of held-out training "
        "people's frames: this recording is unlike the people the model was built from)",
        "  to trust more of it: build a model that includes people like these (jaxproj build "
        "--data bundled+FOLDER), check the skeleton (units, joint map, --plot), or try "
        "--mirror if the person mirrors the robot; the output's confidence marks each frame",
    ]


def _plot(
    plot: Path,
    args: argparse.Namespace,
    rec: Any,
    angles: Any,
    result: Any,
    bones: str,
    mirror: bool,
    robot: robots.Robot,
) -> None:
    """``retarget --plot``: the demo's motion figure for this recording (``report.plot_retarget``):
    human and robot at key frames, the driven joints over time against the per-frame IK."""
    import numpy as np

    from jaxproj.motion.retarget import retarget
    from jaxproj.viz import report

    truth = retarget(
        rec.positions, rec.valid, method="ik", bones=bones, mirror=mirror, smoothing=None,
        times=rec.times, robot=robot,
    )  # fmt: skip
    out = angles[:, robot.driven_index]
    ik_q = truth.angles[:, robot.driven_index]
    ranges = np.degrees(out.max(axis=0) - out.min(axis=0))
    widest = ", ".join(f"{robot.driven_joints[i]} {ranges[i]:.0f}" for i in np.argsort(-ranges)[:4])
    span = float(result.times[-1] - result.times[0])
    title = (f"{Path(args.input).name}: {args.method}, {len(out)} frames over {span:.1f} s "
             f"({rec.time_source}; {rec.fps:.3g} frames/s on average)")  # fmt: skip
    report.plot_retarget(plot, title, rec.positions, result.valid, result.times, out, ik_q,
                         label=args.method, robot=robot, overwrite=args.force)  # fmt: skip
    print(f"  plot -> {plot} (widest joint ranges, deg: {widest})")
