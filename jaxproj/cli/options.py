"""What the ``jaxproj`` subcommands share: the help formatter, option groups added once
(data, neighbours, devices, BVH), value parsers, output-path checks and data loading."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from jaxproj.errors import ConfigError
from jaxproj.projection.config import FULL_READINGS


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Defaults shown in the help, except where there is none to show: required options,
    on/off flags and ``None`` defaults (their help says what leaving them out does)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        default = action.default
        if action.required or default is None or default is False or default == argparse.SUPPRESS:
            return action.help
        return super()._get_help_string(action)


def add_parser(sub: Any, name: str, help: str) -> argparse.ArgumentParser:
    """A subcommand parser with the house help formatter and the options every subcommand
    takes (``--no-cache``)."""
    p = sub.add_parser(name, formatter_class=HelpFormatter, help=help, description=help)
    p.add_argument(
        "--no-cache",
        action="store_true",
        help="run without the persistent compilation cache (compiled programs kept on disk "
        "between runs; `jaxproj info` shows its folder, $JAXPROJ_CACHE_DIR sets it)",
    )
    return p


# ------------------------------------------------------------------------------ value parsers


def parse_ints(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integers, got {text!r}"
        ) from None


def parse_floats(text: str) -> list[float]:
    try:
        return [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers, got {text!r}"
        ) from None


def parse_size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT in pixels, e.g. 480x360, got {text!r}"
        ) from None
    return width, height


def one_or_tuple(values: list | None) -> Any:
    """CLI lists: ``None``, one value, or a per-chain tuple."""
    if values is None:
        return None
    return values[0] if len(values) == 1 else tuple(values)


# ------------------------------------------------------------------------------ output paths

OUTPUT_FOLDER_RULE = "its folder must exist"
"""What the help of every output option says: jaxproj creates no missing folder for a file."""


def output_path(value: str, flag: str, suffixes: tuple[str, ...] = ()) -> Path:
    """``--out``-style option ``flag`` -> a ``Path``, checked before any work: one of
    ``suffixes`` (if given) and an existing parent folder (a typo such as ``/no/dir/r.csv`` must
    not create ``/no/dir``). ``ConfigError`` naming the option and the folder otherwise."""
    out = Path(value)
    if suffixes and out.suffix.lower() not in suffixes:
        names = suffixes[0] if len(suffixes) == 1 else ", ".join(suffixes[:-1])
        names += "" if len(suffixes) == 1 else f" or {suffixes[-1]}"
        raise ConfigError(f"{flag} {out}: use a {names} file name")
    from jaxproj._internal.atomic import missing_folder

    problem = missing_folder(out)  # the Python API's writers apply the same rule
    if problem is not None:
        raise ConfigError(f"{flag} {out}: {problem}")
    return out


# ------------------------------------------------------------------------------ option groups


def add_bvh_options(parser: argparse.ArgumentParser, scale: bool = False) -> None:
    parser.add_argument(
        "--bvh-map",
        default="auto",
        help="BVH input: joint map, Kinect joint -> BVH joint: auto (the built-in map that fits "
        "the hierarchy), cmu (CMU 3dsMax-friendly release), cmu-mb (CMU MotionBuilder-friendly) "
        "or a JSON / TOML file of {Kinect joint: BVH joint} (jaxproj.io.formats.bvh)",
    )
    if scale:
        parser.add_argument(
            "--bvh-scale",
            default="auto",
            help="BVH input: metres per file unit: auto (CMU units for the CMU maps, else the "
            "unit of m, cm, mm, in that gives a human-sized skeleton), a unit name (cmu, m, "
            "cm, mm, in) or a number",
        )


def add_data_options(
    parser: argparse.ArgumentParser,
    role: str,
    msr_subjects: str,
    strict_extra: str,
    utkinect_subjects: str = "",
) -> None:
    """``--data``, ``--subjects``, ``--strict`` and ``--bvh-map`` of ``build`` / ``evaluate``:
    ``role`` names the subjects ("training"), ``msr_subjects`` the bundled protocol's split,
    ``utkinect_subjects`` (if any) which people of 'utkinect' are the default."""
    parser.add_argument(
        "--data",
        default="bundled",
        help="'bundled'/'msr', 'utkinect' or a folder; several joined by '+' (e.g. "
        "bundled+utkinect, bundled+FOLDER: a model should hold frames of the capture set-up it "
        "will serve, docs/results.md)",
    )
    parser.add_argument(
        "--subjects",
        type=parse_ints,
        default=None,
        help=f"{role} subjects, comma-separated (None: {msr_subjects} of the bundled MSR data; "
        f"every recording of 'utkinect'{utkinect_subjects} or a folder; a folder's left-out "
        "files are noted on stderr)",
    )
    parser.add_argument(
        "--strict",
        action="store_true",
        help="with a folder: stop at the first unreadable recording (default: report it on "
        f"stderr{strict_extra})",
    )
    add_bvh_options(parser)


def add_neighbour_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--L", type=int, default=10, help="human-landmark neighbours (candidates)")
    parser.add_argument("--M", type=int, default=10, help="robot-landmark neighbours per candidate")


def add_full_reading_option(parser: argparse.ArgumentParser) -> None:
    """``--full-reading``: which reading ``--method full`` solves."""
    parser.add_argument(
        "--full-reading",
        default="weighted",
        choices=tuple(FULL_READINGS),
        help="reading of the full objective (--method full; converged Gauss-Newton): weighted "
        "(default), or the paper's min_k, each optionally with the candidate as a simplex "
        "vertex. Against the IK on held-out people min+candidate is the most accurate reading "
        "(median M_avg 0.58 deg MSR, 1.16 UTKinect), but relaxed (0.33 / 0.89) beats every "
        "reading and is faster: docs/results.md",
    )


def add_devices_option(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--devices", default="1", help=f"JAX devices {what}: a count or 'all'")


SMOOTHERS = ("offline", "paper", "none")
"""``--smoother`` choices: the zero-lag offline RTS smoother (default), the paper's causal one,
or none."""


def add_smoother_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--smoother offline|paper|none`` and ``--no-smooth`` (the same as ``--smoother none``)."""
    parser.add_argument(
        "--smoother",
        default="offline",
        choices=SMOOTHERS,
        help=f"smoother of {what}: offline = zero-lag RTS smoother of a constant-velocity model "
        "(accel_std 7, noise_std 0.02; chosen on training people, jaxproj.motion.offline); "
        "paper = the paper's causal double exponential smoother (alpha 0.75, gamma 0.3, eta 0.15 "
        "per frame at 15 fps; it lags, made for streaming); none. Both follow each frame's "
        "time step",
    )
    parser.add_argument(
        "--no-smooth", dest="smoother", action="store_const", const="none",
        help="the same as --smoother none",
    )  # fmt: skip


def smoothing(name: str) -> Any:
    """``--smoother`` value -> the settings (``None`` for ``"none"``)."""
    from jaxproj.motion.offline import OFFLINE_SMOOTHING
    from jaxproj.motion.smoothing import PAPER_SMOOTHING

    return {"offline": OFFLINE_SMOOTHING, "paper": PAPER_SMOOTHING, "none": None}[name]


def devices(value: str) -> list | None:
    """``--devices N|all`` -> ``engine.resolve_devices``, errors naming the flag."""
    from jaxproj.projection import api as engine

    try:
        return engine.resolve_devices(value)
    except ConfigError as e:
        raise ConfigError(f"--devices {value}: {e}") from None


# ------------------------------------------------------------------------------ data


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def load_data(
    data: str,
    subjects: list[int] | None,
    split: str,
    strict: bool = False,
    bvh_map: str = "auto",
) -> tuple[list, Any]:
    """Recordings of ``--data`` and, for a folder, its ``datasets.FolderContents`` (else
    ``None``). ``--subjects`` defaults to the MSR Action3D protocol's ``split`` (train / test
    subjects) on the bundled MSR data, to every recording elsewhere. Several sources joined by
    ``+`` (``bundled+utkinect``, ``bundled+/my/recordings``; at most one folder) give all their
    recordings, ``--subjects`` applied to each. For a folder, what was
    skipped (not a recording), left out (``--subjects``) or unreadable is noted on stderr;
    an unreadable recording stops the command only with ``--strict``."""
    from jaxproj._internal.progress import bar
    from jaxproj.io import datasets

    parts = data.split("+")
    if len(parts) > 1 and not Path(data).exists():  # several sources, one training set
        seqs: list = []
        folder = None
        for part in parts:
            if not part:
                raise ConfigError(f"--data {data}: an empty source between '+' signs")
            more, contents = load_data(part, subjects, split, strict, bvh_map)
            if contents is not None:
                if folder is not None:
                    raise ConfigError(f"--data {data}: at most one folder among the sources")
                folder = contents
            seqs += more
        return seqs, folder
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
        log(f"jaxproj: note: {line}")
    return contents.sequences, contents


def unreadable_note(contents: Any) -> str:
    """`` (N unreadable recording(s) not used: ...)`` for a summary line, or ``""``."""
    if contents is None or not contents.unreadable:
        return ""
    names = ", ".join(name for name, _ in contents.unreadable)
    n = len(contents.unreadable)
    return f" ({n} unreadable recording(s) not used: {names}; --strict stops at the first)"
