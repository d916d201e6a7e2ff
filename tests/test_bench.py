"""The benchmark harness (``benchmarks/``) on a tiny configuration. No speed is asserted.

``benchmarks/`` is not part of the installed package: its folder is put on ``sys.path`` here,
as it is when its scripts run.
"""

import argparse
import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from jaxproj import cli
from jaxproj.errors import ConfigError
from jaxproj.projection.objectives import FullConfig

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(0, str(BENCHMARKS))

import bench_projection as bench  # noqa: E402
import harness  # noqa: E402

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
    plan = harness.make_plan(
        True,
        "cpu",
        landmarks=(86,),
        batches=(16, 64),
        configs=(("relaxed", 10, 10), ("full", 4, 4)),
        repeats=2,
        ref_queries=64,
        stream_frames=40,
    )
    plan = dataclasses.replace(
        plan,
        subsample_all=True,
        min_time_s=0.0,
        max_repeats=2,
        public_queries={"relaxed": 256, "full": 64},
    )
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


def test_public_api_records(records):
    """``jaxproj.project`` as users call it: a host array, default batch size, checked first."""
    pub = [r for r in records if r["kind"] == "public"]
    assert {(r["objective"], r["L"], r["M"], r["batch"]) for r in pub} == {
        ("relaxed", 10, 10, 256),
        ("full", 4, 4, 64),
    }
    for r in pub:
        assert r["agrees"] and r["n_checked"] == 64, r
        # the CPU default (4096) fitted to the call: the next power of two of its queries
        assert r["batch_size"] == r["batch"], r
        assert math.isfinite(r["us_per_projection"]) and r["first_call_s"] > 0


def test_reference_agrees_with_the_engine(records):
    for r in records:
        if r["kind"] == "projection" and r["objective"] == "relaxed":
            assert r["max_abs_diff_deg"] <= 0.1, r
        if r["kind"] == "projection" and r["objective"] == "full":
            assert r["max_abs_diff_deg"] <= harness.FULL_TOL_DEG, r


def test_build_streaming_targets_and_table(records):
    (build,) = [r for r in records if r["kind"] == "build"]
    assert build["n_landmarks"] == 86 and build["build_s"] > 0
    (stream,) = [r for r in records if r["kind"] == "streaming"]
    assert 0 < stream["median_us"] <= stream["p99_us"]
    assert stream["frames"] == 40 and stream["compile_s"] >= 0
    assert (stream["L"], stream["M"], stream["N"], stream["n_landmarks"]) == (10, 10, 86, 86)
    targets = [r for r in records if r["kind"] == "target"]
    assert len(targets) == 7
    assert all(t["met"] is None for t in targets if "N~1644" in t["target"])  # N=1644 not run
    table = harness.format_table(records)
    assert "relaxed" in table and "targets" in table


def test_full_convergence_record(records):
    """The full objective's answers against a long (1,000-step) solve of the same solver."""
    (conv,) = [r for r in records if r["kind"] == "full_convergence"]
    assert (conv["L"], conv["M"], conv["N"], conv["queries"]) == (4, 4, 86, 64)
    assert conv["reference_iterations"] == bench.LONG_SOLVE_ITERATIONS == 1000
    assert 0.0 <= conv["fraction_within"] <= 1.0
    assert 0.0 <= conv["p99_abs_diff_deg"] <= conv["max_abs_diff_deg"]
    # the long solve keeps its best iterate, which includes the short solve's path
    assert conv["objective_ratio_median"] >= 1.0 - 1e-6
    assert "1,000-step solve" in harness.format_table(records).replace("1000-step", "1,000-step")


def test_cli_arguments_parse():
    ap = argparse.ArgumentParser()
    harness.add_arguments(ap)
    a = ap.parse_args(["--quick", "--device", "cpu", "--json", "x.json", "--landmarks", "86"])
    assert a.quick and a.device == "cpu" and a.landmarks == [86] and a.json == "x.json"


def test_configs_option_parses_and_rejects_bad_items():
    ap = argparse.ArgumentParser()
    harness.add_arguments(ap)
    a = ap.parse_args(["--configs", "relaxed:10:10,full:5:3"])
    assert a.configs == [("relaxed", 10, 10), ("full", 5, 3)]
    assert harness.make_plan(True, "cpu", configs=a.configs).configs == (
        ("relaxed", 10, 10),
        ("full", 5, 3),
    )
    for bad in ("relaxed:10", "fast:10:10", "relaxed:0:10", "relaxed:a:10", "relaxed:1:2:3"):
        with pytest.raises(SystemExit):
            ap.parse_args(["--configs", bad])


def test_full_cli_options_reach_the_config():
    ap = argparse.ArgumentParser()
    harness.add_arguments(ap)
    a = ap.parse_args(["--full-clusters", "2", "--full-iterations", "10"])
    assert harness.full_config(a.full_clusters, a.full_iterations) == FullConfig(
        clusters=2, iterations=10
    )
    with pytest.raises(ConfigError):
        harness.full_config(-1, None)


def test_json_round_trip(records, tmp_path):
    out = tmp_path / "sub" / "bench.json"
    harness.write_json(records, out)
    assert json.loads(out.read_text()) == json.loads(json.dumps(records))


def test_main_reports_a_bad_option_as_one_line(capsys):
    assert bench.main(["--full-clusters", "-1"]) == 2
    assert "full clusters=-1" in capsys.readouterr().err


@pytest.mark.parametrize(
    "command",
    [
        ["benchmarks/bench_projection.py"],  # the documented command
        ["-m", "benchmarks.bench_projection"],
    ],
)
def test_the_script_runs_from_a_checkout(command):
    res = subprocess.run(
        [sys.executable, *command, "--help"], cwd=ROOT, capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr
    assert "--full-clusters" in res.stdout and "--no-streaming" in res.stdout


def test_the_package_has_no_bench_command():
    # benchmarks/ is not installed with the package: the CLI cannot offer it
    sub = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert "bench" not in sub.choices and "retarget" in sub.choices


def test_rollout_benchmark_runs():
    # the rollout records come from benchmarks/bench_rollout.py: a signature change there once
    # turned every rollout record into "skipped" without failing anything
    import jax

    (rec,) = bench.bench_rollout(True, jax.devices("cpu")[0], frames=2)
    assert rec.get("skipped") is None, rec.get("skipped")
    assert rec["batch"] == 64 and rec["steps"] == 64 * 2 * 33 and rec["steps_per_s"] > 0
    assert rec["mjx_vs_cpu_max_dq_rad"] < 1e-3
