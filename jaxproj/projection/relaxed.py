"""The relaxed objective (paper eq. 4): the candidate with the least back-projected deviation.

For one query ``h*``: the ``L`` nearest human landmarks give ``L`` forward-kernel candidates
``r_j`` (``projector.candidates``); each candidate's ``M`` nearest robot landmarks give ``M``
backward kernels; the answer is the candidate with the least ``min_k ||kappa^r_{j,k}(r_j) - h*||``.

``project_relaxed_one`` is written for ONE query (the float32 reference; callers vmap it). A
batch runs as rows instead (``relaxed_candidates``, ``least_deviations_rows``,
``project_relaxed_rows``): every search of a batch is one call and the back-projection of all
candidates one more, which is what ``api.project_batch`` uses. Those two calls are where the
Pallas kernels of ``jaxproj.projection.ops`` and their XLA twins are chosen, by one ``impl``
argument (``ops.Impl``). Nothing here is jitted; ``L``, ``M`` and ``impl`` are static.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxproj.errors import ConfigError
from jaxproj.projection.elm import predict
from jaxproj.projection.ops import Impl, ImplLike, pallas_interpret, resolve_impl
from jaxproj.projection.ops.backproj_pallas import back_min
from jaxproj.projection.ops.knn_pallas import PruneIndex
from jaxproj.projection.projector import (
    ChainLayout,
    Projector,
    StackedProjector,
    back_deviation,
    candidates,
)
from jaxproj.projection.search import nearest, nearest_rows

TIE_RTOL = 5e-5
"""Near-tie rule of the relaxed objective, with ``TIE_ATOL`` and ``SEARCH_RTOL``: the engine
computes in float32, so where two choices are equal to float32 round-off either is a correct
answer (the engine's pick is deterministic for a given program, not specified). Two kinds:

* deviations: two candidates of a chain tie when their back-projected deviations
  ``dev_a <= dev_b`` (``sqrt`` of the least squared deviation, descriptor units) satisfy
  ``dev_b - dev_a <= TIE_RTOL * dev_a + TIE_ATOL``. A deviation is a float32 sum over the
  kernel's 192 hidden units (``~1e-6`` absolute error on unit-vector coordinates, ``TIE_ATOL``),
  ordered differently by XLA's CPU and GPU reductions, the fused Pallas kernel and the batch's
  blocking: measured argmin flips between such orderings had relative gaps of squared
  deviations 1.5e-5 .. 9.3e-5 (H200, default model, 2026-11-23), i.e. 0.8e-5 .. 4.7e-5 in
  deviation (``TIE_RTOL``);
* searches: the ``n``-th and ``n+1``-th nearest landmarks (human for ``L``, robot for ``M``)
  tie when their squared distances differ by at most ``SEARCH_RTOL * (|x|^2 + |p|^2)``, the
  float32 rounding of ``|x|^2 - 2 x.p + |p|^2``; then either landmark's kernel may be used,
  which moves the candidate's deviation (2-core CPU, default model: 2 of 1,000 held-out poses).

``jaxproj.testing.Reference.judge`` applies the rule against the float64 reference,
``benchmarks.bench_projection`` counts the ties."""

TIE_ATOL = 1e-6
"""Absolute part of the deviation tie (descriptor units): ``TIE_RTOL``."""

SEARCH_RTOL = 1e-6
"""Search ties (``TIE_RTOL``): ~16 float32 epsilons of ``|x|^2 + |p|^2``."""


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
    impl: ImplLike = Impl.AUTO,
) -> jax.Array:
    """Every candidate's least squared back-projected deviation, for a batch and every chain.

    Args:
      stack: one projector per chain, stacked on a leading axis.
      dims: per chain ``(n, m, hidden)`` (``backward_widths``; the stacked arrays may be
        padded beyond them).
      x: ``(S, C, m)`` queries per chain; cand: ``(S, C, L, n)`` candidates; ridx:
        ``(S, C, L, M)`` their robot landmarks.
      impl: ``"xla"``: XLA's three passes (``_least_deviations`` per query); ``"pallas"``: the
        fused kernel (``jaxproj.projection.ops.backproj_pallas``); ``"auto"`` (default):
        ``ops.resolve_impl``'s choice for the default backend (static).

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

    if resolve_impl(impl) is Impl.XLA:
        return xla(stack, x, cand, ridx)
    return kernel(stack, x, cand, ridx, pallas_interpret())


def relaxed_candidates(
    p: Projector | StackedProjector, h: jax.Array, n_l: int, n_m: int, impl: ImplLike = Impl.AUTO
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """Steps 1-2 of the relaxed projection for a batch, every chain at once: the human-landmark
    searches of all queries and the robot-landmark searches of all their candidates as one
    ``search.nearest_rows`` call each (with ``impl="pallas"``, the default on CUDA GPUs, the
    fused kernel of ``jaxproj.projection.ops.knn_pallas``), not one small search per query.

    Args:
      p: a projector, or one projector per chain.
      h: ``(S, m)`` human descriptors.
      n_l, n_m: ``L`` and ``M`` (static).
      impl: the backend of the searches (``ops.Impl``; static).

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
    sizes = None if lay is None else lay.landmarks
    # the queries lie near the human landmarks (held-out MSR poses: 99.5 % certified on the
    # default robot's arms, one H100): the pruned search as well
    if isinstance(p, StackedProjector):
        human_index = _one_chain_index(p.human_index)
        robot_index = _one_chain_index(p.robot_index)
    else:
        human_index, robot_index = stack.human_index, stack.robot_index
    hidx = search_chains(stack.human, stack.human_sq, x.transpose(1, 0, 2), n_l, sizes, impl,
                         True, human_index)  # fmt: skip

    def forward(p: Projector, q: jax.Array, idx: jax.Array) -> jax.Array:
        return predict(p.forward, q, idx)  # (L, n), as ``candidates``

    per_chain = jax.vmap(forward)
    cand = jax.vmap(per_chain, in_axes=(None, 0, 0))(stack, x, hidx.transpose(1, 0, 2))
    c, n = cand.shape[1], cand.shape[3]  # cand: (S, C, L, n)
    rows = cand.transpose(1, 0, 2, 3).reshape(c, s * n_l, n)
    # the candidates lie near the robot landmarks: the pruned search certifies most rows
    ridx = search_chains(stack.robot, stack.robot_sq, rows, n_m, sizes, impl, True, robot_index)
    return x, cand, ridx.reshape(c, s, n_l, n_m).transpose(1, 0, 2, 3)


def search_chains(
    points: jax.Array | np.ndarray,
    points_sq: jax.Array | np.ndarray,
    x: jax.Array,
    n: int,
    sizes: Sequence[int] | None = None,
    impl: ImplLike = Impl.AUTO,
    prune: bool = False,
    index: PruneIndex | None = None,
) -> jax.Array:
    """``(C, R, n)`` indices of the ``n`` nearest landmarks of each chain's rows, each chain
    searched over its own landmarks only.

    Args:
      points: ``(C, K, d)`` stacked landmark sets, padded to the largest chain's ``K``.
      points_sq: ``(C, K)`` their squared norms (``+inf`` on padding).
      x: ``(C, R, d)`` query rows per chain.
      n: how many (static).
      sizes: per chain its real landmark count ``K_c`` (static; ``ChainLayout.landmarks``).
        ``None``, or every chain of the full ``K``: one batched ``search.nearest_rows`` call.
        Otherwise one call per chain over ``points[c, :K_c]``: a chain costs what its own
        landmarks cost, not the largest chain's (the default model's head has 799 landmarks
        against the right arm's 7,099). The same neighbours either way (padding is never
        returned).
      impl: the searches' backend (``ops.Impl``; static).
      prune: the fused kernel's pruned exact search first (``search.nearest_rows``; static).
      index: with ``prune``, the ``(C, ...)`` sets' pruning index computed beforehand
        (``search.nearest_rows``), for the one batched call; chain by chain it is computed in
        the trace.
    """
    k = points.shape[1]
    if sizes is None or all(s == k for s in sizes):
        return nearest_rows(points, points_sq, x, n, impl, prune, index)[0]
    parts = [
        nearest_rows(points[c : c + 1, :s], points_sq[c : c + 1, :s], x[c : c + 1], n, impl, prune)[
            0
        ]
        for c, s in enumerate(sizes)
    ]
    return jnp.concatenate(parts, axis=0)


def _one_chain_index(
    idx: tuple[PruneIndex | None, ...] | None,
) -> PruneIndex | None:
    """A one-chain stacked projector's pruning index (``(1, ...)``), if any."""
    if idx is None or len(idx) != 1 or idx[0] is None:
        return None
    return jax.tree.map(lambda a: a[None], idx[0])


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
    impl: ImplLike = Impl.AUTO,
    split: bool | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Relaxed projection of a batch of queries, every chain at once.

    The same answers as ``project_relaxed_one`` (``project_stacked_one`` for a stacked
    projector) vmapped over the batch, but with every search of the batch as one call
    (``relaxed_candidates``) and the back-projection of all candidates as
    ``least_deviations_rows`` calls (with ``impl="pallas"``, the default on CUDA GPUs, the fused
    kernels of ``jaxproj.projection.ops``, whose sums round differently: see there).

    Args:
      p: a projector, or one projector per chain.
      h: ``(S, m)`` human descriptors.
      n_l, n_m: ``L`` and ``M`` (static).
      chunk: back-project ``chunk`` queries at a time (a ``lax.map`` loop inside the one
        search call; static, must divide ``S``). ``None`` (default): all ``S`` at once. On the
        CPU the searches want many queries per call and the back-projection few (its gathered
        kernels should stay in cache): ``api.project_batch`` sets both.
      impl: the backend of the searches and the back-projection (``ops.Impl``; static),
        resolved once here (``"auto"``: for the default backend).
      split: a stacked projector's chains one after another, each at its own size
        (``StackedProjector.chain_slice``: its landmarks, columns and hidden units without the
        stack's padding), instead of all chains at once padded to the largest (static). ``None``
        (default): split with the fused Pallas kernels (``impl="pallas"``, CUDA GPUs), not with XLA
        (CPUs): one program per chain compiles about 1.8x as long on a CPU (0.9 -> 1.8 s, a
        three-chain model of 200 landmarks a chain, 64 queries, 2-core VM) for no measurable gain
        there (12 against 12-14 ms a call). The same answers within the near-tie rule (the padding
        never wins a search nor enters a kernel), for the work of the chains' own sizes: the stacked
        form searches every chain at the largest chain's landmark count (the default robot's head,
        1,010 landmarks, at its right arm's 10,617; the time-split experiment of issue 44,
        ``benchmarks/README.md``, measured another bundled robot's five chains at 2.05 us per pose
        one by one against 5.35 stacked, one H200).

    Returns:
      ``(r, dev)``: ``(S, n)`` driven joints and ``(S,)`` back-projected deviations (over the
      whole descriptor: ``sqrt(sum_c dev_c^2)`` for chains).
    """
    impl = resolve_impl(impl)
    if split is None:
        split = impl is Impl.PALLAS
    if split and isinstance(p, StackedProjector) and not p.layout.identity:
        parts = [
            project_relaxed_rows(p.chain_slice(c), h[:, list(cols)], n_l, n_m, chunk, impl)
            for c, cols in enumerate(p.layout.inputs)
        ]
        r = jnp.concatenate([a for a, _ in parts], axis=1)  # chain after chain
        order = np.argsort(np.concatenate([np.asarray(o, np.int64) for o in p.layout.outputs]))
        dev = jnp.sqrt(sum((v * v for _, v in parts), start=jnp.zeros_like(parts[0][1])))
        return r[:, order], dev
    stack, lay = _chains(p)
    s = h.shape[0]
    x, cand, ridx = relaxed_candidates(p, h, n_l, n_m, impl)
    dims = backward_widths(p)
    if chunk is None or chunk >= s:
        best = least_deviations_rows(stack, dims, x, cand, ridx, impl)  # (S, C, L)
    else:
        if s % chunk:
            raise ConfigError(f"chunk={chunk} does not divide the batch of {s} queries")

        def part(a: tuple[jax.Array, jax.Array, jax.Array]) -> jax.Array:
            return least_deviations_rows(stack, dims, *a, impl)

        parts = jax.tree.map(lambda a: a.reshape(s // chunk, chunk, *a.shape[1:]), (x, cand, ridx))
        best = jax.lax.map(part, parts).reshape(s, *ridx.shape[1:3])
    return _pick_rows(stack, lay, cand, best)


def pick_rows(
    p: Projector | StackedProjector, cand: jax.Array, best: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Step 3 of the relaxed projection for a batch: per query and chain, the candidate with the
    least deviation, the chains' answers assembled.

    Args:
      p: a projector, or one projector per chain.
      cand: ``(S, C, L, n)`` candidates (``relaxed_candidates``).
      best: ``(S, C, L)`` their least squared deviations (``least_deviations_rows``).

    Returns:
      ``(r, dev)`` as ``project_relaxed_rows``.
    """
    return _pick_rows(*_chains(p), cand, best)


def _pick_rows(
    stack: Projector, lay: ChainLayout | None, cand: jax.Array, best: jax.Array
) -> tuple[jax.Array, jax.Array]:
    s = cand.shape[0]
    r, v = jax.vmap(jax.vmap(_pick), in_axes=(None, 0, 0))(stack, cand, best)  # (S, C, n), (S, C)
    if lay is None or lay.identity:
        return r[:, 0], v[:, 0]
    return r.reshape(s, -1)[:, lay.output_index()], jnp.sqrt(jnp.sum(v * v, axis=1))
