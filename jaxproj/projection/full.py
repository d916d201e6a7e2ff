"""The full objective (paper eq. 2-3): simplex weights over each candidate's robot landmarks.

For one query ``h*`` and each of its ``L`` candidates ``r_j`` (``projector.candidates``), simplex
weights ``w`` over the candidate's ``M`` robot landmarks (and, with
``FullConfig.include_candidate``, the candidate itself as vertex 0) give ``r(w) = V^T w``; the
answer is ``r(w*)`` of the problem with the least objective value. The problems, exactly
(``simplex_newton`` has the notation; ``phi_k(r) = ||kappa^r_{j,k}(r) - h*||^2``):

* ``objective="weighted"`` (default): one problem per candidate,
  ``F(w) = sum_k u_k(w) phi_k(r(w)) + rho/2 ||r(w) - r_j||^2 + eps/2 ||w||^2`` with the kernel
  weights ``u = w`` (or, with the candidate as vertex 0, ``u_k = w_k + w_0 / M``: the candidate is
  judged by the mean of its cluster's kernels).
* ``objective="min"``: the paper's ``min_k min_w`` read literally: ``M`` problems per
  candidate, one per kernel ``k``, ``F_k(w) = phi_k(r(w)) + rho/2 ... + eps/2 ...``; the answer
  is the best of all ``L x M``.

``rho`` (``FullConfig.proximal``) pulls ``r`` toward the candidate only where the kernels do
not hold it (an elbow's yaw on a straight arm: there ``F`` is flat and its minimiser otherwise
not unique); ``eps`` (``FullConfig.ridge``) picks the least-norm weights among those giving
the same ``r``. Both are small enough that a well-conditioned answer does not move
(``benchmarks/results/full_objective.json``).

Two solvers: projected Gauss-Newton in joint space (``simplex_newton``, the default, run to
convergence) and projected Adam (``solve_adam``, fixed steps, the fast option). Both project
with ``optax.projections.projection_simplex`` and never return worse than the warm start.
``project_full_one`` is written for ONE query (callers vmap it); nothing here is jitted; ``L``,
``M`` and the ``FullConfig`` are static.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax

from jaxproj.projection import simplex_newton as sn
from jaxproj.projection.config import FullConfig
from jaxproj.projection.elm import KernelSlice, take
from jaxproj.projection.projector import Projector, candidates
from jaxproj.projection.search import nearest


def problems(
    p: Projector, h: jax.Array, r_c: jax.Array, idx: jax.Array, cfg: FullConfig
) -> tuple[sn.Problem, jax.Array]:
    """The simplex problems of one candidate ``r_c (n,)`` with robot landmarks ``idx (M,)``.

    Returns ``(problems, w0)``: one problem (``"weighted"``) or ``M`` of them stacked on a
    leading axis (``"min"``), and the warm start ``(P,)``: ``e_0`` with the candidate as a
    vertex (the relaxed answer), else the inverse squared distance weights of ``r_c`` to the
    landmarks.
    """
    rk = p.robot[idx]  # (M, n)
    n_m = rk.shape[0]
    kernels = take(p.backward, idx)  # gathered once, evaluated at every step
    dtype = rk.dtype
    if cfg.include_candidate:
        verts = jnp.concatenate([r_c[None], rk], axis=0)  # (M + 1, n)
        w0 = jnp.zeros((n_m + 1,), dtype).at[0].set(1.0)
    else:
        verts = rk
        d2 = jnp.sum((rk - r_c[None]) ** 2, axis=1)
        w0 = 1.0 / (d2 + 1e-8)
        w0 = w0 / jnp.sum(w0)
    rho, eps = jnp.asarray(cfg.proximal, dtype), jnp.asarray(cfg.ridge, dtype)
    if cfg.objective == "weighted":
        mix = jnp.eye(n_m, dtype=dtype)
        if cfg.include_candidate:
            mix = jnp.concatenate([jnp.full((n_m, 1), 1.0 / n_m, dtype), mix], axis=1)
        pr = sn.Problem(
            verts, mix, jnp.zeros((n_m,), dtype), kernels, p.backward.w, h, r_c, rho, eps
        )
        return pr, w0

    def one(k: jax.Array) -> sn.Problem:  # kernel k alone
        ks = KernelSlice(*(a[k][None] for a in kernels))
        zero = jnp.zeros((1, verts.shape[0]), dtype)
        return sn.Problem(verts, zero, jnp.ones((1,), dtype), ks, p.backward.w, h, r_c, rho, eps)

    return jax.vmap(one)(jnp.arange(n_m)), w0


class _AdamState(NamedTuple):
    w: jax.Array
    opt_state: optax.OptState
    best_w: jax.Array
    best_f: jax.Array


def solve_adam(pr: sn.Problem, w0: jax.Array, cfg: FullConfig) -> tuple[jax.Array, jax.Array]:
    """Projected Adam on one problem, ``cfg.iterations`` steps; returns ``(w*, F(w*))``.

    Every step is an Adam update followed by ``optax.projections.projection_simplex``; the
    best iterate is kept, so the returned value is never worse than ``F(w0)``. It stops where
    its steps stop, usually short of the minimum (``benchmarks/RESULTS.md``).
    """
    opt = optax.adam(cfg.learning_rate)
    f = jax.value_and_grad(lambda w: sn.value(pr, w))

    # optax 0.2.8 mixes int32 and float32 inside ``update`` (Adam's bias correction raises the
    # decays to its int32 step count): standard promotion for that call only.
    def step(state: _AdamState, _: None) -> tuple[_AdamState, None]:
        val, g = f(state.w)
        better = val < state.best_f
        best_w = jnp.where(better, state.w, state.best_w)
        best_f = jnp.where(better, val, state.best_f)
        with jax.numpy_dtype_promotion("standard"):  # optax internals, see above
            upd, opt_state = opt.update(g, state.opt_state, state.w)
        w = sn._project(optax.apply_updates(state.w, upd))
        return _AdamState(w, opt_state, best_w, best_f), None

    init = _AdamState(w0, opt.init(w0), w0, sn.value(pr, w0))
    final, _ = jax.lax.scan(step, init, None, length=cfg.iterations)
    f_last = sn.value(pr, final.w)
    better = f_last < final.best_f
    return jnp.where(better, final.w, final.best_w), jnp.where(better, f_last, final.best_f)


def solve(pr: sn.Problem, w0: jax.Array, cfg: FullConfig) -> tuple[jax.Array, jax.Array]:
    """One problem by ``cfg.solver`` (Newton: to ``cfg.iterations`` steps); returns
    ``(r(w*) (n,), F(w*))``."""
    if cfg.solver == "adam":
        w, f = solve_adam(pr, w0, cfg)
        return pr.verts.T @ w, f
    solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol, cfg.gap_tol)
    s = solver.run(pr, solver.init(pr, w0), cfg.iterations)
    return s.d.r, s.d.f


def _solve_newton_screened(
    prs: sn.Problem, w0: jax.Array, order: jax.Array, cfg: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Every problem of one query by Newton for ``cfg.screen`` steps, then only the
    ``cfg.finalists`` with the least objective on to ``cfg.iterations``: ``(r (n,), F)`` of the
    best. A problem far behind after the screen does not catch up (measured against solving
    every problem to the end: ``benchmarks/results/full_objective.json``), and a vmapped loop
    runs as long as its slowest problem, so the long tail is paid for two problems, not ``L``.
    ``order (P,)``: the problems' candidate ranks, for the near-tie rule (``pick``).
    """
    solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol, cfg.gap_tol)
    axes = (_AXES, 0)
    states = jax.vmap(solver.init, in_axes=axes)(prs, w0)
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.screen), in_axes=axes)(prs, states)
    n_p = w0.shape[0]
    if cfg.finalists < n_p:
        _, keep = jax.lax.top_k(-states.d.f, cfg.finalists)
        prs = _batched(prs, lambda a: a[keep])
        states = jax.tree.map(lambda a: a[keep], states)
        order = order[keep]
    states = jax.vmap(lambda pr, s: solver.run(pr, s, cfg.iterations), in_axes=axes)(prs, states)
    j = pick(states.d.f, order, cfg.tie_rtol)
    return states.d.r[j], states.d.f[j]


def pick(f: jax.Array, order: jax.Array, tie_rtol: float) -> jax.Array:
    """The answer among solved problems under the near-tie rule (``FullConfig.tie_rtol``).

    Args:
      f: ``(P,)`` their converged objective values.
      order: ``(P,)`` int their candidates' ranks (0: the nearest human landmark's).
      tie_rtol: relative width of the tie (static).

    Returns:
      The index into ``f`` of the first problem in candidate order whose value is within
      ``tie_rtol * min(f)`` of ``min(f)`` (``argmin(f)`` for ``tie_rtol = 0``, up to exact
      ties).
    """
    f_min = jnp.min(f)
    tied = f <= f_min + jnp.asarray(tie_rtol, f.dtype) * jnp.abs(f_min)
    return jnp.argmin(jnp.where(tied, order, jnp.iinfo(order.dtype).max))


_AXES = sn.Problem(0, 0, 0, 0, None, None, 0, None, None)  # type: ignore[arg-type]
"""vmap axes of a batch of problems of one query: the bank's ``W``, the query and the two
regularisers are shared (not copied per problem)."""


def _batched(prs: sn.Problem, fn: Callable[[jax.Array], jax.Array]) -> sn.Problem:
    """``fn`` applied to the per-problem fields of a batch of problems (``_AXES``)."""
    return prs._replace(
        verts=fn(prs.verts),
        mix=fn(prs.mix),
        mix0=fn(prs.mix0),
        kernels=KernelSlice(*(fn(a) for a in prs.kernels)),
        anchor=fn(prs.anchor),
    )


def _shared(prs: sn.Problem, p: Projector, h: jax.Array, cfg: FullConfig) -> sn.Problem:
    """Replace the broadcast copies of the shared fields by the one unbatched value."""
    dtype = h.dtype
    rho, eps = jnp.asarray(cfg.proximal, dtype), jnp.asarray(cfg.ridge, dtype)
    return prs._replace(w_in=p.backward.w, h=h, rho=rho, eps=eps)


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
      ``(r, f, f0)``: ``(n,)`` projected pose, the objective value of the chosen problem at its
      optimum and at its warm start.
    """
    cand = candidates(p, h, n_l)  # (L, n)
    ridx, _ = nearest(p.robot, p.robot_sq, cand, n_m)  # (L, M)
    prs, w0 = jax.vmap(problems, in_axes=(None, None, 0, 0, None))(p, h, cand, ridx, cfg)
    if cfg.objective == "min":  # (L, M) problems sharing their cluster's warm start
        w0 = jnp.repeat(w0, n_m, axis=0)
        prs = _batched(prs, lambda a: a.reshape(n_l * n_m, *a.shape[2:]))
    prs = _shared(prs, p, h, cfg)
    f0 = jax.vmap(sn.value, in_axes=(_AXES, 0))(prs, w0)
    n_p = f0.shape[0]
    if cfg.clusters == 1 < n_p:  # one problem: index it (a size-1 vmap ran 2x slower on CPU)
        j = jnp.argmin(f0)  # the first minimum, as top_k(-f0, 1) picks it
        r, f = solve(_batched(prs, lambda a: a[j]), w0[j], cfg)
        return jnp.clip(r, p.lower, p.upper), f, f0[j]
    order = jnp.arange(n_p)  # candidate ranks of the problems (``pick``)
    if 0 < cfg.clusters < n_p:  # optimise only the problems that start best
        _, order = jax.lax.top_k(-f0, cfg.clusters)
        prs = _batched(prs, lambda a: a[order])
        w0, f0 = w0[order], f0[order]
    if cfg.solver == "newton" and 0 < cfg.finalists:
        r1, f1 = _solve_newton_screened(prs, w0, order, cfg)
        return jnp.clip(r1, p.lower, p.upper), f1, jnp.min(f0)
    r, f = jax.vmap(solve, in_axes=(_AXES, 0, None))(prs, w0, cfg)
    j = pick(f, order, cfg.tie_rtol)
    return jnp.clip(r[j], p.lower, p.upper), f[j], f0[j]
