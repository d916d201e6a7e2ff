"""Notebooks must run top to bottom."""

import os
import runpy
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.py"))


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path, tmp_path, monkeypatch):
    out = tmp_path / "figure.png"
    monkeypatch.setenv("JAXPROJ_NOTEBOOK_OUT", str(out))
    runpy.run_path(str(path), run_name="__main__")
    assert out.stat().st_size > 10_000
    assert os.environ["JAXPROJ_NOTEBOOK_OUT"] == str(out)
