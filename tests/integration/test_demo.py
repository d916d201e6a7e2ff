"""The main job end to end (quick mode): the report's files, layout and headline ordering."""

import json
import re
import time

import numpy as np
import pytest

from jaxproj._internal.progress import Heartbeat
from jaxproj.errors import ConfigError
from jaxproj.io import datasets
from jaxproj.paper import demo, demo_report
from jaxproj.paper.demo import run_demo
from jaxproj.projection import api as engine


def _tables_without_caption(md: str) -> list[str]:
    """The header rows of the report's tables whose nearest line of text above does not say
    the table's split, frames and metric."""
    lines = md.splitlines()
    bad = []
    for i, line in enumerate(lines):
        if line.startswith("|") and (i == 0 or not lines[i - 1].startswith("|")):
            above = next((x for x in reversed(lines[:i]) if x.strip()), "")
            if not re.search(r"\*Split:\* .+\*Frames:\* .+\*Metric:\* .+", above):
                bad.append(line)
    return bad


def test_the_default_model_trains_on_utkinect_people_and_is_scored_on_the_others():
    cfg = engine.BuildConfig()
    assert cfg.utkinect_people == datasets.UTK_TRAIN_SUBJECTS == (3, 4, 6)
    train = datasets.training_sequences(cfg.utkinect_people)
    utk_train = {s.subject for s in train if s.name.startswith("s")}  # UTKinect: "s03_e01"
    assert utk_train == {3, 4, 6} and sum(s.action == 0 for s in train) == 6  # whole recordings
    assert {s.subject for s in train if s.name.startswith("a")} == set(datasets.TRAIN_SUBJECTS)
    # the demo's UTKinect split: upper-body segments of the people the model never saw
    split = demo.utkinect_split(cfg)
    assert {s.subject for s in split} == set(datasets.UTK_TEST_SUBJECTS) == {7, 9}
    assert {s.action for s in split} <= set(datasets.UTK_UPPER_BODY_ACTIONS)
    msr_only = engine.BuildConfig(utkinect_people=())
    assert {s.subject for s in demo.utkinect_split(msr_only)} == set(datasets.UTK_SUBJECTS)
    assert len(demo.utkinect_split(cfg, quick=True)) == (len(split) + 1) // 2
    with pytest.raises(ConfigError, match="none is left"):
        datasets.utkinect_held_out(datasets.UTK_SUBJECTS)


def test_the_report_names_the_training_and_test_people():
    r = {
        "train_subjects": [1, 3, 5, 7, 9],
        "train_utkinect_people": [3, 4, 6],
        "test_utkinect_people": [7, 9],
        "comparison_frames": {"utkinect": 578},
        "build": {"landmarks": {"head": 1, "left_arm": 2, "right_arm": 3},
                  "bandwidth": {"head": 0.1, "left_arm": 0.2, "right_arm": 0.2},
                  "train_frames": 16005, "default_model": True},
    }  # fmt: skip
    assert "people 7,9, whom the model never saw" in demo_report._utk_split(r)
    assert "578 valid frames" in demo_report._utk_split(r)
    assert "MSR subjects 1,3,5,7,9 and UTKinect-Action3D people 3,4,6" in (
        demo_report._model_words(r)
    )


@pytest.mark.slow
def test_demo_quick_writes_the_report(tmp_path, monkeypatch):
    out = tmp_path / "report"
    said: list[tuple[float, str]] = []
    t0 = time.monotonic()

    def record(text: str) -> None:
        said.append((time.monotonic(), text))

    monkeypatch.setattr(demo, "Heartbeat", lambda: Heartbeat(emit=record))
    run_demo(out, quick=True)
    # progress: a line at once, then never 30 s of silence; every stage says where it is; once
    # a kind of work is measured, the steps that repeat it carry estimates (stage and all)
    gaps = np.diff([t0] + [t for t, _ in said])
    assert gaps[0] < 10.0 and gaps.max() < 30.0, gaps.max()
    steps = {k: [x for _, x in said if re.match(rf"\[{k}/5\] \d+/\d+ (?!still )", x)]
             for k in range(1, 6)}  # fmt: skip
    assert all(steps.values()), steps
    estimated = steps[4] + steps[3][2:] + steps[2][1:]
    assert estimated and all("stage ~" in x and " left (estimates;" in x for x in estimated)
    assert re.search(r"\(\d+ s in all: build_per_chain .*experiments .*report ", said[-1][1])
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert len(pngs) >= 3 and "landmark_size.png" in pngs and "error_distributions.png" in pngs
    for p in out.glob("*.png"):
        assert p.stat().st_size > 10_000
    md = (out / "report.md").read_text()
    assert "## MuJoCo rollout" in md and "### Landmark-set size" in md
    r = json.loads((out / "report.json").read_text())
    s = r["summary"]
    for stat in ("mean", "median", "p95", "max"):
        assert s["relaxed"]["M_avg"][stat] >= 0
    # the acceptance ordering: the projection beats the nearest-landmark baseline
    for method in ("relaxed", "full"):
        assert s[method]["M_avg"]["median"] < s["nearest_landmark"]["M_avg"]["median"]
        assert s[method]["M_max"]["p95"] < s["nearest_landmark"]["M_max"]["p95"]
    assert r["rollout"]["relaxed"]["motions"] == 8
    assert r["rollout"]["backend"] == "mujoco"  # auto, on a CPU-only machine: CPU MuJoCo
    sizes = r["experiments"]["landmark_size"]["sizes"]
    assert [row["target"] for row in sizes] == [demo.QUICK_LANDMARKS, 86]  # quick: two sizes
    for row in sizes:  # each arm chain reaches its target within the bisection's 5 %
        arms = [row["landmarks_per_chain"][c] for c in ("left_arm", "right_arm")]
        assert all(abs(k - row["target"]) <= 0.05 * row["target"] for k in arms), row
    # whole-body and per-chain side by side, on both datasets; per chain beats whole body
    comp = r["comparison"]
    assert set(comp) == {"per_chain", "whole_body"}
    for model in comp.values():
        assert set(model) == {"msr_held_out", "utkinect"}
    for split in ("msr_held_out", "utkinect"):
        a = comp["per_chain"][split]["relaxed"]["M_avg"]["median"]
        b = comp["whole_body"][split]["relaxed"]["M_avg"]["median"]
        assert a < b
    assert "## Whole-body vs per-chain" in md
    # the default training set; UTKinect scored only on people the model never saw
    assert r["train_utkinect_people"] == list(datasets.UTK_TRAIN_SUBJECTS)
    assert r["test_utkinect_people"] == list(datasets.UTK_TEST_SUBJECTS)
    assert r["timings"]["total_s"] > 0
    assert r["quick"] is True and "**Quick run**" in md
    # the results page's protocol: held-out arm actions; every table says what it measured
    assert set(r["test_actions"]) == set(datasets.ARM_ACTIONS)
    assert all(a.split()[0] in {f"a{x:02d}" for x in datasets.ARM_ACTIONS} for a in r["per_action"])
    assert "## Headline: accuracy on held-out people" in md
    assert _tables_without_caption(md) == []
    assert " nan" not in md and "+nan" not in md
    # one model, one set of frames, one number: the headline, the landmark-size row of the
    # same model and the efficiency study's L = M = 10 row
    relaxed = r["unsmoothed"]["relaxed"]["M_avg"]["median"]
    (same,) = [row for row in sizes if row["target"] == demo.QUICK_LANDMARKS]
    (l10,) = [row for row in r["experiments"]["efficiency"]["rows"] if row["L"] == 10]
    assert same["M_avg_median"] == relaxed == l10["M_avg_median"]
    assert same["eval_frames"] == r["valid_frames"]
    # which method and why, with this run's numbers; the IK through the same filter beside it
    assert "## Which method, and why" in md and "**Recommended: " in md
    ro = r["rollout"]
    assert set(ro["trajectories"]) == {"ik", "ik_feasible", "relaxed", "relaxed_feasible"}
    assert f"{ro['ik_feasible']['tracking_error_deg']['mean']:.2f} deg mean" in md
    assert f"{ro['relaxed_feasible']['tracking_error_deg']['mean']:.2f} deg mean" in md
    # stdout's summary says what its table is
    out = demo_report.stdout_summary(r)
    assert out.startswith("Headline (the results page's protocol) QUICK RUN")
    assert f"{r['valid_frames']:,} valid frames" in out and "| split | frames | method |" in out
    # the default output is the zero-lag offline smoother's, labelled; confidence by decile
    assert r["smoothing"]["kind"] == "offline" and "zero-lag offline RTS smoother" in md
    assert abs(r["smoothness"]["relaxed"]["lag_frames_smoothed"]) < 0.5
    deciles = r["confidence"]["relaxed"]["deciles"]
    assert len(deciles) == 10 and "## Confidence: which frames to distrust" in md
    assert deciles[0]["M_max_median"] > deciles[-1]["M_max_median"]
