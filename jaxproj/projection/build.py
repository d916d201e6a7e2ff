"""Building a model: training descriptors -> landmarks -> kernel banks -> a ``Model``.

``build`` turns training descriptors into a ``Model``: per chain, mean-shift landmarks of the
human descriptors (``jaxproj.projection.landmarks``), their robot poses by the robot's IK
(``BuildConfig.robot``: a ``jaxproj.robots.Robot``), and the forward / backward ELM kernel banks
(``jaxproj.projection.elm``), then the chains stacked (``jaxproj.projection.stacked``).
``from_landmarks`` / ``build_from_landmarks`` skip the mean shift; ``check_training_data``
refuses, before any work, a configuration the data cannot serve. ``Model`` lives here, as what
``build`` returns; ``model_file`` writes and reads it, ``api.project`` projects with it.

Shapes: human descriptors ``(N, m)`` (``m = 15`` for the default upper-body bones), robot poses
``(N, n)`` over the robot's ``driven_joints`` (``n = n_driven``), radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

import jax
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.human.skeleton import resolve_bones
from jaxproj.projection import landmarks
from jaxproj.projection.confidence import DEVIATION_SCALE
from jaxproj.projection.config import BuildConfig, ChainConfig
from jaxproj.projection.elm import train_bank
from jaxproj.projection.projector import Projector, StackedProjector, make_projector
from jaxproj.projection.stacked import layout_of, stack_projectors
from jaxproj.robots import Robot


class _BankOptions(TypedDict):
    """The ``train_bank`` options ``build_from_landmarks`` gives both directions."""

    k: int
    hidden: int
    lam: float
    input_scale: float


@dataclass(frozen=True)
class Model:
    """A built projector plus what it was built from.

    Attributes:
      projector: the chains' landmarks and kernel banks (a pytree, see
        ``projector.StackedProjector``; the whole-body model is its one-chain case).
      config: the ``BuildConfig``.
      bandwidth: per chain, the mean-shift bandwidth used.
      counts: per chain, ``(K_c,)`` training frames per landmark.
      n_train: training frames (valid descriptors) the landmarks came from.
      deviation_scale: the model's own confidence scale (``projection.confidence``: calibrated
        by ``api.build``), or ``None`` (a model file from before: its robot's scale is used).
    """

    projector: StackedProjector
    config: BuildConfig
    bandwidth: tuple[float, ...]
    counts: tuple[np.ndarray, ...]
    n_train: int
    deviation_scale: float | None = None

    @property
    def robot(self) -> Robot:
        """The robot the model was built for (``config.robot``, from the registry)."""
        return self.config.robot_spec

    @property
    def confidence_scale(self) -> float:
        """The scale of this model's confidence: its own (``deviation_scale``), else its
        robot's, else ``confidence.DEVIATION_SCALE`` (the default robot's default model's)."""
        from_robot = self.robot.deviation_scale
        if self.deviation_scale is not None:
            return self.deviation_scale
        return DEVIATION_SCALE if from_robot is None else from_robot

    @property
    def n_landmarks(self) -> int:
        """The smallest chain's landmark count (the largest ``L`` and ``M``)."""
        return self.projector.n_landmarks

    @property
    def landmarks(self) -> dict[str, int]:
        """Landmark count per chain (a model holding a bare one-chain ``Projector``, as
        ``Model(projector=...)`` may: ``{"whole": K}``)."""
        lay = getattr(self.projector, "layout", None)
        if lay is None:
            return {"whole": int(self.projector.n_landmarks)}
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
    joints the robot landmarks hold (default: the default robot's driven joints).
    """
    if isinstance(config, BuildConfig):
        config = config.chain_config(0)
    key = jax.random.PRNGKey(config.seed) if key is None else key
    k_fwd, k_bwd = jax.random.split(key)
    if config.k < 2 or len(human) < 2:
        raise ConfigError(f"k={config.k} and the number of landmarks={len(human)} must be >= 2")
    k = min(config.k, len(human))
    opts = _BankOptions(k=k, hidden=config.hidden, lam=config.lam, input_scale=config.input_scale)
    forward = train_bank(human, robot_poses, k_fwd, **opts)
    backward = train_bank(robot_poses, human, k_bwd, **opts)
    return make_projector(human, robot_poses, forward, backward, lower, upper)


def build(
    descriptors: np.ndarray,
    config: BuildConfig = BuildConfig(),  # noqa: B008 - frozen, hashable
    **mean_shift,
) -> Model:
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
    spec = config.robot_spec
    chains = spec.chain_set(config.chains)
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
            robot=spec,
            **mean_shift,
        )
        joints = list(spec.chain_joints(chain))
        lo = spec.lower_driven[joints]
        hi = spec.upper_driven[joints]
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
    spec = config.robot_spec
    chains = spec.chain_set(config.chains)
    for c, chain in enumerate(chains):
        target = config.chain_config(c).landmarks
        if target is None:
            continue
        cols = slice(None) if len(chains) == 1 else list(spec.chain_columns(chain, config.bones))
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
    ``(K, n_driven)`` driven-joint poses (``config.robot``'s). Each chain takes its columns of
    ``human`` and its joints of ``robot_poses``, rows that repeat in the chain's columns
    dropped (first kept); its kernels are trained as ``build`` trains them.
    ``config.landmarks`` / ``bandwidth`` are not used (the model records bandwidth 0)."""
    human = np.asarray(human, np.float32)
    robot_poses = np.asarray(robot_poses, np.float32)
    spec = config.robot_spec
    if human.ndim != 2 or robot_poses.shape != (len(human), spec.n_driven):
        raise ConfigError(f"landmarks must be (K, m) and (K, {spec.n_driven}), got "
                          f"{human.shape}, {robot_poses.shape}")  # fmt: skip
    chains = spec.chain_set(config.chains)
    base_key = jax.random.PRNGKey(config.seed)
    projectors, counts = [], []
    for c, chain in enumerate(chains):
        cols = (
            list(range(human.shape[1]))
            if len(chains) == 1
            else list(spec.chain_columns(chain, config.bones))
        )
        joints = list(spec.chain_joints(chain))
        _, first = np.unique(human[:, cols], axis=0, return_index=True)
        rows = np.sort(first)
        key = base_key if c == 0 else jax.random.fold_in(base_key, c)
        projectors.append(
            build_from_landmarks(
                human[rows][:, cols],
                robot_poses[rows][:, joints],
                config.chain_config(c),
                key=key,
                lower=spec.lower_driven[joints],
                upper=spec.upper_driven[joints],
            )
        )
        counts.append(np.ones(len(rows), np.int64))
    stacked = stack_projectors(projectors, layout_of(config, projectors))
    n = len(human) if n_train is None else n_train
    return Model(stacked, config, tuple(0.0 for _ in chains), tuple(counts), n)
