"""The main job end to end (quick mode): the report's files, layout and headline ordering."""

import json

import pytest

from jaxproj.paper import demo
from jaxproj.paper.demo import run_demo


@pytest.mark.slow
def test_demo_quick_writes_the_report(tmp_path):
    out = tmp_path / "report"
    run_demo(out, quick=True)
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
    assert r["timings"]["total_s"] > 0
    assert r["quick"] is True and "**Quick run**" in md
    # the default output is the zero-lag offline smoother's, labelled; confidence by decile
    assert r["smoothing"]["kind"] == "offline" and "zero-lag offline RTS smoother" in md
    assert abs(r["smoothness"]["relaxed"]["lag_frames_smoothed"]) < 0.5
    deciles = r["confidence"]["relaxed"]["deciles"]
    assert len(deciles) == 10 and "## Confidence: which frames to distrust" in md
    assert deciles[0]["M_max_median"] > deciles[-1]["M_max_median"]
