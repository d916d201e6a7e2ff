"""The benchmark machinery (``jaxproj.bench``) on a tiny configuration. No speed is asserted."""

import argparse
import dataclasses
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from optax.projections import projection_simplex

from jaxproj import bench, smoothing
from jaxproj.projection import FullConfig

KEYS = (
    "objective",
    "L",
    "M",
    "N",
    "batch",
    "device",
    "us_per_projection",
    "throughput",
    "compile_s",
    "reference_us_per_projection",
    "max_abs_diff_deg",
    "speedup",
)


@pytest.fixture(scope="module")
def records():
    """One tiny run: N = 86 (subsampled, no mean shift), batches 16 and 64."""
    plan = bench.make_plan(
        True,
        "cpu",
        landmarks=(86,),
        batches=(16, 64),
        configs=(("relaxed", 10, 10), ("full", 4, 4)),
        repeats=2,
        ref_queries=64,
        stream_frames=40,
    )
    plan = dataclasses.replace(plan, subsample_all=True, min_time_s=0.0, max_repeats=2)
    return bench.run(True, "cpu", plan=plan, rollout=False, log=lambda s: None)


def test_records_have_the_issue_keys_and_finite_numbers(records):
    assert records[0]["kind"] == "header"
    assert {"jax", "jaxlib", "numpy", "mujoco"} <= set(records[0]["versions"])
    proj = [r for r in records if r["kind"] == "projection"]
    assert len(proj) == 4
    for r in proj:
        assert set(KEYS) <= set(r), r
        assert r.get("skipped") is None
        for k in ("us_per_projection", "throughput", "compile_s", "reference_us_per_projection"):
            assert math.isfinite(r[k]) and r[k] > 0, (k, r)
        assert r["speedup"] == pytest.approx(
            r["reference_us_per_projection"] / r["us_per_projection"]
        )
        assert r["n_checked"] == 64  # a batch of 16 is re-run on the next queries
    json.dumps(records)  # serialisable as is


def test_reference_agrees_with_the_engine(records):
    for r in records:
        if r["kind"] == "projection" and r["objective"] == "relaxed":
            assert r["max_abs_diff_deg"] <= 0.1, r
        if r["kind"] == "projection" and r["objective"] == "full":
            assert r["max_abs_diff_deg"] <= bench.FULL_TOL_DEG, r


def test_build_streaming_targets_and_table(records):
    (build,) = [r for r in records if r["kind"] == "build"]
    assert build["n_landmarks"] == 86 and build["build_s"] > 0
    (stream,) = [r for r in records if r["kind"] == "streaming"]
    assert 0 < stream["median_us"] <= stream["p99_us"]
    targets = [r for r in records if r["kind"] == "target"]
    assert len(targets) == 4
    assert all(t["met"] is None for t in targets if "N~1644" in t["target"])  # N=1644 not run
    table = bench.format_table(records)
    assert "relaxed" in table and "targets" in table


def test_simplex_projection_matches_optax():
    x = np.random.default_rng(0).normal(size=(20, 7)) * 2
    got = bench.simplex_projection(x)
    with jax.numpy_dtype_promotion("standard"):  # optax mixes int32 counts with float32
        want = np.stack([np.asarray(projection_simplex(jnp.asarray(r, jnp.float32))) for r in x])
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_stream_smoother_matches_smooth():
    y = np.cumsum(np.random.default_rng(1).normal(size=(30, 10)) * 0.1, axis=0).astype(np.float32)
    s, b, started = jnp.zeros(10), jnp.zeros(10), jnp.asarray(False)
    out = []
    for t in range(len(y)):
        s, b = bench._smooth_step(jnp.asarray(y[t]), s, b, started, smoothing.PAPER_SMOOTHING)
        started = jnp.asarray(True)
        out.append(np.asarray(s))
    np.testing.assert_allclose(np.stack(out), np.asarray(smoothing.smooth(y)), atol=1e-6)


@pytest.fixture(scope="module")
def projector(records):
    """The landmarks of `records` again (module scope: the compiled build is reused)."""
    train = bench.descriptors(bench.TRAIN_SUBJECTS)
    return bench.subsample_projector(train, 86, bench.engine.BuildConfig()), train


def test_reference_full_variants_run(projector):
    p, train = projector
    ref = bench.Reference(p)
    h = train[5]
    for cfg in (FullConfig(), FullConfig(objective="min", include_candidate=True)):
        r, f = ref.full(h, 3, 3, cfg)
        assert r.shape == (10,) and np.isfinite(r).all() and np.isfinite(f)


def test_cli_arguments_parse():
    ap = argparse.ArgumentParser()
    bench.add_arguments(ap)
    a = ap.parse_args(["--quick", "--device", "cpu", "--json", "x.json", "--landmarks", "86"])
    assert a.quick and a.device == "cpu" and a.landmarks == [86] and a.json == "x.json"


@pytest.mark.parametrize("clusters", [1, 2])
def test_reference_full_with_fewer_clusters_matches_the_engine(projector, clusters):
    p, train = projector
    ref = bench.Reference(p)
    cfg = FullConfig(objective="min", include_candidate=True, clusters=clusters)
    h = train[::97][:24]
    got, _ = bench.engine.project(p, h, "full", n_l=5, n_m=5, full=cfg, batch_size=32)
    want = np.stack([ref.full(x, 5, 5, cfg)[0] for x in h])
    assert np.degrees(np.abs(got - want)).max() <= bench.FULL_TOL_DEG


def test_full_cli_options_reach_the_config():
    ap = argparse.ArgumentParser()
    bench.add_arguments(ap)
    a = ap.parse_args(["--full-clusters", "2", "--full-iterations", "10"])
    assert bench._full_config(a.full_clusters, a.full_iterations) == FullConfig(
        clusters=2, iterations=10
    )
    with pytest.raises(bench.engine.ConfigError):
        bench._full_config(-1, None)


def test_rollout_benchmark_runs():
    # the rollout records come from benchmarks/bench_rollout.py: a signature change there once
    # turned every rollout record into "skipped" without failing anything
    import jax

    (rec,) = bench.bench_rollout(True, jax.devices("cpu")[0], frames=2)
    assert rec.get("skipped") is None, rec.get("skipped")
    assert rec["batch"] == 64 and rec["steps"] == 64 * 2 * 33 and rec["steps_per_s"] > 0
    assert rec["mjx_vs_cpu_max_dq_rad"] < 1e-3
