"""Batch offline evaluation: project recorded motions, compare with the IK ground truth.

Metrics (paper section IV), per frame, over the robot's ``driven_joints`` (``n = n_driven``), in
degrees: ``M_max = max_j |r*_j - r_gt_j|`` and ``M_avg = mean_j |r*_j - r_gt_j|``, where ``r_gt``
is the robot's analytic IK of the frame (``Robot.ik``; ``prepare(..., robot=)``, and
``evaluate`` scores for the model's robot, ``Model.robot``). Only valid frames are scored.
Besides these headline numbers, each method's block says where the error is
(``jaxproj.eval.metrics.summarize_errors``): p50 / p95 per driven joint (``per_joint``),
``M_max`` without the robot's loose joints (``M_max_no_elbow_yaw``) and task-space errors from
forward kinematics of the MJCF (``task_space``: wrist and elbow position in cm, upper-arm and
forearm direction in degrees, per side), projected pose against IK pose.

Methods, all on the same landmarks:

* ``relaxed`` / ``full``: the paper's projection (``jaxproj.projection.relaxed``,
  ``jaxproj.projection.full``);
Baselines run per chain on a per-chain model (each chain's landmarks, in its own bones):

* ``nearest_landmark``: the robot pose of the nearest human landmark;
* ``knn_average``: inverse-distance average of the ``L`` nearest landmarks' robot poses;
* ``global_elm``: one regularised ELM (sigmoid, ``GLOBAL_HIDDEN`` hidden units) fitted to all
  landmark pairs ``h -> r``.

Each motion's per-frame answers go through the motion pipeline's stages after the mapping
(``jaxproj.motion.pipeline.finish``: invalid frames filled as in ``jaxproj.motion.retarget``;
with smoothing, the smoother — by default the zero-lag offline one, ``jaxproj.motion.offline``;
the paper's double exponential smoother with ``smoothing=PAPER_SMOOTHING`` — and the clip to
the joint limits) before
scoring, and the mean squared joint jerk (third difference at the recording rate, rad/s^3) and
the lag against the IK's motion (``metrics.lag_frames``, frames) are reported before and after
the smoother (``"smoothness"``; the IK's own jerk under ``"ik"``). For the projections, the
per-frame confidence (``jaxproj.projection.confidence``) is set against their unsmoothed error
by decile (``"confidence"``, ``metrics.confidence_deciles``).

Size: over 500 lines because the report's blocks, the baselines and the one ``evaluate`` that
assembles them read as one unit (the metrics themselves live in ``jaxproj.eval.metrics``).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal.jit import jit
from jaxproj._internal.progress import bar
from jaxproj.errors import ConfigError, JaxprojError
from jaxproj.eval import metrics
from jaxproj.eval.metrics import describe, frame_errors, summarize_errors
from jaxproj.human.skeleton import descriptor
from jaxproj.io.datasets import ACTION_NAMES, MotionSequence, sequence_times
from jaxproj.motion import feasible, pipeline
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.smoothing import Smoothing, frame_gains
from jaxproj.projection.api import Model, project
from jaxproj.projection.confidence import confidence
from jaxproj.projection.config import FullConfig
from jaxproj.projection.projector import Projector
from jaxproj.projection.search import nearest
from jaxproj.robots import DEFAULT, Robot, get

METHODS: tuple[str, ...] = ("relaxed", "full", "nearest_landmark", "knn_average", "global_elm")
GLOBAL_HIDDEN = 1024
FPS = 15.0
"""MSR Action3D frame rate (frames/s), used for the jerk in physical units."""


@dataclass(frozen=True)
class EvalData:
    """Frames of the evaluated motions, concatenated.

    Attributes:
      descriptors: ``(F, m)`` descriptors of every frame (zeros where invalid).
      valid: ``(F,)`` bool.
      truth: ``(F, n)`` IK of every frame (driven joints, rad).
      offsets: ``(S + 1,)`` sequence ``s`` is frames ``offsets[s]:offsets[s + 1]``.
      names, actions, subjects: ``(S,)`` per-sequence metadata.
      times: ``(F,)`` float64 seconds of each frame from its sequence's first frame
        (``datasets.sequence_times``: the recording's own time axis, or MSR's assumed 15 fps).
      timed: whether any sequence carried its own times (then the smoother's gains follow each
        frame's time step; otherwise they are the per-frame gains as given).
      robot: name of the robot whose IK gave ``truth`` (``evaluate`` checks the model's).
    """

    descriptors: np.ndarray
    valid: np.ndarray
    truth: np.ndarray
    offsets: np.ndarray
    names: list[str]
    actions: np.ndarray
    subjects: np.ndarray
    times: np.ndarray | None = None
    timed: bool = False
    robot: str = DEFAULT


def prepare(
    sequences: Sequence[MotionSequence],
    bones: str = "upper",
    mirror: bool = False,
    *,
    robot: Robot | str | None = None,
) -> EvalData:
    """Descriptors, validity and IK truth of every frame of ``sequences``.

    ``robot`` (a ``Robot`` or registered name; ``None``: the default robot) gives the truth:
    ``(F, n_driven)`` ``Robot.ik`` of every frame's ``(F, m)`` descriptor.
    """
    spec = get(robot)
    if not sequences:
        raise ConfigError("no sequences to evaluate")
    pos = np.concatenate([s.positions for s in sequences])
    ok_in = np.concatenate([s.valid for s in sequences])
    d_raw, ok_raw = descriptor(pos, bones=bones, mirror=mirror)
    d, ok = np.asarray(d_raw), np.asarray(ok_raw) & ok_in
    truth = np.asarray(spec.solve_ik(d, bones))
    lengths = [len(s.valid) for s in sequences]
    return EvalData(
        descriptors=d,
        valid=ok,
        truth=truth,
        offsets=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        names=[s.name for s in sequences],
        actions=np.array([s.action for s in sequences]),
        subjects=np.array([s.subject for s in sequences]),
        times=np.concatenate([sequence_times(s) for s in sequences]),
        timed=any(s.times is not None for s in sequences),
        robot=spec.name,
    )


# ------------------------------------------------------------------------------- baselines


def _nearest_landmark(p: Projector, h: jax.Array) -> jax.Array:
    idx = jax.vmap(lambda x: nearest(p.human, p.human_sq, x, 1)[0][0])(h)
    return p.robot[idx]


_nearest_landmark_jit = jit(_nearest_landmark)


def _knn_average(p: Projector, h: jax.Array, n_l: int) -> jax.Array:
    def one(x: jax.Array) -> jax.Array:
        idx, d2 = nearest(p.human, p.human_sq, x, n_l)
        w = 1.0 / (jnp.sqrt(d2) + 1e-6)
        return (w / jnp.sum(w)) @ p.robot[idx]

    return jax.vmap(one)(h)


_knn_average_jit = jit(_knn_average, static_argnames=("n_l",))


@dataclass(frozen=True)
class GlobalELM:
    """One regularised ELM over all landmarks: ``r = sigmoid(W h + b) B``."""

    w: jax.Array  # (hidden, m)
    b: jax.Array  # (hidden,)
    out: jax.Array  # (hidden, n)

    def __call__(self, h: jax.Array) -> jax.Array:
        """``(B, m) -> (B, n)``."""
        return _global_elm_apply(self.w, self.b, self.out, jnp.asarray(h, jnp.float32))


def _global_elm_apply(w: jax.Array, b: jax.Array, out: jax.Array, h: jax.Array) -> jax.Array:
    return jax.nn.sigmoid(h @ w.T + b[None]) @ out


_global_elm_apply = jit(_global_elm_apply)


def fit_global_elm(
    p: Projector, key: jax.Array, hidden: int = GLOBAL_HIDDEN, lam: float = 1e-3
) -> GlobalELM:
    """Fit the ``global_elm`` baseline on the landmark pairs of ``p`` (ridge, closed form).

    ``lam`` is relative to the mean diagonal of the Gram matrix (see the code comment).

    The fit runs op by op, not compiled, under full float32 matmul precision (the jit policy's
    precision, ``jaxproj._internal.jit``). It is one small solve per evaluation, and its ridge
    system is ill-conditioned enough that XLA's fused round-off moved the baseline's answers by
    ~0.5 deg when it was compiled as one program: it stays as it was measured.
    """
    with jax.default_matmul_precision("highest"):
        return _fit_global_elm(p, key, lam, hidden)


def _fit_global_elm(p: Projector, key: jax.Array, lam: float, hidden: int) -> GlobalELM:
    kw, kb = jax.random.split(key)
    m = p.human.shape[1]
    w = jax.random.normal(kw, (hidden, m), jnp.float32) * 2.0
    b = jax.random.uniform(kb, (hidden,), jnp.float32, -1.0, 1.0)
    h = jax.nn.sigmoid(p.human @ w.T + b[None])  # (K, hidden)
    # The ridge is relative to the Gram matrix's mean diagonal: saturated sigmoids make the
    # Gram entries ~hidden/4, and an absolute 1e-3 drowns in its float32 round-off.
    if h.shape[0] <= hidden:  # dual form: B = H^T (lam I + H H^T)^-1 T, a K x K system
        g = h @ h.T
        a = g + lam * jnp.mean(jnp.diag(g)) * jnp.eye(h.shape[0], dtype=h.dtype)
        out = h.T @ jax.scipy.linalg.solve(a, p.robot, assume_a="pos")
    else:  # primal form: B = (lam I + H^T H)^-1 H^T T, a hidden x hidden system
        g = h.T @ h
        a = g + lam * jnp.mean(jnp.diag(g)) * jnp.eye(hidden, dtype=h.dtype)
        out = jax.scipy.linalg.solve(a, h.T @ p.robot, assume_a="pos")
    return GlobalELM(w, b, out)


def _batched(fn: Callable[[jax.Array], jax.Array], h: np.ndarray, n: int, batch: int = 4096):
    """Apply ``fn`` (``(B, m) -> (B, n)``) in fixed-size padded batches (one compile)."""
    outs = []
    for s in range(0, len(h), batch):
        chunk = h[s : s + batch]
        pad = batch - len(chunk)
        if pad:
            chunk = np.concatenate([chunk, np.repeat(chunk[:1], pad, axis=0)])
        outs.append(np.asarray(fn(jnp.asarray(chunk)))[: batch - pad])
    return np.concatenate(outs) if outs else np.zeros((0, n), np.float32)


def predict_method(
    model: Model,
    method: str,
    h: np.ndarray,
    *,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    seed: int = 0,
    devices: Sequence[jax.Device] | None = None,
) -> np.ndarray:
    """``(F, m)`` valid descriptors -> ``(F, n)`` driven angles by ``method`` (see module doc).

    Raises ``JaxprojError`` rather than return a non-finite answer.
    """
    pred, _ = _predict_value(model, method, h, n_l=n_l, n_m=n_m, full=full, seed=seed,
                             devices=devices)  # fmt: skip
    return pred


def _predict_value(
    model: Model,
    method: str,
    h: np.ndarray,
    *,
    n_l: int,
    n_m: int,
    full: FullConfig | None,
    seed: int = 0,
    devices: Sequence[jax.Device] | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """``predict_method`` and, for the projections, ``(F,)`` their objective's value."""
    value = None
    if method in ("relaxed", "full"):
        objective: Literal["relaxed", "full"] = "full" if method == "full" else "relaxed"
        pred, value = project(model, h, objective, n_l=n_l, n_m=n_m, full=full, devices=devices)
    else:
        pred = _predict(model, method, h, n_l=n_l, n_m=n_m, full=full, seed=seed, devices=devices)
    bad = ~np.isfinite(pred).all(axis=1)
    if bad.any():
        raise JaxprojError(
            f"method {method!r} produced non-finite angles for {int(bad.sum())} of {len(pred)} "
            f"frames (first: valid frame {int(np.argmax(bad))})"
        )
    return pred, value


def _predict(model, method, h, *, n_l, n_m, full, seed, devices) -> np.ndarray:
    """A baseline's ``(F, n)`` answers (the projections: ``_predict_value``)."""
    if method not in METHODS:
        raise ConfigError(f"unknown method {method!r}; use one of {METHODS}")
    # the baselines run per chain too, on each chain's own landmarks and bones
    sp = model.projector
    lay = sp.layout
    out = np.zeros((len(h), lay.n), np.float32)
    base_key = jax.random.PRNGKey(seed)
    for c in range(lay.n_chains):
        p = sp.chain(c)
        x = np.ascontiguousarray(h[:, list(lay.inputs[c])])
        n = len(lay.outputs[c])
        if method == "nearest_landmark":
            pred = _batched(functools.partial(_nearest_landmark_jit, p), x, n)
        elif method == "knn_average":
            pred = _batched(functools.partial(_knn_average_jit, p, n_l=n_l), x, n)
        else:  # global_elm
            elm = fit_global_elm(p, base_key if c == 0 else jax.random.fold_in(base_key, c))
            pred = np.clip(_batched(elm, x, n), np.asarray(p.lower), np.asarray(p.upper))
        out[:, list(lay.outputs[c])] = pred
    return out


# --------------------------------------------------------------------------------- metrics

# ``frame_errors`` and ``describe`` live in ``jaxproj.eval.metrics`` and are re-exported here
# (imported above), so ``evaluate.frame_errors`` / ``evaluate.describe`` keep working.


def mean_squared_jerk(motions: np.ndarray, lengths: np.ndarray, fps: float = FPS) -> float:
    """Mean squared third difference (rad/s^3)^2 over all joints and valid time steps.

    Args:
      motions: ``(S, T, n)`` padded motions.
      lengths: ``(S,)``.
    """
    total, count = 0.0, 0
    for x, n in zip(motions, lengths, strict=True):
        if n >= 4:
            j = np.diff(np.asarray(x[:n], np.float64), n=3, axis=0) * fps**3
            total += float(np.sum(j**2))
            count += j.size
    return total / max(count, 1)


def _finish_batch(
    q: jax.Array,
    valid: jax.Array,
    lengths: jax.Array,
    gains: jax.Array | None,
    robot: Robot,
    smoother: str = "offline",
):
    """``pipeline.finish`` (``standing="first"``) vmapped over padded motions ``(S, T, n)``."""
    per_motion = 0 if gains is not None and gains.ndim == 3 else None  # (S, T, 3): per motion
    one = functools.partial(pipeline.finish, standing="first", robot=robot, smoother=smoother)
    return jax.vmap(one, in_axes=(0, 0, 0, per_motion))(q, valid, lengths, gains)


_finish_batch = jit(_finish_batch, static_argnames=("robot", "smoother"))


def padded_valid(data: EvalData) -> np.ndarray:
    """``(S, T_max)`` bool: each motion's frame validity, padding false (``_per_motion``'s
    layout)."""
    lengths = np.diff(data.offsets)
    valid = np.zeros((len(lengths), int(lengths.max())), bool)
    for s, n in enumerate(lengths):
        valid[s, :n] = data.valid[data.offsets[s] : data.offsets[s + 1]]
    return valid


def _per_motion(
    data: EvalData,
    per_frame: np.ndarray,
    gains: jax.Array | None = None,
    *,
    robot: Robot,
    smoother: str = "offline",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(V, n)`` answers of the valid frames -> ``(filled, scored, lengths)``: ``(S, T_max, n)``
    motions filled (``pipeline.finish``; no valid frame: standing), the same smoothed and
    clipped with ``gains`` (``smoothing.frame_gains`` of settings of kind ``smoother``;
    ``None``: ``filled``), ``(S,)`` lengths. Frames past a motion's length are padding."""
    n_seq = len(data.names)
    lengths = np.diff(data.offsets)
    t_max = int(lengths.max())
    full = np.zeros((len(data.valid), per_frame.shape[1]), np.float32)
    full[data.valid] = per_frame
    out = np.zeros((n_seq, t_max, per_frame.shape[1]), np.float32)
    for s in range(n_seq):
        a, b = data.offsets[s], data.offsets[s + 1]
        out[s, : b - a] = full[a:b]
    valid = padded_valid(data)
    # one padded call (padding frames are invalid, so they never feed a real frame)
    filled, scored = _finish_batch(
        jnp.asarray(out), jnp.asarray(valid), jnp.asarray(lengths, jnp.int32), gains,
        robot=robot, smoother=smoother,
    )  # fmt: skip
    return np.asarray(filled), np.asarray(scored), lengths


def _accel_bound(config: feasible.FeasibleConfig, robot: Robot) -> float | list[float]:
    """The acceleration bound the filter applied to ``robot`` (rad/s^2): one number where it
    is the same on every joint, else the ``(n_joints,)`` list."""
    limits = config.accel_limits(robot)
    return float(limits[0]) if np.all(limits == limits[0]) else limits.tolist()


def _motion_times(data: EvalData, t_max: int) -> np.ndarray:
    """``(S, T_max)`` seconds of each motion's frames; padding continues at the last step."""
    lengths = np.diff(data.offsets)
    times = (
        data.times
        if data.times is not None
        else np.concatenate([np.arange(n, dtype=np.float64) / FPS for n in lengths])
    )
    out = np.zeros((len(lengths), t_max))
    for s, n in enumerate(lengths):
        t = times[data.offsets[s] : data.offsets[s + 1]]
        step = t[-1] - t[-2] if n > 1 else 1.0 / FPS
        out[s, :n] = t
        out[s, n:] = t[-1] + step * np.arange(1, t_max - n + 1)
    return out


def _limits_summary(
    motions: np.ndarray, times: np.ndarray, lengths: np.ndarray, robot: Robot
) -> dict:
    """``feasible.feasibility_report`` of each motion ``(S, T, n_joints)``, pooled."""
    reps = [feasible.feasibility_report(m[:n], t[:n], robot=robot)
            for m, t, n in zip(motions, times, lengths, strict=True)]  # fmt: skip
    return {
        "motions": len(reps),
        "motions_over_speed_limit": sum(r["speed_violation_frames"] > 0 for r in reps),
        "speed_violation_frames": sum(r["speed_violation_frames"] for r in reps),
        "steps_over_30deg": sum(r["steps_over_30deg"] for r in reps),
        "max_speed_ratio": max(r["max_speed_ratio"] for r in reps),
        "max_step_deg": max(r["max_step_deg"] for r in reps),
        "accel_violation_frames": sum(r["accel_violation_frames"] for r in reps),
        "max_accel": max(r["max_accel"] for r in reps),
        "limit_violation_frames": sum(r["limit_violation_frames"] for r in reps),
    }


def feasibility_block(
    data: EvalData,
    motions: np.ndarray,
    truth_v: np.ndarray,
    truth_points: np.ndarray,
    config: feasible.FeasibleConfig = feasible.DEFAULT_FEASIBLE,
    *,
    times: np.ndarray | None = None,
    before_points: np.ndarray | None = None,
    robot: Robot | str | None = None,
) -> dict:
    """What the feasibility filter buys and costs for one method's motions.

    Args:
      data: the evaluated frames.
      motions: ``(S, T_max, n_driven)`` driven-joint motions as scored (filled, maybe
        smoothed).
      truth_v, truth_points: IK truth of the valid frames and its ``metrics.arm_points``.
      config: the filter's settings.
      times: ``(S, T_max)`` seconds of the motions' frames (``None``: computed from ``data``).
      before_points: ``metrics.arm_points`` of the motions' valid frames when already computed.
      robot: the robot (``None``: ``data.robot``, the one the truth is for).

    Returns:
      ``{"before": limits, "after": limits, "after_errors": {M_max, M_avg, task_space, ...}
      (``metrics.summarize_errors`` of the filtered motion against the IK), "vs_unfiltered":
      {joint_deg, hand_cm}}`` — limits from ``feasibility_report`` pooled over the motions
      (speed-limit frames, max step, acceleration, joint limits); ``vs_unfiltered`` describes the
      per-frame mean joint change (deg) and the wrist displacement (cm, both arms pooled) of
      the filtered motion against the unfiltered one, valid frames.
    """
    spec = get(data.robot if robot is None else robot)
    lengths = np.diff(data.offsets)
    t_max = motions.shape[1]
    times = _motion_times(data, t_max) if times is None else times
    full = np.tile(spec.standing, motions.shape[:2] + (1,)).astype(np.float32)
    full[..., spec.driven_index] = motions
    safe = feasible.make_feasible(full, times, lengths, config, robot=spec)
    flat = lambda m: np.concatenate([m[s, :n] for s, n in enumerate(lengths)])[data.valid]  # noqa: E731
    before, after = flat(motions), flat(safe[..., spec.driven_index])
    after_points = metrics.arm_points(after, robot=spec)
    if before_points is None:
        before_points = metrics.arm_points(before, robot=spec)
    hand = metrics.arm_errors(after_points, before_points).hand
    return {
        "config": dataclasses.asdict(config) | {"accel": _accel_bound(config, spec)},
        "before": _limits_summary(full, times, lengths, spec),
        "after": _limits_summary(safe, times, lengths, spec),
        "after_errors": summarize_errors(
            after, truth_v, truth_points=truth_points, pred_points=after_points, robot=spec
        ),
        "vs_unfiltered": {
            "joint_deg": describe(np.degrees(np.abs(after - before)).mean(axis=1)),
            "hand_cm": describe(100.0 * hand.reshape(-1)),
        },
    }


def evaluate(
    model: Model,
    data: EvalData,
    methods: Sequence[str] = METHODS,
    *,
    n_l: int = 10,
    n_m: int = 10,
    smoothing: Smoothing | None = OFFLINE_SMOOTHING,
    full: FullConfig | None = None,
    devices: Sequence[jax.Device] | None = None,
    progress: bool = False,
    feasibility: feasible.FeasibleConfig | None = feasible.DEFAULT_FEASIBLE,
) -> dict:
    """Evaluate ``methods`` on ``data``; returns the JSON-ready report (see README).

    ``devices`` is passed to ``engine.project`` (``None``: the default device); ``progress``
    shows a bar over the methods on a terminal. ``feasibility``: also run each method's scored
    motions (and the IK's) through ``jaxproj.motion.feasible`` and report before / after
    (``feasibility_block``) under ``"feasibility"``; ``None`` skips it. The robot is the
    model's (``Model.robot``); ``data`` must hold its IK truth (``prepare(..., robot=)``).

    Raises:
      ConfigError: ``data`` was prepared for another robot than the model's.
    """
    spec = model.robot
    if data.robot != spec.name:
        raise ConfigError(f"data were prepared for robot {data.robot!r}, the model is for "
                          f"{spec.name!r}: prepare(..., robot={spec.name!r})")  # fmt: skip
    lengths = np.diff(data.offsets)
    h = data.descriptors[data.valid]
    truth_v = data.truth[data.valid]
    truth_motion, _, _ = _per_motion(data, truth_v, robot=spec)
    valid_motion = padded_valid(data)
    seq_of_frame = np.repeat(np.arange(len(data.names)), lengths)[data.valid]
    truth_points = metrics.arm_points(truth_v, robot=spec)  # one FK of the truth serves all
    out: dict = {
        "landmarks": model.n_landmarks,  # the smallest chain's: the largest L and M
        "landmarks_per_chain": dict(model.landmarks),
        "L": n_l,
        "M": n_m,
        "frames": int(len(data.valid)),
        "valid_frames": int(data.valid.sum()),
        "sequences": len(data.names),
        "driven_joints": list(spec.driven_joints),
        "smoothing": None
        if smoothing is None
        else {"kind": smoothing.kind, **dataclasses.asdict(smoothing)},
        "devices": [str(d) for d in (devices or jax.devices()[:1])],
        "summary": {},
        "unsmoothed": {},
        "smoothness": {},
        "per_action": {},
        "per_sequence": {n: {} for n in data.names},
        "feasibility": {},
        "confidence": {},
        "wall_s": {},
    }
    t_max = int(lengths.max())
    motion_times = _motion_times(data, t_max)  # the smoother uses them only for timed data
    gains = None
    if smoothing is not None:
        gains = frame_gains(smoothing, motion_times if data.timed else None, lengths)
    predictions: dict[str, np.ndarray] = {}
    for method in bar(methods, "evaluating methods", enabled=progress):
        t0 = time.perf_counter()
        pred, value = _predict_value(model, method, h, n_l=n_l, n_m=n_m, full=full,
                                     devices=devices)  # fmt: skip
        wall = time.perf_counter() - t0
        out["wall_s"][method] = wall
        out["wall_s"][f"{method}_us_per_frame"] = 1e6 * wall / max(len(h), 1)
        m_max, m_avg = frame_errors(pred, truth_v)
        if value is not None:  # the projection's own error against its confidence
            conf = np.asarray(confidence(jnp.asarray(value), model.confidence_scale))
            out["confidence"][method] = metrics.confidence_deciles(conf, m_max, m_avg)
        scored_points = metrics.arm_points(pred, robot=spec)  # the scored FK, used twice below
        out["unsmoothed"][method] = summarize_errors(
            pred, truth_v, truth_points=truth_points, pred_points=scored_points, robot=spec
        )
        kind = "offline" if smoothing is None else smoothing.kind
        motions, sm, _ = _per_motion(data, pred, gains, robot=spec, smoother=kind)
        jerk_raw = mean_squared_jerk(motions, lengths)
        lag_raw = metrics.lag_frames(motions, truth_motion, lengths, valid_motion)
        if smoothing is not None:
            flat = np.concatenate([sm[s, :n] for s, n in enumerate(lengths)])[data.valid]
            m_max, m_avg = frame_errors(flat, truth_v)
            scored_points = metrics.arm_points(flat, robot=spec)
            out["summary"][method] = summarize_errors(
                flat, truth_v, truth_points=truth_points, pred_points=scored_points, robot=spec
            )
            out["smoothness"][method] = {
                "jerk_raw": jerk_raw,
                "jerk_smoothed": mean_squared_jerk(sm, lengths),
                "lag_frames_raw": lag_raw,
                "lag_frames_smoothed": metrics.lag_frames(sm, truth_motion, lengths, valid_motion),
            }
            motions = sm
        else:
            out["summary"][method] = copy.deepcopy(out["unsmoothed"][method])
            out["smoothness"][method] = {"jerk_raw": jerk_raw, "lag_frames_raw": lag_raw}
        predictions[method] = np.concatenate([motions[s, :n] for s, n in enumerate(lengths)])
        if feasibility is not None:
            out["feasibility"][method] = feasibility_block(
                data, motions, truth_v, truth_points, feasibility,
                times=motion_times, before_points=scored_points, robot=spec,
            )  # fmt: skip
        for a in np.unique(data.actions):
            sel = data.actions[seq_of_frame] == a
            label = ACTION_NAMES[a - 1] if 1 <= a <= len(ACTION_NAMES) else "unknown action"
            out["per_action"].setdefault(f"a{a:02d} {label}", {})[method] = {
                "M_max": describe(m_max[sel]),
                "M_avg": describe(m_avg[sel]),
            }
        for s, name in enumerate(data.names):
            sel = seq_of_frame == s
            out["per_sequence"][name][method] = {
                "M_max_mean": float(m_max[sel].mean()) if sel.any() else 0.0,
                "M_avg_mean": float(m_avg[sel].mean()) if sel.any() else 0.0,
            }
    out["smoothness"]["ik"] = {"jerk_raw": mean_squared_jerk(truth_motion, lengths)}
    if feasibility is not None:  # the IK truth itself, as a trajectory for the robot
        out["feasibility"]["ik"] = feasibility_block(
            data, truth_motion, truth_v, truth_points, feasibility,
            times=motion_times, before_points=truth_points, robot=spec,
        )  # fmt: skip
    out["_predictions"] = predictions  # (F, n) per method, dropped before writing JSON
    out["_truth"] = np.concatenate([truth_motion[s, :n] for s, n in enumerate(lengths)])
    return out
