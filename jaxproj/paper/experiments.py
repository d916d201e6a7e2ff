"""The paper's studies (section IV) on the synthetic poses and motions of ``synthetic``: the
basic pose / motion benchmarks (``run_pose_experiments``), the landmark-set size study
(``landmark_size_study``) and the efficiency study (``efficiency_study``).

Errors are the paper's ``M_max`` / ``M_avg`` (degrees, ``evaluate.frame_errors``) of the
projection against the analytic IK of the same frame. The poses, motions and noise model (and why
the IK's ElbowYaw of a straight arm is ill-defined) are described in ``synthetic``. Timings use the
shared helpers of ``timing`` (compilation apart, blocked calls, median).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.eval.evaluate import describe, frame_errors
from jaxproj.human.skeleton import N_JOINTS, descriptor
from jaxproj.paper.synthetic import (
    BASIC_POSES,
    DEFAULT_FPS,
    POSE_NAMES,
    basic_motion,
    check_pose,
    kinect_noise_std,
    skeleton_from_directions,
)
from jaxproj.projection import api as engine
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector, StackedProjector
from jaxproj.robots import Robot
from jaxproj.robots import get as get_robot
from jaxproj.timing import compile_timed, time_calls


def _robot_of(model: engine.Model | Projector) -> Robot:
    """A model's robot (``Model.robot``); a bare projector's: the default robot, the paper's."""
    return model.robot if isinstance(model, engine.Model) else get_robot()


def _bones_of(model: engine.Model | Projector) -> tuple[str, bool]:
    if isinstance(model, engine.Model):
        return model.config.bones, model.config.mirror
    return "upper", False


def _batch_size(n: int) -> int:
    """Power-of-two batch (256..4096): few distinct shapes, so few compiles."""
    return int(min(4096, max(256, 2 ** math.ceil(math.log2(max(n, 1))))))


def _ik(d: np.ndarray, bones: str, robot: Robot) -> np.ndarray:
    """``robot.solve_ik`` on a padded power-of-two batch (one compile for many sizes)."""
    n = len(d)
    size = _batch_size(n) if n <= 4096 else n
    padded = np.concatenate([d, np.repeat(d[:1], size - n, axis=0)]) if size > n else d
    return np.asarray(robot.solve_ik(padded, bones))[:n]


def _descriptors(model: engine.Model | Projector, positions: np.ndarray) -> np.ndarray:
    """``(F, 20, 3)`` -> ``(F, m)`` descriptors with the model's bones; all must be valid."""
    bones, mirror = _bones_of(model)
    dj, okj = descriptor(positions, bones=bones, mirror=mirror)
    d, ok = np.asarray(dj), np.asarray(okj)
    if not ok.all():
        raise ConfigError(f"{int((~ok).sum())} synthetic frames have a degenerate descriptor")
    return d


def _nearest_landmark_deg(p: Projector | StackedProjector, d: np.ndarray) -> np.ndarray:
    """``(F, m)`` -> ``(F,)``: worst bone angle (deg) to the nearest landmark (Euclidean), per
    chain on a chain model (each chain's nearest landmark in its own bones)."""
    if isinstance(p, StackedProjector):
        lay = p.layout
        per_chain = [
            _nearest_landmark_deg(p.chain(c), np.asarray(d)[:, list(lay.inputs[c])])
            for c in range(lay.n_chains)
        ]
        return np.max(per_chain, axis=0)
    human = np.asarray(p.human, np.float64)
    d = np.asarray(d, np.float64)
    idx = np.argmin(np.sum((d[:, None, :] - human[None]) ** 2, axis=-1), axis=1)
    a = d.reshape(len(d), -1, 3)
    b = human[idx].reshape(len(d), -1, 3)
    cos = np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max(axis=-1)


def _motion_set(
    key: jax.Array,
    names: Sequence[str],
    seconds: float,
    fps: float,
    noise_std: float | np.ndarray | None,
    lengths: np.ndarray | None,
) -> np.ndarray:
    """``(len(names), T, 20, 3)``; motion ``POSE_i`` uses ``fold_in(key, i)``."""
    return np.stack(
        [
            basic_motion(
                n,
                seconds=seconds,
                fps=fps,
                noise_std=noise_std,
                key=jax.random.fold_in(key, POSE_NAMES.index(n) + 1),
                lengths=lengths,
            )
            for n in names
        ]
    )


def run_pose_experiments(
    model: engine.Model | Projector,
    *,
    n_l: int = 10,
    n_m: int = 10,
    objectives: Sequence[engine.Objective] = ("relaxed", "full"),
    key: jax.Array,
    seconds: float = 2.0,
    fps: float = DEFAULT_FPS,
    noise_std: float | np.ndarray | None = None,
    lengths: np.ndarray | None = None,
    full: FullConfig | None = None,
    poses: Sequence[str] = POSE_NAMES,
) -> dict:
    """The paper's pose and motion benchmarks (figs. "pose reconstruct" and "statistics").

    Static poses are noise-free; motions are ``basic_motion`` with noise (motion ``POSE_i`` uses
    ``jax.random.fold_in(key, i)``, so the motions do not depend on which poses are run). Every
    error compares the projection of a frame with the IK of the same frame. ``coverage_deg``
    says how far a pose (or the farthest frame of its motion) lies from the landmarks: the
    largest bone angle between it and its nearest landmark.

    Args:
      model: a ``Model`` (its descriptor bones / mirror are used) or a bare ``Projector``
        (upper-body bones).
      n_l, n_m: ``L`` and ``M``.
      objectives: projection objectives to run.
      key: ``jax.random`` key of the motion noise.
      seconds, fps, noise_std, lengths: as in ``basic_motion``.
      full: settings of the full objective.
      poses: which basic poses / motions.

    Returns:
      JSON-ready dict::

        {"landmarks", "L", "M", "frames_per_motion", "fps", "noise_std_m" (pooled or given),
         "truth_deg": {pose: {joint: deg}},
         "coverage_deg": {pose: {"pose", "motion_max"}},
         "poses": {pose: {objective: {"M_max", "M_avg", "joint_errors_deg": {joint: deg}}}},
         "motions": {pose: {objective: {"M_max": [T], "M_avg": [T], "M_max_max", "M_max_mean",
                                        "M_avg_max", "M_avg_mean",
                                        "joint_max_deg": {joint: max over frames}}}},
         "summary": {objective: {"pose_M_max_max", "pose_M_avg_mean", "motion_M_max_max",
                                 "motion_M_avg_mean", "motions_within_10deg",
                                 "pose_M_max_max_excl_elbow_yaw",
                                 "motion_M_max_max_excl_elbow_yaw"}}}

    ElbowYaw is reported apart in the summary because the IK's ElbowYaw of a (nearly) straight
    arm is ill-defined (``synthetic`` module docstring).
    """
    for n in poses:
        check_pose(n)
    p = model.projector if isinstance(model, engine.Model) else model
    engine.check_neighbours(p, n_l, n_m)
    bones, _ = _bones_of(model)
    pose_pos = skeleton_from_directions(np.stack([BASIC_POSES[n] for n in poses]), lengths)
    motions = _motion_set(key, poses, seconds, fps, noise_std, lengths)
    n_p, t = len(poses), motions.shape[1]
    frames = np.concatenate([pose_pos, motions.reshape(-1, N_JOINTS, 3)])
    if noise_std is None:
        noise_val: float | list[float] = float(kinect_noise_std())
    else:
        arr = np.asarray(noise_std, np.float64)
        noise_val = float(arr) if arr.ndim == 0 else arr.tolist()
    out: dict = {
        "landmarks": int(p.n_landmarks),
        "L": n_l,
        "M": n_m,
        "frames_per_motion": int(t),
        "fps": float(fps),
        "noise_std_m": noise_val,
        "truth_deg": {},
        "coverage_deg": {},
        "poses": {n: {} for n in poses},
        "motions": {n: {} for n in poses},
        "summary": {},
    }
    d = _descriptors(model, frames)
    robot = _robot_of(model)
    truth = _ik(d, bones, robot)
    truth_deg = np.degrees(truth.astype(np.float64))
    cover = _nearest_landmark_deg(p, d)
    joints = robot.driven_joints
    for objective in objectives:
        pred, _ = engine.project(
            model, d, objective, n_l=n_l, n_m=n_m, full=full, batch_size=_batch_size(len(d))
        )
        m_max, m_avg = frame_errors(pred, truth)
        err = np.degrees(np.abs(pred.astype(np.float64) - truth))  # (F, n)
        mm_max, mm_avg = m_max[n_p:].reshape(n_p, t), m_avg[n_p:].reshape(n_p, t)
        m_err = err[n_p:].reshape(n_p, t, -1)
        for i, n in enumerate(poses):
            out["poses"][n][objective] = {
                "M_max": float(m_max[i]),
                "M_avg": float(m_avg[i]),
                "joint_errors_deg": dict(zip(joints, err[i].tolist(), strict=True)),
            }
            out["motions"][n][objective] = {
                "M_max": mm_max[i].tolist(),
                "M_avg": mm_avg[i].tolist(),
                "M_max_max": float(mm_max[i].max()),
                "M_max_mean": float(mm_max[i].mean()),
                "M_avg_max": float(mm_avg[i].max()),
                "M_avg_mean": float(mm_avg[i].mean()),
                "joint_max_deg": dict(zip(joints, m_err[i].max(axis=0).tolist(), strict=True)),
            }
        no_yaw = err[:, [i for i, j in enumerate(joints) if "ElbowYaw" not in j]].max(axis=1)
        out["summary"][objective] = {
            "pose_M_max_max": float(m_max[:n_p].max()),
            "pose_M_avg_mean": float(m_avg[:n_p].mean()),
            "motion_M_max_max": float(mm_max.max()),
            "motion_M_avg_mean": float(mm_avg.mean()),
            "motions_within_10deg": int((mm_max.max(axis=1) < 10.0).sum()),
            "pose_M_max_max_excl_elbow_yaw": float(no_yaw[:n_p].max()),
            "motion_M_max_max_excl_elbow_yaw": float(no_yaw[n_p:].max()),
        }
    for i, n in enumerate(poses):
        out["truth_deg"][n] = dict(zip(joints, truth_deg[i].tolist(), strict=True))
        out["coverage_deg"][n] = {
            "pose": float(cover[i]),
            "motion_max": float(cover[n_p + i * t : n_p + (i + 1) * t].max()),
        }
    return out


def _held_out_metrics(
    model: engine.Model,
    eval_descriptors: np.ndarray,
    objective: engine.Objective,
    n_l: int,
    n_m: int,
) -> dict[str, float]:
    bones = model.config.bones
    h = np.asarray(eval_descriptors, np.float32)
    truth = _ik(h, bones, model.robot)
    pred, _ = engine.project(model, h, objective, n_l=n_l, n_m=n_m, batch_size=_batch_size(len(h)))
    m_max, m_avg = frame_errors(pred, truth)
    a, x = describe(m_avg), describe(m_max)
    return {
        "M_avg_median": a["median"],
        "M_avg_mean": a["mean"],
        "M_max_median": x["median"],
        "M_max_p95": x["p95"],
        "eval_frames": a["n"],
    }


def landmark_size_study(
    train_descriptors: np.ndarray,
    sizes: Sequence[int | None] = (1644, 961, 86),
    *,
    objective: engine.Objective = "relaxed",
    key: jax.Array,
    eval_descriptors: np.ndarray | None = None,
    config: engine.BuildConfig | None = None,
    n_l: int = 10,
    n_m: int = 10,
    noise_std: float | np.ndarray | None = None,
    progress: bool = False,
    built: Mapping[engine.BuildConfig, tuple[engine.Model, float]] | None = None,
) -> dict:
    """The paper's landmark-size study: one model per target size, POSE_8 and its motion.

    Args:
      train_descriptors: ``(N, m)`` valid training descriptors.
      sizes: target landmark counts (the mean-shift bandwidth is bisected to reach each);
        ``None``: ``config`` itself, with its own sizes (``BuildConfig()``: the default model's
        bandwidths), its row's ``"target"`` ``None``.
      objective: projection objective.
      key: ``jax.random`` key of the POSE_8 motion noise (the same motion for every size).
      eval_descriptors: optional ``(E, m)`` held-out valid descriptors.
      config: base ``BuildConfig`` (its ``landmarks`` / ``bandwidth`` are replaced per size).
      n_l, n_m: ``L`` and ``M`` (clipped to the landmark count for tiny sets).
      noise_std: motion noise, as in ``basic_motion``.
      progress: print one line per size.
      built: models the caller already built from ``train_descriptors``, by their
        ``BuildConfig``, with their build seconds: a size whose config is here is not built again
        (the build is deterministic, so the answers are the same; ``"build_s"`` is the caller's).

    Returns:
      ``{"objective", "L", "M", "sizes": [row, ...]}``, one row per size with ``"target"``,
      ``"landmarks"`` (count reached by the chains a size target drives, ``_targeted_landmarks``:
      the mean of the two arm chains of a per-chain model, whose head keeps its fixed
      bandwidth; a report should show ``"landmarks_per_chain"`` beside it),
      ``"landmarks_per_chain"``,
      ``"bandwidth"``, ``"build_s"``, ``"pose8_static_M_max"``,
      ``"pose8_static_M_avg"`` (the noise-free pose), ``"pose8_M_max"`` (max M_max over the
      POSE_8 motion, the value ``report.plot_landmark_size`` draws), ``"pose8_M_max_mean"``,
      ``"pose8_M_avg_mean"``, ``"pose8_M_max_frames"`` (per frame) and, with
      ``eval_descriptors``, ``"M_avg_median"``, ``"M_avg_mean"``, ``"M_max_median"``,
      ``"M_max_p95"``, ``"eval_frames"``.
    """
    base = config or engine.BuildConfig()
    rows = []
    # the chains a size target drives (any valid size: only which chains it sets matters)
    driven = dataclasses.replace(base, landmarks=100, bandwidth=None)
    for size in sizes:
        if size is None:
            cfg = base
        else:
            cfg = dataclasses.replace(base, landmarks=int(size), bandwidth=None)
        if built is not None and cfg in built:
            model, build_s = built[cfg]
        else:
            t0 = time.perf_counter()
            model = engine.build(train_descriptors, cfg, calibrate=False)  # no confidence read
            build_s = time.perf_counter() - t0
        k = model.n_landmarks  # the smallest chain
        ll, mm = min(n_l, k), min(n_m, k)
        res = run_pose_experiments(
            model, n_l=ll, n_m=mm, objectives=(objective,), key=key, noise_std=noise_std,
            poses=("POSE_8",),
        )  # fmt: skip
        pose = res["poses"]["POSE_8"][objective]
        motion = res["motions"]["POSE_8"][objective]
        row = {
            "target": None if size is None else int(size),
            "landmarks": _targeted_landmarks(driven, model.landmarks),
            "landmarks_per_chain": model.landmarks,
            "bandwidth": list(model.bandwidth),
            "build_s": build_s,
            "L": ll,
            "M": mm,
            "pose8_static_M_max": pose["M_max"],
            "pose8_static_M_avg": pose["M_avg"],
            "pose8_M_max": motion["M_max_max"],
            "pose8_M_max_mean": motion["M_max_mean"],
            "pose8_M_avg_mean": motion["M_avg_mean"],
            "pose8_M_max_frames": motion["M_max"],
        }
        if eval_descriptors is not None:
            row.update(_held_out_metrics(model, eval_descriptors, objective, ll, mm))
        rows.append(row)
        if progress:
            print(f"landmarks {size}: {model.landmarks} reached, build {build_s:.1f} s", flush=True)
    return {"objective": objective, "L": n_l, "M": n_m, "sizes": rows}


def _targeted_landmarks(config: engine.BuildConfig, landmarks: dict[str, int]) -> int:
    """The landmark count a size target reached: the mean count (rounded) of the chains the
    target drove (``config.chain_config(c).landmarks`` set: the arms of the per-chain model, whose
    head keeps its fixed bandwidth; the one chain of the whole-body model). ``landmarks``: the
    built model's count per chain; chains of another layout count all."""
    names = [n for c, n in enumerate(config.chain_names) if config.chain_config(c).landmarks]
    counts = [landmarks[n] for n in names if n in landmarks] or list(landmarks.values())
    return int(round(float(np.mean(counts))))


def _bytes_per_query(p: Projector | StackedProjector, n_l: int, n_m: int) -> int:
    """Rough peak memory of one projection in a vmapped batch: the ``L x M`` backward kernels
    it evaluates are gathered per query and chain (``out``: hidden x m, plus bias and
    features)."""
    chains = 1
    if isinstance(p, StackedProjector):
        chains, p = p.layout.n_chains, p.stack
    bank = p.backward
    return 4 * chains * n_l * n_m * bank.hidden * (bank.d_out + 3)


def efficiency_study(
    model: engine.Model | Projector,
    descriptors: np.ndarray,
    ls: Sequence[int] = (10, 20, 30, 40, 50),
    objective: engine.Objective = "relaxed",
    batch: int = 4096,
    *,
    repeats: int = 3,
    full: FullConfig | None = None,
    max_bytes: int = 2**31,
) -> dict:
    """Time per projection and accuracy for ``L = M`` in ``ls`` (paper: "efficiency").

    Timing (``timing``): one batch (the first descriptors, repeated if fewer) through the
    engine's jitted ``engine.project_chunk``. ``compile_s`` is the ``lower().compile()`` time of
    exactly the executable that is then timed (``timing.compile_timed``); ``first_call_s`` its
    first call; ``us_per_projection`` the median of ``repeats`` further calls, each blocked until
    its outputs are ready (``timing.time_calls``), divided by the batch size. Accuracy: all of
    ``descriptors`` projected (``engine.project``) and compared with their IK.

    The batch is ``batch`` halved until the estimated working set of the largest ``L`` fits
    ``max_bytes`` (a vmapped projection gathers its ``L x M`` backward kernels per query, ~5.8 kB
    each for hidden 96, m 15, so 4096 queries at ``L = M = 50`` would need ~60 GB), and every
    ``L`` is timed at that one batch, so that the rows' times compare. Each row reports it.

    Args:
      model: a ``Model`` or a bare ``Projector`` (upper-body bones).
      descriptors: ``(B, m)`` valid descriptors.
      ls: neighbourhood sizes (``L = M``), each ``<=`` the landmark count.
      objective: ``"relaxed"`` or ``"full"``.
      batch: largest number of queries per call (halved to fit ``max_bytes``).
      repeats: timed calls per size.
      full: settings of the full objective.
      max_bytes: memory budget of one batch (estimate).

    Returns:
      ``{"objective", "batch" (the one used), "device", "n_queries", "rows": [{"L", "M", "batch",
      "us_per_projection", "compile_s", "first_call_s", "M_avg_median", "M_avg_mean",
      "M_max_p95"}, ...]}``.

    Raises:
      ConfigError: an unknown objective, ``repeats`` or ``batch`` below 1, descriptors that are
        not ``(B >= 1, m)``, or an ``L`` outside ``[1, landmarks]``.
    """
    p = model.projector if isinstance(model, engine.Model) else model
    bones, _ = _bones_of(model)
    if objective not in ("relaxed", "full"):
        raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
    if repeats < 1 or batch < 1:
        raise ConfigError("repeats and batch must be >= 1")
    h = np.asarray(descriptors, np.float32)
    if h.ndim != 2 or len(h) == 0:
        raise ConfigError(f"descriptors must be (B >= 1, m), got {h.shape}")
    for n in ls:
        engine.check_neighbours(p, n, n)
    full = FullConfig() if full is None else full
    truth = _ik(h, bones, _robot_of(model))
    b = int(batch)
    while b > 1 and b * _bytes_per_query(p, max(ls), max(ls)) > max_bytes:
        b //= 2
    rows = []
    for n in ls:
        chunk = jnp.asarray(np.resize(h, (b, h.shape[1])))
        # the arguments as engine.project passes them, so its call reuses this executable
        compiled, compile_s = compile_timed(
            engine.project_chunk, p, chunk, objective=objective, n_l=n, n_m=n, full=full
        )
        first = time_calls(functools.partial(compiled, p, chunk), min_repeats=1, max_repeats=1)
        timed = time_calls(
            functools.partial(compiled, p, chunk), min_repeats=repeats, max_repeats=repeats
        )
        pred, _ = engine.project(model, h, objective, n_l=n, n_m=n, full=full, batch_size=b)
        m_max, m_avg = frame_errors(pred, truth)
        rows.append(
            {
                "L": int(n),
                "M": int(n),
                "batch": b,
                "us_per_projection": timed.median_s / b * 1e6,
                "compile_s": compile_s,
                "first_call_s": first.median_s,
                "M_avg_median": float(np.median(m_avg)),
                "M_avg_mean": float(np.mean(m_avg)),
                "M_max_p95": float(np.percentile(m_max, 95)),
            }
        )
    return {
        "objective": objective,
        "batch": b,
        "device": str(jax.devices()[0]),
        "n_queries": int(len(h)),
        "rows": rows,
    }


__all__ = [
    "efficiency_study",
    "landmark_size_study",
    "run_pose_experiments",
]
