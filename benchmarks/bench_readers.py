"""Speed of the skeleton file readers (``jaxproj.io.readers.read_skeleton``) on dataset-sized files.

The files are written from the bundled MSR Action3D data, so they have the sizes of the real
ones: the median-length motion (39 frames) and the longest (936 frames), each as an MSR Action3D
text file (``x y z confidence``, 20 rows per frame, 6 decimals, as in the dataset) and as a
UTKinect-format file (frame number + 60 values per line). Before timing, every reader answer is
checked against ``np.loadtxt`` of the same file (exit status 1 on a mismatch). The same-run
baseline is ``np.loadtxt`` of the same file, which only parses the numbers (no joint reordering,
no validity mask, no error reporting). Each figure is the median of ``--repeat`` calls after one
warm-up call (``jaxproj.timing.time_calls``).

    python -m benchmarks.bench_readers [--repeat 20] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np

from jaxproj import timing
from jaxproj.io import datasets, readers

MOTIONS = {"median": "a06_s01_e01", "longest": "a13_s09_e03"}
"""The bundled motions the files are made of: the median length (39 frames) and the longest."""


def msr_file_text(positions: np.ndarray, confidence: np.ndarray) -> str:
    """MSR Action3D text of ``(T, 20, 3)`` SDK-order positions and ``(T, 20)`` confidences."""
    rows = np.empty((len(positions), 20, 4))
    rows[:, readers.MSR_TO_SDK, :3] = positions  # inverse of sdk = msr[..., MSR_TO_SDK, :]
    rows[:, readers.MSR_TO_SDK, 3] = confidence
    return "".join(" ".join(f"{v:.6f}" for v in r) + "\n" for r in rows.reshape(-1, 4))


def utk_file_text(positions: np.ndarray) -> str:
    """UTKinect text of ``(T, 20, 3)`` SDK-order positions (frame numbers 1..T)."""
    return "".join(
        f"{t + 1} " + " ".join(f"{v:.6f}" for v in frame.ravel()) + "\n"
        for t, frame in enumerate(positions.astype(np.float64))
    )


def _loadtxt_positions(path: Path, fmt: str) -> np.ndarray:
    """The file's positions through ``np.loadtxt``: ``(T, 20, 3)`` float32, SDK order."""
    raw = np.loadtxt(path)
    if fmt == "msr":
        return raw.reshape(-1, 20, 4)[:, list(readers.MSR_TO_SDK), :3].astype(np.float32)
    return raw[:, 1:].reshape(-1, 20, 3).astype(np.float32)


def check(path: Path, fmt: str, valid: np.ndarray) -> str | None:
    """``None`` when ``read_skeleton`` agrees with ``np.loadtxt`` on ``path``, else the problem."""
    rec = readers.read_skeleton(path)
    if rec.format != fmt:
        return f"{path.name}: detected as {rec.format!r}, not {fmt!r}"
    if not np.array_equal(rec.valid, valid):
        return f"{path.name}: valid mask differs from the dataset's"
    want = _loadtxt_positions(path, fmt)
    if not np.array_equal(rec.positions[valid], want[valid]):
        return f"{path.name}: positions differ from np.loadtxt's"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="timed calls per figure (median kept)")
    ap.add_argument("--json", default=None, help="write the results here")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be positive")

    seqs = {s.name: s for s in datasets.msr_action3d()}
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        files = []
        for label, name in MOTIONS.items():
            s = seqs[name]
            msr = Path(tmp) / f"{name}_skeleton3D.txt"
            msr.write_text(msr_file_text(s.positions, s.confidence))
            utk = Path(tmp) / f"joints_{name}.txt"
            utk.write_text(utk_file_text(s.positions))
            files += [(label, "msr", msr, s.valid), (label, "utkinect", utk, s.valid)]
        for _, fmt, path, valid in files:
            problem = check(path, fmt, valid)
            if problem is not None:
                print(f"bench_readers: wrong answer: {problem}", file=sys.stderr)
                return 1
        for label, fmt, path, valid in files:
            ours = timing.time_calls(
                lambda path=path: readers.read_skeleton(path), min_repeats=args.repeat
            )
            base = timing.time_calls(lambda path=path: np.loadtxt(path), min_repeats=args.repeat)
            records.append(
                {
                    "motion": label,
                    "format": fmt,
                    "frames": int(len(valid)),
                    "kib": path.stat().st_size / 1024,
                    "read_skeleton_ms": 1e3 * ours.median_s,
                    "loadtxt_ms": 1e3 * base.median_s,
                    "speedup_vs_loadtxt": base.median_s / ours.median_s,
                    "repeats": ours.repeats,
                }
            )

    where = f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}"
    print(f"read_skeleton vs np.loadtxt, median of {args.repeat} calls ({where})")
    print(
        f"{'file':<18}{'frames':>7}{'KiB':>8}{'read_skeleton':>15}{'np.loadtxt':>12}{'speedup':>9}"
    )
    for r in records:
        print(
            f"{r['motion'] + ' ' + r['format']:<18}{r['frames']:>7}{r['kib']:>8.0f}"
            f"{r['read_skeleton_ms']:>12.2f} ms{r['loadtxt_ms']:>9.2f} ms"
            f"{r['speedup_vs_loadtxt']:>8.1f}x"
        )
    if args.json:
        meta = {"where": where, "numpy": np.__version__, "repeat": args.repeat}
        Path(args.json).write_text(json.dumps({"meta": meta, "records": records}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
