"""Projection engine tests on a small real landmark set (fast: no mean shift here)."""

import dataclasses

import jax
import numpy as np
import pytest

from jaxproj import robots
from jaxproj.errors import ConfigError, InputError
from jaxproj.human.skeleton import descriptor
from jaxproj.io import datasets
from jaxproj.projection import api as engine
from jaxproj.projection import simplex_newton as sn
from jaxproj.projection.config import ADAM_30, NEWTON, FullConfig
from jaxproj.robots.nao_h25 import ik, robot

CFG = engine.BuildConfig(
    chains="whole", landmarks=None, bandwidth=1.0, k=16, hidden=32, lam=1e-3, input_scale=1.0
)


def _descriptors(subjects, actions=None):
    seqs = datasets.msr_action3d(subjects=subjects, actions=actions)
    pos = np.concatenate([s.positions[s.valid] for s in seqs])
    d, ok = descriptor(pos)
    return np.asarray(d)[np.asarray(ok)]


@pytest.fixture(scope="module")
def model():
    d = _descriptors([1, 3])
    human = d[np.random.default_rng(0).choice(len(d), 400, replace=False)]
    robot_poses = np.asarray(ik.solve_driven(human))
    return engine.from_landmarks(human, robot_poses, CFG, n_train=len(d))


def _deg(a, b):
    return np.degrees(np.abs(np.asarray(a) - np.asarray(b)))


@pytest.mark.parametrize("objective", ["relaxed", "full"])
def test_identity_projecting_a_landmark_returns_its_robot_pose(model, objective):
    p = model.projector.chain(0)
    got, _ = engine.project(model, np.asarray(p.human), objective, batch_size=512)
    err = _deg(got, p.robot).max(axis=1)
    # anchored kernels are exact at their own landmark: identity up to float32 round-off
    assert err.max() < 0.01


def test_similarity_perturbed_landmark_stays_near_the_ik(model):
    p = model.projector.chain(0)
    rng = np.random.default_rng(1)
    h = np.asarray(p.human)
    pert = h + rng.normal(scale=0.03, size=h.shape).astype(np.float32)
    truth = np.asarray(ik.solve_driven(pert))
    got, _ = engine.project(model, pert, "relaxed")
    err = _deg(got, truth).mean(axis=1)
    # better than snapping to the landmark's own pose (what "no projection" would give)
    snap = _deg(p.robot, truth).mean(axis=1)
    assert np.median(err) < 3.0
    assert np.median(err) < np.median(snap)


def test_outputs_within_limits_and_finite_on_held_out_people(model):
    d = _descriptors([2], actions=[1, 5, 9])
    lo, hi = robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX]
    for objective in ("relaxed", "full"):
        got, val = engine.project(model, d, objective)
        assert np.isfinite(got).all() and np.isfinite(val).all()
        assert (got >= lo).all() and (got <= hi).all()


def test_full_objective_is_a_real_optimisation(model):
    d = _descriptors([2], actions=[1, 5])[:32]  # the queries of the next test: one compile
    relaxed, _ = engine.project(model, d, "relaxed")
    for cfg, n in ((FullConfig(), 32), (FullConfig(objective="min", include_candidate=True), 32)):
        d, relaxed = d[:n], relaxed[:n]
        # the model's one chain, solved as ``project`` solves it (``_full_values``), but with the
        # warm start's value too
        r, f_star, f0 = _full_values(model, d, cfg)
        assert np.abs(r - relaxed).max() > 1e-3  # it moves away from the relaxed answer
        assert (f_star <= f0 + 1e-7).all()  # never worse than its warm start
        assert (f_star < f0 - 1e-6).mean() > 0.1  # and it improves a real share of queries


_FULL_FNS: dict = {}
"""``_full_values``' jitted programs by (model, config): each compiled once per query count,
shared by the tests that call it (compiling dominates these tests on 2 cores)."""


def _full_values(model, d, cfg):
    import jax

    from jaxproj.projection.full import project_full_one

    key = (id(model), cfg)
    if key not in _FULL_FNS:
        p = model.projector.chain(0)
        _FULL_FNS[key] = jax.jit(jax.vmap(lambda h: project_full_one(p, h, 10, 10, cfg)))
    r, f, f0 = _FULL_FNS[key](d)
    return np.asarray(r), np.asarray(f), np.asarray(f0)


def test_both_cholesky_forms_solve_the_same_modified_system():
    # the CPU's looped and the GPU's unrolled modified Cholesky (``simplex_newton``) against the
    # float64 NumPy one, on positive definite and indefinite matrices (negative pivots taken
    # by absolute value), vmapped as the solver calls them
    from jaxproj.testing import _modified_cholesky_solve

    rng = np.random.default_rng(0)
    g = rng.normal(size=(64, 10, 10))
    a = g @ g.transpose(0, 2, 1) / 10 + 0.1 * np.eye(10)
    a[32:] -= 1.5 * np.eye(10)  # indefinite: some pivots negative
    rhs = rng.normal(size=(64, 10, 2))
    want = np.stack([_modified_cholesky_solve(x, r) for x, r in zip(a, rhs, strict=True)])
    for solve in (sn._cholesky_solve_looped, sn._cholesky_solve_unrolled, sn._cholesky_solve):
        got = np.asarray(jax.jit(jax.vmap(solve))(a.astype(np.float32), rhs.astype(np.float32)))
        scale = np.abs(want).max(axis=(1, 2), keepdims=True)
        assert np.abs(got - want).max() <= 1e-3 * scale.max(), solve.__name__
        np.testing.assert_allclose(got / scale, want / scale, atol=2e-4)


def test_newton_converges_where_adam_stops_short(model):
    # the same problems, the same warm starts: the default solver (``FullConfig()``, Newton)
    # reaches a lower objective than 30 Adam steps, and its answers agree with its own long
    # solves (200 steps, every problem to the end, no stationarity exit): it has converged
    assert FullConfig() == NEWTON
    d = _descriptors([2], actions=[1, 5])[:32]
    r_n, f_n, f0 = _full_values(model, d, FullConfig())
    _, f_a, _ = _full_values(model, d, ADAM_30)
    long = dataclasses.replace(NEWTON, iterations=200, finalists=0, dec_tol=0.0, step_tol=0.0)
    r_long, f_long, _ = _full_values(model, d, long)
    assert (f_n <= f0 + 1e-7).all()  # monotone: never worse than the warm start
    assert (f_n <= f_a * (1 + 1e-4) + 1e-7).mean() >= 0.95
    assert (f_n < f_a * 0.99).mean() > 0.5
    assert (_deg(r_n, r_long).max(axis=1) <= 0.1).mean() >= 0.95


def test_newton_is_deterministic_and_serves_every_reading(model):
    # (monotonicity against the warm start: test_newton_converges_where_adam_stops_short)
    d = _descriptors([2], actions=[9])[:16]
    for cfg in (
        dataclasses.replace(NEWTON, include_candidate=True),
        dataclasses.replace(NEWTON, objective="min", include_candidate=True, clusters=3),
    ):
        a, fa = engine.project(model, d, "full", full=cfg)
        b, fb = engine.project(model, d, "full", full=cfg)
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(fa, fb)
        assert np.isfinite(a).all() and np.isfinite(fa).all()


def test_newton_answers_do_not_jump_with_one_ulp_of_the_input(model):
    # a converged solve of a problem with a unique minimiser is a continuous function of the
    # query: moving every joint position by one float32 ulp moves no answer by more than 0.1 deg
    # (Adam-30 stops wherever its 30 steps end: it moved answers by degrees)
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    pos = np.asarray(seq.positions, np.float32)[np.asarray(seq.valid, bool)]
    nudged = np.nextafter(pos, np.copysign(np.inf, pos)).astype(np.float32)
    d_a, ok_a = descriptor(pos)
    d_b, ok_b = descriptor(nudged)
    ok = np.asarray(ok_a) & np.asarray(ok_b)
    a, _ = engine.project(model, np.asarray(d_a)[ok], "full", full=NEWTON)
    b, _ = engine.project(model, np.asarray(d_b)[ok], "full", full=NEWTON)
    assert _deg(a, b).max() <= 0.1


def test_no_recompilation_on_the_second_call(model, count_compiles):
    d = _descriptors([2], actions=[2])
    name = engine.project_chunk.__name__
    engine.project(model, d[:10], "relaxed", batch_size=256)  # compiles (unless done before)
    with count_compiles() as compiles:
        engine.project(model, d[10:300], "relaxed", batch_size=256)  # other size, same batch
        engine.project(model, d[:5], "relaxed", batch_size=256)
    assert compiles[name] == 0, compiles
    # the counter does see compilations: a batch size no other test uses is a new static
    # configuration, compiled once, then reused
    with count_compiles() as compiles:
        engine.project(model, d[:5], "relaxed", batch_size=96)
        engine.project(model, d[5:200], "relaxed", batch_size=96)
    assert compiles[name] == 1, compiles


def test_default_batch_fits_short_calls(model, count_compiles):
    """Without ``batch_size`` a short call is padded to the next power of two (at least
    ``MIN_BATCH``), not to a whole default batch; the answers are the same, and sizes in one
    bucket share one compilation."""
    import jax

    assert engine.default_batch_size(None) == 4096  # the CPU default
    fitted = {n: engine.default_batch_size(None, n) for n in (1, 5, 64, 65, 300, 4096, 10**6)}
    assert fitted == {1: 64, 5: 64, 64: 64, 65: 128, 300: 512, 4096: 4096, 10**6: 4096}
    three = jax.devices("cpu")[:1] * 3  # only the count matters here
    assert engine.default_batch_size(three, 100) == 129  # a multiple of the device count
    assert engine.default_batch_size(three) == 3 * 4096  # each device its own default batch
    d = _descriptors([2], actions=[2])
    want, want_v = engine.project(model, d[:300], "relaxed", batch_size=4096)
    got, got_v = engine.project(model, d[:300], "relaxed")
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got_v, want_v)
    name = engine.project_chunk.__name__
    with count_compiles() as compiles:
        engine.project(model, d[:260], "relaxed")  # 260 and 300 share the 512 bucket
    assert compiles[name] == 0, compiles


def test_save_load_is_bit_identical(model, tmp_path):
    path = tmp_path / "p.npz"
    engine.save(model, path)
    back = engine.load(path)
    d = _descriptors([4], actions=[9])[:200]
    for objective in ("relaxed", "full"):
        a, va = engine.project(model, d, objective)
        b, vb = engine.project(back, d, objective)
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(va, vb)
    assert back.config == model.config and back.n_landmarks == model.n_landmarks


def test_load_rejects_corrupt_or_foreign_files(model, tmp_path):
    path = tmp_path / "p.npz"
    engine.save(model, path)
    raw = path.read_bytes()
    (tmp_path / "trunc.npz").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(InputError, match="trunc.npz"):
        engine.load(tmp_path / "trunc.npz")
    np.savez(tmp_path / "other.npz", positions=np.zeros((2, 20, 3)))
    with pytest.raises(InputError, match="not a jaxproj model"):
        engine.load(tmp_path / "other.npz")
    with pytest.raises(InputError, match="not found"):
        engine.load(tmp_path / "missing.npz")
    # a future format version is refused with a clear message
    import json

    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    meta["format_version"] = 99
    data["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "v99.npz", **data)
    with pytest.raises(InputError, match="version 99"):
        engine.load(tmp_path / "v99.npz")


def test_bad_neighbour_counts_are_config_errors(model):
    d = np.zeros((2, 15), np.float32)
    with pytest.raises(ConfigError, match="L="):
        engine.project(model, d, n_l=0)
    with pytest.raises(ConfigError, match="M="):
        engine.project(model, d, n_m=10_000)
    with pytest.raises(ConfigError, match="objective"):
        engine.project(model, d, "exact")


def test_full_with_fewer_clusters_optimises_the_best_starting_ones(model):
    from jaxproj.projection import full
    from jaxproj.projection.projector import candidates
    from jaxproj.projection.search import nearest

    p = model.projector.chain(0)
    d = _descriptors([2], actions=[1, 5])[:24]
    # L = M = 5 (25 problems per query): the exact "min" objective at L = M = 10 solves 100
    # problems per query to the end, 7 s a call on 2 cores
    cfg = FullConfig(solver="newton", objective="min", include_candidate=True, finalists=0)
    n = 5
    exact, _ = engine.project(model, d, "full", full=cfg, n_l=n, n_m=n)
    all_l, _ = engine.project(
        model, d, "full", full=dataclasses.replace(cfg, clusters=n * n), n_l=n, n_m=n
    )
    np.testing.assert_array_equal(all_l, exact)  # clusters >= L * M is the exact objective
    one, f_one = engine.project(
        model, d, "full", full=dataclasses.replace(cfg, clusters=1), n_l=n, n_m=n
    )

    # each step jitted on its own (eager, every primitive compiled apart: ~8 s of a CPU)
    problems = jax.jit(full.problems, static_argnums=4)
    value, solve = jax.jit(sn.value), jax.jit(full.solve, static_argnums=2)

    def by_hand(h):  # solve only the problem whose warm start is best
        cand = candidates(p, h, n)
        ridx, _ = nearest(p.robot, p.robot_sq, cand, n)
        probs = [
            (pr, w0)
            for i in range(n)
            for prs, w0 in [problems(p, h, cand[i], ridx[i], cfg)]
            for pr in [jax.tree.map(lambda a, k=k: a[k], prs) for k in range(n)]
        ]
        start = [float(value(pr, w0)) for pr, w0 in probs]
        pr, w0 = probs[int(np.argmin(start))]
        r, f = solve(pr, w0, cfg)
        return np.clip(r, p.lower, p.upper), f

    # The engine (one program, vmapped) and by_hand (a program per step) round differently; a
    # converged solve is insensitive to that where its minimiser is well-conditioned: 0.05 deg.
    for i in (0, 12):
        r, f = by_hand(d[i])
        assert _deg(one[i], r).max() <= 0.05
        np.testing.assert_allclose(f_one[i], f, rtol=1e-4, atol=1e-7)
    assert np.abs(one - exact).max() > 1e-3  # a different (cheaper) answer on some queries
    got, _ = engine.project(
        model, np.asarray(p.human), "full", full=dataclasses.replace(cfg, clusters=2), n_l=n, n_m=n
    )
    assert _deg(got, p.robot).max() < 0.01  # identity survives the pruning


def test_bad_full_configs_are_config_errors():
    # validated when constructed, before anything is traced
    for bad, match in (
        (dict(clusters=-1), "clusters"),
        (dict(iterations=-2), "iterations"),
        (dict(learning_rate=0.0), "learning_rate"),
        (dict(objective="max"), "objective"),
        (dict(solver="lbfgs"), "solver"),
        (dict(proximal=-1.0), "proximal"),
        (dict(finalists=-1), "finalists"),
    ):
        with pytest.raises(ConfigError, match=match):
            FullConfig(**bad)


def test_k_is_capped_at_a_small_landmark_set():
    d = _descriptors([1], actions=[1])
    human = d[np.random.default_rng(2).choice(len(d), 40, replace=False)]
    robot_poses = np.asarray(ik.solve_driven(human))
    cfg = engine.BuildConfig()  # default k (96) > 40 landmarks
    p = engine.build_from_landmarks(human, robot_poses, cfg)
    assert p.forward.k == p.backward.k == 40 and cfg.chain_config(0).k > 40
    got, _ = engine.project(p, human, "relaxed", batch_size=64)
    assert _deg(got, robot_poses).max() < 0.01  # still exact at the landmarks
    with pytest.raises(ConfigError, match="k=1"):
        engine.build_from_landmarks(human, robot_poses, engine.BuildConfig(k=1))


# ------------------------------------------------------------------------ per-chain stacking


@pytest.fixture(scope="module")
def chain_model():
    d = _descriptors([1, 3])
    human = d[np.random.default_rng(0).choice(len(d), 400, replace=False)]
    cfg = dataclasses.replace(CFG, chains="upper")
    return engine.from_landmarks(human, np.asarray(ik.solve_driven(human)), cfg, n_train=len(d))


def test_chain_model_layout_and_padding(chain_model):
    sp = chain_model.projector
    lay = sp.layout
    assert lay.names == ("head", "left_arm", "right_arm")
    assert lay.inputs == ((0, 1, 2), (3, 4, 5, 6, 7, 8), (9, 10, 11, 12, 13, 14))
    assert lay.outputs == ((0, 1), (2, 3, 4, 5), (6, 7, 8, 9))
    k_max = max(lay.landmarks)
    assert sp.stack.human.shape == (3, k_max, 6) and sp.stack.robot.shape == (3, k_max, 4)
    for c, k in enumerate(lay.landmarks):
        # padding: infinitely far (never a neighbour), zero weights (never enters a kernel)
        assert np.isinf(np.asarray(sp.stack.human_sq[c, k:])).all()
        assert np.isfinite(np.asarray(sp.stack.human_sq[c, :k])).all()
        assert not np.asarray(sp.stack.forward.out[c, k:]).any()
        assert not np.asarray(sp.stack.backward.w[c, :, len(lay.outputs[c]) :]).any()
    # the head's neck directions repeat across the 400 frames far less than whole poses do
    assert lay.landmarks[0] <= lay.landmarks[1]


@pytest.mark.parametrize("objective", ["relaxed", "full"])
def test_stacked_chains_equal_each_chain_alone(chain_model, objective):
    """One vmapped call over the padded stack gives each chain's own answer."""
    import jax.numpy as jnp

    from jaxproj.projection.search import nearest
    from jaxproj.testing import kernel_output_bound

    sp = chain_model.projector
    d = _descriptors([4], actions=[2, 9])[:64]
    got, value = engine.project(chain_model, d, objective, n_l=5, n_m=5)
    per_chain = []
    for c in range(sp.layout.n_chains):
        p = sp.chain(c)
        x = d[:, list(sp.layout.inputs[c])]
        r, v = engine.project(p, x, objective, n_l=5, n_m=5)
        cols = list(sp.layout.outputs[c])
        if objective == "relaxed":
            # The padded stack sums in another order than the chain alone. A relaxed answer is
            # one forward kernel's output (clipped), within its float32 error bound of the exact
            # value both ways (``kernel_output_bound``; the largest over the query's L kernels).
            f = p.forward
            hidx, _ = nearest(p.human, p.human_sq, jnp.asarray(x), 5)
            _, err = kernel_output_bound(f, x, np.asarray(hidx), f.d_in, f.d_out, f.hidden)
            assert np.all(np.abs(got[:, cols] - r) <= 2.0 * err.max(axis=1))
        else:
            # The full answers are a converged solve deep, which stops within its tolerance
            # (last step < 1e-5 rad, the model's promise < 1e-6 F) where another rounding can
            # stop a step earlier or later (measured 1.2e-4 rad on one of 256 angles): 1e-3 rad
            # (0.06 deg). A padding that entered a kernel or won a search would move answers by
            # orders of magnitude more.
            np.testing.assert_allclose(got[:, cols], r, rtol=0, atol=1e-3)
        per_chain.append(v)
    v = np.stack(per_chain, axis=1)
    want = np.sqrt((v**2).sum(1)) if objective == "relaxed" else v.sum(1)
    np.testing.assert_allclose(value, want, rtol=1e-4)


def test_chain_identity_on_every_chains_landmarks(chain_model):
    sp = chain_model.projector
    lay = sp.layout
    for c in range(lay.n_chains):
        p = sp.chain(c)
        got, _ = engine.project(p, np.asarray(p.human), "relaxed", n_l=5, n_m=5)
        assert _deg(got, p.robot).max() < 0.01, lay.names[c]


def test_chain_model_save_load_is_bit_identical(chain_model, tmp_path):
    engine.save(chain_model, tmp_path / "c.npz")
    back = engine.load(tmp_path / "c.npz")
    assert back.projector.layout == chain_model.projector.layout
    d = _descriptors([4], actions=[9])[:100]
    for objective in ("relaxed", "full"):
        a, va = engine.project(chain_model, d, objective, n_l=5, n_m=5)
        b, vb = engine.project(back, d, objective, n_l=5, n_m=5)
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(va, vb)
    assert not list(tmp_path.glob(".*.tmp"))  # written under a temporary name, then renamed


def test_per_chain_settings_are_validated():
    with pytest.raises(ConfigError, match="3 chains"):
        engine.BuildConfig(landmarks=(100, 200))
    with pytest.raises(ConfigError, match="head: give exactly one"):
        engine.BuildConfig(landmarks=(None, 200, 200))
    with pytest.raises(ConfigError, match="unknown chain set"):
        engine.BuildConfig(chains="legs")
    cfg = engine.BuildConfig(landmarks=800)
    assert cfg.chain_config(0).bandwidth == robots.get(robots.DEFAULT).chains[0].bandwidth
    assert cfg.chain_config(1).landmarks == cfg.chain_config(2).landmarks == 800
    assert engine.BuildConfig(landmarks=(50, 800, 700)).chain_config(0).landmarks == 50


def test_batched_relaxed_equals_per_query_and_the_fused_search(chain_model):
    """``engine.project_batch``'s relaxed path (all candidates' robot searches in one
    ``nearest_rows`` call): split (chain after chain at each chain's own size, the default with
    the Pallas kernels) it gives the per-query projection's answers of each chain alone bit for
    bit on the CPU (deviations to the last bit); stacked (``split=False``, every chain padded
    to the largest, the default with XLA) the stacked per-query answers bit for bit, and the
    same answers with the CUDA path's fused Pallas search (``impl="pallas"`` for the searches,
    run in Pallas' interpreter here; XLA's back-projection). The two forms sum in other orders
    (``test_stacked_chains_equal_each_chain_alone`` bounds that)."""
    import jax
    import jax.numpy as jnp

    from jaxproj._internal.jit import jit
    from jaxproj.projection import relaxed
    from jaxproj.projection.stacked import project_stacked_one

    sp = chain_model.projector
    lay = sp.layout
    h = jnp.asarray(_descriptors([4], actions=[2, 9])[:48])

    split = jit(lambda p, x: engine.project_batch(p, x, "relaxed", 5, 5, impl="xla", split=True))
    r, v = split(sp, h)

    @jit
    def alone(p, x):
        out = jnp.zeros((x.shape[0], lay.n), x.dtype)
        sq = jnp.zeros((x.shape[0],), x.dtype)
        for c, cols in enumerate(lay.inputs):
            pc = p.chain_slice(c)
            rc, vc = jax.vmap(lambda q, pc=pc: relaxed.project_relaxed_one(pc, q, 5, 5))(
                x[:, list(cols)]
            )
            out = out.at[:, list(lay.outputs[c])].set(rc)
            sq = sq + vc * vc
        return out, jnp.sqrt(sq)

    r1, v1 = alone(sp, h)
    np.testing.assert_array_equal(np.asarray(r), np.asarray(r1))
    # deviations: the rows' sums are vectorised otherwise than one query's (last bit)
    np.testing.assert_allclose(np.asarray(v), np.asarray(v1), rtol=1e-6, atol=0)
    stacked = jit(lambda p, x: relaxed.project_relaxed_rows(p, x, 5, 5, impl="xla", split=False))
    rs, vs = stacked(sp, h)
    # the default on the CPU ("auto": XLA, which does not split): the same program
    r0, v0 = jit(lambda p, x: engine.project_batch(p, x, "relaxed", 5, 5))(sp, h)
    np.testing.assert_array_equal(np.asarray(r0), np.asarray(rs))
    np.testing.assert_array_equal(np.asarray(v0), np.asarray(vs))
    one = jit(
        lambda p, x: jax.vmap(lambda q: project_stacked_one(p, q, "relaxed", 5, 5, FullConfig()))(x)
    )
    rs1, vs1 = one(sp, h)
    np.testing.assert_array_equal(np.asarray(rs), np.asarray(rs1))
    np.testing.assert_array_equal(np.asarray(vs), np.asarray(vs1))

    @jit
    def fused_search(p, x):
        xs, cand, ridx = relaxed.relaxed_candidates(p, x, 5, 5, impl="pallas")
        best = relaxed.least_deviations_rows(
            p.stack, relaxed.backward_widths(p), xs, cand, ridx, impl="xla"
        )
        return relaxed.pick_rows(p, cand, best)

    r2, v2 = fused_search(sp, h)
    np.testing.assert_allclose(np.asarray(r2), np.asarray(rs), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.asarray(v2), np.asarray(vs), rtol=1e-5)


def test_two_level_relaxed_batches_give_the_same_answers(chain_model, monkeypatch):
    """Searching many queries per call and back-projecting them a few at a time
    (``project_relaxed_rows``' ``chunk``, set by ``engine.search_batch`` on the CPU) changes no
    answer; the reported deviations may differ in the last bit (XLA vectorises the per-chunk
    sums differently); a chunk that does not divide the batch is refused."""
    import jax.numpy as jnp

    from jaxproj._internal.jit import jit
    from jaxproj.projection import relaxed

    sp = chain_model.projector
    h = jnp.asarray(_descriptors([4], actions=[2, 9])[:48])
    rows = jit(relaxed.project_relaxed_rows, static_argnames=("n_l", "n_m", "chunk"))
    r0, v0 = rows(sp, h, n_l=5, n_m=5)
    for chunk in (8, 16, 48):
        r, v = rows(sp, h, n_l=5, n_m=5, chunk=chunk)
        np.testing.assert_array_equal(np.asarray(r), np.asarray(r0))
        np.testing.assert_allclose(np.asarray(v), np.asarray(v0), rtol=1e-6, atol=0)
    with pytest.raises(ConfigError, match="chunk=5 does not divide the batch of 48"):
        rows(sp, h, n_l=5, n_m=5, chunk=5)

    # the engine with both levels active: 48 queries searched per call, 8 back-projected at once
    monkeypatch.setattr(engine, "sub_batch", lambda *a: 8)
    monkeypatch.setattr(engine, "search_batch", lambda *a: 48)
    r, v = jit(lambda p, x: engine.project_batch(p, x, "relaxed", 5, 5))(sp, h)
    np.testing.assert_array_equal(np.asarray(r), np.asarray(r0))
    np.testing.assert_allclose(np.asarray(v), np.asarray(v0), rtol=1e-6, atol=0)


def test_search_batch_divides_the_batch_up_to_the_cpu_count():
    """``engine.search_batch``: a multiple of the back-projection sub-batch that divides the
    batch, the largest such power-of-two multiple up to ``SEARCH_QUERIES_CPU`` queries."""
    cap = engine.SEARCH_QUERIES_CPU
    expected = {(4096, 8): cap, (96, 8): 32, (8, 8): 8, (4096, 1): cap, (1000, 8): 8}
    for (batch, sub), want in expected.items():
        out = engine.search_batch(batch, sub)
        assert out % sub == 0 and batch % out == 0 and out <= max(cap, sub), (batch, sub, out)
        assert out == want, (batch, sub, out)


def test_fused_back_projection_matches_xla(chain_model):
    """The CUDA path's fused back-projection kernel (run in Pallas' interpreter) and XLA's three
    passes each give the least deviations within their float32 error bound of the float64 value
    (``jaxproj.testing.back_deviation_bound``: the bound of this very arithmetic with the actual
    operands, not a fixed tolerance), and the batched relaxed projection with the kernel picks
    XLA's candidates, except where two candidates' deviations lie within their bounds."""
    import jax
    import jax.numpy as jnp

    from jaxproj._internal.jit import jit
    from jaxproj.projection import relaxed
    from jaxproj.projection.projector import candidates
    from jaxproj.projection.search import nearest
    from jaxproj.testing import back_deviation_bound

    sp = chain_model.projector
    st, lay = sp.stack, sp.layout
    dims = relaxed.backward_widths(sp)
    h = jnp.asarray(_descriptors([4], actions=[2, 9])[:48])
    s = h.shape[0]

    @jit
    def prep(st, h):
        x = jnp.concatenate([h, jnp.zeros((s, 1), h.dtype)], axis=1)[:, lay.input_index()]
        per_chain = jax.vmap(candidates, in_axes=(0, 0, None))
        cand = jax.vmap(per_chain, in_axes=(None, 0, None))(st, x, 5)  # (S, C, L, n)
        ridx = jax.vmap(
            jax.vmap(lambda p, c: nearest(p.robot, p.robot_sq, c, 5)[0]),
            in_axes=(None, 0),
        )(st, cand)
        return x, cand, ridx

    x, cand, ridx = prep(st, h)
    b_x = np.asarray(relaxed.least_deviations_rows(st, dims, x, cand, ridx, impl="xla"))
    b_k = np.asarray(relaxed.least_deviations_rows(st, dims, x, cand, ridx, impl="pallas"))
    assert b_k.shape == (s, 3, 5)
    exact, bound = np.empty(b_x.shape), np.empty(b_x.shape)
    for c, (n, m, hidden) in enumerate(dims):
        bank = jax.tree.map(lambda a, c=c: np.asarray(a[c]), st.backward)
        rows = np.asarray(cand[:, c]).reshape(s * 5, -1)
        queries = np.repeat(np.asarray(x[:, c]), 5, axis=0)
        idx = np.asarray(ridx[:, c]).reshape(s * 5, 5)
        b, e = back_deviation_bound(bank, rows, queries, idx, n, m, hidden)
        exact[:, c], bound[:, c] = b.reshape(s, 5), e.reshape(s, 5)
    assert np.all(np.abs(b_x - exact) <= bound), np.max(np.abs(b_x - exact) / bound)
    assert np.all(np.abs(b_k - exact) <= bound), np.max(np.abs(b_k - exact) / bound)
    # a correct pick: a candidate whose deviation is the least to within both bounds
    best = np.argmin(exact, axis=-1)[..., None]
    gap = exact - np.take_along_axis(exact, best, axis=-1)
    correct = gap <= bound + np.take_along_axis(bound, best, axis=-1)  # (S, C, L)
    # the bound discriminates: most (query, chain) pairs have one correct candidate only
    assert np.mean(correct.sum(axis=-1) == 1) > 0.75, np.mean(correct.sum(axis=-1) == 1)
    for b in (b_x, b_k):
        assert np.all(np.take_along_axis(correct, np.argmin(b, axis=-1)[..., None], -1))

    @jit
    def fused_back_projection(p, q):  # XLA's searches, the fused back-projection
        xs, cand, ridx = relaxed.relaxed_candidates(p, q, 5, 5, impl="xla")
        best = relaxed.least_deviations_rows(p.stack, dims, xs, cand, ridx, impl="pallas")
        return relaxed.pick_rows(p, cand, best)

    r_k, v_k = fused_back_projection(sp, h)
    r_k = np.asarray(r_k)
    # the whole batched projection with the kernel: each chain's angles are a correct pick's
    for j in range(5):  # the answer had every chain picked its candidate j
        only_j = np.broadcast_to((np.arange(5) != j).astype(np.float32), (s, 3, 5))
        r_j = np.asarray(relaxed.pick_rows(sp, cand, jnp.asarray(only_j))[0])
        for c, cols in enumerate(lay.outputs):
            same = np.all(r_k[:, list(cols)] == r_j[:, list(cols)], axis=1)
            correct[:, c, j] &= same
    assert np.all(np.any(correct, axis=-1)), np.argwhere(~np.any(correct, axis=-1))
    assert np.all(np.isfinite(np.asarray(v_k)))


def _dot_precisions(jaxpr) -> list:
    """The ``precision`` of every ``dot_general`` in a (closed) jaxpr, sub-jaxprs included."""
    from jax.extend import core as jcore

    found = []
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "dot_general":
            found.append(eqn.params["precision"])
        for v in eqn.params.values():
            for sub in v if isinstance(v, tuple | list) else (v,):
                if isinstance(sub, jcore.ClosedJaxpr):
                    found += _dot_precisions(sub.jaxpr)
                elif isinstance(sub, jcore.Jaxpr):
                    found += _dot_precisions(sub)
    return found


@pytest.mark.parametrize("objective", ["relaxed", "full"])
def test_core_keeps_full_precision_in_a_plain_jit(chain_model, objective):
    """``project_batch`` traced by a caller's own ``jax.jit`` under the lowest default matmul
    precision (bfloat16 passes) still multiplies at full float32 precision: every product of its
    program says HIGHEST (on a GPU the default would be TF32 or bf16; on this CPU the setting
    changes no number, so the program itself is checked), and the relaxed answers of that plain
    ``jax.jit`` are the float64 reference's under the near-tie rule (the full objective's
    program is only traced: its numbers are checked against the reference elsewhere, and its
    compile costs CI ~30 s)."""
    import jax
    import jax.numpy as jnp

    from jaxproj.testing import StackedReference

    sp = chain_model.projector
    h = _descriptors([6], actions=[3, 10])[::7][:24]
    highest = (jax.lax.Precision.HIGHEST, jax.lax.Precision.HIGHEST)

    def users_fn(p, x):
        return engine.project_batch(p, x, objective, 5, 5, impl="xla")

    with jax.default_matmul_precision("bfloat16"):
        low = jax.make_jaxpr(lambda a, b: jnp.dot(a, b))(jnp.ones((2, 2)), jnp.ones((2, 2)))
        assert _dot_precisions(low.jaxpr) != [highest]  # the walk sees a lowered product
        dots = _dot_precisions(jax.make_jaxpr(users_fn)(sp, jnp.asarray(h)).jaxpr)
        if objective == "relaxed":
            r, _ = jax.jit(users_fn)(sp, jnp.asarray(h))
    assert len(dots) >= 3 and all(d == highest for d in dots), dots
    if objective == "relaxed":
        ref = StackedReference(sp)
        pairs = zip(h, np.asarray(r), strict=True)
        verdicts = [ref.judge(x, q, 5, 5, np.radians(0.01)) for x, q in pairs]
        assert "differs" not in verdicts, verdicts


def test_full_near_tie_rule_picks_the_first_candidate_among_ties():
    """``full.pick``: among problems whose objective is within ``tie_rtol`` of the least, the
    first in candidate order; beyond the band, the least; ``tie_rtol = 0``: the least."""
    import jax.numpy as jnp

    from jaxproj.projection.full import pick

    f = jnp.asarray([1.0, 1.0005, 0.9996, 2.0], jnp.float32)
    order = jnp.asarray([3, 1, 2, 0], jnp.int32)
    assert int(pick(f, order, 1e-3)) == 1  # 1.0005 <= 0.9996 (1 + 1e-3), candidate rank 1
    assert int(pick(f, order, 0.0)) == 2  # the least
    assert int(pick(f, order, 1e-4)) == 2  # 1.0 and 1.0005 are outside a 1e-4 band
    far = jnp.asarray([1.0, 1.0011], jnp.float32)
    assert int(pick(far, jnp.asarray([1, 0], jnp.int32), 1e-3)) == 0
    with pytest.raises(ConfigError, match="tie_rtol"):
        FullConfig(tie_rtol=-1e-3)


def test_newton_stops_only_where_the_frank_wolfe_gap_is_small(model):
    """``FullConfig.gap_tol``: a problem counts as stationary only where the Frank-Wolfe gap
    (``g.w - min g``: 0 exactly at a KKT point of the simplex) is within ``gap_tol * F``.
    Without it (``gap_tol = 0``) a rejected step of the indefinite model stopped problems far
    from any KKT point, at objectives the solver with the test goes below."""
    import jax.numpy as jnp

    from jaxproj.projection import full as fo
    from jaxproj.projection.projector import candidates
    from jaxproj.projection.search import nearest

    g = jnp.asarray([0.3, 0.1, 0.1, 0.5])  # a KKT point uses only the least derivatives
    assert float(sn.frank_wolfe_gap(g, jnp.asarray([0.0, 0.25, 0.75, 0.0]))) == 0.0
    assert float(sn.frank_wolfe_gap(g, jnp.asarray([0.5, 0.5, 0.0, 0.0]))) == pytest.approx(0.1)

    p = model.projector.chain(0)

    def solve_all(h, cfg):  # every problem of one query, as far as the solver goes
        cand = candidates(p, h, 10)
        ridx, _ = nearest(p.robot, p.robot_sq, cand, 10)
        prs, w0 = jax.vmap(fo.problems, in_axes=(None, None, 0, 0, None))(p, h, cand, ridx, cfg)
        prs = fo._shared(prs, p, h, cfg)
        solver = sn.gauss_newton(cfg.dec_tol, cfg.step_tol, cfg.gap_tol)
        s = jax.vmap(solver.init, in_axes=(fo._AXES, 0))(prs, w0)
        s = jax.vmap(lambda pr, x: solver.run(pr, x, cfg.iterations), in_axes=(fo._AXES, 0))(prs, s)
        gap = jax.vmap(sn.frank_wolfe_gap)(s.d.grad, s.w)
        stationary = s.done & (s.damping <= sn.DAMPING_STALL)  # not stalled, not capped
        return gap / jnp.maximum(s.d.f, 1e-8), stationary, s.d.f

    d = _descriptors([2], actions=[1, 5])[:24]
    fn = jax.jit(jax.vmap(solve_all, in_axes=(0, None)), static_argnums=1)
    gap, stationary, f = (np.asarray(x) for x in fn(d, NEWTON))
    gap0, stationary0, f0 = (np.asarray(x) for x in fn(d, dataclasses.replace(NEWTON, gap_tol=0)))
    assert stationary.any() and (gap[stationary] <= NEWTON.gap_tol).all()
    assert (gap0[stationary0] > 0.1).any()  # stopped where moving toward a vertex still pays
    assert (f <= f0 * (1 + 1e-5) + 1e-9).mean() >= 0.95  # going on reaches lower objectives
    assert (f < f0 * (1 - 1e-3)).any()


def test_training_people_are_validated_and_recorded_in_the_model_file(model, tmp_path):
    import json

    assert engine.BuildConfig().utkinect_people == datasets.UTK_TRAIN_SUBJECTS == (3, 4, 6)
    assert engine.BuildConfig(utkinect_people=[9, 7]).utkinect_people == (9, 7)  # from JSON
    for bad in ((1,), (3, 3), 3, (True,)):
        with pytest.raises(ConfigError, match="utkinect_people"):
            engine.BuildConfig(utkinect_people=bad)
    cfg = dataclasses.replace(model.config, utkinect_people=(7, 9))
    path = tmp_path / "p.npz"
    engine.save(dataclasses.replace(model, config=cfg), path)
    assert engine.load(path).config.utkinect_people == (7, 9)
    # a file written before the field existed trained on no UTKinect person
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    meta = json.loads(str(data["meta"]))
    del meta["config"]["utkinect_people"]
    data["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "old.npz", **data)
    assert engine.load(tmp_path / "old.npz").config.utkinect_people == ()


def test_precomputed_search_index_gives_the_same_projections(chain_model, monkeypatch):
    """A projector carrying its robot and human landmarks' pruning indices
    (``with_search_index``, what ``stack_projectors`` attaches on CUDA GPUs) projects with the
    Pallas path (Pallas' interpreter here, the pruned search forced on) as one without would:
    its indices are bit for bit those the pruned searches compute in their trace without them
    (``prune_index``, the function the trace calls; ``test_search`` checks the searches' answers
    with and without an index), a projector without them traces both, one with them neither,
    and the public traceable core inside a user's own jit answers as ``project`` through the
    wrappers, bit for bit. The projections run on one chain (the right arm) alone: a third of
    the program to compile; the one without indices is traced, not compiled."""
    import jax.numpy as jnp

    from jaxproj._internal.jit import jit
    from jaxproj.projection.ops import knn_pallas
    from jaxproj.projection.projector import with_search_index
    from jaxproj.projection.stacked import stack_projectors

    monkeypatch.setattr(knn_pallas, "PRUNE_MIN_LANDMARKS", 0)
    index = knn_pallas.prune_index
    sp = chain_model.projector
    assert sp.robot_index is None and sp.human_index is None  # the CPU: not attached by default
    lay = sp.layout
    with_idx = with_search_index(sp)
    for found, sets in ((with_idx.robot_index, "robot"), (with_idx.human_index, "human")):
        assert found is not None and len(found) == lay.n_chains, sets
        for c, idx in enumerate(found):
            assert idx is not None and idx.order.shape == (lay.landmarks[c],), sets
    again = stack_projectors([sp.chain(c) for c in range(lay.n_chains)], lay, search_index=True)
    leaves = jax.tree.leaves
    for name in ("robot_index", "human_index"):
        got, want = leaves(getattr(again, name)), leaves(getattr(with_idx, name))
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    arm = lay.names.index("right_arm")
    p0, p1 = sp.chain_slice(arm), with_idx.chain_slice(arm)
    assert p0.robot_index is None and p1.robot_index is not None
    assert p0.human_index is None and p1.human_index is not None
    traced = []  # the pruned searches compute the indices in their trace only without them
    monkeypatch.setattr(knn_pallas, "prune_index", lambda *a: traced.append(1) or index(*a))
    for name, pts, sq in (("robot_index", p0.robot, p0.robot_sq), ("human_index", p0.human,
                                                                      p0.human_sq)):  # fmt: skip
        in_trace = jax.jit(index, static_argnames=("block", "lbt"))(
            jnp.asarray(pts)[None], jnp.isfinite(jnp.asarray(sq))[None],
            block=knn_pallas.PRUNE_BLOCK, lbt=knn_pallas.PRUNE_LB_TILE,
        )  # fmt: skip
        for a, b in zip(leaves(in_trace), leaves(getattr(p1, name)), strict=True):
            np.testing.assert_array_equal(np.asarray(a)[0], np.asarray(b))
    h = jnp.asarray(_descriptors([4], actions=[2, 9])[:16][:, np.asarray(lay.inputs[arm])])
    user = jit(lambda p, x: engine.project_batch(p, x, "relaxed", 5, 5, impl="pallas"))
    jax.eval_shape(user, p0, h)
    assert len(traced) == 2  # human and robot landmarks
    r1, v1 = user(p1, h)
    assert len(traced) == 2
    r2, v2 = engine.project(p1, np.asarray(h), n_l=5, n_m=5, batch_size=16, impl="pallas")
    assert len(traced) == 2
    np.testing.assert_array_equal(r2, np.asarray(r1))
    np.testing.assert_array_equal(v2, np.asarray(v1))
