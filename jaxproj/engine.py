"""The projection engine's public API: build, project, save, load.

``build`` turns training recordings into a ``Model``: mean-shift landmarks of the human
descriptors (``jaxproj.landmarks``), their robot poses by the analytic IK (``jaxproj.ik``), and
the forward / backward ELM kernel banks (``jaxproj.kernels``). ``project`` maps human
descriptors to robot poses with the relaxed or the full objective (``jaxproj.projection``) in
fixed-size jitted batches. ``save`` / ``load`` round-trip a model through one ``.npz`` file.

Shapes: human descriptors ``(B, m)`` (``m = 15`` for the default upper-body bones), robot poses
``(B, n)`` over ``robot.DRIVEN_JOINTS`` (``n = 10``), radians.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxproj import ik, landmarks, robot
from jaxproj._jit import jit
from jaxproj.exceptions import ConfigError, InputError
from jaxproj.kernels import ELMBank, train_bank
from jaxproj.projection import (
    FullConfig,
    Projector,
    make_projector,
    project_full_one,
    project_relaxed_one,
)

FORMAT = "jaxproj-projector"
FORMAT_VERSION = 2
"""2: kernel output weights stored ``(n_kernels, d_out, hidden)`` (1 had ``hidden, d_out``)."""


@dataclass(frozen=True)
class BuildConfig:
    """How a model is built. Exactly one of ``landmarks`` / ``bandwidth`` sets the landmarks.

    Validated when constructed (``ConfigError`` with what to change).

    Attributes:
      landmarks: target landmark count (the mean-shift bandwidth is found by bisection).
      bandwidth: mean-shift bandwidth, used as is.
      bones: descriptor bone subset (``skeleton.descriptor``); the IK needs ``"upper"`` bones.
      mirror: mirror imitation (human left drives robot right).
      k: training neighbours per ELM kernel (the landmark itself included), capped at the
        number of landmarks ``K``: a small set (the paper's 86) trains every kernel on all its
        landmarks. The ``k`` used is the kernel banks' ``k``.
      hidden: hidden units per kernel (``>= k``).
      lam: ridge regulariser of the ELMs.
      input_scale: standard deviation of the random hidden weights.
      seed: PRNG seed of the random hidden layers.
    """

    landmarks: int | None = 1644
    bandwidth: float | None = None
    bones: str = "upper"
    mirror: bool = False
    k: int = 96
    hidden: int = 96
    lam: float = 1e-3
    input_scale: float = 0.5
    seed: int = 0

    def __post_init__(self) -> None:
        if (self.landmarks is None) == (self.bandwidth is None):
            raise ConfigError("give exactly one of landmarks (a count) or bandwidth")
        if self.landmarks is not None and self.landmarks < 2:
            raise ConfigError(f"landmarks={self.landmarks} must be >= 2")
        if self.bandwidth is not None and not self.bandwidth > 0:
            raise ConfigError(f"bandwidth={self.bandwidth} must be > 0")
        if self.hidden < self.k:
            raise ConfigError(f"hidden={self.hidden} must be >= k={self.k}")


@dataclass(frozen=True)
class Model:
    """A built projector plus what it was built from.

    Attributes:
      projector: landmarks and kernel banks (a pytree, see ``projection.Projector``).
      config: the ``BuildConfig``.
      bandwidth: the mean-shift bandwidth used.
      counts: ``(K,)`` training frames per landmark.
      n_train: training frames (valid descriptors) the landmarks came from.
    """

    projector: Projector
    config: BuildConfig
    bandwidth: float
    counts: np.ndarray
    n_train: int

    @property
    def n_landmarks(self) -> int:
        """Number of landmark pairs ``K``."""
        return self.projector.n_landmarks


def build_from_landmarks(
    human: np.ndarray, robot_poses: np.ndarray, config: BuildConfig
) -> Projector:
    """Train both kernel banks on given landmark pairs ``(K, m)``, ``(K, n)``.

    Each kernel trains on ``min(config.k, K)`` neighbours (see ``BuildConfig.k``).
    """
    key = jax.random.PRNGKey(config.seed)
    k_fwd, k_bwd = jax.random.split(key)
    if config.k < 2 or len(human) < 2:
        raise ConfigError(f"k={config.k} and the number of landmarks={len(human)} must be >= 2")
    k = min(config.k, len(human))
    opts = dict(k=k, hidden=config.hidden, lam=config.lam, input_scale=config.input_scale)
    forward = train_bank(human, robot_poses, k_fwd, **opts)
    backward = train_bank(robot_poses, human, k_bwd, **opts)
    return make_projector(human, robot_poses, forward, backward)


def build(descriptors: np.ndarray, config: BuildConfig = BuildConfig(), **mean_shift) -> Model:
    """Build a model from training descriptors.

    Args:
      descriptors: ``(N, m)`` human descriptors of VALID training frames.
      config: landmarks and kernel settings.
      **mean_shift: extra options passed to ``landmarks.build_landmarks``.

    Returns:
      The ``Model``.
    """
    d = np.asarray(descriptors, np.float32)
    if d.ndim != 2 or len(d) < 2 or not np.isfinite(d).all():
        raise ConfigError(f"descriptors must be finite (N >= 2, m), got shape {d.shape}")
    lm = landmarks.build_landmarks(
        d, target=config.landmarks, bandwidth=config.bandwidth, bones=config.bones, **mean_shift
    )
    projector = build_from_landmarks(lm.human, lm.robot, config)
    return Model(projector, config, float(lm.bandwidth), np.asarray(lm.counts), int(lm.n_frames))


Objective = Literal["relaxed", "full"]


def sub_batch(p: Projector, objective: str, n_l: int, n_m: int, batch: int) -> int:
    """Queries vmapped together inside one jitted batch (the rest is a ``lax.map`` loop).

    Each query gathers ``L * M`` backward kernels (``L * M * hidden * (m + 2)`` floats); a
    sub-batch is sized so that this stays within a cache-sized (CPU, 16 MiB) or memory-sized
    (accelerators, 4 GiB) budget, and divides ``batch``.
    """
    per_query = 4 * n_l * n_m * p.backward.hidden * (p.backward.d_out + 2)
    if objective == "full":
        per_query *= 3  # values, gradients and optimiser state
    budget = 16 * 2**20 if jax.default_backend() == "cpu" else 4 * 2**30
    sub = 1
    while sub * 2 * per_query <= budget and sub * 2 <= batch:
        sub *= 2
    while batch % sub:
        sub //= 2
    return max(sub, 1)


def project_batch(
    p: Projector,
    h: jax.Array,
    objective: str = "relaxed",
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig = FullConfig(),  # noqa: B008 - frozen, hashable
) -> tuple[jax.Array, jax.Array]:
    """The traceable core of ``project`` for one batch (call it inside a jitted function).

    ``(B, m)`` queries -> ``((B, n) angles, (B,) value)``: the one-query projection vmapped over
    sub-batches of ``sub_batch(...)`` queries, the sub-batches looped with ``lax.map``.
    """
    sub = sub_batch(p, objective, n_l, n_m, h.shape[0])

    def one(x: jax.Array) -> tuple[jax.Array, jax.Array]:
        if objective == "relaxed":
            return project_relaxed_one(p, x, n_l, n_m)
        r, f, _ = project_full_one(p, x, n_l, n_m, full)
        return r, f

    if sub >= h.shape[0]:
        return jax.vmap(one)(h)
    return jax.lax.map(one, h, batch_size=sub)


project_chunk = jit(project_batch, static_argnames=("objective", "n_l", "n_m", "full"))
"""Jitted ``project_batch``: ``(projector, (B, m), objective, L, M, full) -> ((B, n), (B,))``."""


def check_neighbours(model_or_projector: Model | Projector, n_l: int, n_m: int) -> None:
    """Raise ``ConfigError`` unless ``1 <= L, M <= K``."""
    p = model_or_projector
    if isinstance(p, Model):
        p = p.projector
    for name, v in (("L", n_l), ("M", n_m)):
        if not 1 <= v <= p.n_landmarks:
            raise ConfigError(f"{name}={v} must lie in [1, number of landmarks={p.n_landmarks}]")


def _placement(devices: Sequence[jax.Device] | None, batch_size: int) -> Any:
    """Where each padded batch goes: the default device, one device, or split along the query
    axis over several (``batch_size`` must then be a multiple of their number)."""
    if devices is None:
        return None
    devices = list(devices)
    if not devices:
        raise ConfigError("devices must name at least one JAX device (or be None)")
    if len(devices) == 1:
        return devices[0]
    if batch_size % len(devices):
        raise ConfigError(f"batch_size={batch_size} must be a multiple of {len(devices)} devices")
    mesh = Mesh(np.array(devices), ("batch",))
    return NamedSharding(mesh, PartitionSpec("batch"))


def project(
    model: Model | Projector,
    descriptors: np.ndarray,
    objective: Objective = "relaxed",
    *,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    batch_size: int = 4096,
    devices: Sequence[jax.Device] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Project human descriptors to robot poses.

    Batches are padded to ``batch_size`` so every call compiles once per
    ``(objective, L, M, full, batch_size)``.

    Args:
      model: a ``Model`` or a bare ``Projector``.
      descriptors: ``(B, m)`` human descriptors (valid frames).
      objective: ``"relaxed"`` or ``"full"``.
      n_l, n_m: ``L`` human and ``M`` robot neighbours.
      full: settings of the full objective (default ``FullConfig()``).
      batch_size: queries per jitted call (``>= 1``).
      devices: where to run: ``None`` (default) the default device; one device; or several,
        over which each batch is split along the query axis (``batch_size`` a multiple of
        their number).

    Returns:
      ``(angles, value)``: ``(B, n)`` float32 driven-joint angles (rad, within limits) and
      ``(B,)`` the objective's value (relaxed: back-projected deviation; full: ``f(w*)``).
    """
    p = model.projector if isinstance(model, Model) else model
    full = FullConfig() if full is None else full
    if objective not in ("relaxed", "full"):
        raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
    check_neighbours(p, n_l, n_m)
    h = np.asarray(descriptors, np.float32)
    if h.ndim != 2 or h.shape[1] != p.human.shape[1]:
        raise ConfigError(f"descriptors must be (B, {p.human.shape[1]}), got {h.shape}")
    if batch_size < 1:
        raise ConfigError(f"batch_size={batch_size} must be >= 1")
    place = _placement(devices, batch_size)
    outs, vals = [], []
    for start in range(0, len(h), batch_size):
        chunk = h[start : start + batch_size]
        pad = batch_size - len(chunk)
        if pad:
            chunk = np.concatenate([chunk, np.repeat(_padding_query(p), pad, axis=0)], axis=0)
        chunk = jnp.asarray(chunk) if place is None else jax.device_put(chunk, place)
        r, v = project_chunk(p, chunk, objective=objective, n_l=n_l, n_m=n_m, full=full)
        outs.append(np.asarray(r)[: batch_size - pad])
        vals.append(np.asarray(v)[: batch_size - pad])
    if not outs:
        return np.zeros((0, p.robot.shape[1]), np.float32), np.zeros((0,), np.float32)
    return np.concatenate(outs), np.concatenate(vals)


def _padding_query(p: Projector) -> np.ndarray:
    """``(1, m)``: a harmless padding query (the first landmark)."""
    return np.asarray(p.human[:1])


# ---------------------------------------------------------------------------- save / load

_BANK_FIELDS = ("w", "inv_scale", "bias", "out", "offset", "neighbours")


def save(model: Model, path: str | Path) -> None:
    """Write a model to one ``.npz``: every array, the config and a format version."""
    p = model.projector
    arrays: dict[str, np.ndarray] = {
        "human": np.asarray(p.human),
        "robot": np.asarray(p.robot),
        "counts": np.asarray(model.counts),
    }
    for name, bank in (("forward", p.forward), ("backward", p.backward)):
        for f in _BANK_FIELDS:
            arrays[f"{name}.{f}"] = np.asarray(getattr(bank, f))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": asdict(model.config),
        "bandwidth": model.bandwidth,
        "n_train": model.n_train,
        "driven_joints": list(robot.DRIVEN_JOINTS),
        "ik": {
            "head_pitch_neutral": ik.HEAD_PITCH_NEUTRAL,
            "elbow_yaw_neutral": ik.ELBOW_YAW_NEUTRAL,
        },
    }
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)
    except OSError as e:
        raise InputError(path, f"cannot write model: {e.strerror or e}") from None


def load(path: str | Path) -> Model:
    """Read a model written by ``save``; ``InputError`` on a missing, corrupt or foreign file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "model file not found")
    try:
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as e:
        raise InputError(path, f"not a readable model file ({type(e).__name__}: {e})") from None
    if "meta" not in data:
        raise InputError(path, "not a jaxproj model (no 'meta' entry)")
    try:
        meta = json.loads(str(data["meta"]))
    except json.JSONDecodeError:
        raise InputError(path, "corrupt model metadata") from None
    if meta.get("format") != FORMAT:
        raise InputError(path, f"not a jaxproj model (format {meta.get('format')!r})")
    if meta.get("format_version") != FORMAT_VERSION:
        raise InputError(
            path,
            f"model format version {meta.get('format_version')} is not supported "
            f"(this jaxproj reads version {FORMAT_VERSION}); rebuild it with `jaxproj build`",
        )
    try:
        config = BuildConfig(**meta["config"])
        banks = {}
        for name in ("forward", "backward"):
            a = {f: data[f"{name}.{f}"] for f in _BANK_FIELDS}
            banks[name] = ELMBank(
                **{f: jnp.asarray(v) for f, v in a.items()},
                n_kernels=int(a["out"].shape[0]),
                hidden=int(a["out"].shape[2]),
                d_in=int(a["w"].shape[1]),
                d_out=int(a["out"].shape[1]),
                k=int(a["neighbours"].shape[1]),
            )
        projector = make_projector(
            data["human"], data["robot"], banks["forward"], banks["backward"]
        )
    except (KeyError, TypeError, IndexError, ValueError) as e:
        raise InputError(path, f"incomplete or inconsistent model file ({e})") from None
    k = projector.n_landmarks
    if data["robot"].shape != (k, len(robot.DRIVEN_JOINTS)) or banks["forward"].n_kernels != k:
        raise InputError(path, "inconsistent array shapes in model file")
    return Model(projector, config, float(meta["bandwidth"]), data["counts"], int(meta["n_train"]))
