"""The notebooks (``notebooks/*.ipynb``): each runs top to bottom in fast mode (``JAXPROJ_FAST=1``)
and its results hold up; each committed notebook holds the outputs of a full run of its current
code cells under the current release (``jaxproj.__version__``; see ``jaxproj.viz.notebook`` and
``notebooks/execute.py``)."""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import nbformat
import numpy as np
import pytest

import jaxproj
from jaxproj.eval import evaluate
from jaxproj.projection import api as engine
from jaxproj.robots.nao_h25 import ik, robot
from jaxproj.viz import notebook

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK_DIR = ROOT / "notebooks"
NAMES = ("01_quickstart", "02_paper_experiments", "03_generalisation", "04_mjx_rollout")
MAX_BYTES = 1_500_000
"""Largest committed notebook (outputs included)."""

HEADER = re.compile(r"jaxproj (?P<version>\S+) \| mode: (?P<mode>full|fast)\b")
"""What ``notebook.header`` prints in each notebook's first code cell."""

LO, HI = robot.LOWER[robot.DRIVEN_INDEX], robot.UPPER[robot.DRIVEN_INDEX]


def _executor() -> Any:
    """``notebooks/execute.py`` as a module (the folder is not a package)."""
    spec = importlib.util.spec_from_file_location("nb_execute", NOTEBOOK_DIR / "execute.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_notebook_is_listed() -> None:
    assert tuple(p.stem for p in _executor().NOTEBOOKS) == NAMES
    assert set(RESULT_CHECKS) == set(MIN_FIGURES) == set(NAMES)


# ----------------------------------------------------------------------------- outputs


def _text(output: Any) -> str:
    if output.output_type == "stream":
        return output.text
    return "".join(str(v) for v in output.get("data", {}).values() if isinstance(v, str))


def _check_outputs(nb: Any, name: str, mode: str) -> str:
    """Every code cell ran once, in order, without an error or a warning, and shows something;
    the first one printed the header of ``mode``. Returns the version the header holds."""
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, name
    for i, cell in enumerate(code, start=1):
        where = f"{name}, code cell {i}: {cell.source.splitlines()[0]!r}"
        assert cell.execution_count == i, f"{where}: not executed in order (re-run execute.py)"
        assert cell.outputs, f"{where}: no output"
        for out in cell.outputs:
            assert out.output_type != "error", f"{where}: {out.get('ename')}: {out.get('evalue')}"
            if out.output_type == "stream" and out.name == "stderr":
                bad = re.search(r"warn|error|traceback", out.text, re.I)
                assert not bad, f"{where}: {out.text}"
    match = HEADER.search("".join(_text(o) for o in code[0].outputs))
    assert match, f"{name}: the first cell does not print notebook.header()"
    assert match["mode"] == mode, f"{name}: ran in {match['mode']} mode, expected {mode}"
    return match["version"]


def _images(nb: Any) -> int:
    return sum("image/png" in o.get("data", {}) for c in nb.cells if c.cell_type == "code"
               for o in c.outputs)  # fmt: skip


MIN_FIGURES = {"01_quickstart": 2, "02_paper_experiments": 6, "03_generalisation": 4,
               "04_mjx_rollout": 5}  # fmt: skip
"""Figures each notebook draws (matplotlib PNGs; the GIF clips come on top)."""


@pytest.mark.parametrize("name", NAMES)
def test_committed_notebook_holds_a_full_run_of_the_current_code(name: str) -> None:
    path = NOTEBOOK_DIR / f"{name}.ipynb"
    rerun = f"re-run `python notebooks/execute.py {name[:2]}`"
    assert path.stat().st_size < MAX_BYTES, f"{path.name}: {path.stat().st_size} bytes"
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    meta = nb.metadata.get("jaxproj", {})
    assert meta.get("mode") == "full", f"{path.name}: not written by a full run; {rerun}"
    assert meta.get("source_sha256") == _executor().source_sha256(nb), (
        f"{path.name}: code cells edited after the run; {rerun}"
    )
    assert meta.get("version") == jaxproj.__version__, (
        f"{path.name}: executed under jaxproj {meta.get('version')}, this is "
        f"{jaxproj.__version__} (a release re-runs the notebooks); {rerun}"
    )
    version = _check_outputs(nb, name, "full")
    assert version == jaxproj.__version__, f"{path.name}: header says jaxproj {version}; {rerun}"
    assert _images(nb) >= MIN_FIGURES[name]


# ------------------------------------------------------------------- results, fast mode


def _results(folder: Path, name: str) -> tuple[dict, Any]:
    res = json.loads((folder / f"{name}.json").read_text())
    arrays = np.load(folder / f"{name}.npz") if (folder / f"{name}.npz").exists() else None
    assert res["fast"] is True
    # the kernel was this very interpreter (the test environment's, not another Python's)
    assert res["python"] == sys.executable
    return res, arrays


def _check_quickstart(folder: Path) -> None:
    res, a = _results(folder, "01_quickstart")
    d, ok, truth = a["descriptors"], a["valid"], a["truth"]
    assert ok.sum() > 20
    np.testing.assert_array_equal(truth, np.asarray(ik.solve_driven(d)))
    model = engine.load(res["model_file"])  # the model the notebook saved
    assert model.landmarks == res["landmarks"]
    # a trivial answer to beat: the mean robot pose of each chain's landmarks, for every frame
    sp = model.projector
    mean = np.zeros(len(robot.DRIVEN_JOINTS))
    for c, joints in enumerate(sp.layout.outputs):
        mean[list(joints)] = np.asarray(sp.chain(c).robot).mean(axis=0)
    baseline = np.median(evaluate.frame_errors(np.broadcast_to(mean, truth[ok].shape),
                                               truth[ok])[1])  # fmt: skip
    assert res["reload_identical"] is True and res["within_limits"] is True
    for objective in ("relaxed", "full"):
        r, smooth = a[f"projected_{objective}"], a[f"smoothed_{objective}"]
        assert r.shape == truth.shape and r.dtype == np.float32 and np.isfinite(r).all()
        assert ((r >= LO) & (r <= HI)).all(), objective
        # the saved model projects exactly what the notebook showed
        again, _ = engine.project(model, d, objective, batch_size=64)
        np.testing.assert_array_equal(again, r, err_msg=objective)
        m_max, m_avg = evaluate.frame_errors(smooth[ok], truth[ok])
        assert np.median(m_avg) == pytest.approx(res["median_M_avg"][objective], rel=1e-6)
        assert m_max.max() == pytest.approx(res["max_M_max"][objective], rel=1e-6)
        # a held-out person: not a copy of the truth, and far better than the trivial answer
        # (measured, fast mode: median M_avg 3.1 / 4.4 deg relaxed / full, trivial ~30 deg)
        assert 0.0 < np.median(m_avg) < baseline / 3, (objective, np.median(m_avg), baseline)
    n, h, w, c = res["render"]["frames"]
    assert n == 4 and c == 3 and w == 2 * 260 and h == 230


def _check_paper_experiments(folder: Path) -> None:
    res, _ = _results(folder, "02_paper_experiments")
    for name, eff in res["efficiency"].items():
        us = [r["us_per_projection"] for r in eff["rows"]]
        assert all(np.isfinite(us)) and min(us) > 0
        assert us[-1] > us[0], (name, us)  # larger neighbourhoods cost more
        assert all(r["M_avg_median"] <= r["M_max_p95"] for r in eff["rows"])
    grid = np.array(res["grid_us"])
    assert grid.shape == (len(res["grid_ls"]),) * 2 and (grid > 0).all()
    assert grid[-1, -1] > grid[0, 0]
    for name, p in res["poses"].items():
        for pose, objectives in p["poses"].items():
            for o, e in objectives.items():
                assert 0 <= e["M_avg"] <= e["M_max"] < 180, (name, pose, o)
        for objectives in p["motions"].values():
            for e in objectives.values():
                m_max, m_avg = np.array(e["M_max"]), np.array(e["M_avg"])
                assert len(m_max) == len(m_avg) > 10
                assert (m_avg <= m_max + 1e-9).all() and np.isfinite(m_max).all()
    for name, study in res["sizes"].items():
        rows = study["sizes"]
        assert [r["target"] for r in rows] == [400, 86]
        for r in rows:
            arms = [v for c, v in r["landmarks_per_chain"].items() if c != "head"]
            assert all(abs(k - r["target"]) <= 0.1 * r["target"] for k in arms), (name, r)
        # more landmarks, better projection (measured, fast mode: whole-body 13.3 -> 6.5 deg,
        # per chain 6.0 -> 1.9 deg median M_avg on held-out frames)
        assert rows[0]["M_avg_median"] < rows[1]["M_avg_median"], name
    rvf = res["relaxed_vs_full"]
    for model in ("per-chain", "whole-body"):
        assert rvf[f"{model}/relaxed"]["us"] < rvf[f"{model}/full"]["us"]
    # the default engine beats the paper's formulation on held-out people (fast: 0.8 vs 5.0)
    assert rvf["per-chain/relaxed"]["median_M_avg"] < rvf["whole-body/relaxed"]["median_M_avg"]


def _check_generalisation(folder: Path) -> None:
    res, _ = _results(folder, "03_generalisation")
    r = res["results"]
    assert set(r) == {f"{m}/{s}" for m in ("per-chain", "whole-body")
                      for s in ("MSR held-out", "UTKinect")}  # fmt: skip
    for key, v in r.items():
        assert v["finite"] and v["within_limits"], key
    for split in ("MSR held-out", "UTKinect"):
        pc, wb = r[f"per-chain/{split}"], r[f"whole-body/{split}"]
        # measured, fast mode: median M_avg 0.6 vs 4.3 (MSR), 1.1 vs 6.8 (UTKinect)
        assert pc["median_M_avg"] < wb["median_M_avg"] / 2, split
        assert pc["p95_M_max"] < wb["p95_M_max"], split
        assert pc["hand_cm_p95"] < wb["hand_cm_p95"], split
        assert pc["p95_M_max_no_elbow_yaw"] <= pc["p95_M_max"]
    tail = res["tail"]
    frames = res["frames"]["MSR held-out"]
    assert abs(tail["frames"] - 0.05 * frames) <= 0.01 * frames + 1
    assert sum(tail["worst_joint_counts"].values()) == tail["frames"]
    assert all(w["m_max"] >= tail["cut_deg"] for w in res["worst"])
    assert len({w["motion"] for w in res["worst"]}) == len(res["worst"]) == 4
    for key in ("elbow_yaw_share", "straight_share", "straight_share_rest"):
        assert 0.0 <= tail[key] <= 1.0


def _check_rollout(folder: Path) -> None:
    res, _ = _results(folder, "04_mjx_rollout")
    s = res["summaries"]
    assert set(s) == set(res["finite"]) == {"IK", "relaxed", "relaxed, feasible"}
    assert all(res["finite"].values())
    n = int(np.sum(res["lengths"]))
    for name, x in s.items():
        assert x["frames"] == n and x["motions"] == len(res["motions"]) == 4
        assert np.isfinite(x["tracking_error_deg"]["mean"]), name
        assert x["joint_limit_violations"]["target_frames"] == 0, name  # targets are clipped
    # what the feasibility filter promises, checked on its targets: no speed-limit frame
    assert res["target_speed_violations"]["relaxed, feasible"] == 0
    assert res["target_speed_violations"]["IK"] > 0
    # and what it buys in simulation (measured, fast mode: tracking mean 4.5 / 3.0 / 0.8 deg)
    feas = s["relaxed, feasible"]["tracking_error_deg"]["mean"]
    assert feas < s["relaxed"]["tracking_error_deg"]["mean"] < s["IK"]["tracking_error_deg"]["mean"]
    assert s["relaxed, feasible"]["speed"]["max_ratio"] < s["IK"]["speed"]["max_ratio"]
    assert res["rendered"] == [4, 220, 480, 3]


RESULT_CHECKS: dict[str, Callable[[Path], None]] = {
    "01_quickstart": _check_quickstart,
    "02_paper_experiments": _check_paper_experiments,
    "03_generalisation": _check_generalisation,
    "04_mjx_rollout": _check_rollout,
}
"""Each notebook's checks of the results it wrote in fast mode."""


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_notebook_runs_in_fast_mode_and_its_results_hold(name: str, tmp_path: Path) -> None:
    # the kernels inherit the run's persistent XLA compilation cache (tests/conftest.py)
    env = {notebook.RESULTS_ENV: str(tmp_path)}
    # a cell that raises fails the test here (nbclient's CellExecutionError, with its traceback)
    nb = _executor().execute(NOTEBOOK_DIR / f"{name}.ipynb", fast=True, env=env, timeout=600)
    _check_outputs(nb, name, "fast")
    assert _images(nb) >= MIN_FIGURES[name]
    RESULT_CHECKS[name](tmp_path)
