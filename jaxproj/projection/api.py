"""The projection engine's public API: build, project, save, load.

(Over 500 lines on purpose: the model's config, build, batched projection and file format are one
unit that changes together; the per-query algorithm lives in ``projection``.)

``build`` turns training recordings into a ``Model``: mean-shift landmarks of the human
descriptors (``jaxproj.projection.landmarks``), their robot poses by the analytic IK (``jaxproj.robots.nao_h25.ik``), and
the forward / backward ELM kernel banks (``jaxproj.projection.elm``). ``project`` maps human
descriptors to robot poses with the relaxed or the full objective (``jaxproj.projection.objectives``) in
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
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from jaxproj._internal.atomic import atomic_write
from jaxproj._internal.jit import jit
from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.projection import landmarks
from jaxproj.projection.elm import ELMBank, train_bank
from jaxproj.projection.objectives import (
    ChainLayout,
    FullConfig,
    Projector,
    StackedProjector,
    make_projector,
    project_full_one,
    project_relaxed_rows,
    project_stacked_one,
    stack_projectors,
)
from jaxproj.robots.nao_h25 import ik, robot

FORMAT = "jaxproj-projector"
FORMAT_VERSION = 3
"""3: one projector per kinematic chain (``chain<c>.*`` arrays, the layout in the metadata);
2: kernel output weights stored ``(n_kernels, d_out, hidden)``; 1: ``(hidden, d_out)``."""

HEAD_BANDWIDTH = 0.01125
"""Mean-shift bandwidth of the head chain when ``BuildConfig.landmarks`` is one number (that
number is then the count of each arm chain, and of the whole-body chain). The neck direction of
a Kinect skeleton varies little (its 3 numbers lie on a small cap of the sphere), so a count
target would bisect the bandwidth over many mean-shift runs; one run at this bandwidth (tuned
leave-one-training-subject-out, ``benchmarks/TUNING.md``) gives ~800 head landmarks on subjects
1,3,5,7,9."""

DEFAULTS: dict[str, dict[str, object]] = {
    "upper": dict(
        bandwidth=(HEAD_BANDWIDTH, 0.01875, 0.01875), k=96, hidden=192, lam=1e-4, input_scale=0.5
    ),
    "whole": dict(landmarks=1644, k=96, hidden=96, lam=1e-3, input_scale=0.5),
}
"""What a ``BuildConfig`` setting left at ``None`` means, per chain set. ``"upper"``: tuned per
chain on the training subjects only (leave-one-training-subject-out over 1,3,5,7,9; the grid,
fold means and the rule are in ``benchmarks/TUNING.md``): mean-shift bandwidths (head, left arm,
right arm; the right arm takes the left arm's tuned value), 192 hidden units, ridge 1e-4.
``"whole"``: the paper's 1644 landmarks and the whole-body engine's earlier defaults, so that
its answers stay those measured before chains existed."""

PerChain = tuple  # a tuple with one value per chain, in chain order


def _per_chain(value: object, c: int, n: int, name: str) -> object:
    if isinstance(value, (tuple, list)):
        if len(value) != n:
            raise ConfigError(f"{name} has {len(value)} values for {n} chains")
        return value[c]
    return value


@dataclass(frozen=True)
class ChainConfig:
    """The settings of one chain's projector (``BuildConfig.chain_config``)."""

    landmarks: int | None
    bandwidth: float | None
    k: int
    hidden: int
    lam: float
    input_scale: float
    seed: int


@dataclass(frozen=True)
class BuildConfig:
    """How a model is built: which chains, and per chain its landmarks and kernels.

    Validated when constructed (``ConfigError`` with what to change). Every per-chain setting
    is one value for all chains or a tuple with one value per chain (in ``ik.CHAIN_SETS[chains]``
    order: head, left_arm, right_arm).

    Attributes:
      chains: ``"upper"`` (default): one projector per kinematic chain (``ik.CHAINS``: head,
        left arm, right arm), searched and trained in the chain's own bones; ``"whole"``: one
        projector over the whole descriptor, the paper's formulation.
      landmarks: target landmark count (the mean-shift bandwidth is found by bisection). One
        number sets each arm chain (and the whole-body chain); the head then uses
        ``HEAD_BANDWIDTH``. A per-chain tuple may hold ``None`` where ``bandwidth`` gives it.
        With neither ``landmarks`` nor ``bandwidth`` given, ``DEFAULTS[chains]`` decides.
      bandwidth: mean-shift bandwidth, used as is (per chain where ``landmarks`` is ``None``).
      bones: descriptor bone subset (``skeleton.descriptor``); the IK needs ``"upper"`` bones.
      mirror: mirror imitation (human left drives robot right).
      k: training neighbours per ELM kernel (the landmark itself included), capped at the
        chain's number of landmarks ``K``: a small set (the paper's 86) trains every kernel on all
        its landmarks. The ``k`` used is in the model's layout.
      hidden: hidden units per kernel (``>= k``).
      lam: ridge regulariser of the ELMs.
      input_scale: standard deviation of the random hidden weights.
      (``k``, ``hidden``, ``lam``, ``input_scale`` left at ``None``: ``DEFAULTS[chains]``.)
      seed: PRNG seed of the random hidden layers (chain 0 uses ``PRNGKey(seed)``, chain ``c``
        ``fold_in(PRNGKey(seed), c)``).
    """

    landmarks: int | PerChain | None = None
    bandwidth: float | PerChain | None = None
    chains: str = "upper"
    bones: str = "upper"
    mirror: bool = False
    k: int | PerChain | None = None
    hidden: int | PerChain | None = None
    lam: float | PerChain | None = None
    input_scale: float | PerChain | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("landmarks", "bandwidth", "k", "hidden", "lam", "input_scale"):
            if isinstance(getattr(self, name), list):  # from JSON
                object.__setattr__(self, name, tuple(getattr(self, name)))
        chains = ik.chain_set(self.chains)
        if not isinstance(self.bones, str):
            object.__setattr__(self, "bones", tuple(self.bones))
        ik.bone_index(self.bones)  # unknown bone names, or a subset the IK cannot use
        for c in range(len(chains)):
            self.chain_config(c)

    @property
    def chain_names(self) -> tuple[str, ...]:
        """Names of the chains, in order."""
        return tuple(ch.name for ch in ik.chain_set(self.chains))

    def chain_config(self, c: int) -> ChainConfig:
        """Chain ``c``'s settings (validated; ``ConfigError`` says what to change)."""
        chains = ik.chain_set(self.chains)
        n, name = len(chains), chains[c].name

        defaults = DEFAULTS[self.chains]
        sizes_given = self.landmarks is not None or self.bandwidth is not None

        def get(field_name: str) -> object:
            value = getattr(self, field_name)
            if value is None and (field_name not in ("landmarks", "bandwidth") or not sizes_given):
                value = defaults.get(field_name)
            return _per_chain(value, c, n, field_name)

        landmarks, bandwidth = get("landmarks"), get("bandwidth")
        if name == "head" and isinstance(self.landmarks, int) and bandwidth is None:
            landmarks, bandwidth = None, HEAD_BANDWIDTH
        if (landmarks is None) == (bandwidth is None):
            raise ConfigError(f"chain {name}: give exactly one of landmarks (a count) or bandwidth")
        if landmarks is not None and landmarks < 2:
            raise ConfigError(f"chain {name}: landmarks={landmarks} must be >= 2")
        if bandwidth is not None and not bandwidth > 0:
            raise ConfigError(f"chain {name}: bandwidth={bandwidth} must be > 0")
        cfg = ChainConfig(
            landmarks, bandwidth, get("k"), get("hidden"), get("lam"), get("input_scale"), self.seed
        )
        if cfg.k < 2:
            raise ConfigError(f"chain {name}: k={cfg.k} must be >= 2")
        if self.k is not None and landmarks is not None and cfg.k > landmarks:
            raise ConfigError(
                f"chain {name}: k={cfg.k} is larger than its landmark count {landmarks} (a kernel "
                f"trains on at most all landmarks): lower k to <= {landmarks} or raise landmarks"
            )
        if cfg.hidden < cfg.k:
            raise ConfigError(f"chain {name}: hidden={cfg.hidden} must be >= k={cfg.k}")
        if not cfg.lam > 0:
            raise ConfigError(f"chain {name}: lam={cfg.lam} must be > 0")
        if not cfg.input_scale > 0:
            raise ConfigError(f"chain {name}: input_scale={cfg.input_scale} must be > 0")
        return cfg


@dataclass(frozen=True)
class Model:
    """A built projector plus what it was built from.

    Attributes:
      projector: the chains' landmarks and kernel banks (a pytree, see
        ``projection.StackedProjector``; the whole-body model is its one-chain case).
      config: the ``BuildConfig``.
      bandwidth: per chain, the mean-shift bandwidth used.
      counts: per chain, ``(K_c,)`` training frames per landmark.
      n_train: training frames (valid descriptors) the landmarks came from.
    """

    projector: StackedProjector
    config: BuildConfig
    bandwidth: tuple[float, ...]
    counts: tuple[np.ndarray, ...]
    n_train: int

    @property
    def n_landmarks(self) -> int:
        """The smallest chain's landmark count (the largest ``L`` and ``M``)."""
        return self.projector.n_landmarks

    @property
    def landmarks(self) -> dict[str, int]:
        """Landmark count per chain."""
        lay = self.projector.layout
        return dict(zip(lay.names, lay.landmarks, strict=True))


def build_from_landmarks(
    human: np.ndarray,
    robot_poses: np.ndarray,
    config: BuildConfig | ChainConfig,
    *,
    key: jax.Array | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
) -> Projector:
    """Train both kernel banks of one projector on given landmark pairs ``(K, m)``, ``(K, n)``.

    Each kernel trains on ``min(config.k, K)`` neighbours (see ``BuildConfig.k``); a
    ``BuildConfig`` gives its first chain's kernel settings (``chain_config(0)``). ``key``
    defaults to ``PRNGKey(config.seed)``; ``lower`` / ``upper`` ``(n,)`` are the limits of the
    joints the robot landmarks hold (default: all of ``robot.DRIVEN_JOINTS``).
    """
    if isinstance(config, BuildConfig):
        config = config.chain_config(0)
    key = jax.random.PRNGKey(config.seed) if key is None else key
    k_fwd, k_bwd = jax.random.split(key)
    if config.k < 2 or len(human) < 2:
        raise ConfigError(f"k={config.k} and the number of landmarks={len(human)} must be >= 2")
    k = min(config.k, len(human))
    opts = dict(k=k, hidden=config.hidden, lam=config.lam, input_scale=config.input_scale)
    forward = train_bank(human, robot_poses, k_fwd, **opts)
    backward = train_bank(robot_poses, human, k_bwd, **opts)
    return make_projector(human, robot_poses, forward, backward, lower, upper)


def build(descriptors: np.ndarray, config: BuildConfig = BuildConfig(), **mean_shift) -> Model:
    """Build a model from training descriptors: per chain, mean-shift landmarks of the chain's
    bones, their IK, and both kernel banks; then the chains are stacked.

    Args:
      descriptors: ``(N, m)`` human descriptors of VALID training frames.
      config: chains, landmarks and kernel settings.
      **mean_shift: extra options passed to ``landmarks.build_landmarks``.

    Returns:
      The ``Model``.
    """
    d = np.asarray(descriptors, np.float32)
    if d.ndim != 2 or len(d) < 2 or not np.isfinite(d).all():
        raise ConfigError(f"descriptors must be finite (N >= 2, m), got shape {d.shape}")
    chains = ik.chain_set(config.chains)
    whole = len(chains) == 1
    check_training_data(d, config)
    base_key = jax.random.PRNGKey(config.seed)
    projectors, bandwidths, counts = [], [], []
    for c, chain in enumerate(chains):
        cc = config.chain_config(c)
        lm = landmarks.build_landmarks(
            d,
            target=cc.landmarks,
            bandwidth=cc.bandwidth,
            bones=config.bones,
            chain=None if whole else chain,
            **mean_shift,
        )
        joints = list(ik.chain_joints(chain))
        lo = robot.LOWER[robot.DRIVEN_INDEX][joints]
        hi = robot.UPPER[robot.DRIVEN_INDEX][joints]
        key = base_key if c == 0 else jax.random.fold_in(base_key, c)
        projectors.append(build_from_landmarks(lm.human, lm.robot, cc, key=key, lower=lo, upper=hi))
        bandwidths.append(float(lm.bandwidth))
        counts.append(np.asarray(lm.counts))
    stacked = stack_projectors(projectors, layout_of(config, projectors))
    return Model(stacked, config, tuple(bandwidths), tuple(counts), int(len(d)))


def check_training_data(d: np.ndarray, config: BuildConfig) -> None:
    """``ConfigError`` unless ``build`` can build ``config`` from descriptors ``d`` ``(N, m)``:
    the descriptor width of the config's bones, and per chain a landmark target the training
    data can reach (at most its distinct frames). ``build`` calls it before any mean shift."""
    m = 3 * len(resolve_bones(config.bones))
    if d.shape[1] != m:
        raise ConfigError(
            f"descriptors have {d.shape[1]} columns, but bones={config.bones!r} gives {m}"
        )
    chains = ik.chain_set(config.chains)
    for c, chain in enumerate(chains):
        target = config.chain_config(c).landmarks
        if target is None:
            continue
        cols = slice(None) if len(chains) == 1 else list(ik.chain_columns(chain, config.bones))
        distinct = len(np.unique(d[:, cols], axis=0))
        if target > distinct:
            raise ConfigError(
                f"chain {chain.name}: landmarks={target} but the training data has only "
                f"{distinct} distinct valid frames for it: lower the landmark count (--landmarks), "
                "give a bandwidth instead, or train on more recordings / subjects"
            )


def from_landmarks(
    human: np.ndarray, robot_poses: np.ndarray, config: BuildConfig, n_train: int | None = None
) -> Model:
    """A ``Model`` on given landmark pairs (no mean shift): ``(K, m)`` descriptors and their
    ``(K, 10)`` driven-joint poses. Each chain takes its columns of ``human`` and its joints of
    ``robot_poses``, rows that repeat in the chain's columns dropped (first kept); its kernels
    are trained as ``build`` trains them. ``config.landmarks`` / ``bandwidth`` are not used (the
    model records bandwidth 0)."""
    human = np.asarray(human, np.float32)
    robot_poses = np.asarray(robot_poses, np.float32)
    if human.ndim != 2 or robot_poses.shape != (len(human), len(robot.DRIVEN_JOINTS)):
        raise ConfigError(f"landmarks must be (K, m) and (K, 10), got {human.shape}, "
                          f"{robot_poses.shape}")  # fmt: skip
    chains = ik.chain_set(config.chains)
    base_key = jax.random.PRNGKey(config.seed)
    projectors, counts = [], []
    for c, chain in enumerate(chains):
        cols = (
            list(range(human.shape[1]))
            if len(chains) == 1
            else list(ik.chain_columns(chain, config.bones))
        )
        joints = list(ik.chain_joints(chain))
        _, first = np.unique(human[:, cols], axis=0, return_index=True)
        rows = np.sort(first)
        key = base_key if c == 0 else jax.random.fold_in(base_key, c)
        projectors.append(
            build_from_landmarks(
                human[rows][:, cols],
                robot_poses[rows][:, joints],
                config.chain_config(c),
                key=key,
                lower=robot.LOWER[robot.DRIVEN_INDEX][joints],
                upper=robot.UPPER[robot.DRIVEN_INDEX][joints],
            )
        )
        counts.append(np.ones(len(rows), np.int64))
    stacked = stack_projectors(projectors, layout_of(config, projectors))
    n = len(human) if n_train is None else n_train
    return Model(stacked, config, tuple(0.0 for _ in chains), tuple(counts), n)


def layout_of(config: BuildConfig, projectors: Sequence[Projector]) -> ChainLayout:
    """The ``ChainLayout`` of ``config``'s chains holding these per-chain projectors."""
    chains = ik.chain_set(config.chains)
    if len(chains) == 1:  # the whole-body projector reads the whole descriptor
        inputs = (tuple(range(3 * len(resolve_bones(config.bones)))),)
    else:
        inputs = tuple(ik.chain_columns(ch, config.bones) for ch in chains)
    return ChainLayout(
        names=tuple(ch.name for ch in chains),
        inputs=inputs,
        outputs=tuple(ik.chain_joints(ch) for ch in chains),
        landmarks=tuple(p.n_landmarks for p in projectors),
        hidden=tuple(p.forward.hidden for p in projectors),
        k=tuple(p.forward.k for p in projectors),
    )


Objective = Literal["relaxed", "full"]


AnyProjector = Projector | StackedProjector


def sub_batch(p: AnyProjector, objective: str, n_l: int, n_m: int, batch: int) -> int:
    """Queries vmapped together inside one jitted batch (the rest is a ``lax.map`` loop).

    Each query gathers ``L * M`` backward kernels per chain (``L * M * hidden * (m + 2)``
    floats); a sub-batch is sized so that this stays within a cache-sized (CPU, 16 MiB) or
    memory-sized (accelerators, 4 GiB) budget, and divides ``batch``.
    """
    chains = 1
    if isinstance(p, StackedProjector):
        chains, p = p.layout.n_chains, p.stack
    per_query = 4 * chains * n_l * n_m * p.backward.hidden * (p.backward.d_out + 2)
    if objective == "full":
        per_query *= 3  # values, gradients and optimiser state
    budget = 16 * 2**20 if jax.default_backend() == "cpu" else 4 * 2**30
    sub = 1
    while sub * 2 * per_query <= budget and sub * 2 <= batch:
        sub *= 2
    while batch % sub:
        sub //= 2
    return max(sub, 1)


def search_batch(p: AnyProjector, n_l: int, batch: int, sub: int) -> int:
    """Queries per search call of the relaxed projection (a multiple of ``sub``, dividing
    ``batch``).

    On the CPU the searches run XLA's ``TopK`` per row, whose per-call costs want many rows per
    call, while the back-projection wants few queries at a time (``sub``, its gathered kernels
    in cache): the searches take as many queries as keep their ``(L, K)`` distance rows per
    chain (``4 * chains * L * K`` bytes per query) within the same 16 MiB budget, and the
    back-projection loops over them ``sub`` at a time (``project_relaxed_rows``' ``chunk``).
    Measured on the 2-core VM, per-chain model at N = 1644 (K up to 1,725), relaxed
    L = M = 10, batch 4,096: 1.15-1.18x at 64 queries per search call (142 us at 128 against
    138 at 64). The forward kernels then round differently in the last bit, so where two
    candidates' deviations tie to float32 round-off another one can be picked: 0.56 % of
    held-out poses moved by more than 0.001 deg (up to 0.39), the float64 reference siding
    with each batching about equally (``benchmarks/experiments/two_level_ab.py``,
    ``benchmarks/RESULTS.md``). Accelerators search and back-project ``sub`` queries together
    (their fused kernels hold no distance matrix): ``sub`` is returned.
    """
    if jax.default_backend() != "cpu":
        return sub
    if isinstance(p, StackedProjector):
        chains, k = p.layout.n_chains, p.stack.human.shape[1]  # K of the largest chain
    else:
        chains, k = 1, p.n_landmarks
    per_query = 4 * chains * n_l * k
    out = sub
    while out * 2 * per_query <= 16 * 2**20 and out * 2 <= batch and batch % (out * 2) == 0:
        out *= 2
    return out


def project_batch(
    p: AnyProjector,
    h: jax.Array,
    objective: str = "relaxed",
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig = FullConfig(),  # noqa: B008 - frozen, hashable
) -> tuple[jax.Array, jax.Array]:
    """The traceable core of ``project`` for one batch (call it inside a jitted function).

    ``(B, m)`` queries -> ``((B, n) angles, (B,) value)``, in sub-batches of ``sub_batch(...)``
    queries looped with ``lax.map``. Relaxed: ``projection.project_relaxed_rows`` per
    ``search_batch(...)`` queries (one human-landmark search for all of them, one
    robot-landmark search for all their candidates), back-projecting ``sub_batch(...)`` queries
    at a time; full: the one-query projection (of every chain, for a ``StackedProjector``;
    ``projection.project_stacked_one``) vmapped.
    """
    sub = sub_batch(p, objective, n_l, n_m, h.shape[0])
    if objective == "relaxed":  # batched form: one search call per search batch
        outer = search_batch(p, n_l, h.shape[0], sub)

        def rows(x: jax.Array) -> tuple[jax.Array, jax.Array]:
            return project_relaxed_rows(p, x, n_l, n_m, chunk=sub)

        if outer >= h.shape[0]:
            return rows(h)
        r, v = jax.lax.map(rows, h.reshape(-1, outer, h.shape[1]))
        return r.reshape(h.shape[0], -1), v.reshape(-1)

    def one(x: jax.Array) -> tuple[jax.Array, jax.Array]:
        if isinstance(p, StackedProjector):
            return project_stacked_one(p, x, objective, n_l, n_m, full)
        r, f, _ = project_full_one(p, x, n_l, n_m, full)
        return r, f

    if sub >= h.shape[0]:
        return jax.vmap(one)(h)
    return jax.lax.map(one, h, batch_size=sub)


project_chunk = jit(project_batch, static_argnames=("objective", "n_l", "n_m", "full"))
"""Jitted ``project_batch``: ``(projector, (B, m), objective, L, M, full) -> ((B, n), (B,))``."""


def check_neighbours(model_or_projector: Model | AnyProjector, n_l: int, n_m: int) -> None:
    """Raise ``ConfigError`` unless ``1 <= L, M <= K`` (``K``: the smallest chain's count)."""
    p = model_or_projector
    if isinstance(p, Model):
        p = p.projector
    where = ""
    if isinstance(p, StackedProjector) and p.layout.n_chains > 1:
        c = int(np.argmin(p.layout.landmarks))
        where = (
            f" (the {p.layout.names[c]} chain has {p.layout.landmarks[c]}: lower L / M, or "
            "build that chain with more landmarks, e.g. --landmarks H,L,R or a smaller bandwidth)"
        )
    for name, v in (("L", n_l), ("M", n_m)):
        if not 1 <= v <= p.n_landmarks:
            raise ConfigError(
                f"{name}={v} must lie in [1, number of landmarks={p.n_landmarks}]{where}"
            )


def _placement(devices: Sequence[jax.Device] | None, batch_size: int) -> Mesh | jax.Device | None:
    """Where each padded batch goes: the default device (``None``), one device, or a 1-D mesh
    ``("batch",)`` over several (``batch_size`` must then be a multiple of their number)."""
    if devices is None:
        return None
    devices = list(devices)
    if not devices:
        raise ConfigError("devices must name at least one JAX device (or be None)")
    if len(set(devices)) != len(devices):
        raise ConfigError(f"devices lists a device twice: {[str(d) for d in devices]}")
    if len(devices) == 1:
        return devices[0]
    if batch_size % len(devices):
        raise ConfigError(f"batch_size={batch_size} must be a multiple of {len(devices)} devices")
    return Mesh(np.array(devices), ("batch",))


def _sharded_batch(
    p: AnyProjector,
    h: jax.Array,
    *,
    mesh: Mesh,
    objective: str,
    n_l: int,
    n_m: int,
    full: FullConfig,
) -> tuple[jax.Array, jax.Array]:
    """``project_batch`` with the query axis split over ``mesh``: every device runs the whole
    one-device program (its own sub-batch loop) on its shard of the queries, the projector
    replicated; no collective (``shard_map``, see ``project``)."""

    def local(p_local: AnyProjector, h_local: jax.Array) -> tuple[jax.Array, jax.Array]:
        return project_batch(p_local, h_local, objective, n_l, n_m, full)

    spec = PartitionSpec("batch")
    # check_vma=False: the fused k-NN kernel's pallas_call (CUDA) declares plain output shapes,
    # which shard_map's varying-axes check rejects; every output here varies along "batch".
    return jax.shard_map(
        local, mesh=mesh, in_specs=(PartitionSpec(), spec), out_specs=(spec, spec), check_vma=False
    )(p, h)


project_sharded = jit(
    _sharded_batch, static_argnames=("mesh", "objective", "n_l", "n_m", "full")
)
"""Jitted ``_sharded_batch``: ``(projector, (B, m) queries sharded over mesh) -> ((B, n), (B,))``
with ``mesh``, ``objective``, ``n_l``, ``n_m``, ``full`` static."""


def resolve_devices(spec: int | str | Sequence[jax.Device] | None) -> list[jax.Device] | None:
    """Devices from a user's ``--devices`` value: ``None`` / ``1`` -> ``None`` (the default
    device), ``N`` -> the first ``N`` of ``jax.devices()``, ``"all"`` -> every one of them, a
    sequence of devices -> as given.

    Raises:
      ConfigError: ``N`` outside ``1..len(jax.devices())``, or a string other than ``"all"``.
    """
    if spec is None:
        return None
    if isinstance(spec, str):
        if spec.strip().lower() == "all":
            found = jax.devices()
            return found if len(found) > 1 else None
        try:
            spec = int(spec)
        except ValueError:
            raise ConfigError(f"devices must be a number or 'all', got {spec!r}") from None
    if isinstance(spec, int):
        found = jax.devices()
        if not 1 <= spec <= len(found):
            raise ConfigError(
                f"devices={spec}: this machine has {len(found)} JAX device(s) "
                f"({', '.join(str(d) for d in found)}); use 1..{len(found)} or 'all'"
            )
        return found[:spec] if spec > 1 else None
    return list(spec)


DEFAULT_BATCH = {"cpu": 4096, "accelerator": 65536}
"""``project``'s default ``batch_size`` per backend: CPU 4096 (cache-sized sub-batches inside
anyway), GPU / TPU 65536 (enough queries per call to fill the device)."""


def default_batch_size(
    devices: Sequence[jax.Device] | None = None, n_queries: int | None = None
) -> int:
    """``project``'s batch when it is not given: ``DEFAULT_BATCH`` for the platform of
    ``devices`` (``None``: the default backend); for ``n_queries`` fewer than that, the next
    power of two ``>= n_queries`` (at least ``MIN_BATCH``, a multiple of the device count), so
    that a short call is not padded to a whole default batch (64 queries on a CPU: 64x less
    work than 4096)."""
    platform = jax.default_backend() if not devices else list(devices)[0].platform
    default = DEFAULT_BATCH["cpu" if platform == "cpu" else "accelerator"]
    return default if n_queries is None else _fitted_batch(default, n_queries, devices)


MIN_BATCH = 64
"""The smallest batch ``project`` compiles for by default (fewer queries are padded to it)."""


def _fitted_batch(default: int, n: int, devices: Sequence[jax.Device] | None) -> int:
    """``default``, or for fewer queries ``n`` the next power of two ``>= n`` (at least
    ``MIN_BATCH``, a multiple of the device count)."""
    if n >= default:
        return default
    bucket = max(MIN_BATCH, 1 << max(n - 1, 0).bit_length())
    k = len(list(devices)) if devices else 1
    return min(default, -(-bucket // k) * k)


def project(
    model: Model | AnyProjector,
    descriptors: np.ndarray,
    objective: Objective = "relaxed",
    *,
    n_l: int = 10,
    n_m: int = 10,
    full: FullConfig | None = None,
    batch_size: int | None = None,
    devices: Sequence[jax.Device] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Project human descriptors to robot poses.

    The queries go to the device in one transfer, are padded to a multiple of ``batch_size``
    and run as one jitted call per batch, dispatched back to back without waiting (the device
    never waits for the host between batches); the answers come back in one transfer. Every
    call compiles once per ``(objective, L, M, full, batch_size)``.

    Args:
      model: a ``Model``, or a bare ``StackedProjector`` / ``Projector``.
      descriptors: ``(B, m)`` human descriptors (valid frames).
      objective: ``"relaxed"`` or ``"full"``.
      n_l, n_m: ``L`` human and ``M`` robot neighbours.
      full: settings of the full objective (default ``FullConfig()``).
      batch_size: queries per jitted call (``>= 1``); ``None``: ``default_batch_size`` (4096 on
        CPU, 65536 on accelerators), or for fewer queries than that the next power of two
        (at least ``MIN_BATCH``): one compilation per such size.
      devices: where to run: ``None`` (default) the default device; one device; or several
        (``resolve_devices`` turns ``"all"`` or a count into a list): each batch is split
        along the query axis over a 1-D mesh of them with ``shard_map``, the projector
        replicated, and every device runs the one-device program on its shard, with no
        collective (``batch_size`` a multiple of their number; the padding of the last batch
        is cut off the answers).

    Returns:
      ``(angles, value)``: ``(B, n)`` float32 driven-joint angles (rad, within limits) and
      ``(B,)`` the objective's value (relaxed: back-projected deviation; full: ``f(w*)``).
    """
    p = model.projector if isinstance(model, Model) else model
    full = FullConfig() if full is None else full
    if objective not in ("relaxed", "full"):
        raise ConfigError(f"objective must be 'relaxed' or 'full', got {objective!r}")
    check_neighbours(p, n_l, n_m)
    m = p.layout.m if isinstance(p, StackedProjector) else p.human.shape[1]
    h = np.asarray(descriptors, np.float32)
    if h.ndim != 2 or h.shape[1] != m:
        raise ConfigError(f"descriptors must be (B, {m}), got {h.shape}")
    if batch_size is None:
        batch_size = default_batch_size(devices, len(h))
    if batch_size < 1:
        raise ConfigError(f"batch_size={batch_size} must be >= 1")
    place = _placement(devices, batch_size)
    n = p.layout.n if isinstance(p, StackedProjector) else p.robot.shape[1]
    if len(h) == 0:
        return np.zeros((0, n), np.float32), np.zeros((0,), np.float32)
    pad = (-len(h)) % batch_size
    if pad:
        h = np.concatenate([h, np.repeat(_padding_query(p), pad, axis=0)], axis=0)
    kw = {"objective": objective, "n_l": n_l, "n_m": n_m, "full": full}
    cut = len(h) - pad
    n_batches = len(h) // batch_size
    if isinstance(place, Mesh):
        # every batch split over the devices: (n_batches, batch, m) with the batch axis sharded,
        # so each device holds its slice of every batch (one transfer in)
        h3 = h.reshape(n_batches, batch_size, m)
        h_dev = jax.device_put(h3, NamedSharding(place, PartitionSpec(None, "batch")))
        outs = [project_sharded(p, h_dev[i], mesh=place, **kw) for i in range(n_batches)]
    else:
        # one transfer in, one dispatch per batch without a host sync, one transfer out
        h_dev = jax.device_put(h, place)
        outs = [
            project_chunk(p, h_dev[s : s + batch_size], **kw)
            for s in range(0, len(h), batch_size)
        ]
    r = jnp.concatenate([o[0] for o in outs]) if len(outs) > 1 else outs[0][0]
    v = jnp.concatenate([o[1] for o in outs]) if len(outs) > 1 else outs[0][1]
    return np.asarray(r)[:cut], np.asarray(v)[:cut]


def _padding_query(p: AnyProjector) -> np.ndarray:
    """``(1, m)``: a harmless padding query (the first landmark of each chain)."""
    if isinstance(p, StackedProjector):
        q = np.zeros((1, p.layout.m), np.float32)
        for c, cols in enumerate(p.layout.inputs):
            q[0, list(cols)] = np.asarray(p.stack.human[c, 0, : len(cols)])
        return q
    return np.asarray(p.human[:1])


# ---------------------------------------------------------------------------- save / load

_BANK_FIELDS = ("w", "inv_scale", "bias", "out", "offset", "neighbours")
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)

# Array shapes of one chain in a model file: K landmarks, m descriptor columns and n joints of
# the chain (known from the layout), Hf / Hb hidden units and kf / kb neighbours (read).
_ARRAY_SHAPES: dict[str, tuple[str, ...]] = {
    "human": ("K", "m"),
    "robot": ("K", "n"),
    "counts": ("K",),
    "forward.w": ("Hf", "m"),
    "forward.inv_scale": ("K",),
    "forward.bias": ("K", "Hf"),
    "forward.out": ("K", "n", "Hf"),
    "forward.offset": ("K", "n"),
    "forward.neighbours": ("K", "kf"),
    "backward.w": ("Hb", "n"),
    "backward.inv_scale": ("K",),
    "backward.bias": ("K", "Hb"),
    "backward.out": ("K", "m", "Hb"),
    "backward.offset": ("K", "m"),
    "backward.neighbours": ("K", "kb"),
}


def save(model: Model, path: str | Path) -> None:
    """Write a model to one ``.npz``: every chain's arrays (unpadded), the config, the chain
    layout and a format version.

    The file is written under a temporary name beside ``path`` and then renamed
    (``jaxproj._internal.atomic``), so an interrupted or failed save never leaves a half-written model;
    the zip members carry fixed timestamps, so the same model gives a byte-identical file.

    Raises:
      InputError: the file cannot be written.
    """
    sp = model.projector
    lay = sp.layout
    arrays: dict[str, np.ndarray] = {}
    for c in range(lay.n_chains):
        p = sp.chain(c)
        arrays[f"chain{c}.human"] = np.asarray(p.human)
        arrays[f"chain{c}.robot"] = np.asarray(p.robot)
        arrays[f"chain{c}.counts"] = np.asarray(model.counts[c])
        for name, bank in (("forward", p.forward), ("backward", p.backward)):
            for f in _BANK_FIELDS:
                arrays[f"chain{c}.{name}.{f}"] = np.asarray(getattr(bank, f))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": asdict(model.config),
        "chains": {"names": list(lay.names), "inputs": lay.inputs, "outputs": lay.outputs},
        "bandwidth": list(model.bandwidth),
        "n_train": model.n_train,
        "driven_joints": list(robot.DRIVEN_JOINTS),
        "ik": {
            "head_pitch_neutral": ik.HEAD_PITCH_NEUTRAL,
            "elbow_yaw_neutral": ik.ELBOW_YAW_NEUTRAL,
        },
    }
    arrays = {"meta": np.array(json.dumps(meta)), **arrays}
    atomic_write(path, lambda tmp: _write_npz(tmp, arrays))


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """``np.savez`` (uncompressed, no pickles) with fixed zip timestamps: deterministic bytes."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_DATE)
            info.external_attr = 0o644 << 16
            with zf.open(info, "w", force_zip64=True) as fh:
                np.lib.format.write_array(fh, np.asanyarray(value), allow_pickle=False)


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def load(path: str | Path) -> Model:
    """Read a model written by ``save``.

    Raises:
      InputError: naming the file: missing, a directory, not an npz archive, truncated or
        corrupt, not a jaxproj model, another format version (a newer one: upgrade jaxproj), a
        chain layout other than this jaxproj's for the model's configuration, a missing,
        mis-shaped or non-finite array.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a directory, not a model file")
    if not path.is_file():
        raise InputError(path, "model file not found")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
            if head != b"PK\x03\x04":
                what = "an empty file" if not head else "not an npz archive"
                raise InputError(path, f"not a jaxproj model ({what}; see `jaxproj build`)")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
    except InputError:
        raise
    except Exception as e:  # zipfile / zlib / numpy errors of a truncated or corrupt archive
        raise InputError(path, f"not a readable model file ({_one_line(e)})") from None
    meta = _read_meta(path, data)
    try:
        config = BuildConfig(**meta["config"])
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(path, f"invalid model configuration ({_one_line(e)})") from None
    chains = ik.chain_set(config.chains)
    _check_layout(path, meta, config, data)
    try:
        bandwidth = tuple(float(b) for b in meta["bandwidth"])
        n_train = int(meta["n_train"])
        if len(bandwidth) != len(chains):
            raise ValueError(f"{len(bandwidth)} bandwidths for {len(chains)} chains")
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(path, f"corrupt model metadata ({_one_line(e)})") from None
    projectors, counts = [], []
    for c, ch in enumerate(chains):
        a = _chain_arrays(path, data, c, len(_chain_inputs(config, ch)), len(ik.chain_joints(ch)))
        banks = {}
        for name in ("forward", "backward"):
            f = {f: a[f"{name}.{f}"] for f in _BANK_FIELDS}
            banks[name] = ELMBank(
                **{k: jnp.asarray(v) for k, v in f.items()},
                n_kernels=int(f["out"].shape[0]),
                hidden=int(f["out"].shape[2]),
                d_in=int(f["w"].shape[1]),
                d_out=int(f["out"].shape[1]),
                k=int(f["neighbours"].shape[1]),
            )
        joints = list(ik.chain_joints(ch))
        projectors.append(
            make_projector(
                a["human"],
                a["robot"],
                banks["forward"],
                banks["backward"],
                robot.LOWER[robot.DRIVEN_INDEX][joints],
                robot.UPPER[robot.DRIVEN_INDEX][joints],
            )
        )
        counts.append(a["counts"])
    try:
        stacked = stack_projectors(projectors, layout_of(config, projectors))
    except (TypeError, ValueError) as e:
        raise InputError(path, f"inconsistent model file ({_one_line(e)})") from None
    return Model(stacked, config, bandwidth, tuple(counts), n_train)


def _read_meta(path: Path, data: dict[str, np.ndarray]) -> dict:
    """The checked ``meta`` entry: a jaxproj model of this format version."""
    if "meta" not in data:
        found = ", ".join(sorted(data)[:5]) or "none"
        raise InputError(path, f"not a jaxproj model (no 'meta' entry; arrays found: {found})")
    try:
        meta = json.loads(str(data["meta"]))
    except (json.JSONDecodeError, TypeError, ValueError):
        raise InputError(path, "corrupt model metadata (not JSON)") from None
    if not isinstance(meta, dict):
        raise InputError(path, "corrupt model metadata (not a JSON object)")
    if meta.get("format") != FORMAT:
        raise InputError(path, f"not a jaxproj model (format {meta.get('format')!r})")
    version = meta.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise InputError(path, f"corrupt model metadata (format_version {version!r})")
    if version > FORMAT_VERSION:
        raise InputError(
            path,
            f"model format version {version} was written by a newer jaxproj (this one reads "
            f"version {FORMAT_VERSION}): upgrade jaxproj, or rebuild the model with "
            "`jaxproj build`",
        )
    if version != FORMAT_VERSION:
        raise InputError(
            path,
            f"model format version {version} is not supported (this jaxproj reads version "
            f"{FORMAT_VERSION}); rebuild it with `jaxproj build`",
        )
    return meta


def _chain_inputs(config: BuildConfig, chain: ik.Chain) -> tuple[int, ...]:
    """Descriptor columns a chain of ``config`` reads (``layout_of``'s rule)."""
    if len(ik.chain_set(config.chains)) == 1:
        return tuple(range(3 * len(resolve_bones(config.bones))))
    return tuple(ik.chain_columns(chain, config.bones))


def _check_layout(path: Path, meta: dict, config: BuildConfig, data: dict) -> None:
    """``InputError`` unless the file's chains are this jaxproj's chains for its config."""
    chains = ik.chain_set(config.chains)
    want = {
        "names": [ch.name for ch in chains],
        "inputs": [list(_chain_inputs(config, ch)) for ch in chains],
        "outputs": [list(ik.chain_joints(ch)) for ch in chains],
    }
    got = meta.get("chains")
    got = {k: got.get(k) for k in want} if isinstance(got, dict) else {}
    rebuild = "written by another chain layout; rebuild it with `jaxproj build`"
    for key, value in want.items():
        if got.get(key) != value:
            raise InputError(
                path,
                f"chain {key} {got.get(key)} differ from this jaxproj's {value} for "
                f"chains={config.chains!r}: {rebuild}",
            )
    if meta.get("driven_joints") != list(robot.DRIVEN_JOINTS):
        raise InputError(path, f"driven joints {meta.get('driven_joints')} differ from this "
                               f"jaxproj's {list(robot.DRIVEN_JOINTS)}: {rebuild}")  # fmt: skip
    held = {k.split(".", 1)[0] for k in data if k != "meta"}
    extra = sorted(held - {f"chain{c}" for c in range(len(chains))})
    if extra:
        raise InputError(
            path, f"arrays {', '.join(extra)} beyond its {len(chains)} chain(s): {rebuild}"
        )


def _chain_arrays(
    path: Path, data: dict[str, np.ndarray], c: int, m: int, n: int
) -> dict[str, np.ndarray]:
    """Chain ``c``'s arrays, checked against ``_ARRAY_SHAPES`` (``InputError`` naming the array:
    missing, mis-shaped, wrong kind, non-finite, neighbour index out of range)."""
    dims: dict[str, int] = {"m": m, "n": n}
    out = {}
    for key, spec in _ARRAY_SHAPES.items():
        name = f"chain{c}.{key}"
        if name not in data:
            raise InputError(path, f"missing array {name!r} (an incomplete or foreign model file)")
        a = data[name]
        integer = key == "counts" or key.endswith("neighbours")
        ok = a.ndim == len(spec) and a.dtype.kind in ("iu" if integer else "f")
        for sym, size in zip(spec, a.shape if ok else (), strict=False):
            ok = ok and dims.setdefault(sym, size) == size and size >= 1
        if not ok:
            want = ", ".join(f"{s}={dims[s]}" if s in dims else s for s in spec)
            kind = "integers" if integer else "floats"
            raise InputError(
                path, f"array {name!r} has shape {a.shape} ({a.dtype}), expected ({want}) {kind}"
            )
        if not integer and not np.isfinite(a).all():
            raise InputError(path, f"array {name!r} has non-finite values")
        out[key] = a
    for bank in ("forward", "backward"):
        nb = out[f"{bank}.neighbours"]
        if nb.min() < 0 or nb.max() >= dims["K"] or nb.shape[1] > dims["K"]:
            raise InputError(path, f"array 'chain{c}.{bank}.neighbours' indexes beyond the "
                                   f"{dims['K']} landmarks")  # fmt: skip
    return out
