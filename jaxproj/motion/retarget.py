"""Whole-motion retargeting: skeleton positions -> robot joint trajectories, in one jitted call.

``retarget`` takes a recording's ``(T, 20, 3)`` joint positions and a mapping — the analytic IK
(``model=None``) or a projector ``Model`` with its objective — and runs, inside ONE compiled
function (``jaxproj.motion.pipeline.motion``, the one pipeline): descriptor -> per-frame mapping
-> fill invalid frames -> smoothing -> clip to the joint limits -> the robot's full
``(T, n_joints)`` configuration. The robot is the model's (``Model.robot``) or, for the IK,
``robot=`` (``None``: the default robot). A recording's length is padded to a bucket
(``_bucket``) so recordings of similar length share one compilation. Options are checked here,
in Python, before tracing.

Invalid frames (lost tracking, non-finite values, degenerate bones, and glitches of one or two
frames: a bone the robot reads that turns more than 60 deg into them and back out,
``pipeline.glitch_frames``; a limb the tracker lost: a bone the robot reads at under half or
over twice its median length, ``pipeline.lost_frames``) are kept and filled by a documented
rule, so a motion never dies halfway and never contains NaN:

* an invalid frame holds the last valid frame's angles (unsmoothed output, and the paper's
  smoother's input); the default offline smoother instead skips its value and bridges the gap
  from the valid frames on both sides;
* leading invalid frames take the first valid frame's angles (trailing ones the last's);
* a motion with no valid frame at all is refused: ``NoValidFrameError`` (a typed
  ``InputError``, ``jaxproj.errors``) saying how many frames failed which check; such a
  recording is a wrong file or a wrong unit, not a motion. (The pipeline's own rule, the
  standing posture throughout, still holds inside a batch: ``jaxproj.eval.evaluate``.)

A motion with only a few valid frames is still retargeted: ``RetargetResult.valid_share`` says
how many, and ``jaxproj retarget`` warns below ``MIN_VALID_SHARE`` (half the frames).

Smoothing then runs over the driven joints: by default the zero-lag offline smoother
(``jaxproj.motion.offline``, an RTS smoother of a constant-velocity model: the whole motion is
known here, so it need not lag), or the paper's causal double exponential smoother
(``jaxproj.motion.smoothing``, ``smoothing=PAPER_SMOOTHING``), with each frame's own time step;
the result is clipped to the joint limits (a smoother can overshoot them). With ``feasible``
(off by default here; on by default for what ``jaxproj retarget`` writes for the robot) the
motion then goes through ``jaxproj.motion.feasible``: joint limits, speed limits and an
acceleration bound; for a robot with ``Robot.separate`` a last pass pushes apart the
self-contacts the filter brought back (``pipeline.playable_full``), so what is written has
none; its small moves can go past the filter's bounds on a few frames (the command line's
report is of what is written).

The head: the neck bone's forward tilt that means "head level" depends on the capture set-up
(the Kinect's Head joint sits differently under another camera height and pitch), so by default
each recording is levelled first: its own median neck tilt over its valid frames is taken as
its neutral and moved to the reference the IK reads as HeadPitch 0 (``neck_neutral=``;
``pipeline.level``), for the IK and the projection alike. The output then stays inside the
robot's coupled ranges (``Robot.coupled_limits``; the default robot's head anti-collision
envelope), as every path through the pipeline's clip does.

Time: ``times`` (seconds per frame, e.g. ``Recording.times``) drive the smoother's gains and the
feasibility filter; without them, frames are ``1 / smoothing.rate`` (15 fps) apart.

Many motions: ``retarget_many`` runs ``retarget``'s checks and last stages per motion around
packed compiled calls (``pipeline.motions``), one per length bucket and batch size.

Size: over 500 lines: ``retarget`` and ``retarget_many`` share their halves (``_plan``, the
checks and the padded arrays; ``_result``, the filter and the last separation), which belong
with the two functions that call them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj._internal import executables
from jaxproj._internal.buckets import (
    MIN_ROWS,
    bucket,
    call_bucketed,
    fine_bucket,
    packed_calls,
)
from jaxproj._internal.jit import jit
from jaxproj._internal.shards import host_shards, on_devices
from jaxproj.errors import ConfigError, JaxprojError, NoValidFrameError
from jaxproj.human import skeletons
from jaxproj.human.skeleton import MIN_BONE_LENGTH, NECK_TILT_REFERENCE
from jaxproj.human.skeletons import SkeletonLike
from jaxproj.io.readers import MAX_DURATION_S, MIN_STEP_S
from jaxproj.motion import pipeline
from jaxproj.motion.feasible import FeasibleConfig, make_feasible
from jaxproj.motion.offline import OFFLINE_SMOOTHING
from jaxproj.motion.pipeline import fill_invalid  # noqa: F401 - re-exported (its old home)
from jaxproj.motion.smoothing import Smoothing, frame_gains, smoother_kind
from jaxproj.projection.api import Model, check_neighbours
from jaxproj.projection.confidence import DEVIATION_SCALE, LOW_CONFIDENCE, rescale
from jaxproj.projection.config import FullConfig
from jaxproj.robots import Robot, get, identity

Method = Literal["ik", "relaxed", "full"]
METHODS: tuple[str, ...] = ("ik", "relaxed", "full")

MIN_VALID_SHARE = 0.5
"""``jaxproj retarget`` warns (stderr, exit 0, the motion written) when fewer than this share
of a recording's frames are valid: the rest only hold or bridge the valid poses around them.
No valid frame at all is an error (``NoValidFrameError``)."""


@dataclass(frozen=True)
class RetargetResult:
    """A retargeted motion.

    Attributes:
      angles: ``(T, n_joints)`` float32 radians in the robot's ``joint_names`` order.
      valid: ``(T,)`` bool, false where the input frame was invalid (its angles were filled).
      times: ``(T,)`` float64 seconds of the frames (as given, or ``t / smoothing.rate``).
      unfiltered: ``(T, n_joints)`` float32 angles before the feasibility filter when ``retarget``
        ran it (``feasible=``), else ``None`` (``angles`` are then the unfiltered ones).
      confidence: ``(T,)`` float32 in ``[0, 1]``, each frame's ``projection.confidence`` (from
        the projection's least back-projection deviation; 1 for the IK, 0 where invalid);
        ``projection.confidence.LOW_CONFIDENCE`` is the cut-off below which a tenth of the
        frames of held-out training people fall with ``method="relaxed"`` (the one cut-off,
        calibrated on the relaxed deviation: ``"full"`` reads its own, lower value against it,
        so it flags fewer frames). ``None`` only when built by hand.
    """

    angles: np.ndarray
    valid: np.ndarray
    times: np.ndarray
    unfiltered: np.ndarray | None = None
    confidence: np.ndarray | None = None

    @property
    def low_confidence_share(self) -> float:
        """Share of the frames with ``confidence < LOW_CONFIDENCE`` (invalid ones included)."""
        if self.confidence is None or len(self.confidence) == 0:
            return 0.0
        return float(np.mean(self.confidence < LOW_CONFIDENCE))

    @property
    def low_confidence_valid_share(self) -> float:
        """Share of the VALID frames with ``confidence < LOW_CONFIDENCE``: the number to set
        against the tenth of held-out training people's frames the cut-off was calibrated on
        (``method="relaxed"``); 0 without confidence or valid frames."""
        if self.confidence is None or not self.valid.any():
            return 0.0
        return float(np.mean(self.confidence[self.valid] < LOW_CONFIDENCE))

    @property
    def valid_share(self) -> float:
        """Share of the frames that are valid (``jaxproj retarget`` warns below
        ``MIN_VALID_SHARE``)."""
        return float(np.mean(self.valid)) if len(self.valid) else 0.0


def _bucket(t: int, coarse: bool = False) -> int:
    """Padded length of a ``t``-frame motion: the least of ``2^k``, ``1.25 * 2^k``, ``1.5 *
    2^k``, ``1.75 * 2^k`` frames that holds it, at least 64 (``buckets.fine_bucket``: every
    padded frame is mapped, and a frame of a bundled robot's generic IK costs ~15 ms on
    a 2-core CPU); ``coarse``: the next power of two, at least 64 (``retarget_many``'s
    packing on an accelerator, where a program costs more than its padded frames)."""
    return bucket(t, MIN_ROWS) if coarse else fine_bucket(t, MIN_ROWS)


_playable_jit = jit(pipeline.playable_full, static_argnames=("robot",))
_playable_many_jit = jit(pipeline.playable_many, static_argnames=("robot",))


def separate_motion(angles: np.ndarray, robot: Robot) -> np.ndarray:
    """``retarget``'s last stage on the host: one motion's ``(T, n_joints)`` angles made
    playable in time order (``pipeline.playable_full``), compiled once per row bucket (the
    padding rows come after the motion's: the pass is causal, they change nothing)."""
    key = identity(robot)

    def fn(x: np.ndarray) -> Any:
        return executables.call(
            _playable_jit, (x,), static={"robot": robot}, name="playable", identity=key
        )

    return np.asarray(call_bucketed(fn, angles, 1, sizes=fine_bucket))


def separate_many(angles: Sequence[np.ndarray], robot: Robot) -> list[np.ndarray]:
    """``separate_motion`` of several motions (``(T_i, n_joints)`` each). On an accelerator,
    stacks of motions of one padded length in one program each (``pipeline.playable_many``,
    packed as ``retarget_many``'s coarse calls, ``buckets.packed_calls``: the motions it
    retargeted meet the programs its own last separation compiled; each motion padded with
    its last frame, after it: a causal pass); on a CPU, one motion at a time, as
    ``retarget_many`` separates there."""
    if jax.default_backend() == "cpu" or len(angles) == 1:
        return [separate_motion(q, robot) for q in angles]
    out: list[np.ndarray] = [np.zeros(0)] * len(angles)
    for rows, members, count in packed_calls([len(q) for q in angles], coarse=True,
                                             frames=PACK_FRAMES_COARSE):  # fmt: skip
        stack = [np.concatenate([angles[i], np.repeat(angles[i][-1:], rows - len(angles[i]),
                                 axis=0)]) for i in members]  # fmt: skip
        x = np.stack(stack + [stack[-1]] * (count - len(stack))).astype(np.float32)
        got = np.asarray(
            executables.call(
                _playable_many_jit,
                (x,),
                static={"robot": robot},
                name="playable_many",
                identity=identity(robot),
            )
        )
        for j, i in enumerate(members):
            out[i] = got[j, : len(angles[i])]
    return out


_motion_jit = jit(
    pipeline.motion,
    static_argnames=(
        "method",
        "n_l",
        "n_m",
        "full",
        "bones",
        "mirror",
        "smoother",
        "robot",
        "neck",
        "shards",
        "level_legs",
    ),
)


def retarget(
    positions: np.ndarray,
    valid: np.ndarray | None = None,
    *,
    model: Model | None = None,
    method: Method | None = None,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    smoothing: Smoothing | None = OFFLINE_SMOOTHING,
    times: np.ndarray | None = None,
    feasible: FeasibleConfig | None = None,
    robot: Robot | str | None = None,
    neck_neutral: float | Literal["recording"] | None = "recording",
    level_legs: bool = True,
    skeleton: SkeletonLike = "kinect_v1",
) -> RetargetResult:
    """Retarget one motion (one compiled call: descriptor -> mapping -> fill -> smooth -> clip;
    then, with ``feasible``, ``feasible.make_feasible``). In a process with several CPU devices
    (the command line's: one per core) the IK's frames are split over them
    (``jaxproj._internal.shards``), with the same answers.

    Args:
      positions: ``(T, 20, 3)`` joint positions, Kinect SDK order.
      valid: optional ``(T,)`` bool from the reader; combined with the descriptor's own check.
      model: a projector ``Model`` for the learned methods; ``None`` for the analytic IK.
      method: ``"ik"`` (default without a model), ``"relaxed"`` (default with one) or ``"full"``.
      n_l, n_m: ``L`` and ``M`` of the projection.
      full: settings of the full objective (default ``FullConfig()``).
      bones, mirror: descriptor options for the IK; a model fixes its own (its config's).
      smoothing: the zero-lag offline smoother (``offline.OfflineSmoothing``, default
        ``OFFLINE_SMOOTHING``), the paper's causal one (``smoothing.PAPER_SMOOTHING``: it lags),
        or ``None`` for no smoothing.
      times: ``(T,)`` seconds of the frames, strictly increasing (``Recording.times``);
        ``None``: frames ``1 / smoothing.rate`` apart (15 fps by default).
      feasible: make the output robot-feasible (``jaxproj.motion.feasible``), or ``None`` (default).
      robot: the robot (a ``Robot`` or a registered name) of the IK method; ``None``: the
        model's robot (``Model.robot``), else the default robot.
      neck_neutral: the recording's neutral neck tilt (the tilt that becomes head pitch 0):
        ``"recording"`` (default), the median neck tilt ``atan2(n_x, n_z)`` of its own valid
        frames; a number, that tilt in rad (e.g. measured on a calibration pose of the same
        set-up); ``None``, no levelling (``skeleton.NECK_TILT_REFERENCE``, MSR Action3D's
        median, for every recording). See ``pipeline.level`` and ``skeleton.level_neck``.
      level_legs: for descriptors with legs, turn every bone so that the recording's median
        shin hangs straight below the trunk (``skeleton.level_body``'s first step; default):
        what a fixed base needs; ``False`` keeps the person's own body frame, for a whole-body
        motion (``jaxproj.motion.whole_body``; ``jaxproj retarget --root world``).
      skeleton: the skeleton the positions were recorded in (``Recording.skeleton``; they are
        laid out as Kinect v1 whatever it is): every bone the robot's correspondence reads
        (``Robot.ik_bones``) must be one it defines, checked before anything is traced.

    Returns:
      ``RetargetResult`` with ``(T, n_joints)`` angles, ``(T,)`` validity, ``(T,)`` times and
      ``(T,)`` confidence.

    Raises:
      ConfigError: bad shapes, a learned method without a model, a ``robot`` other than the
        model's, an unknown robot, a skeleton without a bone the robot reads (named), bad
        ``L`` / ``M``, times not
        increasing by at least ``readers.MIN_STEP_S`` per frame or spanning more than
        ``readers.MAX_DURATION_S``.
      NoValidFrameError: no frame is valid (``valid`` false, non-finite values or a
        degenerate skeleton in every frame; ``no_valid_frame_problem`` words it). Checked
        before anything is traced where ``valid`` or the values alone rule every frame out.
    """
    plan = _plan(positions, valid, model=model, method=method, n_l=n_l, n_m=n_m, full=full,
                 bones=bones, mirror=mirror, smoothing=smoothing, times=times, robot=robot,
                 neck_neutral=neck_neutral, level_legs=level_legs, skeleton=skeleton)  # fmt: skip
    angles, ok_out, conf = executables.call(
        _motion_jit,
        (plan.p, plan.pos, plan.ok, np.int32(plan.t), plan.gains),
        {"neck_neutral": np.float32(plan.neutral)},
        plan.static,
        name="retarget",
        # a projector's arrays are arguments, its layout (static) in the tree's words
        identity=identity(plan.spec),
    )
    return _result(plan, np.asarray(angles), np.asarray(ok_out), np.asarray(conf), feasible)


@dataclass
class _Plan:
    """One motion checked and padded for the compiled pipeline (``retarget``'s first half)."""

    p: Any  # the projector, or None for the IK
    pos: np.ndarray  # (size, 20, 3) padded positions
    ok: np.ndarray  # (size,) bool, padding false
    t: int  # the true length
    ok_in: np.ndarray  # (t,) the given validity
    finite: np.ndarray  # (t,) every coordinate finite
    stamps: np.ndarray  # (t,) s
    gains: np.ndarray  # (3,) or (size, 3)
    neutral: float
    static: dict[str, Any]
    spec: Robot
    model: Model | None


def _plan(
    positions: np.ndarray,
    valid: np.ndarray | None,
    *,
    model: Model | None,
    method: Method | None,
    n_l: int,
    n_m: int,
    full: FullConfig | None,
    bones: str | tuple[str, ...],
    mirror: bool,
    smoothing: Smoothing | None,
    times: np.ndarray | None,
    robot: Robot | str | None,
    neck_neutral: float | Literal["recording"] | None,
    level_legs: bool,
    skeleton: SkeletonLike,
    coarse: bool = False,
) -> _Plan:
    """``retarget``'s checks, in its words, and the padded arrays of its compiled call."""
    positions = np.asarray(positions, dtype=np.float32)
    if positions.ndim != 3 or positions.shape[1:] != (20, 3) or positions.shape[0] < 1:
        raise ConfigError(f"positions must be (T >= 1, 20, 3), got {positions.shape}")
    t = positions.shape[0]
    ok_in = np.ones(t, bool) if valid is None else np.asarray(valid, dtype=bool)
    if ok_in.shape != (t,):
        raise ConfigError(f"valid must be ({t},), got {ok_in.shape}")
    method = method or ("ik" if model is None else "relaxed")
    if method not in METHODS:
        raise ConfigError(f"method must be one of {METHODS}, got {method!r}")
    spec = get(robot)
    if model is not None:
        if robot is not None and spec is not model.robot:
            raise ConfigError(f"robot {spec.name!r} differs from the model's robot "
                              f"{model.robot.name!r}: leave robot=None with a model")  # fmt: skip
        spec = model.robot
    check_skeleton(skeleton, spec)
    p = None
    if method != "ik":
        if model is None:
            raise ConfigError(f"method {method!r} needs a projector model (see `jaxproj build`)")
        check_neighbours(model, n_l, n_m)
        p = model.projector
        bones, mirror = model.config.bones, model.config.mirror
    else:
        spec.check_bones(bones)  # ConfigError for a subset the IK cannot use
    params = smoothing or OFFLINE_SMOOTHING
    kind = smoother_kind(params)  # ConfigError for anything but either smoother's settings
    if times is None:
        stamps = np.arange(t, dtype=np.float64) / params.rate
    else:
        stamps = np.asarray(times, np.float64)
        if stamps.shape != (t,) or not np.isfinite(stamps).all():
            raise ConfigError(f"times must be ({t},) finite seconds, got shape {stamps.shape}")
        if (np.diff(stamps) <= 0).any():
            i = int(np.argmax(np.diff(stamps) <= 0)) + 1
            raise ConfigError(f"times must increase strictly (frame {i}: {stamps[i]:g} s after "
                              f"{stamps[i - 1]:g} s)")  # fmt: skip
        if (np.diff(stamps) < MIN_STEP_S).any() or stamps[-1] - stamps[0] > MAX_DURATION_S:
            raise ConfigError(
                f"times must step by at least {MIN_STEP_S:g} s and span at most "
                f"{MAX_DURATION_S:g} s (got steps from {np.diff(stamps).min():g} s, span "
                f"{stamps[-1] - stamps[0]:g} s)"
            )
    if isinstance(neck_neutral, str):
        if neck_neutral != "recording":
            raise ConfigError(f"neck_neutral must be 'recording', a number (rad) or None, "
                              f"got {neck_neutral!r}")  # fmt: skip
        neck, neutral = "recording", NECK_TILT_REFERENCE
    elif neck_neutral is None:
        neck, neutral = "off", NECK_TILT_REFERENCE
    else:
        neutral = float(neck_neutral)
        if not math.isfinite(neutral) or abs(neutral) > math.pi:
            raise ConfigError(f"neck_neutral must be a finite angle in [-pi, pi] rad, "
                              f"got {neck_neutral!r}")  # fmt: skip
        neck = "given"
    finite = np.isfinite(positions).all(axis=(1, 2))
    if not (ok_in & finite).any():  # nothing to map: refuse before tracing
        raise NoValidFrameError("positions", no_valid_frame_problem(ok_in, finite), t)
    size = _bucket(t, coarse)
    pos = np.concatenate([positions, np.repeat(positions[-1:], size - t, axis=0)])
    ok = np.concatenate([ok_in, np.zeros(size - t, bool)])
    padded = np.concatenate([stamps, np.repeat(stamps[-1:], size - t)])
    gains = frame_gains(params, None if times is None else padded, t)
    static = dict(
        method=method,
        n_l=n_l,
        n_m=n_m,
        full=full or FullConfig(),
        bones=bones,
        mirror=mirror,
        smoother=None if smoothing is None else kind,
        robot=spec,
        neck=neck,
        shards=host_shards() if method == "ik" else 1,
        level_legs=bool(level_legs),
    )
    return _Plan(p, pos, ok, t, ok_in, finite, stamps, np.asarray(gains), neutral, static, spec,
                 model)  # fmt: skip


def _result(
    plan: _Plan,
    angles_padded: np.ndarray,
    ok_out: np.ndarray,
    conf: np.ndarray,
    feasible: FeasibleConfig | None,
    filtered: np.ndarray | None = None,
    separated: np.ndarray | None = None,
) -> RetargetResult:
    """``retarget``'s second half: the compiled call's padded answers cut to the motion, the
    feasibility filter (``filtered``: its answer for the cut angles, already computed) and the
    last separation (``separated``: its answer for ``filtered``, already computed)."""
    t, spec, model, stamps = plan.t, plan.spec, plan.model, plan.stamps
    ok_t = np.asarray(ok_out)[:t]
    if not ok_t.any():  # every usable frame failed the descriptor's own check
        raise NoValidFrameError("positions", no_valid_frame_problem(plan.ok_in, plan.finite), t)
    angles = np.asarray(angles_padded)[:t]
    unfiltered = None
    if feasible is not None:
        unfiltered = angles
        if filtered is None:
            filtered = make_feasible(angles, stamps, config=feasible, robot=spec)
        angles = filtered
        if separated is not None:
            angles = separated
        elif spec.separate is not None:
            # the filter moves joints, and a contact can come back: pushed apart again, last,
            # frame by frame in time order (the rows padded at the end: a causal pass)
            angles = separate_motion(angles, spec)
    if model is not None:  # the compiled call used the robot's scale: the model's own instead
        scale = spec.deviation_scale or DEVIATION_SCALE
        conf = np.asarray(rescale(jnp.asarray(conf), scale, model.confidence_scale))
    conf_t = np.asarray(conf, np.float32)[:t]
    return RetargetResult(angles, ok_t, stamps, unfiltered, conf_t)


Packing = Literal["auto", "fine", "coarse"]
PACKINGS: tuple[str, ...] = ("auto", "fine", "coarse")
"""``retarget_many``'s ``packing`` values."""

PACK_FRAMES = 32768
"""``retarget_many``: padded frames in one compiled call at most (the motions of one length
bucket packed together; a longer motion alone), fine packing."""

PACK_FRAMES_COARSE = 131072
"""The same for coarse packing (an accelerator): a call's passes in time order cost nearly the
same for a hundred rows or a thousand on a GPU (a 64-frame G1 call on an H200: 6.4 s for 128
rows, 9.4 s for 1,024), so a bucket's motions go in as few calls as memory allows
(the 10,000 tiled files of ``benchmarks/batch_cli.py``: 8 calls instead of 22, counted
by length bucket)."""

_motions_jit = jit(
    pipeline.motions,
    static_argnames=("method", "n_l", "n_m", "full", "bones", "mirror", "smoother", "robot",
                     "neck", "shards", "level_legs"),
)  # fmt: skip


def retarget_many(
    positions: Sequence[np.ndarray],
    valid: Sequence[np.ndarray | None] | None = None,
    times: Sequence[np.ndarray | None] | None = None,
    skeleton: Sequence[SkeletonLike] | None = None,
    *,
    model: Model | None = None,
    method: Method | None = None,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    bones: str | tuple[str, ...] = "upper",
    mirror: bool = False,
    smoothing: Smoothing | None = OFFLINE_SMOOTHING,
    feasible: FeasibleConfig | None = None,
    robot: Robot | str | None = None,
    neck_neutral: float | Literal["recording"] | None = "recording",
    level_legs: bool = True,
    pack_frames: int | None = None,
    packing: Packing = "auto",
    devices: Sequence[jax.Device] | None = None,
) -> list[RetargetResult | JaxprojError]:
    """``retarget`` of many motions with one setting, packed: the motions whose padded
    lengths are equal (``retarget``'s length buckets) run together, up to ``pack_frames``
    padded frames a call (``pipeline.motions``: one device program maps all their frames at
    once), the number of motions in a call rounded up to a power of two (the last one
    repeated) so that a few programs serve any batch. A dataset of thousands of short clips
    then costs a few compiled calls instead of one per clip.

    How finely (``packing``): ``"fine"`` pads as little as it can (``retarget``'s quarter-octave
    length buckets; each call's motions rounded up to a power of two), for a CPU, where every
    padded frame of a generic IK costs ~15 ms on 2 cores; ``"coarse"`` compiles as few programs
    as it can (power-of-two length buckets, every call of a bucket the same number of rows, and
    a call's last separation in one program, ``pipeline.playable_many``), for an accelerator,
    where a padded frame is nearly free and a program is not (one G1 retarget on an H200: 58 s
    with an empty cache, 27 s of it XLA compiling, 2026-11-30); ``"auto"``: coarse where JAX's
    default backend is not the CPU. Either way each motion's answer is the same up to float
    rounding.

    Each motion's result is ``retarget``'s for it alone (its checks, its errors, its feasibility
    filter and last separation), except for float rounding: a differently shaped batch can
    round the mapping's sums differently (measured: ``tests/motion/test_retarget_many.py``).

    Args:
      positions: the motions' ``(T_i, 20, 3)`` joint positions.
      valid, times, skeleton: per motion (``None``: ``retarget``'s default for each), the same
        length as ``positions``.
      pack_frames: padded frames per compiled call at most (>= 1; ``None``: ``PACK_FRAMES``,
        or ``PACK_FRAMES_COARSE`` for coarse packing).
      packing: ``"auto"``, ``"fine"`` or ``"coarse"`` (above).
      devices: the calls spread over these devices, a host thread each, the longest calls
        first (``jaxproj._internal.shards.on_devices``; each answer the same as on one
        device); ``None``: JAX's default device.
      the rest: ``retarget``'s, one value for every motion.

    Returns:
      One entry per motion, in order: its ``RetargetResult``, or the ``JaxprojError`` that
      ``retarget`` raises for it (a bad shape, no valid frame, ...); the others go on.

    Raises:
      ConfigError: per-motion sequences of another length than ``positions``; ``pack_frames``
        < 1; another ``packing``. (A setting that ``retarget`` refuses is each motion's error.)
    """
    n = len(positions)
    for name, seq in (("valid", valid), ("times", times), ("skeleton", skeleton)):
        if seq is not None and len(seq) != n:
            raise ConfigError(f"retarget_many: {name} has {len(seq)} entries for {n} motions")
    if pack_frames is not None and pack_frames < 1:
        raise ConfigError(f"retarget_many: pack_frames must be >= 1, got {pack_frames}")
    if packing not in PACKINGS:
        raise ConfigError(f"retarget_many: packing must be one of {PACKINGS}, got {packing!r}")
    coarse = packing == "coarse" or (packing == "auto" and jax.default_backend() != "cpu")
    out: list[Any] = [None] * n
    groups: dict[tuple, list[tuple[int, _Plan]]] = {}
    for i in range(n):
        try:
            plan = _plan(
                positions[i], None if valid is None else valid[i], model=model, method=method,
                n_l=n_l, n_m=n_m, full=full, bones=bones, mirror=mirror, smoothing=smoothing,
                times=None if times is None else times[i], robot=robot,
                neck_neutral=neck_neutral, level_legs=level_legs,
                skeleton=skeletons.DEFAULT if skeleton is None else skeleton[i], coarse=coarse,
            )  # fmt: skip
        except JaxprojError as e:
            out[i] = e
            continue
        groups.setdefault(plan.gains.shape, []).append((i, plan))
    calls: list[tuple[list[tuple[int, _Plan]], list[_Plan]]] = []
    frames = pack_frames or (PACK_FRAMES_COARSE if coarse else PACK_FRAMES)
    for members in groups.values():  # per gains' shape, stacks of one padded length (_bucket's)
        for _, which, count in packed_calls([pl.t for _, pl in members], coarse=coarse,
                                            frames=frames):  # fmt: skip
            chunk = [members[j] for j in which]
            plans = [pl for _, pl in chunk]
            calls.append((chunk, plans + [plans[-1]] * (count - len(plans))))

    def run(call: tuple[list[tuple[int, _Plan]], list[_Plan]]) -> None:
        chunk, plans = call
        first = plans[0]
        angles, ok_out, conf = executables.call(
            _motions_jit,
            (
                first.p,
                np.stack([pl.pos for pl in plans]),
                np.stack([pl.ok for pl in plans]),
                np.array([pl.t for pl in plans], np.int32),
                np.stack([pl.gains for pl in plans]),
            ),
            {"neck_neutral": np.float32(first.neutral)},
            first.static,
            name="retarget_many",
            identity=identity(first.spec),
        )
        angles, ok_out, conf = np.asarray(angles), np.asarray(ok_out), np.asarray(conf)
        filtered = _feasible_rows(plans, angles, feasible)
        separated = _separated_rows(plans, filtered) if coarse else [None] * len(plans)
        for j, (i, plan) in enumerate(chunk):
            try:
                out[i] = _result(plan, angles[j], ok_out[j], conf[j], feasible, filtered[j],
                                 separated[j])  # fmt: skip
            except JaxprojError as e:
                out[i] = e

    # the longest calls first (their passes in time order set a batch's wall time on a GPU)
    calls.sort(key=lambda c: -c[1][0].pos.shape[0] * len(c[1]))
    on_devices(run, calls, devices)
    return out


def _feasible_rows(
    plans: list[_Plan], angles: np.ndarray, feasible: FeasibleConfig | None
) -> list[np.ndarray | None]:
    """The feasibility filter of a packed call's motions, in one batch (``make_feasible``'s):
    ``(rows, size, n_joints)`` padded answers -> each motion's filtered ``(t, n_joints)``
    angles, or ``None`` each where there is no filter or the batch is refused (each motion is
    then filtered alone, and refused in its own words)."""
    if feasible is None:
        return [None] * len(plans)
    size = angles.shape[1]
    times = np.stack([np.concatenate([pl.stamps, pl.stamps[-1] + np.arange(1, size - pl.t + 1)])
                      for pl in plans])  # fmt: skip
    lengths = np.array([pl.t for pl in plans])
    try:
        out = make_feasible(angles, times, lengths, config=feasible, robot=plans[0].spec)
    except ConfigError:
        return [None] * len(plans)
    return [out[j, : pl.t] for j, pl in enumerate(plans)]


def _separated_rows(plans: list[_Plan], filtered: list[np.ndarray | None]) -> list[Any]:
    """The last separation of a packed call's filtered motions (``_feasible_rows``' answers),
    in one program (``pipeline.playable_many``; the padded frames repeat each motion's last,
    after it: a causal pass) -> each motion's ``(t, n_joints)`` angles, or ``None`` each where
    the robot has no ``separate`` or a motion was not filtered in the batch."""
    spec = plans[0].spec
    if spec.separate is None or any(f is None for f in filtered):
        return [None] * len(plans)
    size = plans[0].pos.shape[0]
    x = np.stack([np.concatenate([f, np.repeat(f[-1:], size - len(f), axis=0)])
                  for f in filtered if f is not None])  # fmt: skip
    out = np.asarray(
        executables.call(
            _playable_many_jit,
            (x.astype(np.float32),),
            static={"robot": spec},
            name="playable_many",
            identity=identity(spec),
        )  # fmt: skip
    )
    return [out[j, : pl.t] for j, pl in enumerate(plans)]


def check_skeleton(skeleton: SkeletonLike, robot: Robot) -> None:
    """``ConfigError`` unless ``skeleton`` defines every bone ``robot``'s correspondence reads.

    A recording's ``positions`` are Kinect v1's 20 joints whatever it recorded; the bones its
    skeleton lacks were filled (``skeletons.to_kinect_v1``) and must not drive a joint.
    """
    s = skeletons.get(skeleton)
    lacking = s.missing(robot.ik_bones)
    if lacking:
        raise ConfigError(
            f"the recording's skeleton {s.name!r} has no {', '.join(lacking)} bone(s), which "
            f"robot {robot.name!r} reads ({', '.join(robot.ik_bones)}): record a skeleton "
            "that has them, or use a robot that does not read them"
        )


def no_valid_frame_problem(
    marked: np.ndarray, finite: np.ndarray, why_marked: str | None = None
) -> str:
    """Why no frame of a motion is valid, in words: how many frames hold non-finite values,
    how many others ``valid`` marked (a reader marks lost tracking and non-finite values, and
    zeroes them), and how many the descriptor found degenerate.

    Args:
      marked: ``(T,)`` bool, the ``valid`` given to ``retarget`` (the reader's).
      finite: ``(T,)`` bool, whether every coordinate of the frame is finite.
      why_marked: why the reader marked frames, where it says (``Recording.invalid_reason``);
        ``None``: "lost tracking or non-finite values".
    """
    t = len(marked)
    n_nonfinite = int((~finite).sum())
    n_lost = int((~marked & finite).sum())
    n_degenerate = t - n_nonfinite - n_lost
    parts = []
    if n_nonfinite:
        parts.append(f"{n_nonfinite} with non-finite coordinates (NaN / inf)")
    if n_lost:
        why = why_marked or "lost tracking or non-finite values"
        parts.append(f"{n_lost} marked invalid ({why})")
    if n_degenerate:
        parts.append(
            f"{n_degenerate} with a degenerate skeleton (collapsed joints, bones shorter than "
            f"{1000 * MIN_BONE_LENGTH:g} mm or coordinates too large: check the units)"
        )
    return f"no valid frame among {t}: {', '.join(parts)}"
