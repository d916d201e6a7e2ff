"""What the ``jaxproj`` subcommands share: the parser (one-line errors) and its help formatter,
option groups added once (data, neighbours, devices, BVH, --force), value parsers with their
documented ranges, output-path checks and data loading."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NoReturn

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


class Parser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose usage errors (an unknown option, a value out of its
    range) are one line on stderr, exit status 2, as every other jaxproj error: ``jaxproj
    retarget: error: argument --fps: ... (see jaxproj retarget --help)``, without the usage
    block (several lines for the larger subcommands)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


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


def _number_text(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


class Bounded:
    """An argparse ``type=``: a number of ``kind`` in ``[lo, hi]`` (``(lo, hi]`` with
    ``open_lo``; no upper end for ``hi=None``), finite, else a one-line error naming the range
    (argparse adds the option's name); ``many``: comma-separated values, each in the range
    (``--landmarks 400,1644,1644``), as a list. ``RANGE`` says the range in words, for the
    help."""

    def __init__(
        self,
        kind: type[int] | type[float],
        lo: float,
        hi: float | None = None,
        *,
        open_lo: bool = False,
        many: bool = False,
    ) -> None:
        self.kind, self.lo, self.hi, self.open_lo, self.many = kind, lo, hi, open_lo, many
        lo_text = f"{'>' if open_lo else '>='} {_number_text(lo)}"
        if hi is None:
            self.RANGE = lo_text
        elif open_lo:
            self.RANGE = f"{lo_text} and <= {_number_text(hi)}"
        else:
            self.RANGE = f"{_number_text(lo)}..{_number_text(hi)}"
        self.__name__ = kind.__name__  # what argparse calls the type in its own messages

    def one(self, text: str) -> Any:
        noun = "a whole number" if self.kind is int else "a number"
        try:
            value = self.kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {noun} {self.RANGE}, got {text!r}"
            ) from None
        low_ok = value > self.lo if self.open_lo else value >= self.lo
        if not (math.isfinite(value) and low_ok and (self.hi is None or value <= self.hi)):
            raise argparse.ArgumentTypeError(f"{text} is out of range: use {noun} {self.RANGE}")
        return value

    def __call__(self, text: str) -> Any:
        if not self.many:
            return self.one(text)
        values = [self.one(t.strip()) for t in text.split(",") if t.strip()]
        if not values:
            raise argparse.ArgumentTypeError(f"expected comma-separated values, got {text!r}")
        return values


def robot_name(text: str) -> str:
    """``--robot``: a registered robot's name, or a robot file (``.toml``: read, registered,
    and its robot's name returned)."""
    from jaxproj import robots

    try:
        return robots.get(text).name
    except ConfigError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


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


SIZE_RANGE = (32, 4096)
"""Pixels of each side of ``render --size`` (``jaxproj.viz.render``'s limits)."""


def parse_size(text: str) -> tuple[int, int]:
    lo, hi = SIZE_RANGE
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected WIDTHxHEIGHT in pixels, e.g. 480x360, got {text!r}"
        ) from None
    if not (lo <= width <= hi and lo <= height <= hi):
        raise argparse.ArgumentTypeError(f"{text} is out of range: each side {lo}..{hi} pixels")
    return width, height


def one_or_tuple(values: list | None) -> Any:
    """CLI lists: ``None``, one value, or a per-chain tuple."""
    if values is None:
        return None
    return values[0] if len(values) == 1 else tuple(values)


# ------------------------------------------------------------------------------ output paths

OUTPUT_FOLDER_RULE = "its folder must exist; an existing file is replaced only with --force"
"""What the help of every output option says: jaxproj creates no missing folder for a file,
and replaces no file unless told to."""

FORCE_FIX = "pass --force to replace it"
"""What to do about an existing output, in the CLI's words."""


def add_force_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--force``: replace existing output files (``what``); never an input."""
    parser.add_argument(
        "--force",
        action="store_true",
        help=f"replace an existing {what} (default: refuse, exit 2, before any work); an "
        "output that is one of the command's inputs is refused even with --force",
    )


def output_path(
    value: str,
    flag: str,
    suffixes: tuple[str, ...] = (),
    *,
    force: bool = False,
    inputs: Mapping[str, str | os.PathLike[str] | None] | None = None,
) -> Path:
    """``--out``-style option ``flag`` -> a ``Path``, checked before any work: one of
    ``suffixes`` (if given), an existing parent folder (a typo such as ``/no/dir/r.csv`` must
    not create ``/no/dir``), none of ``inputs`` (what -> path: the recording, ``--model``,
    another output; refused even with ``force``), not an existing file unless ``force``.
    ``ConfigError`` naming the option and the problem otherwise."""
    out = Path(value)
    if suffixes and out.suffix.lower() not in suffixes:
        names = suffixes[0] if len(suffixes) == 1 else ", ".join(suffixes[:-1])
        names += "" if len(suffixes) == 1 else f" or {suffixes[-1]}"
        raise ConfigError(f"{flag} {out}: use a {names} file name")
    from jaxproj._internal.atomic import output_problem

    # the Python API's writers apply the same rules (overwrite=False is --force left out)
    problem = output_problem(out, force, inputs, fix=FORCE_FIX)
    if problem is not None:
        raise ConfigError(f"{flag} {out}: {problem.replace('overwrite=True / ', '')}")
    return out


def folder_inputs(data: str, out: str) -> dict[str, Path]:
    """``{"a file of --data F": out}`` where the existing file ``out`` lies in a folder ``F`` of
    ``--data`` (for ``output_path``'s ``inputs``): it is, or would be read as, a recording."""
    parts = [data] if Path(data).exists() else data.split("+")
    folders = [Path(p) for p in parts if p not in ("bundled", "msr", "utkinect")]
    if not Path(out).is_file():
        return {}
    return {
        f"a file of --data {f}": Path(out)
        for f in folders
        if f.is_dir() and Path(out).resolve().parent == f.resolve()
    }


# ------------------------------------------------------------------------------ option groups


def add_bvh_options(parser: argparse.ArgumentParser, scale: bool = False) -> None:
    parser.add_argument(
        "--bvh-map",
        default="auto",
        help="BVH input: joint map, Kinect joint -> BVH joint: auto (the built-in map that fits "
        "the hierarchy), cmu (CMU 3dsMax-friendly release), cmu-mb (CMU MotionBuilder-friendly), "
        "lafan1 (Ubisoft LAFAN1), mixamo (Mixamo characters, any 'mixamorig:' prefix) or a JSON "
        "/ TOML file of {Kinect joint: BVH joint} (jaxproj.io.formats.bvh)",
    )
    if scale:
        parser.add_argument(
            "--bvh-rest-frame",
            default="drop",
            choices=("drop", "keep"),
            help="BVH input: drop leaves out a first frame that is a converter's "
            "synthetic rest pose (every joint rotation 0 in frame 0 and not in frame 1; some "
            "CMU conversions begin with a T-pose), keep reads it",
        )
        parser.add_argument(
            "--bvh-scale",
            default="auto",
            help="BVH input: metres per file unit: auto (CMU units for the CMU maps, else the "
            "unit of m, cm, mm, in that gives a human-sized skeleton), a unit name (cmu, m, "
            "cm, mm, in) or a number",
        )


def add_reading_options(parser: argparse.ArgumentParser) -> None:
    """``--skeleton``, ``--body``, ``--up`` and ``--units``: what ``read_skeleton`` cannot
    always tell from a file (``jaxproj.io.readers``)."""
    from jaxproj.human import skeletons

    parser.add_argument(
        "--skeleton",
        default=None,
        choices=skeletons.names(),
        help="npz / npy input: the skeleton the joint array holds (None: the file's skeleton "
        "key, else guessed from the joint count, which the summary says)",
    )
    parser.add_argument(
        "--body",
        default="first",
        type=_body,
        help="NTU RGB+D / Azure Kinect input (several people per frame): first, or a 0-based "
        "index into each frame's bodies",
    )
    parser.add_argument(
        "--up",
        default="y",
        choices=("y", "z"),
        help="npz / npy input: the axis that points up in the file (y: SMPL, Kinect, HumanML3D; "
        "z: AMASS, most mocap)",
    )
    parser.add_argument(
        "--units",
        default="auto",
        choices=("auto", "m", "cm", "mm"),
        help="npz / npy / csv input: the positions' unit (auto: read from the bones' lengths, "
        "converted to metres with a note)",
    )


def _body(text: str) -> str | int:
    if text == "first":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected 'first' or a 0-based body index, got {text!r}"
        ) from None


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
        help="'bundled'/'msr', 'utkinect', a folder, a recording or @LIST (a text file of "
        "recordings, one a line); several joined by '+' (e.g. "
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


NEIGHBOURS = Bounded(int, 1, 200)
"""``--L`` / ``--M``: 1..200 (the paper's sweep is 5..50; the search's cost grows with L x M; a
model also caps both at its smallest chain's landmark count)."""


def add_neighbour_options(parser: argparse.ArgumentParser) -> None:
    rule = f"{NEIGHBOURS.RANGE} (and at most the model's smallest chain's landmark count)"
    parser.add_argument(
        "--L", type=NEIGHBOURS, default=10, help=f"human-landmark neighbours (candidates): {rule}"
    )
    parser.add_argument(
        "--M", type=NEIGHBOURS, default=10, help=f"robot-landmark neighbours per candidate: {rule}"
    )


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
    subjects) on the bundled MSR data, to every recording elsewhere. A recording file, or
    ``@LIST`` (a text file naming recordings, one a line: ``batch.expand``'s rules), is read as
    a folder of those files (``datasets.load_files``). Several sources joined by ``+``
    (``bundled+utkinect``, ``bundled+/my/recordings``; at most one folder, file or list) give
    all their recordings, ``--subjects`` applied to each. For a folder, what was
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
                    raise ConfigError(
                        f"--data {data}: at most one folder, file or list among the sources"
                    )
                folder = contents
            seqs += more
        return seqs, folder
    if subjects is None and data in ("bundled", "msr"):
        subjects = list(datasets.TRAIN_SUBJECTS if split == "train" else datasets.TEST_SUBJECTS)
    if data in ("bundled", "msr", "utkinect"):
        return datasets.load_sequences(data, subjects), None
    read = lambda files: bar(files, "reading recordings")  # noqa: E731
    if data.startswith("@") or Path(data).is_file():  # a recording, or a list of them
        from jaxproj.cli.batch import expand

        files = [f for f, _ in expand([data])]
        contents = datasets.load_files(
            files, subjects, where=data, strict=strict, progress=read, bvh_map=bvh_map
        )
    else:
        contents = datasets.load_folder(
            data, subjects, strict=strict, progress=read, bvh_map=bvh_map
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
