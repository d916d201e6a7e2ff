"""Configuration projection (paper section II-D): a human pose -> a NAO pose.

For one query ``h*`` (a human descriptor):

1. the ``L`` nearest human landmarks ``h_j`` give ``L`` candidates ``r_j = kappa^h_j(h*)``
   through their forward kernels;
2. each candidate's ``M`` nearest robot landmarks ``r_{j,k}`` give ``M`` backward kernels;
3. **relaxed** objective (paper eq. 4): the answer is the candidate with the least
   back-projected deviation ``min_k ||kappa^r_{j,k}(r_j) - h*||``;
4. **full** objective (paper eq. 2-3): for each ``j``, simplex weights ``w`` over its ``M`` robot
   landmarks give ``r(w) = sum_k w_k r_{j,k}``; ``w`` minimises a back-projected deviation (see
   ``full_objective``) by projected gradient (optax), and the answer is ``r(w*)`` of the ``j``
   with the least objective value.

The ``*_one`` functions are written for ONE query (the full objective and the float32 reference
of the relaxed one; callers vmap them). The relaxed projection of a batch runs as rows instead
(``relaxed_candidates``, ``least_deviations_rows``, ``project_relaxed_rows``): every search of
a batch is one call and the back-projection of all candidates one more, which is what
``engine.project_batch`` uses. Nothing here is jitted; the public entry points
(``engine.project``) are. ``L`` and ``M`` are static.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from optax.projections import projection_simplex

from jaxproj.errors import ConfigError
from jaxproj.projection.elm import (
    ELMBank,
    KernelSlice,
    predict,
    predict_slice,
    project_inputs,
    take,
)
from jaxproj.projection.ops.backproj_pallas import back_min
from jaxproj.projection.search import nearest, nearest_rows, sq_norms
from jaxproj.robots.nao_h25 import robot


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
    """

    human: jax.Array
    robot: jax.Array
    human_sq: jax.Array
    robot_sq: jax.Array
    forward: ELMBank
    backward: ELMBank
    lower: jax.Array
    upper: jax.Array
    n_landmarks: int = field(metadata=dict(static=True))


def make_projector(
    human: jax.Array,
    robot_poses: jax.Array,
    forward: ELMBank,
    backward: ELMBank,
    lower: jax.Array | None = None,
    upper: jax.Array | None = None,
) -> Projector:
    """Assemble a ``Projector`` from landmarks ``(K, m)``, ``(K, n)`` and the two banks.

    ``lower`` / ``upper`` ``(n,)`` are the limits of the ``n`` joints the robot landmarks hold
    (default: ``robot.DRIVEN_JOINTS``'s, for ``n = 10``).
    """
    human = jnp.asarray(human, jnp.float32)
    robot_poses = jnp.asarray(robot_poses, jnp.float32)
    if lower is None:
        lower = robot.LOWER[robot.DRIVEN_INDEX]
    if upper is None:
        upper = robot.UPPER[robot.DRIVEN_INDEX]
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


def project_relaxed_one(
    p: Projector, h: jax.Array, n_l: int, n_m: int
) -> tuple[jax.Array, jax.Array]:
    """Relaxed projection of one query.

    Args:
      p: the projector.
      h: ``(m,)`` human descriptor.
      n_l, n_m: ``L`` and ``M`` (static).

    Returns:
      ``(r, dev)``: ``(n,)`` projected robot pose (clipped to the joint limits) and the
      back-projected deviation ``min_k ||kappa^r_{j,k}(r_j) - h||`` of the chosen candidate.
    """
    cand = candidates(p, h, n_l)  # (L, n)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, n_m)  # (L, M)
    return _relaxed_pick(p, h, cand, ridx)


def _relaxed_pick(
    p: Projector, h: jax.Array, cand: jax.Array, ridx: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Steps 2-3 of the relaxed projection of one query, given its candidates ``(L, n)`` and
    their robot landmarks ``ridx (L, M)``: the candidate with the least back-projected deviation
    and that deviation (``project_relaxed_one``'s result)."""
    return _pick(p, cand, _least_deviations(p, h, cand, ridx))


def _least_deviations(p: Projector, h: jax.Array, cand: jax.Array, ridx: jax.Array) -> jax.Array:
    """``(L,)``: each candidate's least squared back-projected deviation over its ``M`` kernels."""
    dev = jax.vmap(back_deviation, in_axes=(None, 0, None, 0))(p, cand, h, ridx)  # (L, M)
    return jnp.min(dev, axis=1)


def _pick(p: Projector, cand: jax.Array, best: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The candidate ``(L, n)`` whose least squared deviation ``best (L,)`` is smallest: its
    pose clipped to the joint limits, and its deviation."""
    j = jnp.argmin(best)
    return jnp.clip(cand[j], p.lower, p.upper), jnp.sqrt(best[j])


def backward_widths(p: Projector | StackedProjector) -> list[tuple[int, int, int]]:
    """Per chain ``(n, m, hidden)``: robot width, descriptor width and backward hidden units
    (one entry for a plain projector), before any padding of the stacked arrays."""
    if isinstance(p, StackedProjector):
        lay = p.layout
        widths = zip(lay.outputs, lay.inputs, lay.hidden, strict=True)
        return [(len(o), len(i), hidden) for o, i, hidden in widths]
    return [(p.robot.shape[1], p.human.shape[1], p.backward.hidden)]


def least_deviations_rows(
    stack: Projector,
    dims: Sequence[tuple[int, int, int]],
    x: jax.Array,
    cand: jax.Array,
    ridx: jax.Array,
    fused: bool | None = None,
) -> jax.Array:
    """Every candidate's least squared back-projected deviation, for a batch and every chain.

    Args:
      stack: one projector per chain, stacked on a leading axis.
      dims: per chain ``(n, m, hidden)`` (``backward_widths``; the stacked arrays may be
        padded beyond them).
      x: ``(S, C, m)`` queries per chain; cand: ``(S, C, L, n)`` candidates; ridx:
        ``(S, C, L, M)`` their robot landmarks.
      fused: ``None`` (default): the fused Pallas kernel (``jaxproj.projection.ops.backproj_pallas``) on CUDA
        GPUs and XLA elsewhere; ``True``: the kernel in Pallas' interpreter on any platform (for
        tests); ``False``: XLA.

    Returns:
      ``(S, C, L)``: ``min_k ||kappa^r_{j,k}(r_j) - h||^2`` (``_least_deviations`` per query).
    """

    def xla(stack: Projector, x: jax.Array, cand: jax.Array, ridx: jax.Array) -> jax.Array:
        per_query = jax.vmap(_least_deviations)  # over chains
        return jax.vmap(per_query, in_axes=(None, 0, 0, 0))(stack, x, cand, ridx)

    def kernel(
        stack: Projector, x: jax.Array, cand: jax.Array, ridx: jax.Array, interpret: bool
    ) -> jax.Array:
        s, _, n_l, n_m = ridx.shape
        best = []
        for c, (n, m, hidden) in enumerate(dims):
            bank = jax.tree.map(lambda a, c=c: a[c], stack.backward)
            rows = cand[:, c].reshape(s * n_l, -1)
            queries = jnp.repeat(x[:, c], n_l, axis=0)
            idx = ridx[:, c].reshape(s * n_l, n_m)
            b = back_min(bank, rows, queries, idx, n, m, hidden, interpret=interpret)
            best.append(b.reshape(s, n_l))
        return jnp.stack(best, axis=1)

    if fused is False:
        return xla(stack, x, cand, ridx)
    if fused:
        return kernel(stack, x, cand, ridx, True)
    return jax.lax.platform_dependent(
        stack, x, cand, ridx, cuda=partial(kernel, interpret=False), default=xla
    )


def relaxed_candidates(
    p: Projector | StackedProjector, h: jax.Array, n_l: int, n_m: int
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Steps 1-2 of the relaxed projection for a batch, every chain at once: the human-landmark
    searches of all queries and the robot-landmark searches of all their candidates as one
    ``search.nearest_rows`` call each (the fused Pallas kernel on CUDA GPUs,
    ``jaxproj.projection.ops.knn_pallas``), not one small search per query.

    Args:
      p: a projector, or one projector per chain.
      h: ``(S, m)`` human descriptors.
      n_l, n_m: ``L`` and ``M`` (static).

    Returns:
      ``(x, cand, ridx)``: ``(S, C, m_max)`` each chain's part of the queries, ``(S, C, L, n)``
      the forward-kernel candidates (as ``candidates``) and ``(S, C, L, M)`` their robot
      landmarks (``C = 1`` for a plain projector).
    """
    stack, lay = _chains(p)
    s = h.shape[0]
    if lay is None or lay.identity:
        x = h[:, None, :]  # (S, 1, m)
    else:
        x = jnp.concatenate([h, jnp.zeros((s, 1), h.dtype)], axis=1)[:, lay.input_index()]
    hidx, _ = nearest_rows(stack.human, stack.human_sq, x.transpose(1, 0, 2), n_l)  # (C, S, L)

    def forward(p: Projector, q: jax.Array, idx: jax.Array) -> jax.Array:
        return predict(p.forward, q, idx)  # (L, n), as ``candidates``

    per_chain = jax.vmap(forward)
    cand = jax.vmap(per_chain, in_axes=(None, 0, 0))(stack, x, hidx.transpose(1, 0, 2))
    c, n = cand.shape[1], cand.shape[3]  # cand: (S, C, L, n)
    rows = cand.transpose(1, 0, 2, 3).reshape(c, s * n_l, n)
    ridx, _ = nearest_rows(stack.robot, stack.robot_sq, rows, n_m)  # (C, S * L, M)
    return x, cand, ridx.reshape(c, s, n_l, n_m).transpose(1, 0, 2, 3)


def _chains(p: Projector | StackedProjector) -> tuple[Projector, ChainLayout | None]:
    """``p``'s projectors stacked on a leading chain axis, and the layout (``None`` for a plain
    projector: one chain reading the whole descriptor)."""
    if isinstance(p, StackedProjector):
        return p.stack, p.layout
    return jax.tree.map(lambda a: a[None], p), None


def project_relaxed_rows(
    p: Projector | StackedProjector,
    h: jax.Array,
    n_l: int,
    n_m: int,
    chunk: int | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Relaxed projection of a batch of queries, every chain at once.

    The same answers as ``project_relaxed_one`` (``project_stacked_one`` for a stacked
    projector) vmapped over the batch, but with every search of the batch as one call
    (``relaxed_candidates``) and the back-projection of all candidates as
    ``least_deviations_rows`` calls (on CUDA GPUs the fused kernel of
    ``jaxproj.projection.ops.backproj_pallas``, whose sums round differently: see there).

    Args:
      p: a projector, or one projector per chain.
      h: ``(S, m)`` human descriptors.
      n_l, n_m: ``L`` and ``M`` (static).
      chunk: back-project ``chunk`` queries at a time (a ``lax.map`` loop inside the one
        search call; static, must divide ``S``). ``None`` (default): all ``S`` at once. On the
        CPU the searches want many queries per call and the back-projection few (its gathered
        kernels should stay in cache): ``engine.project_batch`` sets both.

    Returns:
      ``(r, dev)``: ``(S, n)`` driven joints and ``(S,)`` back-projected deviations (over the
      whole descriptor: ``sqrt(sum_c dev_c^2)`` for chains).
    """
    stack, lay = _chains(p)
    s = h.shape[0]
    x, cand, ridx = relaxed_candidates(p, h, n_l, n_m)
    dims = backward_widths(p)
    if chunk is None or chunk >= s:
        best = least_deviations_rows(stack, dims, x, cand, ridx)  # (S, C, L)
    else:
        if s % chunk:
            raise ConfigError(f"chunk={chunk} does not divide the batch of {s} queries")

        def part(a: tuple[jax.Array, jax.Array, jax.Array]) -> jax.Array:
            return least_deviations_rows(stack, dims, *a)

        parts = jax.tree.map(lambda a: a.reshape(s // chunk, chunk, *a.shape[1:]), (x, cand, ridx))
        best = jax.lax.map(part, parts).reshape(s, *ridx.shape[1:3])
    r, v = jax.vmap(jax.vmap(_pick), in_axes=(None, 0, 0))(stack, cand, best)  # (S, C, n), (S, C)
    if lay is None or lay.identity:
        return r[:, 0], v[:, 0]
    return r.reshape(s, -1)[:, lay.output_index()], jnp.sqrt(jnp.sum(v * v, axis=1))


Objective = Literal["weighted", "min"]
Solver = Literal["adam", "newton"]


@dataclass(frozen=True)
class FullConfig:
    """Settings of the full (simplex-weighted) objective. Static (hashable) under ``jax.jit``.

    Validated when constructed: a bad value raises ``ConfigError``.

    Attributes:
      objective: ``"weighted"`` (default) ``f(w) = sum_k w_k ||kappa^r_{j,k}(r(w)) - h||^2``;
        ``"min"`` ``f(w) = min_k ||kappa^r_{j,k}(r(w)) - h||^2`` (the paper's eq. 2 read
        literally as the best kernel of the cluster).
      solver: ``"adam"`` (default): projected ``optax.adam`` steps; ``"newton"``: projected
        Newton steps on the face of the simplex the weights lie on, tried in parallel beside
        projected-gradient steps, the best kept (``_solve_cluster_newton``). Both project with
        ``optax.projections.projection_simplex`` and never return worse than the warm start.
        Adam's 30 steps stop far from a minimum (``benchmarks/RESULTS.md``); Newton's converge.
      iterations: solver steps per candidate (fixed; no early exit), ``>= 0``.
      learning_rate: Adam step size on the weights, ``> 0`` (the weights live on the simplex, so
        the scale is absolute: 0.05 moves at most ~5% of mass per step). Unused by Newton.
      include_candidate: add the candidate ``r_j`` itself as vertex 0 of its simplex (warm start
        ``w0 = e_0``, i.e. the relaxed answer).
      clusters: optimise only the ``clusters`` candidates whose objective is smallest at their
        warm start (``0``: all ``L``, the exact full objective). A speed option: it skips the
        projected gradient of clusters that start far behind; its measured effect on the
        answers is in ``benchmarks/RESULTS.md``.
    """

    objective: Objective = "weighted"
    solver: Solver = "adam"
    iterations: int = 30
    learning_rate: float = 0.05
    include_candidate: bool = False
    clusters: int = 0

    def __post_init__(self) -> None:
        if self.objective not in ("weighted", "min"):
            raise ConfigError(f"full objective must be 'weighted' or 'min', got {self.objective!r}")
        if self.solver not in ("adam", "newton"):
            raise ConfigError(f"full solver must be 'adam' or 'newton', got {self.solver!r}")
        if self.iterations < 0:
            raise ConfigError(f"full iterations={self.iterations} must be >= 0")
        if not self.learning_rate > 0:
            raise ConfigError(f"full learning_rate={self.learning_rate} must be > 0")
        if self.clusters < 0:
            raise ConfigError(f"full clusters={self.clusters} must be >= 0 (0: all L)")


class _PGState(NamedTuple):
    w: jax.Array
    opt_state: optax.OptState
    best_w: jax.Array
    best_f: jax.Array


class _Cluster(NamedTuple):
    verts: jax.Array  # (V, n) simplex vertices
    w0: jax.Array  # (V,) warm start
    kernels: KernelSlice  # the M backward kernels, gathered once


def _cluster(p: Projector, r_c: jax.Array, idx: jax.Array, cfg: FullConfig) -> _Cluster:
    """The simplex problem of one candidate ``r_c (n,)`` with robot landmarks ``idx (M,)``.

    The simplex spans the candidate's ``M`` robot landmarks and, with
    ``cfg.include_candidate``, the candidate ``r_c`` itself as vertex 0 (then ``w0 = e_0``: the
    relaxed answer is the warm start). Otherwise ``w0`` is the inverse squared distance weights
    of ``r_c`` to the landmarks.
    """
    rk = p.robot[idx]  # (M, n)
    kernels = take(p.backward, idx)  # gathered once, evaluated at every step
    if cfg.include_candidate:
        verts = jnp.concatenate([r_c[None], rk], axis=0)  # (M + 1, n)
        w0 = jnp.zeros((verts.shape[0],), rk.dtype).at[0].set(1.0)
    else:
        verts = rk
        d2 = jnp.sum((rk - r_c[None]) ** 2, axis=1)
        w0 = 1.0 / (d2 + 1e-8)
        w0 = w0 / jnp.sum(w0)
    return _Cluster(verts, w0, kernels)


def _objective(p: Projector, h: jax.Array, c: _Cluster, cfg: FullConfig, w: jax.Array) -> jax.Array:
    """The full objective ``f(w)`` of one cluster (see ``FullConfig.objective``)."""
    r = jnp.einsum("m,mn->n", w, c.verts)
    back = predict_slice(c.kernels, project_inputs(p.backward, r))  # (M, m)
    dev = jnp.sum((back - h[None]) ** 2, axis=-1)
    if cfg.objective == "min":
        return jnp.min(dev)
    wk = w[1:] / jnp.maximum(jnp.sum(w[1:]), 1e-12) if cfg.include_candidate else w
    return jnp.sum(wk * dev)


def _start_value(p: Projector, h: jax.Array, c: _Cluster, cfg: FullConfig) -> jax.Array:
    """``f(w0)``: the objective of one cluster at its warm start."""
    return _objective(p, h, c, cfg, c.w0)


def _solve_cluster(
    p: Projector, h: jax.Array, c: _Cluster, f0: jax.Array, cfg: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Projected gradient on the simplex of one cluster (``_cluster``) whose warm-start value
    is ``f0``; returns (r(w*), f(w*)).

    Every step is an Adam update followed by ``optax.projections.projection_simplex``; the
    best iterate is kept, so the returned value is never worse than ``f0``.
    """

    def objective(w: jax.Array) -> jax.Array:
        return _objective(p, h, c, cfg, w)

    opt = optax.adam(cfg.learning_rate)
    f = jax.value_and_grad(objective)

    # The two optax calls below run under JAX's standard dtype promotion, because optax 0.2.8
    # mixes int32 and float32 inside them, whatever we pass in: Adam's bias correction computes
    # ``decay ** count`` with its int32 step count (``optax.tree.bias_correction``) and the
    # simplex projection divides by int32 ``arange`` indices (``_projection_unit_simplex``).
    # Nothing else is inside the block: our own arithmetic (objective, gradient, best-iterate
    # bookkeeping, ``apply_updates`` of two float32 arrays) follows the caller's promotion mode.
    def step(state: _PGState, _: None) -> tuple[_PGState, None]:
        val, g = f(state.w)
        better = val < state.best_f
        best_w = jnp.where(better, state.w, state.best_w)
        best_f = jnp.where(better, val, state.best_f)
        with jax.numpy_dtype_promotion("standard"):  # optax internals, see above
            upd, opt_state = opt.update(g, state.opt_state, state.w)
        w = optax.apply_updates(state.w, upd)
        with jax.numpy_dtype_promotion("standard"):  # optax internals, see above
            w = projection_simplex(w)
        return _PGState(w, opt_state, best_w, best_f), None

    w0 = c.w0
    init = _PGState(w0, opt.init(w0), w0, f0)
    final, _ = jax.lax.scan(step, init, None, length=cfg.iterations)
    f_last = objective(final.w)
    better = f_last < final.best_f
    w_best = jnp.where(better, final.w, final.best_w)
    f_best = jnp.where(better, f_last, final.best_f)
    r_best = jnp.einsum("m,mn->n", w_best, c.verts)
    return r_best, f_best


NEWTON_DAMPING = (0.0, 1e-4, 1e-2, 1e-1)
"""Levenberg damping of the Newton trials, as fractions of the Hessian's Frobenius norm."""

NEWTON_STEPS = (1.0, 0.5, 0.25)
"""Fractions of each damped Newton step tried."""

GRADIENT_STEPS = (4.0, 1.0, 0.25, 1 / 16, 1 / 64)
"""Projected-gradient trials, as multiples of the adaptive gradient step."""


def _face_newton(
    grad: jax.Array, hess: jax.Array, free: jax.Array, damping: jax.Array
) -> jax.Array:
    """Newton direction ``d (V,)`` on the face of the simplex where ``free (V,)`` weights lie.

    Minimises ``grad . d + d^T (hess + damping I) d / 2`` over ``sum(d) = 0`` and ``d_k = 0``
    off the face (one ``(V + 1)``-square KKT solve); ``0`` where the system is singular.
    """
    v = grad.shape[0]
    a = hess + damping * jnp.eye(v, dtype=hess.dtype)
    a = jnp.where(free[:, None] & free[None, :], a, 0.0) + jnp.diag(jnp.where(free, 0.0, 1.0))
    one = free.astype(hess.dtype)
    kkt = jnp.concatenate(
        [
            jnp.concatenate([a, one[:, None]], axis=1),
            jnp.concatenate([one, jnp.zeros((1,), hess.dtype)])[None],
        ]
    )
    rhs = jnp.concatenate([jnp.where(free, -grad, 0.0), jnp.zeros((1,), hess.dtype)])
    d = jnp.linalg.solve(kkt, rhs)[:v]
    return jnp.where(jnp.all(jnp.isfinite(d)), d, 0.0)


class _NewtonState(NamedTuple):
    w: jax.Array
    f: jax.Array
    step: jax.Array  # the adaptive projected-gradient step


def _solve_cluster_newton(
    p: Projector, h: jax.Array, c: _Cluster, f0: jax.Array, cfg: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Projected Newton on the simplex of one cluster; returns (r(w*), f(w*)).

    Every step computes the objective's gradient and Hessian in the weights (``V = M`` or
    ``M + 1`` of them: small), then tries in parallel
    * damped Newton steps on the current face (the weights' support; ``NEWTON_DAMPING`` x
      ``NEWTON_STEPS``; the damping adds ``-lambda_min`` of the Hessian restricted to the face
      where that is not positive definite), and
    * projected-gradient steps (``GRADIENT_STEPS`` x an adaptive step), which move weights on or
      off the face,
    each projected with ``optax.projections.projection_simplex``, and keeps the trial with the
    least objective if it improves (monotone: never worse than ``f0``). The objective is flat
    along some directions (e.g. an elbow's yaw on a straight arm), where gradient steps crawl;
    the Newton steps follow its curvature there.
    """

    def objective(w: jax.Array) -> jax.Array:
        return _objective(p, h, c, cfg, w)

    v = c.w0.shape[0]
    damping = jnp.asarray(NEWTON_DAMPING, c.w0.dtype)
    fractions = jnp.asarray(NEWTON_STEPS, c.w0.dtype)
    scales = jnp.asarray(GRADIENT_STEPS, c.w0.dtype)
    n_newton = len(NEWTON_DAMPING) * len(NEWTON_STEPS)

    def project(w: jax.Array) -> jax.Array:
        with jax.numpy_dtype_promotion("standard"):  # optax internals, see _solve_cluster
            return projection_simplex(w)

    def step(state: _NewtonState, _: None) -> tuple[_NewtonState, None]:
        w = state.w
        grad = jax.grad(objective)(w)
        hess = jax.hessian(objective)(w)
        hess = 0.5 * (hess + hess.T)
        free = w > 0
        n_free = jnp.sum(free.astype(w.dtype))
        centre = jnp.where(free[:, None] & free[None, :], jnp.eye(v, dtype=w.dtype) - 1 / n_free, 0)
        lam_min = jnp.linalg.eigvalsh(centre @ hess @ centre)[0]
        norm = jnp.sqrt(jnp.sum(hess * hess)) + 1e-12
        shift = 1.01 * jnp.maximum(0.0, -lam_min)
        dirs = jax.vmap(lambda d: _face_newton(grad, hess, free, shift + d * norm))(damping)
        newton = (w[None, None] + fractions[None, :, None] * dirs[:, None]).reshape(-1, v)
        gradient = w[None] - (state.step * scales)[:, None] * grad[None]
        trials = jax.vmap(project)(jnp.concatenate([newton, gradient]))
        values = jax.vmap(objective)(trials)
        i = jnp.argmin(values)
        better = values[i] < state.f
        by_gradient = better & (i >= n_newton)
        grown = state.step * scales[jnp.maximum(i - n_newton, 0)] * 2.0
        new_step = jnp.where(by_gradient, grown, jnp.where(better, state.step, state.step / 16))
        return _NewtonState(
            jnp.where(better, trials[i], w), jnp.where(better, values[i], state.f), new_step
        ), None

    init = _NewtonState(c.w0, f0, jnp.ones((), c.w0.dtype))
    final, _ = jax.lax.scan(step, init, None, length=cfg.iterations)
    return jnp.einsum("m,mn->n", final.w, c.verts), final.f


def project_full_one(
    p: Projector, h: jax.Array, n_l: int, n_m: int, cfg: FullConfig
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Full projection of one query.

    Args:
      p: the projector.
      h: ``(m,)`` human descriptor.
      n_l, n_m: ``L`` and ``M`` (static).
      cfg: objective and solver settings (static).

    Returns:
      ``(r, f, f0)``: ``(n,)`` projected pose, the objective value at the chosen cluster's
      optimum and at its warm start.
    """
    cand = candidates(p, h, n_l)  # (L, n)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, n_m)  # (L, M)
    clusters = jax.vmap(_cluster, in_axes=(None, 0, 0, None))(p, cand, ridx, cfg)
    f0 = jax.vmap(_start_value, in_axes=(None, None, 0, None))(p, h, clusters, cfg)  # (L,)
    solve = _solve_cluster_newton if cfg.solver == "newton" else _solve_cluster
    if cfg.clusters == 1 < n_l:  # one cluster: index it (a size-1 vmap ran 2x slower on CPU)
        j = jnp.argmin(f0)  # the first minimum, as top_k(-f0, 1) picks it
        r, f = solve(p, h, jax.tree.map(lambda a: a[j], clusters), f0[j], cfg)
        return jnp.clip(r, p.lower, p.upper), f, f0[j]
    if 0 < cfg.clusters < n_l:  # optimise only the clusters that start best
        _, keep = jax.lax.top_k(-f0, cfg.clusters)
        clusters = jax.tree.map(lambda a: a[keep], clusters)
        f0 = f0[keep]
    r, f = jax.vmap(solve, in_axes=(None, None, 0, 0, None))(p, h, clusters, f0, cfg)
    j = jnp.argmin(f)
    return jnp.clip(r[j], p.lower, p.upper), f[j], f0[j]


# --------------------------------------------------------------------------- stacked chains


@dataclass(frozen=True)
class ChainLayout:
    """How chains split a descriptor and fill the driven joints (static, hashable).

    Attributes:
      names: chain names (``ik.Chain.name``), in stacking order.
      inputs: per chain, the descriptor columns it reads (``3 * n_bones`` each).
      outputs: per chain, the positions in ``robot.DRIVEN_JOINTS`` it writes.
      landmarks: per chain, its landmark count ``K_c`` (before padding to the largest).
      hidden: per chain, hidden units of its forward and backward kernels.
      k: per chain, training neighbours of its kernels.
    """

    names: tuple[str, ...]
    inputs: tuple[tuple[int, ...], ...]
    outputs: tuple[tuple[int, ...], ...]
    landmarks: tuple[int, ...]
    hidden: tuple[int, ...]
    k: tuple[int, ...]

    @property
    def n_chains(self) -> int:
        """``C``."""
        return len(self.names)

    @property
    def m_max(self) -> int:
        """Widest chain input (padded width of the stacked human landmarks)."""
        return max(len(c) for c in self.inputs)

    @property
    def n_max(self) -> int:
        """Widest chain output (padded width of the stacked robot landmarks)."""
        return max(len(c) for c in self.outputs)

    @property
    def m(self) -> int:
        """Width of the whole descriptor."""
        return sum(len(c) for c in self.inputs)

    @property
    def n(self) -> int:
        """Number of driven joints written."""
        return sum(len(c) for c in self.outputs)

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
    """

    stack: Projector
    layout: ChainLayout = field(metadata=dict(static=True))

    @property
    def n_landmarks(self) -> int:
        """The smallest chain's landmark count (``L`` and ``M`` may not exceed it)."""
        return min(self.layout.landmarks)

    def chain(self, c: int) -> Projector:
        """Chain ``c``'s own projector, unpadded (host-side; for baselines, tests, reports)."""
        lay = self.layout
        k, m, n = lay.landmarks[c], len(lay.inputs[c]), len(lay.outputs[c])
        h, kk = lay.hidden[c], lay.k[c]
        s = jax.tree.map(lambda a: a[c], self.stack)
        fwd = _slice_bank(s.forward, k, m, n, h, kk)
        bwd = _slice_bank(s.backward, k, n, m, h, kk)
        return make_projector(s.human[:k, :m], s.robot[:k, :n], fwd, bwd, s.lower[:n], s.upper[:n])


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


def _pad(a: jax.Array, shape: tuple[int, ...], value: float = 0.0) -> np.ndarray:
    a = np.asarray(a)
    return np.pad(
        a, [(0, t - s) for s, t in zip(a.shape, shape, strict=True)], constant_values=value
    )


def _pad_bank(bank: ELMBank, k: int, hidden: int, d_in: int, d_out: int, kk: int) -> ELMBank:
    return ELMBank(
        w=_pad(bank.w, (hidden, d_in)),
        inv_scale=_pad(bank.inv_scale, (k,)),
        bias=_pad(bank.bias, (k, hidden)),
        out=_pad(bank.out, (k, d_out, hidden)),
        offset=_pad(bank.offset, (k, d_out)),
        neighbours=_pad(bank.neighbours, (k, kk), -1),
        n_kernels=k,
        hidden=hidden,
        d_in=d_in,
        d_out=d_out,
        k=kk,
    )


def stack_projectors(chains: Sequence[Projector], layout: ChainLayout) -> StackedProjector:
    """Pad per-chain projectors to the largest and stack them (see ``StackedProjector``)."""
    if len(chains) != layout.n_chains or not chains:
        raise ConfigError(f"{len(chains)} projectors for {layout.n_chains} chains")
    for c, p in enumerate(chains):
        want = (layout.landmarks[c], len(layout.inputs[c]), len(layout.outputs[c]))
        want += (layout.hidden[c], layout.hidden[c], layout.k[c], layout.k[c])
        got = (p.n_landmarks, p.human.shape[1], p.robot.shape[1], p.forward.hidden)
        got += (p.backward.hidden, p.forward.k, p.backward.k)
        if got != want:
            raise ConfigError(f"chain {layout.names[c]}: projector {got} does not match {want}")
    k, m, n = max(layout.landmarks), layout.m_max, layout.n_max
    hf = hb = max(layout.hidden)
    kk = max(layout.k)
    padded = [
        Projector(
            human=_pad(p.human, (k, m)),
            robot=_pad(p.robot, (k, n)),
            human_sq=_pad(p.human_sq, (k,), np.inf),
            robot_sq=_pad(p.robot_sq, (k,), np.inf),
            forward=_pad_bank(p.forward, k, hf, m, n, kk),
            backward=_pad_bank(p.backward, k, hb, n, m, kk),
            lower=_pad(p.lower, (n,)),
            upper=_pad(p.upper, (n,)),
            n_landmarks=k,
        )
        for p in chains
    ]
    stack = jax.tree.map(lambda *a: jnp.asarray(np.stack(a)), *padded)
    return StackedProjector(stack=stack, layout=layout)


def project_stacked_one(
    sp: StackedProjector, h: jax.Array, objective: str, n_l: int, n_m: int, full: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Project one query through every chain (vmapped over the chain axis).

    Args:
      sp: the stacked projector.
      h: ``(m,)`` whole descriptor.
      objective: ``"relaxed"`` or ``"full"`` (static).
      n_l, n_m: ``L`` and ``M`` per chain (static).
      full: full-objective settings (static).

    Returns:
      ``(r, value)``: ``(n,)`` driven joints (each chain's answer in its joints), and the
      objective's value over the whole descriptor: relaxed, ``sqrt(sum_c dev_c^2)`` (the chains
      split the descriptor, so this is the deviation of the assembled pose); full, ``sum_c f_c``.
    """

    def chain(p: Projector, x: jax.Array) -> tuple[jax.Array, jax.Array]:
        if objective == "relaxed":
            return project_relaxed_one(p, x, n_l, n_m)
        r, f, _ = project_full_one(p, x, n_l, n_m, full)
        return r, f

    lay = sp.layout
    if lay.identity:  # the whole-body projector: no gather, no scatter
        return chain(jax.tree.map(lambda a: a[0], sp.stack), h)
    x = jnp.concatenate([h, jnp.zeros((1,), h.dtype)])[lay.input_index()]  # (C, m_max)
    r, v = jax.vmap(chain)(sp.stack, x)  # (C, n_max), (C,)
    out = r.reshape(-1)[lay.output_index()]
    value = jnp.sqrt(jnp.sum(v * v)) if objective == "relaxed" else jnp.sum(v)
    return out, value
