"""The projector pytrees: one chain's landmarks and kernel banks, and the chains stacked.

``Projector`` holds everything one projection needs (``(K, m)`` human and ``(K, n)`` robot
landmarks, both ELM banks, joint limits); ``StackedProjector`` holds one per kinematic chain,
padded and stacked on a leading chain axis, with its static ``ChainLayout``. The two per-query
steps that both objectives share (``candidates``, ``back_deviation``) live here too, so that
``relaxed`` and ``full`` depend on this module and not on each other. Stacking per-chain
projectors (padding) is ``jaxproj.projection.stacked``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TypeVar

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection.elm import ELMBank, predict
from jaxproj.projection.ops import knn_pallas
from jaxproj.projection.search import nearest, sq_norms
from jaxproj.robots import Robot, get


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Projector:
    """Landmarks and both kernel banks: everything a projection needs (a pytree).

    Attributes:
      human: ``(K, m)`` human landmarks ``h_i`` (descriptors).
      robot: ``(K, n)`` robot landmarks ``r_i = IK(h_i)`` (driven joint angles, rad).
      human_sq, robot_sq: ``(K,)`` squared norms (for the distance computations).
      forward: ELM bank ``h -> r`` (one kernel per landmark).
      backward: ELM bank ``r -> h``.
      lower, upper: ``(n,)`` joint limits the outputs are clipped to.
      robot_index: the robot landmarks' pruning index (``knn_pallas.PruneIndex`` of one set:
        no leading set axis), computed once by ``with_search_index``; ``None``: the pruned
        search computes it in every traced call (the same answers). It belongs to ``robot``:
        a projector made with other robot landmarks must not keep it.
      human_index: the same for the human landmarks (``human``).
    """

    human: jax.Array | np.ndarray
    robot: jax.Array | np.ndarray
    human_sq: jax.Array | np.ndarray
    robot_sq: jax.Array | np.ndarray
    forward: ELMBank
    backward: ELMBank
    lower: jax.Array | np.ndarray
    upper: jax.Array | np.ndarray
    n_landmarks: int = field(metadata=dict(static=True))
    robot_index: knn_pallas.PruneIndex | None = None
    human_index: knn_pallas.PruneIndex | None = None


def make_projector(
    human: jax.typing.ArrayLike,
    robot_poses: jax.typing.ArrayLike,
    forward: ELMBank,
    backward: ELMBank,
    lower: jax.typing.ArrayLike | None = None,
    upper: jax.typing.ArrayLike | None = None,
    robot: Robot | str | None = None,
) -> Projector:
    """Assemble a ``Projector`` from landmarks ``(K, m)``, ``(K, n)`` and the two banks.

    ``lower`` / ``upper`` ``(n,)`` are the limits of the ``n`` joints the robot landmarks hold
    (default: all driven joints of ``robot``, a ``Robot`` or registered name; ``None``: the
    default robot).
    """
    human = jnp.asarray(human, jnp.float32)
    robot_poses = jnp.asarray(robot_poses, jnp.float32)
    if lower is None:
        lower = get(robot).lower_driven
    if upper is None:
        upper = get(robot).upper_driven
    return Projector(
        human=human,
        robot=robot_poses,
        human_sq=sq_norms(human),
        robot_sq=sq_norms(robot_poses),
        forward=forward,
        backward=backward,
        lower=jnp.asarray(lower, jnp.float32),
        upper=jnp.asarray(upper, jnp.float32),
        n_landmarks=int(human.shape[0]),
    )


def candidates(p: Projector, h: jax.Array, n_l: int) -> jax.Array:
    """``(m,) -> (L, n)``: forward-kernel candidates of the ``L`` nearest human landmarks."""
    idx, _ = nearest(p.human, p.human_sq, h, n_l)
    return predict(p.forward, h, idx)


def back_deviation(p: Projector, r: jax.Array, h: jax.Array, idx: jax.Array) -> jax.Array:
    """``||kappa^r_k(r) - h||^2`` for backward kernels ``idx (M,)`` at one robot point ``r``."""
    back = predict(p.backward, r, idx)  # (M, m)
    return jnp.sum((back - h[None]) ** 2, axis=-1)


def _widths(columns: tuple[tuple[int, ...], ...]) -> list[int]:
    """Per chain, how many columns (inputs) or joints (outputs) it has."""
    return [len(c) for c in columns]


@dataclass(frozen=True)
class ChainLayout:
    """How chains split a descriptor and fill the driven joints (static, hashable).

    Attributes:
      names: chain names (``Chain.name``), in stacking order.
      inputs: per chain, the descriptor columns it reads (``3 * n_bones`` each).
      outputs: per chain, the positions in the robot's ``driven_joints`` it writes.
      landmarks: per chain, its landmark count ``K_c`` (before padding to the largest).
      hidden: per chain, hidden units of its forward and backward kernels.
      k: per chain, training neighbours of its kernels.
      width: the whole descriptor's width (``3 * n_bones`` of the model's bones); chains may
        share columns (e.g. legs that read the waist's bones) and leave some unread, so it is
        not the sum of their inputs. ``None``: that sum (chains that split the descriptor).
    """

    names: tuple[str, ...]
    inputs: tuple[tuple[int, ...], ...]
    outputs: tuple[tuple[int, ...], ...]
    landmarks: tuple[int, ...]
    hidden: tuple[int, ...]
    k: tuple[int, ...]
    width: int | None = None

    def __post_init__(self) -> None:
        if self.width is not None and any(c >= self.width for cols in self.inputs for c in cols):
            raise ConfigError(f"a chain reads a column beyond the descriptor's width {self.width}")

    @property
    def n_chains(self) -> int:
        """``C``."""
        return len(self.names)

    @property
    def m_max(self) -> int:
        """Widest chain input (padded width of the stacked human landmarks)."""
        return max(_widths(self.inputs))

    @property
    def n_max(self) -> int:
        """Widest chain output (padded width of the stacked robot landmarks)."""
        return max(_widths(self.outputs))

    @property
    def m(self) -> int:
        """Width of the whole descriptor (``width``, else the sum of the chains' inputs)."""
        return sum(_widths(self.inputs)) if self.width is None else self.width

    @property
    def n(self) -> int:
        """Number of driven joints written."""
        return sum(_widths(self.outputs))

    @property
    def identity(self) -> bool:
        """One chain reading the whole descriptor and writing every joint, in order."""
        return (
            self.n_chains == 1
            and self.inputs[0] == tuple(range(self.m))
            and self.outputs[0] == tuple(range(self.n))
        )

    def input_index(self) -> np.ndarray:
        """``(C, m_max)`` int: columns of ``[h, 0]`` that make each chain's padded input."""
        idx = np.full((self.n_chains, self.m_max), self.m, np.int32)  # padding reads the 0
        for c, cols in enumerate(self.inputs):
            idx[c, : len(cols)] = cols
        return idx

    def output_index(self) -> np.ndarray:
        """``(n,)`` int: for each driven joint, its place in the flattened ``(C, n_max)``."""
        idx = np.zeros(self.n, np.int32)
        for c, cols in enumerate(self.outputs):
            idx[list(cols)] = c * self.n_max + np.arange(len(cols))
        return idx


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class StackedProjector:
    """One projector per kinematic chain, stacked along a leading chain axis (a pytree).

    ``stack`` is a ``Projector`` whose every array has a leading ``(C,)`` axis, padded to the
    largest chain: landmarks to ``K_max`` rows, inputs to ``m_max`` and outputs to ``n_max``
    columns, hidden layers to the widest. Padding never wins a nearest-neighbour search (padded
    landmarks have squared norm ``+inf``, hence infinite distance to every point) and never enters
    a kernel (padded weights, offsets and columns are 0, and padded query columns are 0 too).
    The whole-body projector (the paper's formulation) is the one-chain case.

    Attributes:
      stack: the padded, stacked per-chain projectors.
      layout: the static chain layout.
      robot_index: per chain, the pruning index of its own robot landmarks (as
        ``chain_slice(c).robot``: ``Projector.robot_index``; ``None`` for a chain too small to
        be pruned), or ``None``: computed in every traced call. ``chain_slice`` hands it on.
      human_index: the same for the human landmarks (``Projector.human_index``).
    """

    stack: Projector
    layout: ChainLayout = field(metadata=dict(static=True))
    robot_index: tuple[knn_pallas.PruneIndex | None, ...] | None = None
    human_index: tuple[knn_pallas.PruneIndex | None, ...] | None = None

    @property
    def n_landmarks(self) -> int:
        """The smallest chain's landmark count (``L`` and ``M`` may not exceed it)."""
        return min(self.layout.landmarks)

    def chain(self, c: int) -> Projector:
        """Chain ``c``'s own projector, unpadded (host-side; for baselines, tests, reports):
        ``chain_slice`` made anew by ``make_projector``."""
        s = self.chain_slice(c)
        return make_projector(s.human, s.robot, s.forward, s.backward, s.lower, s.upper)

    def chain_slice(self, c: int) -> Projector:
        """Chain ``c`` at its own size: the stack's arrays sliced to the chain's landmarks,
        columns and hidden units (static slices; traceable, nothing recomputed: what
        ``relaxed.project_relaxed_rows(split=True)`` runs)."""
        lay = self.layout
        k, m, n = lay.landmarks[c], len(lay.inputs[c]), len(lay.outputs[c])
        h, kk = lay.hidden[c], lay.k[c]
        s = jax.tree.map(lambda a: a[c], self.stack)
        return Projector(
            human=s.human[:k, :m],
            robot=s.robot[:k, :n],
            human_sq=s.human_sq[:k],
            robot_sq=s.robot_sq[:k],
            forward=_slice_bank(s.forward, k, m, n, h, kk),
            backward=_slice_bank(s.backward, k, n, m, h, kk),
            lower=s.lower[:n],
            upper=s.upper[:n],
            n_landmarks=k,
            robot_index=None if self.robot_index is None else self.robot_index[c],
            human_index=None if self.human_index is None else self.human_index[c],
        )


def _slice_bank(bank: ELMBank, k: int, d_in: int, d_out: int, hidden: int, kk: int) -> ELMBank:
    return ELMBank(
        w=bank.w[:hidden, :d_in],
        inv_scale=bank.inv_scale[:k],
        bias=bank.bias[:k, :hidden],
        out=bank.out[:k, :d_out, :hidden],
        offset=bank.offset[:k, :d_out],
        neighbours=bank.neighbours[:k, :kk],
        n_kernels=k,
        hidden=hidden,
        d_in=d_in,
        d_out=d_out,
        k=kk,
    )


def robot_index_of(p: Projector) -> knn_pallas.PruneIndex | None:
    """The pruning index of ``p``'s robot landmarks (one set, no leading axis; ``None`` for a
    set the full scan serves: ``knn_pallas.prune_block``), computed by one jitted call of the
    function the pruned search traces otherwise (``knn_pallas.prune_index``), on the same
    arrays: the same index bit for bit."""
    return _index_of(p.robot, p.robot_sq)


def human_index_of(p: Projector) -> knn_pallas.PruneIndex | None:
    """The same as ``robot_index_of`` for ``p``'s human landmarks."""
    return _index_of(p.human, p.human_sq)


def _index_of(
    points: jax.Array | np.ndarray, sq: jax.Array | np.ndarray
) -> knn_pallas.PruneIndex | None:
    block = knn_pallas.prune_block(int(points.shape[0]))
    if block is None:
        return None
    valid = jnp.isfinite(jnp.asarray(sq))[None]
    idx = _prune_index(jnp.asarray(points)[None], valid, block, knn_pallas.PRUNE_LB_TILE)
    return jax.tree.map(lambda a: a[0], idx)


_prune_index = jax.jit(knn_pallas.prune_index, static_argnames=("block", "lbt"))


_P = TypeVar("_P", Projector, StackedProjector)


def with_search_index(p: _P) -> _P:
    """``p`` with its robot and human landmarks' pruning indices computed once
    (``robot_index_of``, ``human_index_of``; per chain at the chain's own size for a stacked
    projector, as ``chain_slice`` hands them to the relaxed projection's split path), instead
    of in every traced call of the pruned search (``knn_pallas.knn``; 1.09 / 1.40 ms a call on
    the default robot's arms' robot landmarks, one H100). The same answers. ``stack_projectors``
    calls it where the default backend runs the Pallas kernels."""
    if isinstance(p, StackedProjector):
        chains = [p.chain_slice(c) for c in range(p.layout.n_chains)]
        robot = tuple(robot_index_of(q) for q in chains)
        human = tuple(human_index_of(q) for q in chains)
        return dataclasses.replace(p, robot_index=robot, human_index=human)
    return dataclasses.replace(p, robot_index=robot_index_of(p), human_index=human_index_of(p))
