"""What a NAO would be asked to play: joint speeds and limits of ``jaxproj retarget``'s exports.

Issue 43's row "worst exported joint speed / rated speed". Each bundled UTKinect-Action3D
recording (10 whole recordings, subjects 3, 4, 6, 7, 9; times from their frame numbers) is
written back as its own ``joints_sXX_eYY.txt`` and run through the command line exactly as a
user would, ``jaxproj retarget FILE --out F.json`` and ``--out F.csv`` (plus ``EXTRA`` options),
and the written files are read as text (the JSON's ``angleLists`` / ``timeLists``, the CSV's
columns). Per recording and over all of them:

* ``worst_rated_ratio``: the largest ``|q_t - q_{t-1}| / (t_t - t_{t-1})`` over the rated speed
  of its joint (``Robot.rated_speeds``: Aldebaran's where published, else 0.75 x no-load), and
  the joint; ``worst_no_load_ratio`` the same against the no-load ``velocity_limits``;
* ``min_limit_gap_rad``: the smallest distance of a written angle to its joint's range
  ``[lower, upper]`` (negative: outside), with the joint;
* ``vs_unfiltered_deg``: p95 and max over frames and the 10 driven joints of the exported
  motion's difference from the same command with ``--no-feasible`` (what the filter costs).

    python -m benchmarks.export_limits [--extra "--speeds no-load"] [--json OUT]

Rated speeds: the robot's ``rated_speeds`` where this jaxproj has them, else the same published
table (``FALLBACK_RATED``, to measure revisions from before they were added).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shlex
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from jaxproj.cli.main import main as cli
from jaxproj.io.bundled import utkinect_action3d
from jaxproj.robots import NAO_H25

_PUBLISHED = {"ShoulderPitch": 6.14, "ElbowYaw": 6.14, "HeadYaw": 6.14,
              "ShoulderRoll": 5.33, "ElbowRoll": 5.33, "HeadPitch": 5.33}  # fmt: skip


def _fallback_rated() -> np.ndarray:
    vmax = np.asarray(NAO_H25.velocity_limits, np.float64)
    out = 0.75 * vmax
    for i, name in enumerate(NAO_H25.joint_names):
        key = name[1:] if name[:1] in "LR" and name[1:] in _PUBLISHED else name
        if key in _PUBLISHED:
            out[i] = _PUBLISHED[key]
    return out


FALLBACK_RATED = _fallback_rated()
"""Rated speeds (rad/s) for a jaxproj without ``Robot.rated_speeds``: Aldebaran's published
6.14 / 5.33 rad/s, else 0.75 x no-load (the rule ``Robot.rated_speeds`` documents)."""


def rated_speeds() -> np.ndarray:
    value = getattr(NAO_H25, "rated_speeds", None)
    return FALLBACK_RATED if value is None else np.asarray(value, np.float64)


def write_utkinect(path: Path, frames: np.ndarray, positions: np.ndarray) -> None:
    """A ``joints_sXX_eYY.txt`` file: frame number, then x y z of the 20 joints, per line."""
    lines = []
    for f, p in zip(frames.tolist(), positions.astype(np.float64), strict=True):
        lines.append(" ".join([str(f), *(repr(float(np.float32(v))) for v in p.ravel())]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_json(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    doc = json.loads(path.read_text(encoding="utf-8"))
    angles = np.array(doc["angleLists"], np.float64).T  # (T, n)
    times = np.array(doc["timeLists"][0], np.float64)
    assert all(t == doc["timeLists"][0] for t in doc["timeLists"])
    return list(doc["names"]), angles, times


def read_csv(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    rows = path.read_text(encoding="utf-8").splitlines()
    header = rows[0].split(",")
    values = np.array([[float(c) for c in r.split(",")] for r in rows[1:]], np.float64)
    names = header[1:]
    if names[-1] == "confidence":
        names, values = names[:-1], values[:, :-1]
    return names, values[:, 1:], values[:, 0]


def measure(names: list[str], angles: np.ndarray, times: np.ndarray) -> dict:
    idx = [NAO_H25.index(n) for n in names]
    rated, vmax = rated_speeds()[idx], np.asarray(NAO_H25.velocity_limits, np.float64)[idx]
    lo = np.asarray(NAO_H25.lower, np.float64)[idx]
    hi = np.asarray(NAO_H25.upper, np.float64)[idx]
    speed = np.abs(np.diff(angles, axis=0)) / np.diff(times)[:, None]
    r_rated, r_free = speed / rated, speed / vmax
    gap = np.minimum(angles - lo, hi - angles)
    w, g = int(np.argmax(r_rated.max(0))), int(np.argmin(gap.min(0)))
    return {
        "frames": int(len(times)),
        "worst_rated_ratio": float(r_rated.max()),
        "worst_rated_joint": names[w],
        "steps_over_rated": int((r_rated > 1.0).any(axis=1).sum()),
        "worst_no_load_ratio": float(r_free.max()),
        "min_limit_gap_rad": float(gap.min()),
        "min_limit_gap_joint": names[g],
    }


def run(extra: list[str]) -> dict:
    seqs = utkinect_action3d(segments=False)
    out: dict = {"recordings": {}}
    driven = [NAO_H25.index(n) for n in NAO_H25.driven_joints]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for seq in seqs:
            src = folder / f"joints_{seq.name}.txt"
            assert seq.frame_numbers is not None
            write_utkinect(src, seq.frame_numbers, seq.positions)
            rec: dict = {}
            for ext, opts in ((".json", extra), (".csv", extra), (".raw.csv", ["--no-feasible"])):
                dst = folder / f"{seq.name}{ext}"
                with contextlib.redirect_stdout(io.StringIO()):
                    status = cli(["retarget", str(src), "--out", str(dst), *opts])
                if status != 0:
                    raise SystemExit(f"jaxproj retarget {src} failed ({status})")
                rec[ext] = dst
            measured = {
                "json": measure(*read_json(rec[".json"])),
                "csv": measure(*read_csv(rec[".csv"])),
            }
            _, q, _ = read_csv(rec[".csv"])
            _, raw, _ = read_csv(rec[".raw.csv"])
            diff = np.degrees(np.abs(q[:, driven] - raw[:, driven]))
            measured["vs_unfiltered_deg"] = {"p95": float(np.percentile(diff, 95)),
                                             "max": float(diff.max())}  # fmt: skip
            out["recordings"][seq.name] = measured
    recs = out["recordings"].values()
    for kind in ("json", "csv"):
        worst = max(recs, key=lambda r: r[kind]["worst_rated_ratio"])[kind]
        tight = min(recs, key=lambda r: r[kind]["min_limit_gap_rad"])[kind]
        out[kind] = {
            "frames": sum(r[kind]["frames"] for r in recs),
            "worst_rated_ratio": worst["worst_rated_ratio"],
            "worst_rated_joint": worst["worst_rated_joint"],
            "steps_over_rated": sum(r[kind]["steps_over_rated"] for r in recs),
            "worst_no_load_ratio": max(r[kind]["worst_no_load_ratio"] for r in recs),
            "min_limit_gap_rad": tight["min_limit_gap_rad"],
            "min_limit_gap_joint": tight["min_limit_gap_joint"],
        }
    out["vs_unfiltered_deg"] = {
        "p95_median": float(np.median([r["vs_unfiltered_deg"]["p95"] for r in recs])),
        "max": max(r["vs_unfiltered_deg"]["max"] for r in recs),
    }
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--extra", default="", help="more `jaxproj retarget` options, one string")
    p.add_argument("--json", help="write the results here")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    extra = shlex.split(args.extra)
    out = {"command": "jaxproj retarget joints_sXX_eYY.txt --out F.json|F.csv " + args.extra,
           "rated_speeds": dict(zip(NAO_H25.joint_names, rated_speeds().tolist(), strict=True)),
           **run(extra)}  # fmt: skip
    out["seconds"] = round(time.perf_counter() - t0, 1)
    for kind in ("json", "csv"):
        r = out[kind]
        print(
            f"{kind}: {r['frames']} frames, worst speed / rated {r['worst_rated_ratio']:.4f} "
            f"({r['worst_rated_joint']}), steps over rated {r['steps_over_rated']}, worst / "
            f"no-load {r['worst_no_load_ratio']:.4f}, closest to a limit "
            f"{r['min_limit_gap_rad']:.3g} rad ({r['min_limit_gap_joint']})"
        )
    v = out["vs_unfiltered_deg"]
    print(f"exported vs --no-feasible (driven joints): median p95 {v['p95_median']:.2f} deg, "
          f"max {v['max']:.1f} deg; {out['seconds']} s")  # fmt: skip
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
