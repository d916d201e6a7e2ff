"""Projected Gauss-Newton on the simplex, in joint space: the full objective's converged solver.

One simplex problem (``full.Problem``) is ``min_w F(w)`` over the unit simplex with

    r(w) = V^T w                                   # (n,) joint angles; V (P, n) the vertices
    u(w) = A w + c                                 # (K,) weights of the problem's K kernels
    F(w) = sum_k u_k ||e_k(r)||^2 + rho/2 ||r - r_c||^2 + eps/2 ||w||^2
    e_k(r) = kappa_k(r) - h                        # (m,) backward kernel k's residual

The kernels see ``w`` only through the ``n`` joint angles ``r`` (4 for an arm, 2 for the head),
so their derivatives are taken there, written out for the ELM (``residuals``, ``jacobians``):
``J_k = B_k diag(sigmoid'(z_k)) s_k W`` (``(m, n)``). In the weights,

    grad F = A^T phi + V g_r + eps w,              g_r = sum_k u_k 2 J_k^T e_k + rho (r - r_c)
    hess F ~ A^T P V^T + V P^T A + V H_r V^T + eps I,   H_r = sum_k u_k 2 J_k^T J_k + rho I

(``phi_k = ||e_k||^2``, ``P`` the rows ``2 J_k^T e_k``; ``H_r`` is Gauss-Newton's: the
residuals' second derivatives are left out, which changes the steps, never the stationary points).

Each ``update`` minimises the quadratic model on the simplex (``simplex_qp``: a primal
active-set method, ``QP_SWEEPS`` modified-Cholesky KKT solves) at each of the Levenberg-Marquardt
dampings ``DAMPINGS`` x the current one; the best trial is kept if it lowers ``F`` (monotone: a
solve never returns worse than its warm start), and the damping adapts. A problem is ``done``
when it is stationary (the model promises a decrease below ``dec_tol * F`` *and* the step just
taken moved ``r`` by less than ``step_tol`` *and* the Frank-Wolfe gap ``frank_wolfe_gap`` is at
most ``gap_tol * F``) or when no damping improves it any more (float32 has nothing left to
give). The gap is the first-order certificate: the model alone is not one, since the weighted
objective's Hessian is indefinite (its cross terms) and a rejected trial of an indefinite model
"promises" nothing at a point that is not stationary. ``run`` loops ``update`` in a
``lax.while_loop`` until the problem is done or a step cap; vmapped, the loop runs until every
problem of the batch is done (the batch's early exit) or the cap.

The solver is optax-style, ``SimplexSolver(init, update, run)``, with a ``NamedTuple`` state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from optax.projections import projection_simplex

from jaxproj.projection.elm import KernelSlice

DAMPINGS = (1.0, 32.0)
"""Multiples of the current damping tried at every step (each a full Newton trial)."""

DAMPING_START = 1e-4
"""Initial damping, as a fraction of the Hessian's mean diagonal."""

QP_SWEEPS = 6
"""Active-set sweeps of each step's quadratic subproblem (one KKT solve each). Every sweep
keeps the point feasible and lowers the model, so a subproblem cut short still gives a descent
trial; the objective judges it."""

WEIGHT_FLOOR = 1e-7
"""Weights below this count as 0 (the simplex projection leaves float32 dust of ~1e-8)."""

DAMPING_STALL = 1e6
"""A problem whose damping (fraction) grows past this has stalled: no step lowers ``F``."""


class Problem(NamedTuple):
    """One simplex problem (see the module doc); a pytree of arrays, vmappable."""

    verts: jax.Array  # (P, n) simplex vertices V
    mix: jax.Array  # (K, P) A: the kernels' weights' linear part
    mix0: jax.Array  # (K,) c: their constant part
    kernels: KernelSlice  # the K backward kernels
    w_in: jax.Array | np.ndarray  # (hidden, n) the backward bank's shared input weights W
    h: jax.Array  # (m,) the query
    anchor: jax.Array  # (n,) r_c: the proximal term's centre (the cluster's candidate)
    rho: jax.Array  # () proximal weight
    eps: jax.Array  # () ridge on the weights


def residuals(pr: Problem, r: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``e (K, m)`` the kernels' residuals at ``r (n,)``, and their hidden outputs ``q (K, H)``."""
    ks = pr.kernels
    z = (pr.w_in @ r)[None] * ks.inv_scale[:, None] + ks.bias
    q = jax.nn.sigmoid(z)
    return ks.offset + jnp.einsum("kh,koh->ko", q, ks.out) - pr.h[None], q


def jacobians(pr: Problem, q: jax.Array) -> jax.Array:
    """``J (K, m, n)``: ``d e_k / d r`` from the hidden outputs ``q (K, H)`` at ``r``."""
    ks = pr.kernels
    dq = q * (1.0 - q) * ks.inv_scale[:, None]
    return jnp.einsum("koh,hn->kon", ks.out * dq[:, None, :], pr.w_in)


def value(pr: Problem, w: jax.Array) -> jax.Array:
    """``F(w)`` (scalar) at weights ``w (P,)``."""
    r = pr.verts.T @ w
    e, _ = residuals(pr, r)
    u = pr.mix @ w + pr.mix0
    d = r - pr.anchor
    return u @ jnp.sum(e * e, axis=1) + 0.5 * pr.rho * (d @ d) + 0.5 * pr.eps * (w @ w)


class Derivatives(NamedTuple):
    f: jax.Array  # ()
    grad: jax.Array  # (P,)
    hess: jax.Array  # (P, P), Gauss-Newton in r
    r: jax.Array  # (n,)


def derivatives(pr: Problem, w: jax.Array) -> Derivatives:
    """``F``, its gradient and its (Gauss-Newton in ``r``) Hessian in the weights at ``w``."""
    r = pr.verts.T @ w
    e, q = residuals(pr, r)
    jac = jacobians(pr, q)  # (K, m, n)
    u = pr.mix @ w + pr.mix0
    phi = jnp.sum(e * e, axis=1)  # (K,)
    pg = 2.0 * jnp.einsum("kon,ko->kn", jac, e)  # (K, n): grad of phi_k in r
    d = r - pr.anchor
    f = u @ phi + 0.5 * pr.rho * (d @ d) + 0.5 * pr.eps * (w @ w)
    eye_n = jnp.eye(r.shape[0], dtype=w.dtype)
    g_r = u @ pg + pr.rho * d
    h_r = 2.0 * jnp.einsum("kon,kop->np", jac * u[:, None, None], jac) + pr.rho * eye_n
    cross = pr.mix.T @ pg @ pr.verts.T  # (P, P): A^T P V^T
    hess = cross + cross.T + pr.verts @ h_r @ pr.verts.T
    hess = hess + pr.eps * jnp.eye(w.shape[0], dtype=w.dtype)
    grad = pr.mix.T @ phi + pr.verts @ g_r + pr.eps * w
    return Derivatives(f, grad, hess, r)


def _cholesky_solve_unrolled(a: jax.Array, rhs: jax.Array) -> jax.Array:
    """``A^{-1} rhs`` for a small symmetric positive definite ``a (P, P)`` and ``rhs (P, k)``.

    Cholesky and the two triangular solves unrolled over the static ``P`` in plain array
    operations: vmapped over many problems they run as wide elementwise work, where a batched
    LAPACK call per problem is slow on a CPU. A pivot that comes out negative (``a`` not
    positive definite: the cross terms of the weighted objective) is replaced by its absolute
    value, a modified Cholesky factorisation: the solve is then of a nearby positive definite
    matrix, and the step it gives is judged by the objective itself.
    """
    p = a.shape[0]
    idx = jnp.arange(p)
    floor = 1e-12 * jnp.max(jnp.abs(jnp.diag(a)))
    cols: list[jax.Array] = []  # columns of the lower factor
    for j in range(p):
        v = a[:, j]
        for k in range(j):
            v = v - cols[k] * cols[k][j]
        pivot = jnp.maximum(jnp.abs(v[j]), floor)  # a negative pivot: its curvature reflected
        cols.append(
            jnp.where(idx > j, v / jnp.sqrt(pivot), 0.0) + jnp.where(idx == j, jnp.sqrt(pivot), 0.0)
        )
    y = rhs
    ys = []
    for j in range(p):  # L y = rhs
        yj = y[j] / cols[j][j]
        ys.append(yj)
        y = y - cols[j][:, None] * yj[None]
    x: list[jax.Array] = [jnp.zeros_like(rhs[0])] * p
    for j in reversed(range(p)):  # L^T x = y
        acc = ys[j]
        for k in range(j + 1, p):
            acc = acc - cols[j][k] * x[k]
        x[j] = acc / cols[j][j]
    return jnp.stack(x)


def _cholesky_solve_looped(a: jax.Array, rhs: jax.Array) -> jax.Array:
    """``A^{-1} rhs`` for a small symmetric positive definite ``a (P, P)`` and ``rhs (P, k)``.

    ``_cholesky_solve_unrolled``'s factorisation and solves, each a ``lax.fori_loop`` over the
    ``P`` columns of whole-matrix array operations (right-looking): the program holds one loop
    body instead of ``O(P^2)`` unrolled steps. The CPU's choice: compiling a full projection
    takes 6.1 s instead of 10.1 (2-core VM) at the same speed; on a GPU the loop runs 3.1x
    slower (H200, default model, public API: 4.5 K against 13.8 K poses/s), so GPUs keep the
    unrolled form.
    """
    p = a.shape[0]
    idx = jnp.arange(p)
    floor = 1e-12 * jnp.max(jnp.abs(jnp.diag(a)))

    def factor(j: jax.Array, carry: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        work, low = carry  # work: a minus the outer products of the columns so far
        v = work[:, j]
        pivot = jnp.sqrt(jnp.maximum(jnp.abs(v[j]), floor))  # negative: curvature reflected
        below = jnp.where(idx > j, v / pivot, 0.0)
        low = low.at[:, j].set(below + jnp.where(idx == j, pivot, 0.0))
        return work - below[:, None] * below[None, :], low

    _, low = jax.lax.fori_loop(0, p, factor, (a, jnp.zeros_like(a)))
    diag = jnp.diag(low)

    def forward(j: jax.Array, carry: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        y, ys = carry  # L y = rhs, column by column
        yj = y[j] / diag[j]
        return y - low[:, j, None] * yj[None], ys.at[j].set(yj)

    _, ys = jax.lax.fori_loop(0, p, forward, (rhs, jnp.zeros_like(rhs)))

    def backward(i: jax.Array, x: jax.Array) -> jax.Array:
        j = p - 1 - i  # L^T x = y, from the last row up (x is 0 where not yet solved)
        return x.at[j].set((ys[j] - low[:, j] @ x) / diag[j])

    return jax.lax.fori_loop(0, p, backward, jnp.zeros_like(rhs))


def _cholesky_solve(a: jax.Array, rhs: jax.Array) -> jax.Array:
    """``A^{-1} rhs`` by the modified Cholesky factorisation (``_cholesky_solve_unrolled``):
    looped over columns on CPUs (``_cholesky_solve_looped``: compiles in half the time), unrolled
    elsewhere.

    Picked when traced, by JAX's default backend: ``lax.platform_dependent`` traced and
    lowered both forms into every program (a Newton projection's trace, 100-landmark model, 64
    queries, 2-core VM: 2.2-2.7 s with both, 1.3-1.8 s with one; a lone KKT solve's compile
    0.6-0.7 s against 0.4-0.5 s). A program lowered for another platform than the default one
    (arrays placed on a CPU device of a GPU machine) runs the default backend's form: the same
    solve, rounded in another order.
    """
    if jax.default_backend() == "cpu":
        return _cholesky_solve_looped(a, rhs)
    return _cholesky_solve_unrolled(a, rhs)


def _kkt_solve(b: jax.Array, c: jax.Array, free: jax.Array) -> tuple[jax.Array, jax.Array]:
    """``y (P,)`` minimising ``y^T B y / 2 + c.y`` over ``sum(y) = 1`` with ``y_i = 0`` off
    ``free``, and the constraint's multiplier ``nu``: ``B_FF y_F = -c_F - nu 1``."""
    a = jnp.where(free[:, None] & free[None, :], b, 0.0) + jnp.diag(jnp.where(free, 0.0, 1.0))
    one = free.astype(b.dtype)
    z = _cholesky_solve(a, jnp.stack([jnp.where(free, -c, 0.0), one], axis=1))
    nu = (jnp.sum(z[:, 0]) - 1.0) / jnp.sum(z[:, 1])
    return z[:, 0] - nu * z[:, 1], nu


def simplex_qp(b: jax.Array, c: jax.Array, x0: jax.Array, sweeps: int) -> jax.Array:
    """Minimise ``x^T B x / 2 + c.x`` over the unit simplex, from the feasible ``x0 (P,)``.

    A primal active-set method (``B`` positive definite on the faces it visits): solve the
    KKT system on the free weights; if the solution is feasible, free the fixed weight whose
    multiplier is most negative (none: optimal); else step to the first weight that reaches 0
    and fix it. Each sweep is one KKT solve; ``sweeps`` of them (the loop stops changing
    ``x`` once it is optimal), so a face change costs a sweep, not a kernel evaluation.
    """

    def sweep(_: int, state: tuple[jax.Array, jax.Array, jax.Array]) -> tuple:
        x, free, finished = state
        y, nu = _kkt_solve(b, c, free)
        feasible = jnp.all(jnp.where(free, y, 0.0) >= 0.0)
        lam = jnp.where(free, jnp.inf, b @ y + c + nu)  # the fixed weights' multipliers
        i_in = jnp.argmin(lam)
        optimal = feasible & (lam[i_in] >= 0.0)
        # infeasible: move from x toward y until the first free weight reaches 0
        dec = free & (y < x)
        ratio = jnp.where(dec, x / jnp.where(dec, x - y, 1.0), jnp.inf)
        i_out = jnp.argmin(ratio)
        alpha = jnp.clip(ratio[i_out], 0.0, 1.0)
        x_part = jnp.where(free, x + alpha * (y - x), 0.0).at[i_out].set(0.0)
        x_new = jnp.where(feasible, y, x_part)
        free_new = jnp.where(
            feasible, free.at[i_in].set(~optimal | free[i_in]), free.at[i_out].set(False)
        )
        keep = finished
        return (
            jnp.where(keep, x, x_new),
            jnp.where(keep, free, free_new),
            finished | optimal,
        )

    x0 = jnp.where(x0 > WEIGHT_FLOOR, x0, 0.0)
    x0 = x0 / jnp.sum(x0)
    # ``finished`` starts as a False derived from x0, so batched like the rest of the carry
    # (vmap's loop rule then needs no second pass to widen it: a faster trace)
    x, _, _ = jax.lax.fori_loop(0, sweeps, sweep, (x0, x0 > 0, x0[0] < 0.0))
    return x


def _project(w: jax.Array) -> jax.Array:
    # optax 0.2.8's simplex projection divides by int32 indices: standard promotion inside
    with jax.numpy_dtype_promotion("standard"):
        return projection_simplex(w)


class NewtonState(NamedTuple):
    """The solver's state for one problem."""

    w: jax.Array  # (P,) current weights (on the simplex)
    d: Derivatives  # at w
    damping: jax.Array  # () Levenberg-Marquardt damping, a fraction of mean(diag(H))
    step: jax.Array  # () largest |change of r| of the last accepted step (inf at the start)
    done: jax.Array  # () bool
    steps: jax.Array  # () int32 updates taken


class SimplexSolver(NamedTuple):
    """An optax-style solver: ``init(problem, w0) -> state``, ``update(problem, state) -> state``,
    and ``run(problem, state, cap) -> state`` (``update`` until done or ``cap`` steps in all)."""

    init: Callable[[Problem, jax.Array], NewtonState]
    update: Callable[[Problem, NewtonState], NewtonState]
    run: Callable[[Problem, NewtonState, int], NewtonState]


def frank_wolfe_gap(grad: jax.Array, w: jax.Array) -> jax.Array:
    """``grad . w - min(grad)``: the decrease of ``F`` that its linearisation at ``w (P,)``
    promises by moving all the way to the best vertex of the simplex; ``>= 0``, and ``0``
    exactly at a KKT point of ``min F`` over the simplex (every weight in use has the least
    partial derivative)."""
    return grad @ w - jnp.min(grad)


def gauss_newton(dec_tol: float, step_tol: float, gap_tol: float = 0.0) -> SimplexSolver:
    """The projected Gauss-Newton solver (module doc).

    Args:
      dec_tol: stationarity: the quadratic model predicts a decrease of ``F`` of at most
        ``dec_tol * max(F, 1e-8)`` (its least damped step) ...
      step_tol: ... and the step just taken (none, if rejected) moved every joint by less
        than ``step_tol`` rad ...
      gap_tol: ... and the Frank-Wolfe gap at the new point is at most
        ``gap_tol * max(F, 1e-8)`` (``0``: no gap test, the stop of 0.2.0).
    """
    dampings = jnp.asarray(DAMPINGS, jnp.float32)
    sweeps = QP_SWEEPS

    def init(pr: Problem, w0: jax.Array) -> NewtonState:
        d = derivatives(pr, w0)
        inf = jnp.asarray(jnp.inf, w0.dtype)
        return NewtonState(
            w0, d, jnp.asarray(DAMPING_START, w0.dtype), inf, jnp.asarray(False), jnp.int32(0)
        )

    def update(pr: Problem, s: NewtonState) -> NewtonState:
        w, d = s.w, s.d
        scale = jnp.mean(jnp.diag(d.hess)) + 1e-12
        lams = s.damping * dampings * scale
        eye = jnp.eye(w.shape[0], dtype=w.dtype)

        def trial(lam: jax.Array) -> jax.Array:
            b = d.hess + lam * eye
            return simplex_qp(b, d.grad - b @ w, w, sweeps)

        trials = jax.vmap(trial)(lams)
        dx = trials - w[None]  # (T, P)
        predicted = -(dx @ d.grad + 0.5 * jnp.einsum("tp,pq,tq->t", dx, d.hess, dx))
        values = jax.vmap(lambda t: value(pr, t))(trials)
        ok = jnp.all(jnp.isfinite(trials), axis=1) & jnp.isfinite(values)
        values = jnp.where(ok, values, jnp.inf)  # a damping too small for a convex model
        # what the model promises at most (a failed trial promises nothing)
        predicted = jnp.max(jnp.where(ok, predicted, -jnp.inf))
        predicted = jnp.where(jnp.any(ok), predicted, jnp.inf)
        i = jnp.argmin(values)
        better = values[i] < d.f
        w_new = jnp.where(better, trials[i], w)
        d_new = jax.tree.map(lambda a, b: jnp.where(better, a, b), derivatives(pr, w_new), d)
        step = jnp.where(better, jnp.max(jnp.abs(d_new.r - d.r)), 0.0)
        factor = jnp.where(better, dampings[i] / 8.0, 4096.0)
        damping = jnp.clip(s.damping * factor, 1e-9, 2 * DAMPING_STALL)
        flat = predicted <= dec_tol * jnp.maximum(d.f, 1e-8)
        gap = frank_wolfe_gap(d_new.grad, w_new)
        kkt = (gap_tol <= 0.0) | (gap <= gap_tol * jnp.maximum(d_new.f, 1e-8))
        done = (flat & (step <= step_tol) & kkt) | (damping > DAMPING_STALL)
        return NewtonState(w_new, d_new, damping, step, s.done | done, s.steps + 1)

    def run(pr: Problem, state: NewtonState, cap: int) -> NewtonState:
        def cond(s: NewtonState) -> jax.Array:
            return ~s.done & (s.steps < cap)

        return jax.lax.while_loop(cond, lambda s: update(pr, s), state)

    return SimplexSolver(init, update, run)
