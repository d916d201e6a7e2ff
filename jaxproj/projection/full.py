"""The full objective (paper eq. 2-3): simplex weights over each candidate's robot landmarks.

For one query ``h*`` and each of its ``L`` candidates ``r_j`` (``projector.candidates``), simplex
weights ``w`` over the candidate's ``M`` robot landmarks give ``r(w) = sum_k w_k r_{j,k}``; ``w``
minimises a back-projected deviation (``cluster_objective``, see ``FullConfig.objective``) by a
projected solver, and the answer is ``r(w*)`` of the ``j`` with the least objective value.

Two solvers as pure functions of one cluster (``cluster``): projected Adam (``solve_cluster``)
and projected Newton on the simplex's faces (``solve_cluster_newton``), both with
``optax.projections.projection_simplex``. ``project_full_one`` is written for ONE query
(callers vmap it); nothing here is jitted; ``L``, ``M`` and the ``FullConfig`` are static.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax
from optax.projections import projection_simplex

from jaxproj.projection.config import FullConfig
from jaxproj.projection.elm import KernelSlice, predict_slice, project_inputs, take
from jaxproj.projection.projector import Projector, candidates
from jaxproj.projection.search import nearest


class _PGState(NamedTuple):
    w: jax.Array
    opt_state: optax.OptState
    best_w: jax.Array
    best_f: jax.Array


class Cluster(NamedTuple):
    """The simplex problem of one candidate (``cluster``)."""

    verts: jax.Array  # (V, n) simplex vertices
    w0: jax.Array  # (V,) warm start
    kernels: KernelSlice  # the M backward kernels, gathered once


def cluster(p: Projector, r_c: jax.Array, idx: jax.Array, cfg: FullConfig) -> Cluster:
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
    return Cluster(verts, w0, kernels)


def cluster_objective(
    p: Projector, h: jax.Array, c: Cluster, cfg: FullConfig, w: jax.Array
) -> jax.Array:
    """The full objective ``f(w)`` of one cluster (see ``FullConfig.objective``)."""
    r = jnp.einsum("m,mn->n", w, c.verts)
    back = predict_slice(c.kernels, project_inputs(p.backward, r))  # (M, m)
    dev = jnp.sum((back - h[None]) ** 2, axis=-1)
    if cfg.objective == "min":
        return jnp.min(dev)
    wk = w[1:] / jnp.maximum(jnp.sum(w[1:]), 1e-12) if cfg.include_candidate else w
    return jnp.sum(wk * dev)


def start_value(p: Projector, h: jax.Array, c: Cluster, cfg: FullConfig) -> jax.Array:
    """``f(w0)``: the objective of one cluster at its warm start."""
    return cluster_objective(p, h, c, cfg, c.w0)


def solve_cluster(
    p: Projector, h: jax.Array, c: Cluster, f0: jax.Array, cfg: FullConfig
) -> tuple[jax.Array, jax.Array]:
    """Projected gradient on the simplex of one cluster (``cluster``) whose warm-start value
    is ``f0``; returns (r(w*), f(w*)).

    Every step is an Adam update followed by ``optax.projections.projection_simplex``; the
    best iterate is kept, so the returned value is never worse than ``f0``.
    """

    def objective(w: jax.Array) -> jax.Array:
        return cluster_objective(p, h, c, cfg, w)

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


def solve_cluster_newton(
    p: Projector, h: jax.Array, c: Cluster, f0: jax.Array, cfg: FullConfig
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
        return cluster_objective(p, h, c, cfg, w)

    v = c.w0.shape[0]
    damping = jnp.asarray(NEWTON_DAMPING, c.w0.dtype)
    fractions = jnp.asarray(NEWTON_STEPS, c.w0.dtype)
    scales = jnp.asarray(GRADIENT_STEPS, c.w0.dtype)
    n_newton = len(NEWTON_DAMPING) * len(NEWTON_STEPS)

    def project(w: jax.Array) -> jax.Array:
        with jax.numpy_dtype_promotion("standard"):  # optax internals, see solve_cluster
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
    clusters = jax.vmap(cluster, in_axes=(None, 0, 0, None))(p, cand, ridx, cfg)
    f0 = jax.vmap(start_value, in_axes=(None, None, 0, None))(p, h, clusters, cfg)  # (L,)
    solve = solve_cluster_newton if cfg.solver == "newton" else solve_cluster
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
