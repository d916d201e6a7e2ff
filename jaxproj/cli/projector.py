"""``jaxproj build`` (a projector from recordings) and ``jaxproj evaluate`` (its batch
evaluation against the IK, with baselines)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from jaxproj import robots
from jaxproj._internal.progress import bar
from jaxproj.cli import options
from jaxproj.io.bundled import UTK_SUBJECTS, UTK_TRAIN_SUBJECTS

BUILD_STAGES = ("descriptors", "landmarks and kernels", "save")
"""The steps of ``jaxproj build`` its progress bar counts (on a terminal only)."""

LANDMARKS = options.Bounded(int, 2, 100_000, many=True)
"""``build --landmarks``: 2..100,000 per chain (``BuildConfig`` needs >= 2; the bundled training
set holds ~30,000 frames)."""
BANDWIDTH = options.Bounded(float, 0.0, 10.0, open_lo=True, many=True)
"""``build --bandwidth``: > 0 and <= 10 (descriptor distances between unit bone directions
stay under 2 per bone: a larger bandwidth makes one landmark)."""
K = options.Bounded(int, 2, 4096)
"""``build --k``: 2..4096 training neighbours per kernel (tuned: 96)."""
HIDDEN = options.Bounded(int, 2, 4096)
"""``build --hidden``: 2..4096 hidden units (tuned: 96 / 192)."""
POSITIVE = options.Bounded(float, 0.0, None, open_lo=True)
"""``build --lam`` / ``--input-scale``: finite and > 0."""
SEED = options.Bounded(int, 0, 2**32 - 1)
"""``build --seed``: a uint32, as ``jax.random.PRNGKey`` takes."""


def add_parsers(sub: Any) -> None:
    _add_build(sub)
    _add_evaluate(sub)


def _add_build(sub: Any) -> None:
    pb = options.add_parser(sub, "build", "build a projector (landmarks + ELM kernels)")
    options.add_data_options(pb, "training", "1,3,5,7,9", " and use the others")
    pb.add_argument(
        "--utkinect-people",
        type=_parse_people,
        default=None,
        help="with --data bundled/msr: the bundled UTKinect-Action3D people (of "
        f"{','.join(map(str, UTK_SUBJECTS))}) whose whole recordings join the MSR training "
        "subjects; 'none': MSR alone (None: "
        f"{','.join(map(str, UTK_TRAIN_SUBJECTS))}, the default model's training set, "
        "without --subjects; none with --subjects; evaluate scores UTKinect on the others)",
    )
    pb.add_argument(
        "--robot",
        default=robots.DEFAULT,
        type=options.robot_name,
        help=f"the robot the projector is for: a name ({', '.join(robots.names())}) or a robot "
        "file (robot.toml; docs: Robots); its chains, limits and IK; the model records it",
    )
    pb.add_argument(
        "--chains",
        default="upper",
        choices=("upper", "whole"),
        help="upper: one projector per chain of the robot (its robot file's or module's chains); "
        "whole: the paper's whole-body projector",
    )
    size = pb.add_mutually_exclusive_group()
    size.add_argument(
        "--pairs",
        nargs=2,
        metavar=("RECORDING", "MOTION"),
        help="build from given pairs, no IK and no mean shift (the paper's hand-given pairs): a "
        "skeleton recording (any format retarget reads) and a motion file of the robot for it "
        "(.npz / .csv, the same number of frames: another retargeter's output, or poses set by "
        "hand); every frame valid in both is a landmark (--data, --subjects and "
        "--utkinect-people are refused)",
    )
    size.add_argument(
        "--landmarks",
        type=LANDMARKS,
        help=f"target landmark count, bisected, each {LANDMARKS.RANGE}: one number for each chain "
        "(a chain its robot file marks keep_bandwidth keeps its bandwidth) or one per chain, "
        "e.g. 400,1644,1644 (neither this nor --bandwidth: engine.DEFAULTS, the tuned "
        "bandwidths; the paper's largest set is 1644, and a chain cannot hold more landmarks "
        "than training frames)",
    )
    size.add_argument(
        "--bandwidth",
        type=BANDWIDTH,
        help=f"mean-shift bandwidth, each {BANDWIDTH.RANGE} (descriptor units: unit bone "
        "directions): one, or one per chain",
    )
    tuned = "None: engine.DEFAULTS of the chain set"
    pb.add_argument(
        "--k",
        type=K,
        default=None,
        help=f"training neighbours per kernel, {K.RANGE} ({tuned}, 96; at most the landmarks)",
    )
    pb.add_argument(
        "--hidden",
        type=HIDDEN,
        default=None,
        help=f"hidden units, {HIDDEN.RANGE} and >= k ({tuned}; with --k: max(k, 192))",
    )
    pb.add_argument(
        "--lam",
        type=POSITIVE,
        default=None,
        help=f"ELM ridge regulariser, {POSITIVE.RANGE} ({tuned})",
    )
    pb.add_argument(
        "--input-scale",
        type=POSITIVE,
        default=None,
        help=f"hidden-weight std, {POSITIVE.RANGE} ({tuned})",
    )
    pb.add_argument(
        "--seed", type=SEED, default=0, help=f"PRNG seed of the hidden layers, {SEED.RANGE}"
    )
    pb.add_argument("--mirror", action="store_true", help="mirror imitation")
    pb.add_argument(
        "--out", required=True, help=f"output projector .npz; {options.OUTPUT_FOLDER_RULE}"
    )
    options.add_force_option(pb, "--out")
    pb.set_defaults(func=build)


def _add_evaluate(sub: Any) -> None:
    pe = options.add_parser(sub, "evaluate", "batch evaluation against the IK, with baselines")
    pe.add_argument("--model", required=True, help="projector file from `jaxproj build`")
    options.add_data_options(
        pe,
        "evaluated",
        "2,4,6,8,10",
        " and in the JSON's data_files, and evaluate the others",
        " (of the people the model did not train on)",
    )
    pe.add_argument(
        "--objective",
        default="all",
        choices=("relaxed", "full", "all"),
        help="projection objective(s); the baselines always run",
    )
    options.add_neighbour_options(pe)
    options.add_smoother_option(pe, "the scored motions (unsmoothed figures are reported too)")
    options.add_devices_option(
        pe, "to spread the queries over (one share per device, each running its own program)"
    )
    pe.add_argument(
        "--json", required=True, help=f"output report JSON; {options.OUTPUT_FOLDER_RULE}"
    )
    options.add_force_option(pe, "--json")
    pe.set_defaults(func=evaluate)


def _parse_people(text: str) -> tuple[int, ...]:
    """``--utkinect-people``: comma-separated people, or ``none`` / empty for none."""
    if text.strip().lower() in ("", "none"):
        return ()
    return tuple(options.parse_ints(text))


def training_people(
    data: str, subjects: list[int] | None, people: tuple[int, ...] | None
) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """``(added, recorded)``: the UTKinect-Action3D people ``build`` adds to ``--data`` (whole
    recordings) and those its training data then holds (``BuildConfig.utkinect_people``).

    With the bundled MSR data alone (``bundled`` / ``msr``): ``--utkinect-people``, or when it
    is not given the default training set's (``UTK_TRAIN_SUBJECTS``) unless ``--subjects``
    picks the MSR people (then none). Data that holds ``utkinect`` (alone or joined by ``+``)
    adds none and holds its ``--subjects`` (default: all five). Other data: none. A
    ``--utkinect-people`` naming some is refused but with the bundled MSR data alone.
    """
    from jaxproj.errors import ConfigError

    if data in ("bundled", "msr"):
        added = (UTK_TRAIN_SUBJECTS if subjects is None else ()) if people is None else people
        return added, added
    if people:
        raise ConfigError(
            f"--utkinect-people adds bundled UTKinect-Action3D people to --data bundled / msr "
            f"only, not to --data {data}: leave it out"
        )
    if "utkinect" in data.split("+"):
        held = set(UTK_SUBJECTS if subjects is None else subjects)
        return (), tuple(s for s in UTK_SUBJECTS if s in held)
    return (), ()


def _pairs(args: argparse.Namespace, cfg: Any) -> tuple[Any, Any]:
    """``(descriptors (K, m), driven angles (K, n_driven))``: the frames of ``--pairs`` valid
    in both files. ConfigError / InputError naming the file for a mismatch."""
    from jaxproj.errors import ConfigError
    from jaxproj.human.descriptors import frame_descriptors
    from jaxproj.io.motion_files import load_motion
    from jaxproj.io.readers import read_skeleton
    from jaxproj.motion.retarget import check_skeleton

    rec_path, motion_path = args.pairs
    rec = read_skeleton(rec_path, bvh_map=args.bvh_map)
    robot = cfg.robot_spec
    check_skeleton(rec.skeleton, robot)
    motion = load_motion(motion_path, robot=robot)
    if motion.n_frames != len(rec.valid):
        raise ConfigError(f"--pairs: {rec_path} has {len(rec.valid)} frames but {motion_path} "
                          f"has {motion.n_frames}: one robot pose per recording frame")  # fmt: skip
    d, keep = frame_descriptors([rec], bones=cfg.bones, mirror=cfg.mirror)
    keep = keep & motion.valid
    if keep.sum() < 2:
        raise ConfigError(f"--pairs: {int(keep.sum())} frames valid in both {rec_path} and "
                          f"{motion_path}: need at least 2")  # fmt: skip
    q = robot.clip(motion.angles)[:, robot.driven_index]
    return d[keep], q[keep]


def build(args: argparse.Namespace) -> int:
    from jaxproj.io import datasets
    from jaxproj.projection import api as engine

    out = options.output_path(
        args.out, "--out", (".npz",), force=args.force,
        inputs=options.folder_inputs(args.data, args.out),
    )  # fmt: skip
    if args.pairs is not None:
        given = [f for f in ("data", "subjects", "utkinect_people") if getattr(args, f) not in
                 (None, "bundled")]  # fmt: skip
        if given:
            from jaxproj.errors import ConfigError

            flags = ", ".join(f"--{f.replace('_', '-')}" for f in given)
            raise ConfigError(f"--pairs gives the training pairs: leave {flags} out")
        return _build_pairs(args, out)
    people, recorded = training_people(args.data, args.subjects, args.utkinect_people)
    cfg = engine.BuildConfig(
        chains=args.chains,
        landmarks=options.one_or_tuple(args.landmarks),
        bandwidth=options.one_or_tuple(args.bandwidth),
        k=args.k,
        hidden=args.hidden if args.hidden is not None or args.k is None else max(args.k, 192),
        lam=args.lam,
        input_scale=args.input_scale,
        seed=args.seed,
        mirror=args.mirror,
        utkinect_people=recorded,
        robot=args.robot,
    )
    t0 = time.perf_counter()
    seqs, contents = options.load_data(args.data, args.subjects, "train", args.strict, args.bvh_map)
    if people:  # the default training set: datasets.training_sequences
        seqs = seqs + datasets.utkinect_action3d(subjects=people, segments=False)
    stages = bar(BUILD_STAGES, "build")
    next(stages)  # descriptors
    d = datasets.valid_descriptors(seqs, bones=cfg.bones, mirror=cfg.mirror)
    n_frames = sum(len(s.valid) for s in seqs)
    engine.check_training_data(d, cfg)  # a landmark count the data cannot reach: before the log
    options.log(f"mean shift over {len(d)} descriptors, then the ELM kernel banks ...")
    next(stages)  # landmarks and kernels
    model = engine.build(d, cfg)
    next(stages)  # save
    engine.save(model, out, overwrite=args.force)
    for _ in stages:  # the bar completes and closes
        pass
    dt = time.perf_counter() - t0
    lay = model.projector.layout
    parts = []
    for c, name in enumerate(lay.names):
        target = cfg.chain_config(c).landmarks
        aim = f"target {target}, " if target else ""
        parts.append(
            f"{name} {lay.landmarks[c]} ({aim}bandwidth {model.bandwidth[c]:.4f}, k={lay.k[c]}, "
            f"hidden={lay.hidden[c]})"
        )
    per_chain = ", ".join(parts)
    utk = f" (with UTKinect people {','.join(map(str, recorded))})" if recorded else ""
    print(
        f"built {cfg.chains} chains: {per_chain} from {model.n_train} valid frames "
        f"(of {n_frames}){utk}, seed={cfg.seed} in {dt:.1f} s -> {out}"
        + options.unreadable_note(contents)
    )
    return 0


def _build_pairs(args: argparse.Namespace, out: Path) -> int:
    from jaxproj.projection import api as engine

    cfg = engine.BuildConfig(
        chains=args.chains, k=args.k,
        hidden=args.hidden if args.hidden is not None or args.k is None else max(args.k, 192),
        lam=args.lam, input_scale=args.input_scale, seed=args.seed, mirror=args.mirror,
        utkinect_people=(), robot=args.robot,
    )  # fmt: skip
    t0 = time.perf_counter()
    human, poses = _pairs(args, cfg)
    model = engine.calibrated(engine.from_landmarks(human, poses, cfg), human)
    engine.save(model, out, overwrite=args.force)
    lay = model.projector.layout
    per_chain = ", ".join(f"{n} {lay.landmarks[c]}" for c, n in enumerate(lay.names))
    print(f"built {cfg.chains} chains from {len(human)} given pairs ({per_chain} distinct "
          f"landmarks, no IK) in {time.perf_counter() - t0:.1f} s -> {out}")  # fmt: skip
    return 0


def evaluate(args: argparse.Namespace) -> int:
    from jaxproj._internal.mjx import import_mjx

    import_mjx()  # before jaxproj.eval imports it: without Warp's notice
    from jaxproj.eval import evaluate
    from jaxproj.projection import api as engine
    from jaxproj.viz import report

    inputs = {"--model": args.model, **options.folder_inputs(args.data, args.json)}
    json_out = options.output_path(args.json, "--json", force=args.force, inputs=inputs)
    devices = options.devices(args.devices)
    model = engine.load(args.model)
    engine.check_neighbours(model, args.L, args.M)
    objectives = ["relaxed", "full"] if args.objective == "all" else [args.objective]
    methods = objectives + ["nearest_landmark", "knn_average", "global_elm"]
    t0 = time.perf_counter()
    subjects = _utkinect_subjects(args.data, args.subjects, model.config.utkinect_people)
    seqs, contents = options.load_data(args.data, subjects, "test", args.strict, args.bvh_map)
    data = evaluate.prepare(
        seqs, bones=model.config.bones, mirror=model.config.mirror, robot=model.robot
    )
    out = evaluate.evaluate(
        model,
        data,
        methods,
        n_l=args.L,
        n_m=args.M,
        smoothing=options.smoothing(args.smoother),
        devices=devices,
        progress=True,
    )
    out["wall_s"]["total"] = time.perf_counter() - t0
    out["subjects"] = sorted({int(s.subject) for s in seqs})
    out["model_utkinect_people"] = list(model.config.utkinect_people)
    out["data"] = args.data
    out["model"] = str(args.model)
    if contents is not None:
        out["data_files"] = contents.to_json()
    report.write_json(Path(json_out), out, overwrite=args.force)
    print(report.summary_table(out["summary"], methods))
    print(
        f"{out['valid_frames']} valid frames of {out['sequences']} sequences -> {args.json}"
        + options.unreadable_note(contents)
    )
    return 0


def _utkinect_subjects(
    data: str, subjects: list[int] | None, trained: tuple[int, ...]
) -> list[int] | None:
    """``evaluate --data utkinect``'s people: by default those the model did not train on
    (``BuildConfig.utkinect_people``); given ones it trained on are scored with a warning."""
    import sys

    from jaxproj.errors import ConfigError

    if data != "utkinect" or not trained:
        return subjects
    if subjects is None:
        rest = [s for s in UTK_SUBJECTS if s not in trained]
        if not rest:
            raise ConfigError(
                "the model trained on every bundled UTKinect-Action3D person: none is left to "
                "evaluate on (give --subjects to score trained people anyway)"
            )
        return rest
    seen = sorted(set(subjects) & set(trained))
    if seen:
        print(
            f"jaxproj: warning: the model trained on UTKinect-Action3D people {seen}: their "
            "scores are not held-out accuracy",
            file=sys.stderr,
        )
    return subjects
