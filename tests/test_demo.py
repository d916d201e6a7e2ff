"""The main job end to end (quick mode): the report's files, layout and headline ordering."""

import json

import pytest

from jaxproj.demo import run_demo


@pytest.mark.slow
def test_demo_quick_writes_the_report(tmp_path):
    out = tmp_path / "report"
    run_demo(out, quick=True)
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert len(pngs) >= 3 and "landmark_size.png" in pngs and "error_distributions.png" in pngs
    for p in out.glob("*.png"):
        assert p.stat().st_size > 10_000
    md = (out / "report.md").read_text()
    assert "## MJX rollout" in md and "### Landmark-set size" in md
    r = json.loads((out / "report.json").read_text())
    s = r["summary"]
    for stat in ("mean", "median", "p95", "max"):
        assert s["relaxed"]["M_avg"][stat] >= 0
    # the acceptance ordering: the projection beats the nearest-landmark baseline
    for method in ("relaxed", "full"):
        assert s[method]["M_avg"]["median"] < s["nearest_landmark"]["M_avg"]["median"]
        assert s[method]["M_max"]["p95"] < s["nearest_landmark"]["M_max"]["p95"]
    assert r["rollout"]["relaxed"]["motions"] == 8
    assert {row["landmarks"] for row in r["experiments"]["landmark_size"]["sizes"]} >= {1635}
    assert r["timings"]["total_s"] > 0
