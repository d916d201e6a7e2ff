"""The README stays short and its Python example runs.

The example is the README's one fenced ``python`` block: read a recording, build a small
projector, retarget, save a motion. It runs as written, in a temporary folder, and the motion
file it writes must load with one ``(26,)`` pose per recorded frame.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import jaxproj
from jaxproj.io import datasets
from jaxproj.robots.nao_h25 import robot

README = Path(__file__).resolve().parents[2] / "README.md"
MAX_LINES = 150
"""The README's length limit (issue 28): what, install, the two commands, the example, links."""

FENCE = re.compile(r"^```python\n(.*?)^```$", re.DOTALL | re.MULTILINE)


def python_blocks(text: str) -> list[str]:
    """The sources of the fenced ``python`` blocks of a Markdown text, in order."""
    return FENCE.findall(text)


def test_readme_is_short() -> None:
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"README.md has {n} lines (at most {MAX_LINES}: move detail to docs/)"


def test_readme_has_one_short_python_example() -> None:
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) == 1, f"README.md should hold one python block, found {len(blocks)}"
    code_lines = [line for line in blocks[0].splitlines() if line.strip()]
    assert len(code_lines) <= 10, f"the example has {len(code_lines)} lines (at most 10)"


def test_readme_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (code,) = python_blocks(README.read_text(encoding="utf-8"))
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {"__name__": "readme_example"})

    # the example retargets the first bundled take of subject 2, action 1, and saves it
    seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]
    n_frames = seq.positions.shape[0]
    path = tmp_path / "motion.npz"
    assert path.is_file()
    motion = jaxproj.load_motion(path)
    assert motion.angles.shape == (n_frames, 26)
    assert motion.angles.dtype == np.float32
    assert motion.times.shape == (n_frames,)
    assert np.all(np.diff(motion.times) > 0)
    np.testing.assert_array_equal(motion.valid, seq.valid)
    # angles are real robot poses: finite and within the joint limits
    lower, upper = robot.LOWER, robot.UPPER
    assert np.all(np.isfinite(motion.angles))
    assert np.all((motion.angles >= lower) & (motion.angles <= upper))
    # and they moved: the recorded arm motion is not a held pose
    assert np.ptp(motion.angles[motion.valid], axis=0).max() > 0.1
