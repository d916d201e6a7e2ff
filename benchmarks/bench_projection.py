"""Speed benchmark of the projection engine.

    python -m benchmarks.bench_projection [--quick] [--device cpu|gpu] [--json OUT]
        [--landmarks 86,1644] [--batches 1,256,4096] [--configs relaxed:10:10,full:10:10]
        [--repeats N] [--ref-queries N]
        [--no-streaming] [--no-rollout] [--full-clusters C] [--full-iterations I]

(also ``python -m benchmarks.bench_projection ...`` from the repository root). Needs a checkout
(``benchmarks/`` is not installed with the package) and the test extra (scipy, for the
reference). Results and how they were run: ``benchmarks/RESULTS.md``.

What is measured (every timing waits for the device with ``block_until_ready``; compilation is
timed apart; timing primitives from ``jaxproj.timing``):

* **projection** records, one per ``(objective, L, M, N, batch)``: the engine's jitted
  ``engine.project_chunk`` on a fixed batch of held-out queries. ``compile_s`` is the
  ``lower(...).compile()`` time of exactly that executable (``timing.compile_timed``); the
  executable is then called once (warm-up, its answer is checked, see below) and again
  ``repeats`` times (``timing.time_calls``); ``us_per_projection`` is the median call time
  divided by the batch, ``throughput`` its inverse (projections/s).
* the **reference** (``reference_us_per_projection``, ``speedup``): ``jaxproj.testing.Reference``,
  a faithful per-query NumPy + ``scipy.spatial.cKDTree`` implementation of the paper's algorithm
  on the SAME trained landmarks and kernels, in float64 -- the baseline a Python user would
  write. It is timed per query over ``ref_queries`` queries in the same run, and it is the
  "exact mode" every projection record is checked against before timing: ``max_abs_diff_deg`` is
  the largest ``|engine - reference|`` over the driven joints of the first ``n_checked`` queries
  (at least ``n_check`` = 64: a smaller batch is run again on the next queries; up to
  ``ref_queries``), in degrees, with ``n_disagree`` queries beyond the tolerance (0.1 deg
  relaxed, 1 deg full).
* **build** records, one per landmark count: descriptors -> landmarks (mean shift with the
  bandwidth search) -> both ELM kernel banks, timed on a second build so that compilation is
  excluded (``compile_s`` = first build minus second); ``banks_s`` times the two kernel banks
  alone (``engine.build_from_landmarks``).
* the **streaming** record: latency of one frame through the public
  ``jaxproj.motion.streaming.update``
  (a ``(20, 3)`` host array of joint positions -> descriptor -> relaxed projection -> one
  smoothing step -> clip -> a host array of 10 angles; one jitted call, host <-> device transfers
  included), after 50 warm-up frames; median and p99. ``compile_s`` is the first call's time
  minus the median (trace + compile).
* **rollout** records: MJX rollout (``jaxproj.eval.rollout.simulate``) NAO physics steps per second
  per batch size, through ``bench`` of ``benchmarks.bench_rollout``, with motion 0
  checked against CPU MuJoCo; marked ``skipped`` when MuJoCo MJX is not available.

Landmark sets: ``N = 0`` (``--landmarks default``) is the default model, ``BuildConfig()``, what
``jaxproj build`` makes with no options (799 / 3,668 / 7,099 landmarks per chain), the model
every user starts with. Relaxed records judge every checked answer under the
near-tie rule (``n_exact``, ``n_ties``, ``n_differs``: ``harness.near_ties``).
N = 86, 961, 1644 are real models, ``engine.build(train, BuildConfig(landmarks=N))``
on the valid upper-body descriptors of MSR Action3D subjects 1, 3, 5, 7, 9 (the count reached by
the bandwidth search is ``n_landmarks``, e.g. 1635 for 1644). There are only ~11k training frames,
so N = 8192 has no mean-shift counterpart: it is a deterministic subsample (seed 0) of 8192
distinct training descriptors with their IK poses, trained with ``engine.build_from_landmarks``.
Queries: the valid descriptors of subjects 2, 4, 6, 8, 10 (all actions) in a fixed random order,
tiled to the batch size.

The JSON written by ``--json`` is a list of records; each has ``kind`` (``header``, ``build``,
``projection``, ``streaming``, ``rollout``, ``target``). Projection records carry ``objective, L,
M, N, batch, device, us_per_projection, throughput, compile_s, reference_us_per_projection,
max_abs_diff_deg, speedup`` (plus ``n_landmarks, repeats, n_checked``...). The header holds the
machine, the versions and the date. A configuration that would not fit in memory (XLA's own
estimate of the compiled executable, checked before running it) or would take too long is kept as
a record with ``skipped`` saying why. Shared machinery (plan, records, targets, table, options):
``harness.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import jax
import numpy as np

from benchmarks import harness
from benchmarks.harness import (
    DEFAULT_N,
    SYNTHETIC_N,
    Plan,
    agreement,
    available_bytes,
    frame_latencies,
    get_device,
    header,
    make_plan,
    near_ties,
    needed_bytes,
    record,
    table_row,
    target_checks,
    time_plan,
)
from jaxproj.errors import ConfigError, JaxprojError
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.motion import streaming as jaxproj_streaming
from jaxproj.motion.smoothing import PAPER_SMOOTHING, SmoothingParams
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, StackedProjector
from jaxproj.robots.nao_h25 import ik
from jaxproj.testing import Reference, StackedReference
from jaxproj.timing import compile_timed

TRAIN_SUBJECTS = (1, 3, 5, 7, 9)
TEST_SUBJECTS = (2, 4, 6, 8, 10)


# ----------------------------------------------------------------------------------- data


def descriptors(subjects: Sequence[int]) -> np.ndarray:
    """``(N, 15)`` upper-body descriptors of the valid frames of the bundled data's subjects."""
    seqs = datasets.msr_action3d(subjects=list(subjects))
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    return np.asarray(d)[np.asarray(ok)]


def queries(test: np.ndarray, batch: int) -> np.ndarray:
    """``(batch, m)``: ``test`` (already in a fixed random order) tiled to ``batch`` rows."""
    reps = -(-batch // len(test))
    return np.ascontiguousarray(np.tile(test, (reps, 1))[:batch])


def shuffled(d: np.ndarray, seed: int = 0) -> np.ndarray:
    """Rows of ``d`` in a fixed random order."""
    return d[np.random.default_rng(seed).permutation(len(d))]


def default_model(robot: str, path: str | None = None) -> engine.Model:
    """The model at ``path``, else ``robot``'s default model built as ``jaxproj build`` builds
    it (``BuildConfig(robot=robot)`` on ``datasets.training_sequences``)."""
    if path:
        return engine.load(path)
    cfg = engine.BuildConfig(robot=robot)
    train = datasets.training_sequences(cfg.utkinect_people)
    return engine.build(datasets.valid_descriptors(train, bones=cfg.bones), cfg)


def subsample_model(train: np.ndarray, n: int, config: engine.BuildConfig) -> engine.Model:
    """A model on ``n`` distinct training descriptors (seed 0) and their IK poses (each chain
    of a per-chain model keeps the distinct rows of its own columns)."""
    uniq = np.unique(train, axis=0)
    if n > len(uniq):
        raise ConfigError(f"N={n} exceeds the {len(uniq)} distinct training descriptors")
    idx = np.sort(np.random.default_rng(0).choice(len(uniq), n, replace=False))
    human = uniq[idx].astype(np.float32)
    robot_poses = np.asarray(ik.solve_driven(human), np.float32)
    return engine.from_landmarks(human, robot_poses, config)


def _retrain_banks(model: engine.Model) -> None:
    """Train every chain's two kernel banks again on its landmarks (the ``banks_s`` timing)."""
    sp = model.projector
    for c in range(sp.layout.n_chains):
        p = sp.chain(c)
        cc = model.config.chain_config(c)
        jax.block_until_ready(engine.build_from_landmarks(p.human, p.robot, cc))


def build_models(
    train: np.ndarray,
    landmarks: Sequence[int],
    device: jax.Device,
    log: Callable[[str], None],
    subsample_all: bool = False,
    chains: str = "upper",
) -> tuple[dict[int, engine.Model], list[dict]]:
    """Build one model per landmark count (per arm chain for ``chains="upper"``); also return
    their build records."""
    models: dict[int, engine.Model] = {}
    records = []
    for n in landmarks:
        sub = (subsample_all or n == SYNTHETIC_N) and n != DEFAULT_N
        cfg = engine.BuildConfig(chains=chains, landmarks=None if n == DEFAULT_N else n)
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            model = subsample_model(train, n, cfg) if sub else engine.build(train, cfg)
            jax.block_until_ready(model.projector)
            times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        _retrain_banks(model)
        banks_s = time.perf_counter() - t0
        models[n] = dataclasses.replace(model, projector=jax.device_put(model.projector, device))
        p = model.projector
        rec = record(
            "build",
            objective="build",
            N=n,
            chains=chains,
            landmarks_per_chain=model.landmarks,
            device=device.platform,
            compile_s=max(times[0] - times[1], 0.0),
            n_landmarks=max(model.landmarks.values()),
            build_s=times[1],
            first_build_s=times[0],
            banks_s=banks_s,
            landmarks_source="subsample" if sub else "mean_shift",
        )
        records.append(rec)
        log(
            f"build N={n} ({chains}): K={model.landmarks}, {times[1]:.2f} s "
            f"(first {times[0]:.2f} s), banks {banks_s:.2f} s"
        )
        del p
    return models, records


# ------------------------------------------------------------------------------ reference


def time_reference(
    ref: Reference | StackedReference,
    h: np.ndarray,
    objective: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Answers ``(Q, n)`` and objective values ``(Q,)`` for queries ``h (Q, m)``, and the
    median-free mean us per query.

    The first query is run once untimed (warm-up); then every query once, timed as a whole.
    """
    ref.project(h[0], objective, n_l, n_m, full)
    t0 = time.perf_counter()
    out = [ref.project(q, objective, n_l, n_m, full) for q in h]
    us = (time.perf_counter() - t0) / len(h) * 1e6
    return np.asarray([o[0] for o in out]), np.asarray([o[1] for o in out]), us


# ------------------------------------------------------------------------------ streaming


def bench_streaming(
    model: engine.Model | Projector,
    positions: np.ndarray,
    device: jax.Device,
    n_frames: int,
    n_l: int = 10,
    n_m: int = 10,
    params: SmoothingParams = PAPER_SMOOTHING,
    warmup: int = 50,
) -> dict:
    """Per-frame latency of ``jaxproj.motion.streaming.update`` over ``positions (T, 20, 3)``
    (cycled): a host array in, a host array of angles out, the state carried from frame to frame."""
    frames = np.asarray(positions, np.float32)
    state = jax.device_put(jaxproj_streaming.init(model), device)
    angles = np.zeros(0, np.float32)

    def step(i: int) -> None:
        nonlocal state, angles
        out, state = jaxproj_streaming.update(
            model, state, frames[i % len(frames)], n_l=n_l, n_m=n_m, smoothing=params
        )
        angles = np.asarray(out)  # the host has the answer: the frame is done

    with jax.default_device(device):
        t0 = time.perf_counter()
        step(0)  # trace + compile + one frame
        first_s = time.perf_counter() - t0
        lat_us = frame_latencies(step, n_frames, max(warmup - 1, 0)) * 1e6
    if not np.isfinite(angles).all():
        raise RuntimeError("streaming produced non-finite angles")
    med = float(np.median(lat_us))
    return record(
        "streaming",
        objective="streaming",
        L=n_l,
        M=n_m,
        N=None,
        batch=1,
        device=device.platform,
        us_per_projection=med,
        throughput=1e6 / med,
        compile_s=max(first_s - med * 1e-6, 0.0),
        median_us=med,
        p99_us=float(np.percentile(lat_us, 99)),
        mean_us=float(lat_us.mean()),
        frames=n_frames,
    )


# ----------------------------------------------------------------------------- projection


def bench_projection(
    p: Projector | StackedProjector,
    h_all: np.ndarray,
    objective: str,
    n_l: int,
    n_m: int,
    batch: int,
    device: jax.Device,
    plan: Plan,
    ref_answers: np.ndarray,
    full: FullConfig | None = None,
    estimate_us: float | None = None,
    ref: StackedReference | None = None,
    ref_values: np.ndarray | None = None,
) -> dict:
    """One projection record (see the module doc); ``ref_answers`` are the reference's poses
    for the first rows of ``h_all`` and ``ref_values`` their objective values (``agreement``);
    ``ref`` (relaxed) judges them under the near-tie rule."""
    rec = record(
        "projection",
        objective=objective,
        L=n_l,
        M=n_m,
        batch=batch,
        device=device.platform,
        n_landmarks=p.n_landmarks,
    )
    if estimate_us is not None and estimate_us * batch * 1e-6 > plan.max_call_s:
        rec["skipped"] = (
            f"estimated {estimate_us * batch * 1e-6:.0f} s per call (from a smaller batch) "
            f"exceeds the {plan.max_call_s:.0f} s budget"
        )
        return rec
    full = FullConfig() if full is None else full
    h = jax.device_put(queries(h_all, batch), device)
    compiled, rec["compile_s"] = compile_timed(
        engine.project_chunk, p, h, objective, n_l, n_m, full
    )
    need, avail = needed_bytes(compiled), available_bytes(device)
    rec["memory_bytes"] = need
    if need is not None and avail is not None and need > plan.memory_fraction * avail:
        rec["skipped"] = (
            f"needs {need / 2**30:.1f} GiB (XLA estimate), more than "
            f"{plan.memory_fraction:.0%} of the {avail / 2**30:.1f} GiB available"
        )
        return rec
    t0 = time.perf_counter()
    r, v = jax.block_until_ready(compiled(p, h))
    rec["first_call_s"] = time.perf_counter() - t0
    r, v = np.asarray(r), np.asarray(v)
    # a batch smaller than the check is run again on the next queries until it is covered
    start = batch
    while len(r) < min(plan.n_check, len(ref_answers)):
        more = jax.device_put(queries(np.roll(h_all, -start, axis=0), batch), device)
        r2, v2 = compiled(p, more)
        r, v = np.concatenate([r, np.asarray(r2)]), np.concatenate([v, np.asarray(v2)])
        start += batch
    if not (np.isfinite(r).all() and np.isfinite(v).all()):
        raise RuntimeError(f"non-finite engine output for {objective} L={n_l} M={n_m}")
    n = min(len(r), len(ref_answers), max(plan.n_check, batch))
    diff = np.degrees(np.abs(r[:n] - ref_answers[:n]))
    per_query = diff.max(axis=1)
    f_ref = None if ref_values is None else ref_values[:n]
    rec.update(
        n_checked=int(n),
        max_abs_diff_deg=float(per_query.max()),
        median_abs_diff_deg=float(np.median(per_query)),
        **agreement(objective, per_query, v[:n], f_ref, (full or FullConfig()).tie_rtol),
    )
    if objective == "relaxed" and ref is not None:
        rec.update(near_ties(ref, queries(h_all, n), r[:n], n_l, n_m, per_query[:n]))
    timing = time_plan(lambda: compiled(p, h), plan)
    sec, reps = timing.median_s, timing.repeats
    rec.update(
        us_per_projection=sec / batch * 1e6,
        throughput=batch / sec,
        repeats=reps,
        call_s=sec,
    )
    return rec


def bench_public(
    model: engine.Model,
    h_all: np.ndarray,
    objective: str,
    n_l: int,
    n_m: int,
    n_queries: int,
    device: jax.Device,
    plan: Plan,
    ref_answers: np.ndarray,
    full: FullConfig | None = None,
    devices: list | None = None,
    ref: StackedReference | None = None,
    ref_values: np.ndarray | None = None,
) -> dict:
    """A ``public`` record: ``jaxproj.project`` as users call it -- a host NumPy array of
    ``n_queries`` descriptors in, host arrays out, default ``batch_size`` -- timed end to end
    (transfers included); the first call (which compiles) is timed apart, answers checked
    against the reference first."""
    rec = record(
        "public", objective=objective, L=n_l, M=n_m, batch=n_queries, device=device.platform,
        n_landmarks=model.projector.n_landmarks,
    )  # fmt: skip
    h = queries(h_all, n_queries)
    if devices is None and device != jax.devices()[0]:
        devices = [device]
    rec["devices"] = [str(d) for d in (devices or [device])]
    rec["batch_size"] = engine.default_batch_size(devices, n_queries)

    def call() -> tuple[np.ndarray, np.ndarray]:
        return engine.project(
            model, h, objective, n_l=n_l, n_m=n_m, full=full, devices=devices
        )  # fmt: skip

    t0 = time.perf_counter()
    r, v = call()
    rec["first_call_s"] = time.perf_counter() - t0
    n = min(len(ref_answers), len(r))
    per_query = np.degrees(np.abs(r[:n] - ref_answers[:n])).max(axis=1)
    f_ref = None if ref_values is None else ref_values[:n]
    rec.update(
        n_checked=int(n), max_abs_diff_deg=float(per_query.max()),
        **agreement(objective, per_query, v[:n], f_ref, (full or FullConfig()).tie_rtol),
    )  # fmt: skip
    if objective == "relaxed" and ref is not None:
        rec.update(near_ties(ref, h[:n], r[:n], n_l, n_m, per_query))
    timing = time_plan(call, dataclasses.replace(plan, min_repeats=3, max_repeats=5))
    sec = timing.median_s
    rec.update(
        us_per_projection=sec / n_queries * 1e6, throughput=n_queries / sec,
        repeats=timing.repeats, call_s=sec,
    )  # fmt: skip
    return rec


# -------------------------------------------------------------------------------- rollout


def bench_rollout(
    quick: bool, device: jax.Device, frames: int = 30, devices: list | None = None
) -> list[dict]:
    """Rollout steps/s (``benchmarks.bench_rollout.bench``: synthetic arm motions, 15 frames/s,
    33 physics steps per frame) with the backend ``rollout.simulate`` picks by default for
    ``device`` (``backend``: MJX on an accelerator, CPU MuJoCo on a CPU), one record per batch
    size; motion 0 is checked against the written-out CPU MuJoCo ``mj_step`` loop
    (``vs_cpu_max_dq_rad``); a ``skipped`` record when MuJoCo MJX cannot be imported."""
    backend = "mujoco" if device.platform == "cpu" and not devices else "mjx"
    rec = record("rollout", objective="rollout", device=device.platform, backend=backend)
    try:
        from benchmarks import bench_rollout as mod  # imports jaxproj.eval.rollout, MJX
    except ImportError as e:
        return [rec | {"skipped": f"rollout module not available ({e})"}]
    if device.platform == "cpu":
        batches = (64,) if quick else (64, 256)
    else:
        batches = (32768,) if quick else (4096, 16384, 32768)  # the target is quoted at 32,768
    out = []
    try:
        from jaxproj.robots.nao_h25 import robot

        substeps = round((1.0 / 15.0) / robot.load_model("fixed").opt.timestep)
        ref = mod.motions(1, frames, 0)[0]
        cpu_q, cpu_ncon, _ = mod.cpu_rollout(ref, substeps)
        with jax.default_device(device):
            for b in batches:
                r = mod.bench(
                    b, frames, 0, 1 if quick else 3, substeps, devices=devices, backend=backend
                )
                dq = float(np.abs(np.asarray(r.pop("qpos0")) - cpu_q).max())
                out.append(
                    rec
                    | dict(
                        batch=b,
                        throughput=r["steps_per_s"],
                        compile_s=r["compile_s"],
                        steps_per_s=r["steps_per_s"],
                        run_s=r["run_s"],
                        steps=r["steps"],
                        frames=frames,
                        substeps=substeps,
                        finite=r["finite"],
                        vs_cpu_max_dq_rad=dq,
                        cpu_contacts=int(cpu_ncon),
                    )
                )
    except Exception as e:  # noqa: BLE001 - report, do not lose the projection numbers
        return out + [rec | {"skipped": f"rollout benchmark failed: {type(e).__name__}: {e}"}]
    return out


LONG_SOLVE_ITERATIONS = 1000
"""Steps of the long reference solve that defines an *exact* full-objective answer."""

CONVERGED_TOL_DEG = 0.1
"""How close to the long solve an exact full answer must be (the speed issue's definition)."""


def bench_full_convergence(
    model: engine.Model, h: np.ndarray, n_l: int, n_m: int, full: FullConfig
) -> dict:
    """A ``full_convergence`` record: the full objective's answers with the benchmarked solver
    ``full`` against the same solver run for ``LONG_SOLVE_ITERATIONS`` steps, on the queries
    ``h`` (held-out people): the fraction within ``CONVERGED_TOL_DEG`` on every joint."""
    long = dataclasses.replace(full, iterations=LONG_SOLVE_ITERATIONS)
    r, f = engine.project(model, h, "full", n_l=n_l, n_m=n_m, full=full)
    r_long, f_long = engine.project(model, h, "full", n_l=n_l, n_m=n_m, full=long)
    diff = np.degrees(np.abs(r - r_long)).max(axis=1)
    return record(
        "full_convergence", objective="full", L=n_l, M=n_m, queries=len(h),
        full_config=dataclasses.asdict(full), reference_iterations=LONG_SOLVE_ITERATIONS,
        tolerance_deg=CONVERGED_TOL_DEG,
        fraction_within=float(np.mean(diff <= CONVERGED_TOL_DEG)),
        p99_abs_diff_deg=float(np.quantile(diff, 0.99)), max_abs_diff_deg=float(diff.max()),
        objective_ratio_median=float(np.median(f / np.maximum(f_long, 1e-12))),
    )  # fmt: skip


# ----------------------------------------------------------------------------------- run


def run(
    quick: bool,
    device: str,
    *,
    plan: Plan | None = None,
    streaming: bool = True,
    rollout: bool = True,
    log: Callable[[str], None] | None = None,
    full: FullConfig | None = None,
    chains: str = "upper",
    devices: list | None = None,
    **plan_overrides: Any,
) -> list[dict]:
    """Run the benchmark suite; returns the records (header first, target checks last).

    ``chains`` is the model's chain set (``"upper"``, the default per-chain engine, or
    ``"whole"``, the paper's whole-body projector); every record names it. ``full`` sets the
    full objective's solver (default ``FullConfig()``, the exact full
    objective); the reference runs the same configuration, and every full record carries it.
    """
    dev = get_device(device)
    plan = plan or make_plan(quick, device, **plan_overrides)
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    records = [header(dev)]
    log(f"bench on {records[0]['device_kind']} ({records[0]['cpu_usable']} usable CPU cores)")
    train = descriptors(TRAIN_SUBJECTS)
    test = shuffled(descriptors(TEST_SUBJECTS))
    models, builds = build_models(train, plan.landmarks, dev, log, plan.subsample_all, chains)
    records += builds
    full = FullConfig() if full is None else full
    for n in plan.landmarks:
        p = models[n].projector
        ref = StackedReference(p)
        for objective, n_l, n_m in plan.configs:
            if max(n_l, n_m) > p.n_landmarks:
                continue
            nq = max(plan.ref_queries[objective], plan.n_check)
            ans, vals, ref_us = time_reference(ref, test[:nq], objective, n_l, n_m, full)
            log(f"reference {objective} L={n_l} M={n_m} N={n}: {ref_us:.0f} us/query")
            estimate = None
            for batch in sorted(plan.batches):
                rec = bench_projection(
                    p, test, objective, n_l, n_m, batch, dev, plan, ans, full, estimate, ref, vals
                )
                rec.update(N=n, chains=chains, reference_us_per_projection=ref_us)
                rec.update(reference_queries=nq)
                if objective == "full":
                    rec["full_config"] = dataclasses.asdict(full)
                if rec.get("us_per_projection"):
                    rec["speedup"] = ref_us / rec["us_per_projection"]
                    estimate = rec["us_per_projection"]
                else:
                    rec.setdefault("speedup", None)
                    rec.setdefault("max_abs_diff_deg", None)
                records.append(rec)
                log(table_row(rec))
            if objective == "full":
                rec = bench_full_convergence(models[n], test[:nq], n_l, n_m, full)
                rec.update(N=n, chains=chains)
                records.append(rec)
                log(
                    f"full L={n_l} M={n_m} N={n}: {rec['fraction_within']:.4f} of {nq} answers "
                    f"within {rec['tolerance_deg']} deg of a {rec['reference_iterations']}-step "
                    f"solve (max {rec['max_abs_diff_deg']:.2f} deg)"
                )
            n_pub = plan.public_queries.get(objective, 0)
            if n_pub:
                rec = bench_public(
                    models[n],
                    test,
                    objective,
                    n_l,
                    n_m,
                    n_pub,
                    dev,
                    plan,
                    ans,
                    full,
                    devices,
                    ref,
                    vals,
                )
                rec.update(N=n, chains=chains, reference_us_per_projection=ref_us)
                rec["speedup"] = ref_us / rec["us_per_projection"]
                if objective == "full":
                    rec["full_config"] = dataclasses.asdict(full)
                records.append(rec)
                log(f"public jaxproj.project {table_row(rec)}")
    if streaming:
        n_stream = next((n for n in (DEFAULT_N, 1644) if n in models), max(models))
        seqs = datasets.msr_action3d(subjects=list(TEST_SUBJECTS))
        pos = np.concatenate([s.positions[s.valid] for s in seqs[:20]])
        rec = bench_streaming(models[n_stream], pos, dev, plan.stream_frames)
        rec["N"] = n_stream
        rec["chains"] = chains
        rec["n_landmarks"] = max(models[n_stream].landmarks.values())
        records.append(rec)
        log(f"streaming N={n_stream}: median {rec['median_us']:.0f} us, p99 {rec['p99_us']:.0f} us")
    if rollout:
        for rec in bench_rollout(quick, dev, frames=plan.rollout_frames, devices=devices):
            records.append(rec)
            if rec.get("steps_per_s"):
                log(f"rollout batch {rec['batch']}: {rec['steps_per_s']:.4g} steps/s")
    records += target_checks(records, device)
    return records


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark from the command line: print the table, write ``--json``; returns the
    exit status (2 with one line on a configuration error)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.add_arguments(ap)
    args = ap.parse_args(argv)
    plan = make_plan(
        args.quick,
        args.device,
        landmarks=args.landmarks,
        batches=args.batches,
        configs=args.configs,
        repeats=args.repeats,
        ref_queries=args.ref_queries,
    )
    try:
        records = run(
            args.quick,
            args.device,
            plan=harness.smoke_plan(plan) if args.smoke else plan,
            streaming=not args.no_streaming,
            rollout=not args.no_rollout,
            full=harness.full_config(args.full_clusters, args.full_iterations),
            chains=args.chains,
            devices=engine.resolve_devices(args.devices),
        )
    except JaxprojError as e:
        print(f"bench_projection: error: {e}", file=sys.stderr)
        return 2
    if args.json:
        harness.write_json(records, args.json)
    print(harness.format_table(records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
