"""``jaxproj retarget`` over many recordings: a batch, one process, one output folder.

``jaxproj retarget A.bvh B.csv FOLDER @LIST --out OUT/`` retargets every recording the inputs
name in this process: the model is read once (``retarget.load_model``) and
every compiled program serves every recording whose length falls in the same shape bucket
(``jaxproj._internal.buckets``), so the per-file compile that one command per file pays is paid
once per bucket (with the persistent compilation cache across runs too, ``jaxproj.cli.cache``).

* **Packed** (``run``'s ``many``: ``retarget.retarget_files``): up to ``pack_recordings()``
  recordings (1,024 on a CPU, 16,384 on an accelerator) are read, then retargeted together
  (``jaxproj.motion.retarget.retarget_many``: the recordings of one length bucket in one
  compiled call, their feasibility filters in one batch), then written; each recording's
  output is its own command's up to float rounding.
  A round that fails as a whole is done again one recording at a time.
* **Inputs** (``expand``): a file; a folder: every recording in it and its sub-folders (the
  folder rules of ``jaxproj.io.readers.recording_format``: documentation, labels and models are
  left out), sorted by path; ``@LIST``: a text file of paths, one a line (blank lines and lines
  starting with ``#`` skipped; relative paths from the list's folder). A path named twice is
  retargeted once.
* **Outputs**: ``OUT/<name><--out-format>``, ``<name>`` the recording's path under its input
  folder without its suffix (a file named directly: its file name), so the tree of a folder is
  kept. Two recordings that would write one output are refused before any work. Each output is
  written whole or not at all (``jaxproj._internal.atomic``); ``--resume`` leaves out a
  recording whose output exists, so a stopped batch goes on where it stopped; without it an
  existing output is refused unless ``--force``, before any work.
* **A recording that fails** (an unreadable file, no valid frame, ...) is reported on stderr when
  it fails and again at the end, and the batch goes on; the exit status is then 1 (0 when every
  recording was written or left out by ``--resume``).
* **Progress** on stderr, a line a recording: ``[3/40] walk.bvh: 1,102 frames in 4.1 s (269
  frames/s)``; at the end a table on stdout: per recording its frames, valid share and (for the
  projector) low-confidence share, and the totals with the batch's frames per second.

Options that name one output (``--plot``) are refused in a batch.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from jaxproj.errors import ConfigError, JaxprojError


def is_batch(inputs: Sequence[str]) -> bool:
    """Whether ``retarget``'s inputs make a batch: several, a folder or an ``@LIST``."""
    return len(inputs) > 1 or inputs[0].startswith("@") or Path(inputs[0]).is_dir()


def expand(inputs: Sequence[str]) -> list[tuple[Path, str]]:
    """``(recording, output name without suffix)`` for every recording the inputs name, in
    order, each once (module doc).

    Raises:
      ConfigError: a missing file, folder or list; a folder or list with no recording.
    """
    from jaxproj.io.readers import recording_format

    found: dict[Path, str] = {}
    for item in inputs:
        if item.startswith("@"):
            listed = Path(item[1:])
            if not listed.is_file():
                raise ConfigError(f"{item}: no such list file")
            lines = listed.read_text(encoding="utf-8", errors="replace").splitlines()
            paths = [ln.strip() for ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
            if not paths:
                raise ConfigError(f"{item}: the list names no recording")
            for p in paths:
                path = Path(p) if Path(p).is_absolute() else listed.parent / p
                if not path.is_file():
                    raise ConfigError(f"{item}: {p}: no such file")
                found.setdefault(path.resolve(), path.stem)
        elif Path(item).is_dir():
            root = Path(item)
            files = sorted(f for f in root.rglob("*") if f.is_file())
            kept = [f for f in files if recording_format(f)[0] is not None]
            if not kept:
                raise ConfigError(f"{item}: a folder with no recording")
            for f in kept:
                found.setdefault(f.resolve(), str(f.relative_to(root).with_suffix("")))
        else:
            if not Path(item).is_file():
                raise ConfigError(f"{item}: no such file or folder")
            found.setdefault(Path(item).resolve(), Path(item).stem)
    return list(found.items())


def plan(
    inputs: Sequence[str], out: str, suffix: str, resume: bool, force: bool
) -> tuple[list[tuple[Path, Path]], list[Path]]:
    """``([(recording, output)] to write, [outputs left out by --resume])``, checked before any
    work: no two recordings write one output, no output overwritten without ``force``.

    Raises:
      ConfigError: ``--out`` is an existing file; two recordings, one output; an existing output
        without ``--resume`` or ``--force``.
    """
    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise ConfigError(f"--out {out}: a batch writes into a folder, and this is a file")
    found = expand(inputs)
    if not folder.exists() and folder.suffix.lower() in (".npz", ".csv", ".json"):
        raise ConfigError(f"--out {out}: a batch writes into a folder, and this names a file "
                          f"({len(found)} recordings): give a folder")  # fmt: skip
    todo: list[tuple[Path, Path]] = []
    skipped: list[Path] = []
    owner: dict[Path, Path] = {}
    for src, name in found:
        dst = folder / f"{name}{suffix}"
        if dst in owner:
            raise ConfigError(
                f"--out {out}: {owner[dst]} and {src} would both write {dst}; retarget them "
                "into two folders"
            )
        owner[dst] = src
        if dst.exists() and resume:
            skipped.append(dst)
        elif dst.exists() and not force:
            raise ConfigError(
                f"--out {out}: {dst} exists: --resume leaves it out, --force overwrites it"
            )
        else:
            todo.append((src, dst))
    return todo, skipped


def processes(text: str | None) -> tuple[str, int, int] | None:
    """``--processes HOST:PORT,N,I`` -> ``(coordinator, N, I)`` (``None``: one process).

    Raises:
      ConfigError: not three comma-separated parts, ``N < 1`` or ``I`` not in ``0..N-1``.
    """
    if text is None:
        return None
    parts = text.split(",")
    try:
        address, count, index = parts[0], int(parts[1]), int(parts[2])
    except (IndexError, ValueError):
        raise ConfigError(
            f"--processes {text}: expected HOST:PORT,N,I (the coordinator, the number of "
            "processes, this process's number)"
        ) from None
    if len(parts) != 3 or ":" not in address or count < 1 or not 0 <= index < count:
        raise ConfigError(f"--processes {text}: expected HOST:PORT,N,I with N >= 1 and 0 <= I < N")
    return address, count, index


def share(todo: list[tuple[Path, Path]], count: int, index: int) -> list[tuple[Path, Path]]:
    """Process ``index`` of ``count``'s recordings: every ``count``-th from the ``index``-th of
    the batch's order (the same in every process: ``plan`` is deterministic)."""
    return todo[index::count]


PACK_RECORDINGS = 1024
PACK_RECORDINGS_ACCELERATOR = 16384
"""Recordings read, retargeted together (``many``) and written in one round of a batch at
most: 1,024 on a CPU (a round's progress line every few minutes), 16,384 on an accelerator
(``pack_recordings``), where a round's length buckets each cost their passes in time order
however few recordings they hold: 10,000 G1 files in rounds of 1,024 ran the longest bucket
ten times."""


def pack_recordings() -> int:
    """A round's recordings (``PACK_RECORDINGS`` on a CPU, ``PACK_RECORDINGS_ACCELERATOR``
    elsewhere)."""
    import jax

    return PACK_RECORDINGS if jax.default_backend() == "cpu" else PACK_RECORDINGS_ACCELERATOR


def run(
    args: argparse.Namespace,
    one: Callable[[argparse.Namespace], dict[str, Any]],
    many: Callable[[list[argparse.Namespace]], list[dict[str, Any] | Exception]] | None = None,
    check: Callable[[], object] | None = None,
) -> int:
    """The batch (module doc): ``one(args)`` retargets one recording (``args.input``) to one
    file (``args.out``) and returns its table row; ``many`` (where given) does so for up to
    ``pack_recordings()`` at once, returning each one's row or exception (a round that fails as
    a whole is done again with ``one``, recording by recording). With ``--processes`` this
    process joins JAX's multi-process runtime (``jax.distributed.initialize``, before any JAX
    computation) and takes its share (``share``). ``check()`` then runs before any recording: its
    ``ConfigError`` (a bad option) stops the batch."""
    if args.plot is not None:
        raise ConfigError("--plot draws one recording: leave it out of a batch")
    multi = processes(args.processes)
    todo, skipped = plan(args.input, args.out, args.out_format, args.resume, args.force)
    if multi is not None:
        import jax

        address, count, index = multi
        jax.distributed.initialize(address, num_processes=count, process_id=index)
        todo = share(todo, jax.process_count(), jax.process_index())
        skipped = skipped[index::count]
    if check is not None:  # the batch's own options that need JAX (after its runtime started)
        check()
    n = len(todo) + len(skipped)
    rows: list[tuple[str, dict[str, Any]]] = []
    failed: list[tuple[Path, str]] = []
    start = time.perf_counter()

    def each_args(src: Path, dst: Path) -> argparse.Namespace:
        dst.parent.mkdir(parents=True, exist_ok=True)
        each = copy.copy(args)
        each.input, each.out, each.force = str(src), str(dst), True
        return each

    def report(i: int, src: Path, got: dict[str, Any] | Exception, dt: float) -> None:
        if isinstance(got, Exception):
            text = " ".join(str(got).split())
            message = text if isinstance(got, JaxprojError) else f"{type(got).__name__}: {text}"
            message = message.removeprefix(f"{src}: ")  # the file is named once
            failed.append((src, message))
            print(f"[{i}/{len(todo)}] {src}: failed: {message}", file=sys.stderr, flush=True)
            return
        got["wall_s"] = dt
        rows.append((str(src), got))
        rate = got["frames"] / max(dt, 1e-9)
        line = f"[{i}/{len(todo)}] {src}: {got['frames']:,} frames in {dt:.1f} s"
        line += f" ({rate:,.0f} frames/s)"
        print(line, file=sys.stderr, flush=True)

    def alone(each: argparse.Namespace) -> tuple[dict[str, Any] | Exception, float]:
        t0 = time.perf_counter()
        try:
            return one(each), time.perf_counter() - t0
        except Exception as err:  # a batch never dies halfway: each failure is reported
            return err, time.perf_counter() - t0

    step = pack_recordings() if many is not None else 1
    for r in range(0, len(todo), step):
        chunk = todo[r : r + step]
        argss = [each_args(src, dst) for src, dst in chunk]
        t0 = time.perf_counter()
        got: list[dict[str, Any] | Exception] | None = None
        if many is not None:
            print(f"[{r + 1}-{r + len(chunk)}/{len(todo)}] reading and retargeting "
                  f"{len(chunk)} recordings together", file=sys.stderr, flush=True)  # fmt: skip
            try:
                got = many(argss)
            except Exception:  # noqa: BLE001 (the round again, one recording at a time)
                got = None
        if got is None:
            for k, each in enumerate(argss):
                res, dt = alone(each)
                report(r + k + 1, chunk[k][0], res, dt)
            continue
        # a round's time, shared by its recordings in proportion to their frames
        wall_round = time.perf_counter() - t0
        frames = [g["frames"] if isinstance(g, dict) else 0 for g in got]
        total = max(sum(frames), 1)
        for k, res in enumerate(got):
            report(r + k + 1, chunk[k][0], res, wall_round * frames[k] / total)
    wall = time.perf_counter() - start
    print(summary(rows, failed, skipped, n, wall))
    for src, message in failed:
        print(f"jaxproj: error: {src}: {message}", file=sys.stderr)
    if multi is not None:
        import jax

        jax.distributed.shutdown()
    return 1 if failed else 0


def summary(
    rows: list[tuple[str, dict[str, Any]]],
    failed: list[tuple[Path, str]],
    skipped: list[Path],
    n: int,
    wall: float,
) -> str:
    """The batch's table: a line per recording written, then the totals."""
    lines = [f"{'recording':40s} {'frames':>8s} {'valid %':>8s} {'low-conf. %':>11s} {'s':>7s}"]
    for src, r in rows:
        low = "-" if r["low_confidence"] is None else f"{100 * r['low_confidence']:.1f}"
        name = src if len(src) <= 40 else "..." + src[-37:]
        valid = 100 * r["valid"] / max(r["frames"], 1)
        lines.append(f"{name:40s} {r['frames']:8,d} {valid:8.1f} {low:>11s} {r['wall_s']:7.1f}")
    frames = sum(r["frames"] for _, r in rows)
    lines.append(
        f"batch: {n} recordings: {len(rows)} written, {len(skipped)} left out (--resume: "
        f"output present), {len(failed)} failed; {frames:,} frames in {wall:.1f} s "
        f"({frames / max(wall, 1e-9):,.0f} frames/s, {len(rows) / max(wall, 1e-9):.2f} "
        "recordings/s)"
    )
    return "\n".join(lines)


_MODELS: dict[tuple[str, int, int], Any] = {}
"""``load_model``'s models by (path, mtime, size): a batch reads its model once."""


def load_model(path: str) -> Any:
    """``jaxproj.projection.api.load(path)``, read once per process while the file is unchanged
    (a batch retargets every recording with one model)."""
    from jaxproj.projection import api as engine

    st = Path(path).stat()
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size)
    if key not in _MODELS:
        _MODELS.clear()
        _MODELS[key] = engine.load(path)
    return _MODELS[key]
