"""Shared helpers of the speed benchmarks in ``benchmarks/``: what a run measures (``Plan``),
records, the machine header, memory checks, the issue's speed targets, the table and the options.

Not part of the ``jaxproj`` package (a wheel does not ship ``benchmarks/``): the scripts next to
import it as ``benchmarks.harness``: run them from the repository root as modules,
``python -m benchmarks.bench_projection``.
Timing itself uses ``jaxproj.timing`` (``compile_timed``, ``time_calls``).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import importlib
import json
import os
import platform
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection.config import FullConfig
from jaxproj.timing import Timing, time_calls

SYNTHETIC_N = 8192
"""Landmark count built by subsampling training frames (no mean-shift counterpart)."""

DEFAULT_N = 0
"""``N`` of the default model: ``BuildConfig()``, what ``jaxproj build`` makes with no options
(per chain 799 / 3,668 / 7,099 landmarks on the training subjects); ``--landmarks default``."""

RELAXED_TOL_DEG = 0.1
"""Engine vs reference: the relaxed answers must agree to this (degrees)."""
FULL_TOL_DEG = 1.0
"""Engine vs reference, full objective: stated tolerance (degrees). Float32 steps against
float64 can stop apart where the objective is flat: an answer further than this from the
reference's still agrees when its objective value ties with the reference's optimum
(``agreement``)."""


def agreement(
    objective: str, diff_deg: np.ndarray, f: np.ndarray | None, f_ref: np.ndarray | None,
    tie_rtol: float,
) -> dict:  # fmt: skip
    """Whether answers agree with the reference's, given their ``(Q,)`` largest differences
    from its poses (deg). Relaxed: within ``RELAXED_TOL_DEG`` (the near-tie rule is judged apart,
    ``near_ties``). Full: within ``FULL_TOL_DEG``, or an objective *tie*: the engine's value
    ``f (Q,)`` at most ``tie_rtol`` (``FullConfig.tie_rtol``, the engine's own rule for tied
    problems) above the reference's optimum ``f_ref (Q,)``, where the objective is so flat
    that the angles can sit a degree apart (a default-config query of the 86-landmark smoke
    model: 1.11 deg apart at values 1.03782 / 1.03735, 0.05 %). Returns ``n_disagree``,
    ``n_value_ties`` (full), ``tolerance_deg`` and ``agrees``."""
    tol = RELAXED_TOL_DEG if objective == "relaxed" else FULL_TOL_DEG
    close = diff_deg <= tol
    tie = np.zeros_like(close)
    if objective == "full" and f is not None and f_ref is not None:
        tie = ~close & (f <= f_ref + tie_rtol * np.abs(f_ref))
    out = dict(n_disagree=int(np.sum(~close & ~tie)), tolerance_deg=tol)
    if objective == "full":
        out["n_value_ties"] = int(np.sum(tie))
    return out | dict(agrees=out["n_disagree"] == 0)


EXACT_TOL_DEG = 1e-2
"""Engine vs reference, relaxed, under the near-tie rule (``projection.relaxed.TIE_RTOL``): an
answer is *exact* within this of the reference's pick on every joint, a *tie* within it of
a candidate that ties with the pick, and otherwise it *differs* (``near_ties``). How close the
exact ones are is reported apart (``max_abs_diff_exact_deg``): float32 forward kernels round a
candidate by up to ~0.002 deg (2-core CPU, default model)."""


def near_ties(
    ref: Any, h: np.ndarray, r: np.ndarray, n_l: int, n_m: int, diff_deg: np.ndarray
) -> dict:
    """Judge the relaxed answers ``r (Q, n)`` of queries ``h (Q, m)`` with the reference's
    ``judge`` (``jaxproj.testing``), given their ``(Q,)`` largest differences from the
    reference's picks (deg): ``n_exact``, ``n_ties``, ``n_differs`` (must be 0),
    ``max_abs_diff_exact_deg`` (over the exact ones) and ``exact_tolerance_deg``."""
    tol = float(np.radians(EXACT_TOL_DEG))
    v = np.asarray([ref.judge(q, a, n_l, n_m, tol) for q, a in zip(h, r, strict=True)])
    exact = v == "exact"
    return dict(
        n_exact=int(np.sum(exact)),
        n_ties=int(np.sum(v == "tie")),
        n_differs=int(np.sum(v == "differs")),
        max_abs_diff_exact_deg=float(np.max(diff_deg[exact], initial=0.0)),
        exact_tolerance_deg=EXACT_TOL_DEG,
    )


@dataclass(frozen=True)
class Plan:
    """What one benchmark run measures."""

    landmarks: tuple[int, ...]
    batches: tuple[int, ...]
    configs: tuple[tuple[str, int, int], ...]  # (objective, L, M)
    min_repeats: int
    max_repeats: int
    min_time_s: float
    ref_queries: dict[str, int]
    n_check: int
    stream_frames: int
    max_call_s: float
    memory_fraction: float = 0.5
    subsample_all: bool = False
    """Build every N by subsampling training frames (fast; for tests), not by mean shift."""
    public_queries: dict[str, int] = dataclasses.field(default_factory=dict)
    """Queries of the ``public`` records per objective (``jaxproj.project`` on a host array with
    its default arguments); none for an objective left out."""
    rollout_frames: int = 30
    """Frames per motion of the MJX rollout records (15 frames/s)."""


def smoke_plan(plan: Plan) -> Plan:
    """``--smoke``: ``plan`` cut to a check that every record is produced (the tests run this):
    landmark sets subsampled (no mean shift), no minimum timing, at most 2 timed calls, small
    public-API calls, 40 streaming frames, 2-frame rollouts. Its speeds mean nothing."""
    return dataclasses.replace(
        plan,
        subsample_all=True,
        min_time_s=0.0,
        max_repeats=2,
        public_queries={"relaxed": 256, "full": 64},
        stream_frames=40,
        rollout_frames=2,
    )


def make_plan(
    quick: bool,
    device: str,
    *,
    landmarks: Sequence[int] | None = None,
    batches: Sequence[int] | None = None,
    configs: Sequence[tuple[str, int, int]] | None = None,
    repeats: int | None = None,
    ref_queries: int | None = None,
    n_check: int = 64,
    stream_frames: int | None = None,
) -> Plan:
    """The default plan for ``quick`` / full mode on ``device``, with optional overrides."""
    if quick:
        plan = Plan(
            landmarks=(86, 1644),
            batches=(1, 256, 4096),
            configs=(("relaxed", 10, 10), ("full", 10, 10), ("relaxed", 50, 50)),
            min_repeats=3,
            max_repeats=100,
            min_time_s=0.3,
            ref_queries={"relaxed": 200, "full": 64},
            n_check=n_check,
            stream_frames=600,
            max_call_s=60.0,
            public_queries={"relaxed": 16384, "full": 4096},
        )
    else:
        plan = Plan(
            landmarks=(86, 961, 1644, SYNTHETIC_N),
            batches=(1, 256, 4096),
            configs=(
                ("relaxed", 10, 10),
                ("relaxed", 50, 50),
                ("full", 10, 10),
                ("full", 50, 50),
            ),
            min_repeats=5,
            max_repeats=300,
            min_time_s=1.0,
            ref_queries={"relaxed": 500, "full": 64},
            n_check=n_check,
            stream_frames=2000,
            max_call_s=300.0,
            public_queries={"relaxed": 65536, "full": 4096},
        )
    if device == "gpu":
        # a GPU's memory is the process's own: let a run take most of what is free; the public
        # API on 1 M host poses (the speed issue's figure), the full objective on 256 K
        plan = dataclasses.replace(
            plan, batches=(*plan.batches, 65536), memory_fraction=0.85,
            public_queries={"relaxed": 1 << 20, "full": 1 << 18},
        )  # fmt: skip
    over: dict[str, Any] = {}
    if landmarks is not None:
        over["landmarks"] = tuple(landmarks)
    if batches is not None:
        over["batches"] = tuple(batches)
    if configs is not None:
        over["configs"] = tuple(configs)
    if repeats is not None:
        over["min_repeats"] = repeats
        over["max_repeats"] = max(repeats, 3 * repeats)
    if ref_queries is not None:
        over["ref_queries"] = {"relaxed": ref_queries, "full": ref_queries}
    if stream_frames is not None:
        over["stream_frames"] = stream_frames
    return dataclasses.replace(plan, **over)


# ---------------------------------------------------------------------------------- records


def record(kind: str, **kw: Any) -> dict:
    """A record of ``kind`` with every common key (``None`` unless given in ``kw``)."""
    base = dict(
        kind=kind,
        objective=None,
        L=None,
        M=None,
        N=None,
        batch=None,
        device=None,
        us_per_projection=None,
        throughput=None,
        compile_s=None,
    )
    base.update(kw)
    return base


def available_bytes(device: jax.Device) -> int | None:
    """Free memory of ``device`` in bytes (host RAM for the CPU); ``None`` when unknown."""
    if device.platform == "cpu":
        try:
            with open("/proc/meminfo") as fh:
                for line in fh:
                    if line.startswith("MemAvailable:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            pass
        try:
            return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return None
    try:
        stats = device.memory_stats() or {}
    except Exception:  # noqa: BLE001 - backends differ in what they expose
        return None
    limit = stats.get("bytes_limit")
    return None if limit is None else int(limit) - int(stats.get("bytes_in_use", 0))


def total_memory() -> int:
    """Physical host memory in bytes (0 when unknown)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0


def needed_bytes(compiled: Any) -> int | None:
    """XLA's estimate of the memory a compiled executable needs (bytes); ``None`` if unknown."""
    try:
        ma = compiled.memory_analysis()
        return int(ma.temp_size_in_bytes + ma.argument_size_in_bytes + ma.output_size_in_bytes)
    except Exception:  # noqa: BLE001 - not every backend reports it
        return None


# ----------------------------------------------------------------------------------- timing


def time_plan(fn: Callable[[], Any], plan: Plan) -> Timing:
    """``jaxproj.timing.time_calls`` with the plan's repeats: the median seconds per blocked
    ``fn()`` over at least ``min_repeats`` calls, more (up to ``max_repeats``) while the total
    stays under ``min_time_s``."""
    return time_calls(
        fn,
        min_repeats=plan.min_repeats,
        max_repeats=plan.max_repeats,
        min_time_s=plan.min_time_s,
    )


def frame_latencies(step: Callable[[int], Any], n_frames: int, warmup: int) -> np.ndarray:
    """``(n_frames,)`` seconds of each call ``step(i)`` after ``warmup`` untimed calls.

    ``step`` must return host data (or block itself): a streamed frame's latency is the time
    until its answer is on the host.
    """
    for i in range(warmup):
        step(i)
    lat = np.empty(n_frames)
    for i in range(n_frames):
        t0 = time.perf_counter()
        step(warmup + i)
        lat[i] = time.perf_counter() - t0
    return lat


# -------------------------------------------------------------------------------- targets


def _find(records: list[dict], **kw: Any) -> list[dict]:
    return [
        r for r in records if all(r.get(k) == v for k, v in kw.items()) and r.get("skipped") is None
    ]


def target_checks(records: list[dict], device: str) -> list[dict]:
    """The issue's speed targets that apply to ``device``, checked against ``records``."""
    out = []

    def check(name: str, recs: list[dict], key: str, op: str, threshold: float) -> None:
        vals = [r[key] for r in recs if r.get(key) is not None]
        if not vals:
            out.append(_target(name, None, op, threshold, None))
            return
        value = min(vals) if op == "<=" else max(vals)
        met = value <= threshold if op == "<=" else value >= threshold
        out.append(_target(name, value, op, threshold, met))

    proj = dict(kind="projection", N=1644)
    pub = dict(kind="public", N=1644)

    def full_name(name: str, recs: list[dict]) -> str:
        """Say so when the full records are of the pruned (approximate) full objective."""
        pruned = sorted(
            {(r["full_config"]["clusters"], r["full_config"]["iterations"])
             for r in recs if 0 < r["full_config"]["clusters"] < r["L"]}
        )  # fmt: skip
        if not pruned:
            return name
        c, it = pruned[0]
        return f"{name} [pruned full objective, clusters={c}, {it} steps: an approximation]"

    def check_converged(f10: list[dict]) -> None:
        """An *exact* full answer is within 0.1 deg of a long (1,000-step) solve on >= 99.9 %
        of held-out poses: measured on the configuration the full records ran."""
        conv = _find(records, kind="full_convergence", L=10, M=10, N=1644)
        check(full_name("full L=M=10, N~1644: fraction of answers within 0.1 deg of a "
                        "1,000-step solve", f10 or conv),
              conv, "fraction_within", ">=", 0.999)  # fmt: skip

    if device == "cpu":
        r10 = _find(records, objective="relaxed", L=10, M=10, batch=4096, **proj)
        f10 = _find(records, objective="full", L=10, M=10, batch=4096, **proj)
        check("relaxed L=M=10, N~1644, batch 4096: us/projection",
              r10, "us_per_projection", "<=", 10.0)  # fmt: skip
        check("relaxed L=M=10, N~1644, batch 4096: speedup vs reference",
              r10, "speedup", ">=", 20.0)  # fmt: skip
        check("public jaxproj.project relaxed L=M=10, N~1644: us/projection",
              _find(records, objective="relaxed", L=10, M=10, **pub), "us_per_projection",
              "<=", 10.0)  # fmt: skip
        check(full_name("full L=M=10, N~1644, batch 4096: us/projection", f10),
              f10, "us_per_projection", "<=", 100.0)  # fmt: skip
        check_converged(f10)
        stream = _find(records, kind="streaming")
        check("streaming latency median (us)", stream, "median_us", "<=", 50.0)
        check("streaming latency p99 (us)", stream, "p99_us", "<=", 150.0)
    else:
        r10 = _find(records, objective="relaxed", L=10, M=10, **pub)
        r50 = _find(records, objective="relaxed", L=50, M=50, **pub)
        f10 = _find(records, objective="full", L=10, M=10, **pub)
        check("public jaxproj.project relaxed L=M=10, N~1644, 1 M host poses: projections/s",
              r10, "throughput", ">=", 20e6)  # fmt: skip
        check("public jaxproj.project relaxed L=M=50, N~1644: projections/s",
              r50, "throughput", ">=", 2e6)  # fmt: skip
        check(full_name("public jaxproj.project full L=M=10, N~1644: projections/s", f10),
              f10, "throughput", ">=", 2e6)  # fmt: skip
        check_converged(f10)
        check("MJX rollout: NAO steps/s (batched)",
              _find(records, kind="rollout"), "steps_per_s", ">=", 2e6)  # fmt: skip
    return out


def _target(name: str, value: float | None, op: str, threshold: float, met: bool | None) -> dict:
    if value is None or met is None:
        factor = None
    elif op == "<=":
        factor = value / threshold
    else:
        factor = threshold / value if value > 0 else float("inf")
    return dict(
        kind="target", target=name, value=value, op=op, threshold=threshold, met=met,
        off_by_factor=None if met or factor is None else factor,
    )  # fmt: skip


# ----------------------------------------------------------------------------------- run


def header(device: jax.Device) -> dict:
    """Machine, versions and date."""
    import jaxlib

    versions = {
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "numpy": np.__version__,
    }
    for mod in ("scipy", "optax", "mujoco"):
        try:
            versions[mod] = importlib.import_module(mod).__version__
        except ImportError:
            versions[mod] = None
    from jaxproj import __version__

    versions["jaxproj"] = __version__
    cpu_model = platform.processor() or None
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu_model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    return dict(
        kind="header",
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        platform=platform.platform(),
        machine=platform.machine(),
        cpu_model=cpu_model,
        cpu_count=os.cpu_count(),
        cpu_usable=usable,
        memory_gib=round(total_memory() / 2**30, 1),
        memory_available_gib=round((available_bytes(jax.devices("cpu")[0]) or 0) / 2**30, 1),
        device=device.platform,
        device_kind=getattr(device, "device_kind", str(device)),
        device_count=len(jax.devices(device.platform)),
        versions=versions,
        argv=sys.argv,
    )


def get_device(device: str) -> jax.Device:
    """The first JAX device of ``"cpu"`` / ``"gpu"``; ``ConfigError`` when there is none."""
    if device not in ("cpu", "gpu"):
        raise ConfigError(f"--device must be cpu or gpu, got {device!r}")
    try:
        devs = jax.devices(device)
    except RuntimeError as e:
        raise ConfigError(
            f"--device {device}: no {device.upper()} visible to JAX ({e}); "
            "install jax[cuda12] and check nvidia-smi, or use --device cpu"
        ) from None
    if not devs:
        raise ConfigError(f"--device {device}: no {device.upper()} visible to JAX")
    return devs[0]


def write_json(records: list[dict] | dict, path: str | Path) -> None:
    """Write the records as a JSON list (one record per element), or one result as a JSON
    object, creating folders."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(records, indent=1) + "\n")


def report(result: dict, path: str | None) -> None:
    """An experiment's result: printed as JSON, and written to ``path`` (``--json``) if given."""
    if path:
        write_json(result, path)
    print(json.dumps(result, indent=1))


# ---------------------------------------------------------------------------------- output


def _fmt(v: Any, spec: str) -> str:
    return "-" if v is None else format(v, spec)


def table_row(r: dict) -> str:
    """One projection record as a line of the table."""
    if r.get("skipped"):
        tail = f"skipped: {r['skipped']}"
    else:
        tail = (
            f"{_fmt(r.get('us_per_projection'), '10.2f')} {_fmt(r.get('throughput'), '12.4g')} "
            f"{_fmt(r.get('compile_s'), '8.2f')} "
            f"{_fmt(r.get('reference_us_per_projection'), '9.1f')} "
            f"{_fmt(r.get('speedup'), '8.2f')} {_fmt(r.get('max_abs_diff_deg'), '9.2g')}"
        )
    return f"{r['objective']:8s} {r['L']:>3} {r['M']:>3} {r['N']:>5} {r['batch']:>6}  " + tail


def format_table(records: list[dict]) -> str:
    """A readable table of the records and the target checks."""
    lines = []
    head = records[0] if records and records[0].get("kind") == "header" else None
    if head:
        v = head["versions"]
        lines.append(
            f"# {head['date']}  {head['device_kind']}  ({head['cpu_model']}, "
            f"{head['cpu_usable']} cores)  jax {v['jax']}  numpy {v['numpy']}"
        )
    builds = [r for r in records if r["kind"] == "build"]
    if builds:
        lines.append("\nkernel-bank build (second build; compile excluded)")
        lines.append(f"{'N':>5} {'K':>5} {'build_s':>8} {'banks_s':>8} {'compile_s':>9}  source")
        for r in builds:
            lines.append(
                f"{r['N']:>5} {r['n_landmarks']:>5} {r['build_s']:8.2f} {r['banks_s']:8.3f} "
                f"{r['compile_s']:9.2f}  {r['landmarks_source']}"
            )
    proj = [r for r in records if r["kind"] == "projection"]
    if proj:
        lines.append("\nprojection (median over repeats; reference = NumPy + cKDTree per query)")
        lines.append(
            f"{'obj':8s} {'L':>3} {'M':>3} {'N':>5} {'batch':>6}  {'us/proj':>10} "
            f"{'proj/s':>12} {'compile':>8} {'ref_us':>9} {'speedup':>8} {'maxdiff°':>9}"
        )
        lines += [table_row(r) for r in proj]
    public = [r for r in records if r["kind"] == "public"]
    if public:
        lines.append(
            "\npublic jaxproj.project (host array in and out, default batch_size; 'batch' = "
            "queries per call)"
        )
        lines += [table_row(r) for r in public]
    for r in records:
        if r["kind"] == "streaming":
            lines.append(
                f"\nstreaming (pose -> descriptor -> relaxed L={r['L']} M={r['M']} N={r['N']} -> "
                f"smoothing step, host round trip): median {r['median_us']:.1f} us, "
                f"p99 {r['p99_us']:.1f} us over {r['frames']} frames"
            )
        if r["kind"] == "full_convergence":
            lines.append(
                f"\nfull objective L={r['L']} M={r['M']} N={r['N']}, "
                f"{r['full_config']['iterations']} steps vs a {r['reference_iterations']}-step "
                f"solve: {r['fraction_within']:.4f} of {r['queries']} answers within "
                f"{r['tolerance_deg']} deg (p99 {r['p99_abs_diff_deg']:.2f}, max "
                f"{r['max_abs_diff_deg']:.2f} deg; f / f_long median "
                f"{r['objective_ratio_median']:.3f})"
            )
        if r["kind"] == "rollout":
            if r.get("skipped"):
                lines.append(f"\nrollout: skipped ({r['skipped']})")
            else:
                lines.append(
                    f"\n{r.get('backend')} rollout (batch {r.get('batch')}): "
                    f"{_fmt(r.get('steps_per_s'), '.4g')} NAO steps/s, compile "
                    f"{_fmt(r.get('compile_s'), '.1f')} s, motion 0 vs CPU MuJoCo max |dq| "
                    f"{_fmt(r.get('vs_cpu_max_dq_rad'), '.1e')} rad"
                )
    targets = [r for r in records if r["kind"] == "target"]
    if targets:
        lines.append("\ntargets")
        for t in targets:
            status = {True: "met", False: "NOT MET", None: "not measured"}[t["met"]]
            extra = f" (off by {t['off_by_factor']:.1f}x)" if t.get("off_by_factor") else ""
            lines.append(
                f"  {t['target']}: {_fmt(t['value'], '.4g')} {t['op']} {t['threshold']:g} "
                f"-> {status}{extra}"
            )
    return "\n".join(lines)


def _configs(text: str) -> list[tuple[str, int, int]]:
    out = []
    for item in text.split(","):
        parts = item.strip().split(":")
        try:
            objective, n_l, n_m = parts[0], int(parts[1]), int(parts[2])
        except (IndexError, ValueError):
            raise argparse.ArgumentTypeError(
                f"expected objective:L:M items like relaxed:10:10, got {item!r}"
            ) from None
        if len(parts) != 3 or objective not in ("relaxed", "full") or min(n_l, n_m) < 1:
            raise argparse.ArgumentTypeError(
                f"expected objective:L:M with objective relaxed or full and L, M >= 1, got {item!r}"
            )
        out.append((objective, n_l, n_m))
    return out


def _ints(text: str) -> list[int]:
    try:
        return [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected integers like 86,1644, got {text!r}") from None


def _landmark_counts(text: str) -> list[int]:
    """``--landmarks``: counts, ``default`` (``DEFAULT_N``: the model ``jaxproj build`` makes)."""
    return _ints(",".join(str(DEFAULT_N) if t.strip() == "default" else t for t in text.split(",")))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``python -m benchmarks.bench_projection``."""
    parser.add_argument("--quick", action="store_true", help="a subset that runs in minutes")
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="a seconds-long check that every record is produced, speeds meaningless (the tests)",
    )
    parser.add_argument("--device", default="cpu", choices=("cpu", "gpu"))
    parser.add_argument(
        "--chains",
        default="upper",
        choices=("upper", "whole"),
        help="the model: per-chain (the default engine) or the paper's whole-body projector",
    )
    parser.add_argument("--json", default=None, metavar="OUT", help="write the records here")
    parser.add_argument(
        "--landmarks",
        type=_landmark_counts,
        default=None,
        help="override N, e.g. default,1644 (default: BuildConfig(), the model `jaxproj build` "
        "makes; a number: BuildConfig(landmarks=N))",
    )
    parser.add_argument("--batches", type=_ints, default=None, help="override batch sizes")
    parser.add_argument(
        "--configs",
        type=_configs,
        default=None,
        help="override the projections measured, e.g. relaxed:10:10,full:10:10 (objective:L:M)",
    )
    parser.add_argument("--repeats", type=int, default=None, help="minimum timed calls")
    parser.add_argument("--ref-queries", type=int, default=None, help="reference queries")
    parser.add_argument("--no-streaming", action="store_true", help="skip streaming latency")
    parser.add_argument("--no-rollout", action="store_true", help="skip the MJX rollout")
    parser.add_argument(
        "--devices",
        default="1",
        help="JAX devices for the public-API records and the rollout: a count or 'all'",
    )
    parser.add_argument(
        "--full-clusters",
        type=int,
        default=0,
        help="full objective: optimise only this many best-starting clusters (0: all, exact)",
    )
    parser.add_argument(
        "--full-iterations", type=int, default=None, help="full objective: projected-gradient steps"
    )


def full_config(clusters: int, iterations: int | None) -> FullConfig:
    """The full objective's settings from ``--full-clusters`` / ``--full-iterations``
    (``ConfigError`` on a bad value)."""
    cfg = FullConfig(clusters=clusters)
    if iterations is not None:
        cfg = dataclasses.replace(cfg, iterations=iterations)
    return cfg
